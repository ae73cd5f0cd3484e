//! Failures: recorded, or stopping the run with `--on-error stop`; a store that cannot be
//! written; and what is refused: ids that nest, inputs that are no regular file, ids too
//! long for a file name.

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

use serde_json::Value;

use super::{
    afe_err, afe_ok, assert_same, events, extracted, good_corpus, s, sorted, status, stderr,
    stored, stored_ids, TempDir, REQUESTS,
};

#[test]
fn failures_are_recorded_or_stop_the_run() {
    let tmp = TempDir::new("stop");
    let corpus = tmp.join("corpus");
    good_corpus(&corpus, 6);
    // a mono file cannot give an ILD
    let store = tmp.join("skip.zarr");
    let out = afe_ok(&[
        "batch",
        s(&corpus),
        "-r",
        "ratemap,ild",
        "-o",
        s(&store),
        "--progress",
        "none",
    ]);
    assert!(stderr(&out).contains("2 failed"), "{}", stderr(&out));
    let st = status(&store);
    let failed: Vec<&Value> = st["failed"].as_array().expect("failed").iter().collect();
    let ids: Vec<&str> = failed
        .iter()
        .map(|r| r["id"].as_str().expect("id"))
        .collect();
    assert_eq!(ids, ["spk1/session 0/utt04.wav", "top00.wav"]);
    for r in &failed {
        let e = r["error"].as_str().expect("error");
        assert!(e.contains("ild"), "{e}");
        assert!(e.contains("two"), "{e}");
    }
    assert_eq!(st["done"], 4);

    // longest first on one worker: the 1.5 s stereo file, then the 1.21 s mono one fails
    let store = tmp.join("stop.zarr");
    afe_err(
        &[
            "batch",
            s(&corpus),
            "-r",
            "ratemap,ild",
            "-o",
            s(&store),
            "-j",
            "1",
            "--on-error",
            "stop",
            "--progress",
            "none",
        ],
        &["stopped at 'spk1/session 0/utt04.wav'", "ild"],
    );
    let st = status(&store);
    assert_eq!(st["failed"].as_array().expect("failed").len(), 1, "{st}");
    assert_eq!(st["done"], 1, "{st}");
    assert_eq!(
        stored_ids(&store),
        BTreeSet::from(["top05.wav".to_string()])
    );
}

#[test]
fn a_store_that_cannot_be_written_stops_the_run_and_leaves_the_files_to_resume() {
    let tmp = TempDir::new("full");
    let corpus = tmp.join("corpus");
    let ids = good_corpus(&corpus, 12);
    let store = tmp.join("store.zarr");
    let params = ["-r", REQUESTS, "-p", "fb_nChannels=8"];
    let mut args = vec!["batch", s(&corpus), "-o", s(&store)];
    args.extend(params);
    args.extend(["-j", "1", "--progress", "none"]);
    // a file size limit of 64 blocks (32 or 64 KiB): writing a longer chunk fails with
    // EFBIG (SIGXFSZ ignored), as a full disk fails with ENOSPC
    let out = Command::new("sh")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 64 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_afe"))
        .args(&args)
        .output()
        .expect("run sh");
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let line = err
        .lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or_else(|| panic!("no error line in: {err}"));
    for needle in [
        "cannot write the store",
        "File too large",
        "run the same command again",
    ] {
        assert!(line.contains(needle), "'{needle}' not in: {line}");
    }
    // no file is recorded as failed, and what is recorded is whole
    let st = status(&store);
    assert_eq!(st["failed"], serde_json::json!([]), "{st}");
    assert_eq!(st["missing"], serde_json::json!([]), "{st}");
    let before = st["done"].as_u64().expect("done");
    assert!(before < ids.len() as u64, "{st}");

    let ev = events(&afe_ok(&{
        let mut a = args.clone();
        a.pop();
        a.push("jsonl");
        a
    }));
    assert_eq!(ev[0]["already_done"], before);
    let st = status(&store);
    assert_eq!(st["done"], ids.len(), "{st}");
    let npz = tmp.join("x.npz");
    for id in &ids {
        let want = sorted(extracted(&corpus.join(id), &params, &npz));
        assert_same(&stored(&store, id), &want, id);
    }
}

/// Issue 57, finding 8: ids of two manifests that nest (`p` and `p/q`) never share one
/// store, whichever comes first; and a store where they nest already (the ledger of one
/// lost, as when two runs start at once) never has the inner file deleted by the outer
/// one's redo.
#[test]
fn ids_that_nest_with_the_stores_are_refused_and_never_delete_a_finished_file() {
    let tmp = TempDir::new("nest");
    let corpus = tmp.join("corpus");
    let files = good_corpus(&corpus, 2);
    let outer = corpus.join("a.tsv");
    std::fs::write(&outer, format!("p\t{}\n", files[0])).expect("write");
    let inner = corpus.join("b.tsv");
    std::fs::write(&inner, format!("p/q\t{}\n", files[1])).expect("write");
    let run = |manifest: &Path, store: &Path| {
        vec![
            "batch".to_string(),
            s(manifest).to_string(),
            "-r".into(),
            "ratemap".into(),
            "-p".into(),
            "fb_nChannels=4".into(),
            "-o".into(),
            s(store).to_string(),
            "--progress".into(),
            "none".into(),
        ]
    };
    fn args(v: &[String]) -> Vec<&str> {
        v.iter().map(String::as_str).collect()
    }
    for (first, second, id, stored) in [(&outer, &inner, "p/q", "p"), (&inner, &outer, "p", "p/q")]
    {
        let store = tmp.join(&format!("first-{}.zarr", stored.replace('/', "-")));
        afe_ok(&args(&run(first, &store)));
        let before = stored_ids(&store);
        afe_err(
            &args(&run(second, &store)),
            &[
                &format!("file id '{id}' nests with '{stored}', which the store"),
                "redoing 'p' would delete 'p/q'",
                "give",
            ],
        );
        assert_eq!(stored_ids(&store), before);
    }
    // a store holding both (the inner one's record lost): the outer one's redo fails
    // with the reason and leaves the inner one whole
    let store = tmp.join("both.zarr");
    afe_ok(&args(&run(&inner, &store)));
    std::fs::remove_dir_all(store.join(".afe-batch")).expect("rm logs");
    let out = afe_ok(&args(&run(&outer, &store)));
    let err = stderr(&out) + &String::from_utf8_lossy(&out.stdout);
    assert!(
        err.contains("file id 'p' is also the folder of 'p/q'"),
        "{err}"
    );
    assert!(stored_ids(&store).contains("p/q"));
    let q = store.join("p/q/ratemap_left");
    assert!(q.join("zarr.json").is_file() && q.join("c/0/0").is_file());
}

/// Issue 57, minor: a FIFO or a device as an input is "not a regular file", and an id
/// with a part too long for a file name is refused before anything is written.
#[test]
fn a_device_or_fifo_input_and_an_overlong_id_are_refused_clearly() {
    let tmp = TempDir::new("messages");
    let store = tmp.join("s.zarr");
    let fifo = tmp.join("live");
    let made = Command::new("mkfifo").arg(&fifo).status();
    assert!(made.is_ok_and(|s| s.success()), "mkfifo");
    for input in [Path::new("/dev/null"), fifo.as_path()] {
        afe_err(
            &["batch", s(input), "-r", "ratemap", "-o", s(&store)],
            &[s(input), "not a regular file (a FIFO or a device)"],
        );
    }
    let files = good_corpus(&tmp.join("corpus"), 1);
    let manifest = tmp.join("corpus/long.tsv");
    std::fs::write(&manifest, format!("{}\t{}\n", "x".repeat(300), files[0])).expect("write");
    afe_err(
        &["batch", s(&manifest), "-r", "ratemap", "-o", s(&store)],
        &[
            "a part is 300 bytes long, more than the 200",
            "give a shorter id",
        ],
    );
    assert!(!store.exists());
}
