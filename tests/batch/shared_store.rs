//! Several runs into one store: shards that fill it as a single run does, two unsharded
//! runs at once (an overwrite meanwhile refused), and a run with other parameters refused
//! unless it overwrites (a folder that is no store never touched).

use std::collections::BTreeSet;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::afe;
use serde_json::Value;

use crate::common;

use super::{
    afe_err, afe_ok, assert_same, assert_same_stores, events, extracted, good_corpus,
    ledger_records, s, sorted, status, stderr, stored, stored_ids, TempDir,
};

#[test]
fn shards_fill_one_store_as_a_single_run_does() {
    let tmp = TempDir::new("shards");
    let corpus = tmp.join("corpus");
    let ids = good_corpus(&corpus, 16);
    let single = tmp.join("single.zarr");
    let sharded = tmp.join("sharded.zarr");
    let base = [
        "-r",
        "ratemap",
        "-p",
        "fb_nChannels=16",
        "--progress",
        "jsonl",
    ];
    let mut args = vec!["batch", s(&corpus), "-o", s(&single)];
    args.extend(base);
    afe_ok(&args);
    let mut counts = Vec::new();
    for shard in ["0/2", "1/2"] {
        let mut args = vec!["batch", s(&corpus), "-o", s(&sharded), "--shard", shard];
        args.extend(base);
        let ev = events(&afe_ok(&args));
        counts.push(ev[0]["files"].as_u64().expect("files"));
    }
    assert_eq!(counts.iter().sum::<u64>(), ids.len() as u64, "{counts:?}");
    assert!(counts.iter().all(|&n| n > 0), "{counts:?}");
    assert_eq!(status(&sharded)["done"], ids.len());
    assert_same_stores(&sharded, &single);

    let bad_store = tmp.join("bad.zarr");
    for (shard, needle) in [
        ("2/2", "shard 2/2"),
        ("1/0", "shard 1/0"),
        ("x", "--shard 'x'"),
        ("1-2", "--shard '1-2'"),
    ] {
        afe_err(
            &[
                "batch",
                s(&corpus),
                "-r",
                "ratemap",
                "-o",
                s(&bad_store),
                "--shard",
                shard,
            ],
            &[needle, "I/N"],
        );
        assert!(!bad_store.exists(), "{shard} created the store");
    }
}

#[test]
fn other_parameters_are_refused_unless_overwrite() {
    let tmp = TempDir::new("params");
    let corpus = tmp.join("corpus");
    good_corpus(&corpus, 4);
    let store = tmp.join("store.zarr");
    let run = |n: &str, extra: &[&str]| {
        let p = format!("fb_nChannels={n}");
        let mut args = vec![
            "batch",
            s(&corpus),
            "-r",
            "ratemap",
            "-p",
            &p,
            "-o",
            s(&store),
            "--progress",
            "none",
        ];
        args.extend(extra);
        afe(&args)
    };
    assert!(run("8", &[]).status.success());
    let hash8 = status(&store)["param_hash"].clone();
    let out = run("16", &[]);
    assert!(!out.status.success());
    let err = stderr(&out);
    for needle in [
        r#""fb_nChannels":8"#,
        r#""fb_nChannels":16"#,
        "--overwrite",
        s(&store),
    ] {
        assert!(err.contains(needle), "'{needle}' not in: {err}");
    }
    // refused before anything was touched
    assert_eq!(status(&store)["param_hash"], hash8);
    assert_eq!(stored(&store, "top00.wav")[0].1[1], 8);

    assert!(run("16", &["--overwrite"]).status.success());
    let st = status(&store);
    assert_ne!(st["param_hash"], hash8);
    assert_eq!(st["params"]["fb_nChannels"], 16);
    assert_eq!(st["done"], 4);
    assert_eq!(stored_ids(&store).len(), 4);
    assert_eq!(stored(&store, "top00.wav")[0].1[1], 16);
    // the same parameters again: accepted, nothing to redo
    let out = run("16", &[]);
    assert!(out.status.success());
    assert!(
        stderr(&out).contains("0 done now, 4 done before"),
        "{}",
        stderr(&out)
    );

    // a folder that is not a store is never touched
    let other = tmp.join("other");
    std::fs::create_dir_all(&other).expect("dir");
    std::fs::write(other.join("keep.txt"), "mine").expect("write");
    afe_err(
        &["batch", s(&corpus), "-r", "ratemap", "-o", s(&other)],
        &["not an afe store"],
    );
    assert_eq!(std::fs::read_dir(&other).expect("dir").count(), 1);
}

/// Spawns `afe` with `args`, its stdout piped (the `--progress jsonl` events) and its
/// stderr kept.
fn spawn(args: &[&str]) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_afe"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn afe")
}

/// Waits until `store` records a finished file, or panics if `child` ends first.
fn wait_for_first_record(child: &mut std::process::Child, store: &Path) {
    let start = Instant::now();
    while !ledger_records(store).iter().any(|r| r["status"] == "done") {
        if let Some(code) = child.try_wait().expect("try_wait") {
            panic!("the run ended ({code}) before any file was recorded");
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no file recorded in 60 s"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// The summary event of a finished `--progress jsonl` run, which must have succeeded.
fn summary_of(child: std::process::Child) -> Value {
    let out = child.wait_with_output().expect("wait");
    assert!(out.status.success(), "afe batch failed: {}", stderr(&out));
    let ev = events(&out);
    let last = ev.last().expect("events").clone();
    assert_eq!(last["event"], "summary", "{ev:?}");
    last
}

#[test]
fn two_unsharded_runs_share_one_store_and_an_overwrite_meanwhile_is_refused() {
    let tmp = TempDir::new("concurrent");
    let corpus = tmp.join("corpus");
    let ids = good_corpus(&corpus, 24);
    let store = tmp.join("store.zarr");
    let params = ["-r", "ratemap,ild,itd,ic", "-p", "fb_nChannels=16"];
    let mut args = vec!["batch", s(&corpus), "-o", s(&store)];
    args.extend(params);
    args.extend(["-j", "1", "--progress", "jsonl"]);
    // the second run starts while the first one is writing (it has recorded one file)
    let mut first = spawn(&args);
    wait_for_first_record(&mut first, &store);
    let second = spawn(&args);
    // an overwrite with other parameters while they write: refused, naming a run
    let line = afe_err(
        &[
            "batch",
            s(&corpus),
            "-r",
            "ratemap",
            "-o",
            s(&store),
            "--overwrite",
            "--progress",
            "none",
        ],
        &["another run is writing the store", "--overwrite"],
    );
    assert!(
        line.contains(&format!("pid {} on ", first.id()))
            || line.contains(&format!("pid {} on ", second.id())),
        "{line}"
    );
    let (a, b) = (summary_of(first), summary_of(second));
    // mono files cannot give an ILD: they fail in whichever run takes them
    let count = |v: &Value, key: &str| v[key].as_u64().expect(key);
    let failed = |v: &Value| v["failed"].as_array().expect("failed").len() as u64;
    for run in [&a, &b] {
        assert_eq!(count(run, "files"), ids.len() as u64, "{run}");
        assert_eq!(
            count(run, "done")
                + count(run, "done_elsewhere")
                + count(run, "already_done")
                + failed(run),
            ids.len() as u64,
            "{run}"
        );
    }
    // each good file computed by exactly one of them; the second run did share the work
    let mono = ids.len() as u64 - ids.len() as u64 / 4 * 3;
    assert_eq!(
        count(&a, "done") + count(&b, "done"),
        ids.len() as u64 - mono
    );
    assert!(count(&b, "already_done") < ids.len() as u64 - mono, "{b}");

    let st = status(&store);
    assert_eq!(st["done"], ids.len() as u64 - mono, "{st}");
    assert_eq!(st["missing"], serde_json::json!([]), "{st}");
    assert_eq!(
        st["params"]["fb_nChannels"], 16,
        "the overwrite touched the store"
    );
    // every file of the corpus holds what `afe extract` computes, or failed for its ILD
    let npz = tmp.join("x.npz");
    let failed_ids: BTreeSet<&str> = st["failed"]
        .as_array()
        .expect("failed")
        .iter()
        .map(|r| r["id"].as_str().expect("id"))
        .collect();
    for id in &ids {
        let wav = hound::WavReader::open(corpus.join(id)).expect("wav").spec();
        if wav.channels == 1 {
            assert!(failed_ids.contains(id.as_str()), "{id}");
            continue;
        }
        let want = sorted(extracted(&corpus.join(id), &params, &npz));
        assert_same(&stored(&store, id), &want, id);
    }
}
