//! Threads, traces and `afe bench`: the same numbers on any number of threads, the
//! schedule's trace, and the benchmark's figures.

use crate::common;

use common::{afe, assert_clear_error, npz_arrays, tmp, tone, write_wav};

use super::with_stdout_closed;

#[test]
fn threads_trace_and_bench() {
    let wav = tmp("threads.wav");
    write_wav(&wav, 2, 16000, 8000, tone);
    let w = wav.to_str().expect("path");
    let seq = tmp("seq.npz");
    let par = tmp("par.npz");
    let trace = tmp("trace.json");
    let out = afe(&[
        "extract",
        w,
        "-r",
        "ratemap,itd",
        "--chunk",
        "160",
        "--threads",
        "0",
        "-o",
        seq.to_str().expect("path"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = afe(&[
        "extract",
        w,
        "-r",
        "ratemap,itd",
        "--chunk",
        "160",
        "--threads",
        "2",
        "--trace",
        trace.to_str().expect("path"),
        "-o",
        par.to_str().expect("path"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        npz_arrays(&seq),
        npz_arrays(&par),
        "threads change no number"
    );

    let t: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&trace).expect("trace written")).expect("json");
    let events = t["traceEvents"].as_array().expect("events");
    let processed: Vec<&serde_json::Value> =
        events.iter().filter(|e| e["cat"] == "process").collect();
    // 50 chunks × (time, 2 filterbanks, 2 IHC, 2 ratemaps, crosscorrelation, itd), and
    // the two halves of the crosscorrelation's channels, one per worker, that it joins
    assert_eq!(processed.len(), 50 * 11);
    for name in [
        "crosscorrelation#1",
        "crosscorrelation#1/part0",
        "crosscorrelation#1/part1",
    ] {
        assert!(processed.iter().any(|e| e["name"] == name), "{name}");
    }
    let never = tmp("never-traced.npz");
    let out = afe(&[
        "extract",
        w,
        "-r",
        "ild",
        "--threads",
        "0",
        "--trace",
        trace.to_str().expect("path"),
        "-o",
        never.to_str().expect("path"),
    ]);
    assert_clear_error(&out, "--threads 1 or more", &never);

    let out = afe(&[
        "bench",
        w,
        "-r",
        "ild",
        "--chunk",
        "441",
        "--threads",
        "1",
        "--repeat",
        "2",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let b: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(b["audio_seconds"], 0.5);
    assert_eq!(b["threads"], 1);
    assert_eq!(b["chunk"], 441);
    assert!(b["x_realtime"].as_f64().expect("number") > 0.0);
    assert!(b["wall_seconds_median"].as_f64().expect("number") > 0.0);
    assert!(b["wall_seconds_first"].as_f64().expect("number") > 0.0);
    assert_eq!(b["outputs"], "kept");
    // the figure names the machine and the instruction set it came from
    let host = &b["host"];
    assert!(!host["cpu"].as_str().expect("cpu").is_empty());
    assert!(host["cores"].as_u64().expect("cores") >= 1);
    assert!(["avx512", "avx2", "baseline"].contains(&host["simd"].as_str().expect("simd")));
    assert_eq!(host["version"], env!("CARGO_PKG_VERSION"));
    // the schedule of the last run, as `extract --trace` writes it
    let bench_trace = tmp("bench-trace.json");
    let traced = |threads: &str| {
        afe(&[
            "bench",
            w,
            "-r",
            "ratemap,itd",
            "--chunk",
            "160",
            "--threads",
            threads,
            "--repeat",
            "2",
            "--trace",
            bench_trace.to_str().expect("path"),
        ])
    };
    let out = traced("2");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let t: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&bench_trace).expect("trace written")).expect("json");
    let events = t["traceEvents"].as_array().expect("events");
    let processed = events.iter().filter(|e| e["cat"] == "process").count();
    assert_eq!(processed, 50 * 11, "one run's chunks, not both runs'");
    std::fs::remove_file(&bench_trace).expect("removed");
    assert_clear_error(&traced("0"), "--threads 1 or more", &bench_trace);
    // with --discard every chunk's output is still computed and seen, then dropped
    for chunk in ["441", "1000000"] {
        let out = afe(&[
            "bench",
            w,
            "-r",
            "ild",
            "--chunk",
            chunk,
            "--repeat",
            "1",
            "--discard",
            "--json",
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let d: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        assert_eq!(d["outputs"], "discarded");
        assert_eq!(d["output_values"], b["output_values"], "chunk {chunk}");
    }
    assert!(b["output_values"].as_u64().expect("count") > 0);
    // pitch depends on chunk boundaries: the whole signal goes through in one call, the
    // ratemap in blocks (handed on as they come with --discard)
    let values = |discard: &[&str]| {
        let mut args = vec!["bench", w, "-r", "pitch,ratemap", "--repeat", "1", "--json"];
        args.extend_from_slice(discard);
        let out = afe(&args);
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        v["output_values"].as_u64().expect("count")
    };
    let kept = values(&[]);
    assert!(kept > 0);
    assert_eq!(values(&["--discard"]), kept);
    // `afe bench ... | head` ends quietly too
    let stderr = with_stdout_closed(&["bench", w, "-r", "ild", "--repeat", "1", "--json"]);
    assert!(!stderr.contains("panicked"), "{stderr}");
}
