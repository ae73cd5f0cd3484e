//! The `afe` command line contract: outputs, and one clear error line (non-zero exit, no
//! output file) for every kind of bad input.

use crate::common;

use common::{
    afe, assert_clear_error, library_arrays, npz_arrays, npz_metadata, sorted, tmp, tone, write_wav,
};
use serde_json::json;

#[test]
fn extract_writes_the_oracle_layout_and_chunking_does_not_change_it() {
    let wav = tmp("tone.wav");
    write_wav(&wav, 2, 16000, 4000, tone);
    let whole = tmp("whole.npz");
    let out = afe(&[
        "extract",
        wav.to_str().expect("path"),
        "-r",
        "ratemap,ild,crosscorrelation",
        "-p",
        "fb_nChannels=8",
        "-o",
        whole.to_str().expect("path"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let arrays = npz_arrays(&whole);
    let names: Vec<&str> = arrays.iter().map(|a| a.0.as_str()).collect();
    assert_eq!(
        names,
        [
            "ratemap_left",
            "ratemap_right",
            "ild_mono",
            "crosscorrelation_mono"
        ]
    );
    // 4000 samples, W = 320, H = 160: 24 frames; 8 channels; ceil(1.1e-3·16000) = 18 → 37 lags
    assert_eq!(arrays[0].1, vec![24, 8]);
    assert_eq!(arrays[3].1, vec![24, 8, 37]);
    // each array's description is in the metadata entry
    let meta = npz_metadata(&whole);
    assert_eq!(meta.as_object().map(|m| m.len()), Some(names.len()));
    let cc = &meta["crosscorrelation_mono"];
    assert_eq!(cc["lags_s"].as_array().map(Vec::len), Some(37));
    assert_eq!(
        (&cc["window_s"], &cc["hop_s"]),
        (&json!(0.02), &json!(0.01))
    );
    assert_eq!(cc["parameters"]["fb_nChannels"], 8);
    assert_eq!(meta["ratemap_left"]["ear"], "left");
    // the values are the library's, bit for bit
    let library = library_arrays(
        &wav,
        &["ratemap", "ild", "crosscorrelation"],
        &[("fb_nChannels", json!(8))],
        false,
    );
    assert_eq!(sorted(arrays.clone()), library);

    let chunked = tmp("chunked.npz");
    let out = afe(&[
        "extract",
        wav.to_str().expect("path"),
        "-r",
        "ratemap,ild,crosscorrelation",
        "-p",
        "fb_nChannels=8",
        "--chunk",
        "77",
        "-o",
        chunked.to_str().expect("path"),
    ]);
    assert!(out.status.success());
    assert_eq!(npz_arrays(&chunked), arrays);

    let all = tmp("all.npz");
    let out = afe(&[
        "extract",
        wav.to_str().expect("path"),
        "-r",
        "ild",
        "--all",
        "-o",
        all.to_str().expect("path"),
    ]);
    assert!(out.status.success());
    let every = sorted(npz_arrays(&all));
    assert_eq!(every, library_arrays(&wav, &["ild"], &[], true));
    let names: Vec<String> = every.into_iter().map(|a| a.0).collect();
    for n in [
        "time_left",
        "filterbank_right",
        "innerhaircell_left",
        "ild_mono",
    ] {
        assert!(names.iter().any(|k| k == n), "{n} missing from {names:?}");
    }
}

#[test]
fn params_file_takes_oracle_style_json() {
    let wav = tmp("p.wav");
    write_wav(&wav, 2, 16000, 3200, tone);
    let params = tmp("params.json");
    std::fs::write(&params, r#"{"fb_nChannels": 16, "fb_lowFreqHz": 100, "fb_highFreqHz": 6000, "ihc_method": "halfwave", "rm_scaling": "magnitude"}"#).expect("write");
    let out_file = tmp("p.npz");
    let out = afe(&[
        "extract",
        wav.to_str().expect("path"),
        "-r",
        "ratemap",
        "--params",
        params.to_str().expect("path"),
        "-o",
        out_file.to_str().expect("path"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let arrays = npz_arrays(&out_file);
    assert_eq!(arrays[0].1, vec![19, 16]);
    let params = [
        ("fb_nChannels", json!(16)),
        ("fb_lowFreqHz", json!(100)),
        ("fb_highFreqHz", json!(6000)),
        ("ihc_method", json!("halfwave")),
        ("rm_scaling", json!("magnitude")),
    ];
    assert_eq!(
        sorted(arrays),
        library_arrays(&wav, &["ratemap"], &params, false)
    );
}

#[test]
fn every_bad_input_is_one_clear_line() {
    let good = tmp("good.wav");
    write_wav(&good, 2, 16000, 3200, tone);
    let g = good.to_str().expect("path");
    let o = tmp("never.npz");
    let os = o.to_str().expect("path");

    assert_clear_error(
        &afe(&["extract", g, "-r", ",", "-o", os]),
        "no request given",
        &o,
    );
    assert_clear_error(
        &afe(&["extract", g, "-r", "ratemapp", "-o", os]),
        "unknown request 'ratemapp'",
        &o,
    );
    assert_clear_error(
        &afe(&[
            "extract",
            g,
            "-r",
            "ratemap",
            "-p",
            "rm_wsize=0.1",
            "-o",
            os,
        ]),
        "unknown parameter 'rm_wsize'",
        &o,
    );
    assert_clear_error(
        &afe(&[
            "extract",
            g,
            "-r",
            "ratemap",
            "-p",
            "ihc_method=daux",
            "-o",
            os,
        ]),
        "'dau'",
        &o,
    );
    assert_clear_error(
        &afe(&[
            "extract",
            g,
            "-r",
            "ratemap",
            "-p",
            "fb_nChannels=abc",
            "-o",
            os,
        ]),
        "fb_nChannels",
        &o,
    );
    assert_clear_error(
        &afe(&[
            "extract",
            g,
            "-r",
            "ratemap",
            "-p",
            "rm_hSizeSec=0",
            "-o",
            os,
        ]),
        "rm_hSizeSec",
        &o,
    );
    assert_clear_error(
        &afe(&["extract", "/nonexistent/x.wav", "-r", "ratemap", "-o", os]),
        "cannot open '/nonexistent/x.wav'",
        &o,
    );

    let text = tmp("notwav.wav");
    std::fs::write(&text, "this is not audio").expect("write");
    assert_clear_error(
        &afe(&[
            "extract",
            text.to_str().expect("path"),
            "-r",
            "ratemap",
            "-o",
            os,
        ]),
        "as WAV",
        &o,
    );

    let three = tmp("three.wav");
    write_wav(&three, 3, 16000, 100, tone);
    assert_clear_error(
        &afe(&[
            "extract",
            three.to_str().expect("path"),
            "-r",
            "ratemap",
            "-o",
            os,
        ]),
        "3 channels",
        &o,
    );

    let nan = tmp("nan.wav");
    write_wav(
        &nan,
        2,
        16000,
        100,
        |i| if i == 51 { f32::NAN } else { 0.1 },
    );
    assert_clear_error(
        &afe(&[
            "extract",
            nan.to_str().expect("path"),
            "-r",
            "ratemap",
            "-o",
            os,
        ]),
        "sample 25 of the right channel is NaN",
        &o,
    );

    // read block by block: the position is still the one in the whole file
    let late_nan = tmp("late-nan.wav");
    write_wav(&late_nan, 2, 16000, 6000, |i| {
        if i == 2 * 5000 {
            f32::NAN
        } else {
            0.1
        }
    });
    assert_clear_error(
        &afe(&[
            "extract",
            late_nan.to_str().expect("path"),
            "-r",
            "ratemap",
            "-o",
            os,
        ]),
        "sample 5000 of the left channel is NaN",
        &o,
    );

    let empty = tmp("empty.wav");
    write_wav(&empty, 2, 16000, 0, tone);
    assert_clear_error(
        &afe(&[
            "extract",
            empty.to_str().expect("path"),
            "-r",
            "ratemap",
            "-o",
            os,
        ]),
        "holds no samples",
        &o,
    );

    let mono = tmp("mono.wav");
    write_wav(&mono, 1, 16000, 1000, tone);
    assert_clear_error(
        &afe(&[
            "extract",
            mono.to_str().expect("path"),
            "-r",
            "itd",
            "-o",
            os,
        ]),
        "needs a binaural",
        &o,
    );
    let mono_out = tmp("mono.npz");
    let ok = afe(&[
        "extract",
        mono.to_str().expect("path"),
        "-r",
        "ratemap",
        "-o",
        mono_out.to_str().expect("path"),
    ]);
    assert!(ok.status.success());
    assert_eq!(npz_arrays(&mono_out)[0].0, "ratemap_mono");
}

#[test]
fn list_json_names_every_request_with_defaults() {
    let out = afe(&["list", "--json"]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let ratemap = v
        .as_array()
        .expect("array")
        .iter()
        .find(|r| r["name"] == "ratemap")
        .expect("ratemap listed");
    let w = ratemap["parameters"]
        .as_array()
        .expect("params")
        .iter()
        .find(|p| p["name"] == "rm_wSizeSec")
        .expect("rm_wSizeSec");
    assert_eq!(w["default"], 0.02);
    assert_eq!(w["unit"], "s");
    assert_eq!(
        ratemap["chain"],
        serde_json::json!(["ratemap", "innerhaircell", "filterbank", "time"])
    );
    let text = afe(&["list"]);
    assert!(String::from_utf8_lossy(&text.stdout).contains("fb_nChannels"));
}

#[test]
fn list_one_request_or_one_parameter() {
    // a request: its chain, request first, as the AFE's parameterHelper
    let out = afe(&["list", "ild", "--json"]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let names: Vec<&str> = v
        .as_array()
        .expect("array")
        .iter()
        .filter_map(|e| e["name"].as_str())
        .collect();
    assert_eq!(names, ["ild", "innerhaircell", "filterbank", "time"]);
    let text = String::from_utf8_lossy(&afe(&["list", "ild"]).stdout).into_owned();
    assert!(
        text.starts_with("ild  (binaural")
            && text.contains("ihc_method")
            && !text.contains("rm_wSizeSec")
    );
    // a parameter: where it belongs and what it takes
    let one: serde_json::Value =
        serde_json::from_slice(&afe(&["list", "rm_wSizeSec", "--json"]).stdout).expect("json");
    assert_eq!(
        (
            one["processor"].as_str(),
            one["default"].as_f64(),
            one["unit"].as_str()
        ),
        (Some("ratemap"), Some(0.02), Some("s"))
    );
    assert_clear_error(
        &afe(&["list", "rm_wsize"]),
        "'rm_wsize' is neither a request nor a parameter",
        &tmp("none"),
    );
    // a reader that goes away (`afe list | head -1`) ends the listing quietly
    let stderr = with_stdout_closed(&["list"]);
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// Runs `afe args` with its standard output closed (a reader that went away); returns
/// what it wrote to standard error.
fn with_stdout_closed(args: &[&str]) -> String {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_afe"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run");
    drop(child.stdout.take());
    let res = child.wait_with_output().expect("wait");
    String::from_utf8_lossy(&res.stderr).into_owned()
}

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

/// Runs `afe extract WAV -r ild` with `extra` arguments.
fn extract_ild(wav: &std::path::Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec!["extract", wav.to_str().expect("path"), "-r", "ild"];
    args.extend_from_slice(extra);
    afe(&args)
}

/// Names in `dir` that look like a temporary output.
fn partials(dir: &std::path::Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .expect("dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("partial"))
        .collect()
}

/// Issue 13, items 1, 2, 7 and 8: outputs never clobber a link, a device, the input or
/// each other, are checked before the computation, and leave no temporary file.
#[test]
fn outputs_are_checked_first_and_never_clobber() {
    let dir = tmp("outputs");
    std::fs::create_dir_all(&dir).expect("dir");
    let wav = dir.join("in.wav");
    write_wav(&wav, 2, 16000, 3200, tone);
    let path = |name: &str| dir.join(name);
    let s = |p: &std::path::Path| p.to_str().expect("path").to_string();

    // a symlink stays a link, and the file it names gets the arrays
    std::fs::write(path("real.npz"), b"old").expect("write");
    let _ = std::fs::remove_file(path("link.npz"));
    std::os::unix::fs::symlink("real.npz", path("link.npz")).expect("link");
    let out = extract_ild(&wav, &["-o", &s(&path("link.npz"))]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta = std::fs::symlink_metadata(path("link.npz")).expect("link");
    assert!(meta.file_type().is_symlink());
    assert_eq!(npz_arrays(&path("real.npz"))[0].0, "ild_mono");

    // a full device: an error, and the device is still a device
    if std::path::Path::new("/dev/full").exists() {
        let out = extract_ild(&wav, &["-o", "/dev/full"]);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("cannot write '/dev/full'"), "{err}");
        assert!(!std::fs::metadata("/dev/full").expect("device").is_file());
    }

    // a missing directory, or one for the trace, fails before anything is written
    let missing = path("nope/out.npz");
    let out = extract_ild(&wav, &["-o", &s(&missing)]);
    assert_clear_error(&out, "does not exist", &missing);
    let out = extract_ild(
        &wav,
        &[
            "--threads",
            "1",
            "--trace",
            &s(&path("nope/t.json")),
            "-o",
            &s(&path("t.npz")),
        ],
    );
    assert_clear_error(&out, "does not exist", &path("t.npz"));

    // the trace and the arrays into one file, or the arrays over the input: refused
    let both = path("both.npz");
    let out = extract_ild(
        &wav,
        &["--threads", "1", "--trace", &s(&both), "-o", &s(&both)],
    );
    assert_clear_error(&out, "two outputs", &both);
    let before = std::fs::read(&wav).expect("input");
    let out = extract_ild(&wav, &["-o", &s(&wav)]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("is the input file"));
    assert_eq!(
        std::fs::read(&wav).expect("input"),
        before,
        "input untouched"
    );

    // two runs into one file: each writes a whole file of its own, the last one stays
    let shared = path("shared.npz");
    let runs: Vec<std::process::Child> = (0..2)
        .map(|k| {
            let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_afe"));
            let request = if k == 0 { "ild" } else { "ratemap" };
            cmd.args(["extract", &s(&wav), "-r", request, "-o", &s(&shared)]);
            cmd.stderr(std::process::Stdio::null())
                .spawn()
                .expect("spawn")
        })
        .collect();
    for mut r in runs {
        assert!(r.wait().expect("wait").success());
    }
    let names: Vec<String> = npz_arrays(&shared).into_iter().map(|a| a.0).collect();
    let ild = vec!["ild_mono".to_string()];
    let ratemap = vec!["ratemap_left".to_string(), "ratemap_right".to_string()];
    assert!(
        names == ild || names == ratemap,
        "one run's arrays: {names:?}"
    );
    assert!(partials(&dir).is_empty(), "{:?}", partials(&dir));

    // standard output (a pipe here) is written in place: the zip reaches the reader
    let out = extract_ild(&wav, &["-o", "/dev/stdout"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.stdout.starts_with(b"PK"), "a zip on stdout");

    // a signal shorter than one block through a per-chunk request keeps its arrays
    let short = path("short.wav");
    write_wav(&short, 2, 16000, 4000, tone);
    let pitch = path("pitch.npz");
    let out = afe(&["extract", &s(&short), "-r", "pitch", "-o", &s(&pitch)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let names: Vec<String> = npz_arrays(&pitch).into_iter().map(|a| a.0).collect();
    assert_eq!(names, ["pitch_left", "pitch_right"]);

    // issue 13, item 9: argument errors exit with 1, as the README says of every error
    let out = afe(&["extract", "--bogus"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--bogus"));
    assert_eq!(afe(&["--help"]).status.code(), Some(0));

    // issue 13, item 9: an empty value is an error, not silently the default
    let never = path("never.npz");
    let out = extract_ild(&wav, &["-p", "fb_nChannels=", "-o", &s(&never)]);
    assert_clear_error(&out, "'fb_nChannels=' has no value", &never);

    // an absurd repeat count is refused by the parser, without a panic
    let out = afe(&[
        "bench",
        &s(&wav),
        "-r",
        "ild",
        "--repeat",
        "18446744073709551615",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--repeat") && !err.contains("panicked"),
        "{err}"
    );
}

/// `--dtype f32` stores every value rounded to float32 (complex64 for the STFT), the
/// float64 run's values exactly so rounded, and each description says so.
#[test]
fn extract_dtype_f32_stores_the_rounded_values() {
    let dir = tmp("dtype-f32");
    std::fs::create_dir_all(&dir).expect("dir");
    let wav = dir.join("in.wav");
    write_wav(&wav, 2, 16000, 8000, tone);
    let run = |dtype: &str| {
        let out = dir.join(format!("{dtype}.npz"));
        let res = afe(&[
            "extract",
            wav.to_str().expect("utf-8"),
            "-r",
            "ratemap,ild,stft",
            "--dtype",
            dtype,
            "-o",
            out.to_str().expect("utf-8"),
        ]);
        assert!(
            res.status.success(),
            "{}",
            String::from_utf8_lossy(&res.stderr)
        );
        out
    };
    let (wide, narrow) = (run("f64"), run("f32"));
    let bytes = |p: &std::path::Path| std::fs::metadata(p).expect("size").len();
    assert!(bytes(&narrow) < bytes(&wide) * 6 / 10);
    let (a, b) = (npz_arrays(&wide), npz_arrays(&narrow));
    assert_eq!(a.len(), b.len());
    for ((ka, sa, va), (kb, sb, vb)) in a.iter().zip(&b) {
        assert_eq!((ka, sa), (kb, sb));
        let rounded: Vec<f64> = va.iter().map(|&v| f64::from(v as f32)).collect();
        assert_eq!(&rounded, vb, "{ka}");
    }
    let meta = npz_metadata(&narrow);
    assert_eq!(meta["ild_mono"]["dtype"], "float32");
    assert_eq!(meta["stft_left"]["dtype"], "complex64");
    assert_eq!(npz_metadata(&wide)["stft_left"]["dtype"], "complex128");
    std::fs::remove_dir_all(&dir).expect("clean");
}

/// Outputs that would take more than half of the memory available get a warning before
/// the work; more than all of it, a clear error and nothing written.
#[test]
fn extract_announces_outputs_too_large_for_the_memory() {
    let dir = tmp("memory-check");
    std::fs::create_dir_all(&dir).expect("dir");
    let wav = dir.join("in.wav");
    write_wav(&wav, 2, 16000, 16000, tone);
    let out = dir.join("out.npz");
    let run = |available: &str| {
        common::afe_env(
            &[
                "extract",
                wav.to_str().expect("utf-8"),
                "-r",
                "ratemap",
                "-o",
                out.to_str().expect("utf-8"),
            ],
            &[("AFE_MEMORY_AVAILABLE_GB", std::path::Path::new(available))],
        )
    };
    let warned = run("0.00008");
    let stderr = String::from_utf8_lossy(&warned.stderr);
    assert!(warned.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning: the outputs will take 49.6 kB, more than half of the 80.0 kB of memory available: store them as float32"),
        "{stderr}"
    );
    std::fs::remove_file(&out).expect("written");
    let refused = run("0.00004");
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success());
    assert!(
        stderr.contains("keeping the outputs would take 49.6 kB, more than the 40.0 kB of memory available: store them as float32 (`dtype=\"float32\"`, `--dtype f32`), ask for fewer requests"),
        "{stderr}"
    );
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).expect("clean");
}

/// A tone, then 0.9 s of digital silence: the filterbank's decay stops at 0 instead of
/// running through the subnormals (see `afe_core::denormals`), unless
/// `AFE_KEEP_SUBNORMALS=1` asks for the IEEE arithmetic of the AFE; both on two threads.
#[test]
fn silence_is_flushed_to_zero_unless_subnormals_are_kept() {
    let dir = tmp("subnormals");
    std::fs::create_dir_all(&dir).expect("dir");
    let wav = dir.join("in.wav");
    write_wav(
        &wav,
        2,
        16000,
        16000,
        |i| if i < 3200 { tone(i) } else { 0.0 },
    );
    let subnormals = |keep: &str| {
        let out = dir.join(format!("keep-{keep}.npz"));
        let run = common::afe_env(
            &[
                "extract",
                wav.to_str().expect("utf-8"),
                "-r",
                "filterbank",
                "--threads",
                "2",
                "-o",
                out.to_str().expect("utf-8"),
            ],
            &[("AFE_KEEP_SUBNORMALS", std::path::Path::new(keep))],
        );
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        npz_arrays(&out)
            .iter()
            .map(|(_, _, data)| data.iter().filter(|v| v.is_subnormal()).count())
            .sum::<usize>()
    };
    assert_eq!(subnormals("0"), 0);
    assert!(subnormals("1") > 1000);
    std::fs::remove_dir_all(&dir).expect("clean");
}
