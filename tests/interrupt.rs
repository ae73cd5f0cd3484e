//! SIGINT and SIGTERM stop the CLI cleanly (issue 13, items 8 and the "nothing lost"
//! rule): extraction leaves no output and no temporary, a stream saves what it computed
//! as a valid file, a batch keeps its finished files and resumes; the exit code is 130.

mod common;

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::{npz_arrays, tmp, tone, write_wav};

fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_afe"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run afe")
}

fn signal(child: &Child, sig: &str) {
    let ok = Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .expect("kill")
        .success();
    assert!(ok, "kill {sig} failed");
}

/// Waits until `ready` holds (polling), at most 60 s.
fn wait_for(ready: impl Fn() -> bool) {
    let start = Instant::now();
    while !ready() {
        assert!(start.elapsed() < Duration::from_secs(60), "timed out");
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn no_temporaries(dir: &Path) {
    let left: Vec<_> = std::fs::read_dir(dir)
        .expect("dir")
        .filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("partial") || n.contains(".tmp"))
        .collect();
    assert!(left.is_empty(), "temporaries left: {left:?}");
}

/// A FIFO at `path`, made anew.
fn new_fifo(path: &Path) {
    let _ = std::fs::remove_file(path);
    let made = Command::new("mkfifo").arg(path).status().expect("mkfifo");
    assert!(made.success());
}

/// Half a second into `child`'s wait for its input, `sig` ends it at once: exit 130 within
/// a second, and no output at `out`.
fn assert_signal_ends_the_wait(child: Child, sig: &str, out: &Path) {
    std::thread::sleep(Duration::from_millis(500));
    let signalled = Instant::now();
    signal(&child, sig);
    let res = child.wait_with_output().expect("wait");
    let took = signalled.elapsed();
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert_eq!(res.status.code(), Some(130), "{sig}: {stderr}");
    assert!(took < Duration::from_secs(1), "{sig}: {took:?}");
    assert!(!out.exists(), "{sig}: an output was written");
}

#[test]
fn sigint_on_a_stream_saves_what_it_computed() {
    let out = tmp("interrupted-stream.npz");
    let child = spawn(&[
        "stream",
        "--source",
        "synth:fs=16000,tone=440,noise=0.1",
        "--realtime",
        "--for",
        "60",
        "-r",
        "ratemap,ild",
        "--threads",
        "0",
        "-o",
        out.to_str().expect("utf-8"),
    ]);
    std::thread::sleep(Duration::from_millis(1500));
    signal(&child, "-INT");
    let res = child.wait_with_output().expect("wait");
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert_eq!(res.status.code(), Some(130), "stderr: {stderr}");
    let stdout = String::from_utf8_lossy(&res.stdout);
    assert!(stdout.contains("interrupted"), "{stdout}");
    let arrays = npz_arrays(&out);
    let names: Vec<&str> = arrays.iter().map(|(k, _, _)| k.as_str()).collect();
    assert_eq!(names, ["ratemap_left", "ratemap_right", "ild_mono"]);
    // about 1.5 s of 10-ms frames were computed: more than none, far fewer than 60 s
    let frames = arrays[0].1[0];
    assert!((20..3000).contains(&frames), "{frames} frames");
    assert!(arrays
        .iter()
        .all(|(_, s, _)| s[0] + 1 >= frames && s[0] <= frames + 1));
    no_temporaries(out.parent().expect("dir"));
}

/// SIGTERM half a second into an extraction stops it within a fraction of a second, on
/// both executors: a file read block by block (the cues) and a whole signal whose pitch
/// absorbs its autocorrelation block by block (issue 44, item 9); nothing is written.
#[test]
fn sigterm_during_extract_writes_nothing() {
    let dir = tmp("interrupted-extract");
    std::fs::create_dir_all(&dir).expect("dir");
    let input = dir.join("long.wav");
    // 120 s: seconds of work even when optimised
    write_wav(&input, 2, 44100, 44100 * 120, tone);
    let out = dir.join("out.npz");
    for (requests, threads) in [("ratemap,ild,itd,ic", "0"), ("pitch", "0"), ("pitch", "2")] {
        let child = spawn(&[
            "extract",
            input.to_str().expect("utf-8"),
            "-r",
            requests,
            "--threads",
            threads,
            "-o",
            out.to_str().expect("utf-8"),
        ]);
        std::thread::sleep(Duration::from_millis(500));
        signal(&child, "-TERM");
        let sent = Instant::now();
        let res = child.wait_with_output().expect("wait");
        let what = format!("{requests} on {threads} threads");
        let stderr = String::from_utf8_lossy(&res.stderr);
        assert_eq!(res.status.code(), Some(130), "{what}: {stderr}");
        assert!(
            stderr.contains("interrupted") && stderr.contains("nothing was written"),
            "{what}: {stderr}"
        );
        // the whole run takes seconds; the stop comes at the next block
        assert!(
            sent.elapsed() < Duration::from_secs(1),
            "{what}: {:?}",
            sent.elapsed()
        );
        assert!(!out.exists(), "{what}");
        no_temporaries(&dir);
    }
    std::fs::remove_dir_all(&dir).expect("clean");
}

/// A signal that comes while the output is being written (its temporary file exists)
/// abandons the write: no output, no temporary (the probe's 437-MB autocorrelation was
/// still written in full, exit 130).
#[test]
fn sigint_while_the_output_is_written_writes_nothing() {
    let dir = tmp("interrupted-write");
    std::fs::create_dir_all(&dir).expect("dir");
    let input = dir.join("five.wav");
    write_wav(&input, 2, 44100, 44100 * 5, tone);
    let out = dir.join("out.npz");
    // 5 s of autocorrelation: 218 MB to write, computed in a fraction of that time
    let child = spawn(&[
        "extract",
        input.to_str().expect("utf-8"),
        "-r",
        "autocorrelation",
        "--threads",
        "0",
        "-o",
        out.to_str().expect("utf-8"),
    ]);
    let writing = || {
        std::fs::read_dir(&dir)
            .expect("dir")
            .filter_map(Result::ok)
            .any(|e| e.file_name().to_string_lossy().contains("partial"))
    };
    let start = Instant::now();
    while !writing() {
        assert!(start.elapsed() < Duration::from_secs(60), "no write began");
        std::thread::sleep(Duration::from_millis(2));
    }
    signal(&child, "-INT");
    let res = child.wait_with_output().expect("wait");
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert_eq!(res.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("nothing was written"), "{stderr}");
    assert!(!out.exists(), "the output was written: {stderr}");
    no_temporaries(&dir);
    std::fs::remove_dir_all(&dir).expect("clean");
}

#[test]
fn sigint_during_a_batch_keeps_finished_files_and_resumes() {
    let dir = tmp("interrupted-batch");
    let corpus = dir.join("corpus");
    std::fs::create_dir_all(&corpus).expect("dir");
    for k in 0..6 {
        write_wav(
            &corpus.join(format!("f{k}.wav")),
            2,
            44100,
            44100 * 20,
            tone,
        );
    }
    let store = dir.join("s.zarr");
    let args = [
        "batch",
        corpus.to_str().expect("utf-8"),
        "-r",
        "ratemap,ild",
        "-j",
        "1",
        "--progress",
        "jsonl",
        "-o",
        store.to_str().expect("utf-8"),
    ];
    let child = spawn(&args);
    let logs = store.join(".afe-batch");
    // interrupt once the first file is recorded
    wait_for(|| {
        std::fs::read_dir(&logs).is_ok_and(|d| {
            d.filter_map(Result::ok)
                .any(|e| std::fs::read_to_string(e.path()).is_ok_and(|t| t.contains("\"done\"")))
        })
    });
    signal(&child, "-INT");
    let res = child.wait_with_output().expect("wait");
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert_eq!(res.status.code(), Some(130), "stderr: {stderr}");
    assert!(stderr.contains("run it again to resume"), "{stderr}");
    let first: usize = String::from_utf8_lossy(&res.stdout)
        .lines()
        .filter(|l| l.contains("\"event\":\"file\""))
        .count();
    assert!(
        (1..6).contains(&first),
        "{first} files before the interrupt"
    );
    // the run again does only the rest
    let again = Command::new(env!("CARGO_BIN_EXE_afe"))
        .args(args)
        .output()
        .expect("run");
    assert!(
        again.status.success(),
        "{}",
        String::from_utf8_lossy(&again.stderr)
    );
    let summary = String::from_utf8_lossy(&again.stdout)
        .lines()
        .find(|l| l.contains("\"event\":\"summary\""))
        .map(|l| serde_json::from_str::<serde_json::Value>(l).expect("json"))
        .expect("summary");
    assert_eq!(summary["already_done"], first);
    assert_eq!(summary["done"], 6 - first);
    std::fs::remove_dir_all(&dir).expect("clean");
}

/// Item 8 of issue 44: `afe extract` on a FIFO waits for its writer in `open`, where no
/// check of the stop flag runs: the first SIGTERM (or SIGINT) ends it at once, exit 130,
/// nothing written. Likewise while it waits for the rest of the header from a writer that
/// stalls.
#[test]
fn a_signal_stops_the_wait_on_a_fifo() {
    for (sig, stall_after_header) in [("-TERM", false), ("-INT", false), ("-TERM", true)] {
        let fifo = tmp(&format!("wait{sig}{stall_after_header}.fifo"));
        new_fifo(&fifo);
        let out = tmp(&format!("wait{sig}{stall_after_header}.npz"));
        let child = spawn(&[
            "extract",
            fifo.to_str().expect("utf-8"),
            "-r",
            "ild",
            "-o",
            out.to_str().expect("utf-8"),
        ]);
        // a writer that sends the first bytes of a header, then nothing
        let writer = stall_after_header.then(|| {
            let path = fifo.clone();
            std::thread::spawn(move || {
                let wav = tmp("wait-header.wav");
                write_wav(&wav, 2, 16000, 16000, tone);
                let bytes = std::fs::read(&wav).expect("wav");
                let mut f = std::fs::OpenOptions::new()
                    .write(true)
                    .open(&path)
                    .expect("open the fifo");
                std::io::Write::write_all(&mut f, &bytes[..8]).expect("write");
                std::thread::sleep(Duration::from_secs(5));
            })
        });
        assert_signal_ends_the_wait(child, sig, &out);
        no_temporaries(out.parent().expect("dir"));
        drop(writer);
    }
}

/// `--params` naming a FIFO that no one writes (issue 57): the first SIGINT or SIGTERM
/// ends the wait at once (it was ignored).
#[test]
fn a_signal_stops_the_wait_on_a_params_fifo() {
    let dir = tmp("params-fifo");
    std::fs::create_dir_all(&dir).expect("dir");
    let input = dir.join("in.wav");
    write_wav(&input, 2, 16000, 16000, tone);
    for sig in ["-INT", "-TERM"] {
        let fifo = dir.join(format!("params{sig}.fifo"));
        new_fifo(&fifo);
        let out = dir.join("out.npz");
        let child = spawn(&[
            "extract",
            input.to_str().expect("utf-8"),
            "-r",
            "ild",
            "--params",
            fifo.to_str().expect("utf-8"),
            "-o",
            out.to_str().expect("utf-8"),
        ]);
        assert_signal_ends_the_wait(child, sig, &out);
    }
    std::fs::remove_dir_all(&dir).expect("clean");
}
