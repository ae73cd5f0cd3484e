//! Resuming: a run killed with SIGKILL resumes without redoing its finished files, and
//! `status` and a resume find what was deleted from a store and skip garbage in its log.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant, SystemTime};

use serde_json::Value;

use super::{
    afe_ok, assert_same_stores, errors_of, events, good_corpus, ledger_records, s, status,
    write_signal, Kind, TempDir, REQUESTS,
};

/// Copies a folder tree.
fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("dir");
    for entry in std::fs::read_dir(from).expect("read dir") {
        let path = entry.expect("entry").path();
        let dest = to.join(path.file_name().expect("name"));
        if path.is_dir() {
            copy_dir(&path, &dest);
        } else {
            std::fs::copy(&path, &dest).expect("copy");
        }
    }
}

/// Waits until `store` records a finished file (then kills `child`), or panics if the
/// child ends first.
fn kill_after_first_record(child: &mut std::process::Child, store: &Path) {
    let start = Instant::now();
    loop {
        if ledger_records(store).iter().any(|r| r["status"] == "done") {
            child.kill().expect("kill");
            child.wait().expect("wait");
            return;
        }
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

#[test]
fn a_killed_run_resumes_without_redoing_finished_files() {
    let tmp = TempDir::new("resume");
    let corpus = tmp.join("corpus");
    let rates = [44100, 22050];
    let ids: Vec<String> = (0..24)
        .map(|k| {
            let id = format!("d{}/f{k:02}.wav", k % 3);
            let kind = Kind {
                fs: rates[k % 2],
                channels: 2 - (k % 5 == 0) as u16,
                float: k % 3 == 0,
                seconds: 0.8 + 0.03 * k as f64,
            };
            write_signal(&corpus.join(&id), kind, 1000 + k as u64);
            id
        })
        .collect();
    let copy = tmp.join("copy");
    copy_dir(&corpus, &copy);

    let whole = tmp.join("whole.zarr");
    afe_ok(&[
        "batch",
        s(&corpus),
        "-r",
        "ratemap",
        "-o",
        s(&whole),
        "-j",
        "2",
        "--progress",
        "none",
    ]);

    let store = tmp.join("resumed.zarr");
    let args = [
        "batch",
        s(&copy),
        "-r",
        "ratemap",
        "-o",
        s(&store),
        "-j",
        "1",
        "--progress",
        "jsonl",
    ];
    let mut child = Command::new(env!("CARGO_BIN_EXE_afe"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn afe");
    kill_after_first_record(&mut child, &store);
    let before: BTreeSet<String> = ledger_records(&store)
        .iter()
        .filter(|r| r["status"] == "done")
        .map(|r| r["id"].as_str().expect("id").to_string())
        .collect();
    assert!(
        !before.is_empty() && before.len() < ids.len(),
        "killed after {} of {} files",
        before.len(),
        ids.len()
    );
    // the finished files' metadata files, with their modification times
    let mtimes = |id: &str| -> Vec<(PathBuf, SystemTime)> {
        let mut files = vec![store.join(id).join("zarr.json")];
        for a in ["ratemap_left", "ratemap_right", "ratemap_mono"] {
            let p = store.join(id).join(a).join("zarr.json");
            if p.exists() {
                files.push(p);
            }
        }
        files
            .into_iter()
            .map(|p| {
                let t = std::fs::metadata(&p)
                    .expect("meta")
                    .modified()
                    .expect("mtime");
                (p, t)
            })
            .collect()
    };
    let times_before: Vec<_> = before.iter().map(|id| mtimes(id)).collect();
    // the file in flight (one worker, longest first: f23, f22, ...) as a kill in its
    // first writes leaves it, whether or not this kill did: its folder's group metadata
    // truncated, its own group torn with a stray file in it
    let next = &ids[ids.len() - 1 - before.len()];
    let folder = store.join(next).parent().expect("folder").to_path_buf();
    std::fs::create_dir_all(store.join(next)).expect("dir");
    std::fs::write(folder.join("zarr.json"), "").expect("truncate");
    std::fs::write(store.join(next).join("zarr.json"), "{\"zarr_for").expect("torn");
    std::fs::write(store.join(next).join("stray"), "x").expect("stray");

    let out = afe_ok(&args);
    let ev = events(&out);
    assert_eq!(ev[0]["event"], "start");
    assert_eq!(ev[0]["already_done"], before.len());
    let redone: BTreeSet<String> = ev
        .iter()
        .filter(|e| e["event"] == "file")
        .map(|e| {
            assert_eq!(e["status"], "done", "{e}");
            e["id"].as_str().expect("id").to_string()
        })
        .collect();
    assert!(
        redone.is_disjoint(&before),
        "recomputed: {:?}",
        redone.intersection(&before).collect::<Vec<_>>()
    );
    let all: BTreeSet<String> = redone.union(&before).cloned().collect();
    assert_eq!(all, ids.iter().cloned().collect::<BTreeSet<_>>());
    let last = ev.last().expect("summary");
    assert_eq!(last["event"], "summary");
    assert_eq!(last["done"], ids.len() - before.len());
    for (id, times) in before.iter().zip(&times_before) {
        assert_eq!(&mtimes(id), times, "{id} was rewritten");
    }

    assert!(!store.join(next).join("stray").exists());
    let meta: Value =
        serde_json::from_slice(&std::fs::read(folder.join("zarr.json")).expect("read"))
            .expect("the folder's group is written again");
    assert_eq!(meta["node_type"], "group");
    assert_same_stores(&store, &whole);
    let st = status(&store);
    assert_eq!(st["done"], ids.len());
    assert_eq!(st["failed"], serde_json::json!([]));
    // a third run finds nothing to do
    let out = afe_ok(&args);
    let ev = events(&out);
    assert_eq!(ev[0]["already_done"], ids.len(), "{ev:?}");
    assert_eq!(ev.len(), 2, "{ev:?}");
}

#[test]
fn status_and_resume_find_deleted_groups_arrays_and_chunks_and_skip_garbage_in_the_log() {
    let tmp = TempDir::new("damaged");
    let corpus = tmp.join("corpus");
    let ids = good_corpus(&corpus, 8);
    let store = tmp.join("store.zarr");
    let params = ["-r", REQUESTS, "-p", "fb_nChannels=8"];
    let mut args = vec!["batch", s(&corpus), "-o", s(&store)];
    args.extend(params);
    args.extend(["--progress", "jsonl"]);
    afe_ok(&args);
    let reference = tmp.join("reference.zarr");
    copy_dir(&store, &reference);

    // a whole group, one array, one chunk, and a chunk cut short
    let stereo: Vec<&String> = ids
        .iter()
        .filter(|id| store.join(id).join("ratemap_left").exists())
        .collect();
    let (group, array, chunk, cut) = (stereo[0], stereo[1], stereo[2], stereo[3]);
    std::fs::remove_dir_all(store.join(group)).expect("rm group");
    std::fs::remove_dir_all(store.join(array).join("ratemap_right")).expect("rm array");
    std::fs::remove_file(store.join(chunk).join("filterbank_left/c/0/0")).expect("rm chunk");
    let cut_chunk = store.join(cut).join("ratemap_left/c/0/0");
    let len = std::fs::metadata(&cut_chunk).expect("chunk").len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&cut_chunk)
        .expect("open")
        .set_len(len / 2)
        .expect("cut");
    // binary bytes in a log, between whole lines
    let log = std::fs::read_dir(store.join(".afe-batch"))
        .expect("logs")
        .map(|e| e.expect("entry").path())
        .find(|p| p.extension().is_some_and(|e| e == "jsonl"))
        .expect("a log");
    let mut bytes = std::fs::read(&log).expect("log");
    bytes.extend(b"\x00\xff\xfe{\"id\":\x80garbage\n");
    std::fs::write(&log, bytes).expect("write log");

    let st = status(&store);
    assert_eq!(st["done"], ids.len() - 4, "{st}");
    let missing = errors_of(&st, "missing");
    assert_eq!(
        missing.keys().collect::<BTreeSet<_>>(),
        BTreeSet::from([group, array, chunk, cut])
    );
    assert!(
        missing[group].contains("group metadata is missing"),
        "{missing:?}"
    );
    assert!(missing[array].contains("'ratemap_right'"), "{missing:?}");
    assert!(
        missing[chunk].contains("chunk [0, 0] is missing"),
        "{missing:?}"
    );
    assert!(
        missing[cut].contains(&format!("holds {} bytes", len / 2)),
        "{missing:?}"
    );
    let warnings = st["warnings"].as_array().expect("warnings");
    assert_eq!(warnings.len(), 1, "{st}");
    assert!(warnings[0]
        .as_str()
        .expect("text")
        .contains("skipped 1 line(s)"));
    let text = afe_ok(&["batch", "status", s(&store)]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(text.contains(", 0 failed, 4 missing"), "{text}");

    // the resume computes exactly those again, and the store equals the one before
    let ev = events(&afe_ok(&args));
    assert_eq!(ev[0]["already_done"], ids.len() - 4);
    let redone: BTreeSet<&str> = ev
        .iter()
        .filter(|e| e["event"] == "file")
        .map(|e| e["id"].as_str().expect("id"))
        .collect();
    assert_eq!(
        redone,
        BTreeSet::from([group, array, chunk, cut].map(String::as_str))
    );
    let summary = ev.last().expect("summary");
    assert_eq!(
        summary["incomplete"].as_array().expect("incomplete").len(),
        4
    );
    assert_same_stores(&store, &reference);
    let st = status(&store);
    assert_eq!(st["done"], ids.len());
    assert_eq!(st["missing"], serde_json::json!([]));
}
