//! Issue 44 (reliability, part 2), the command line's items: a work and memory budget
//! instead of an abort (4), bounded reads (8), several outputs written together or not at
//! all (12), and messages that name what is wrong (12).

mod common;

use std::time::{Duration, Instant};

use common::{afe, assert_clear_error, tmp, tone, write_wav};

/// The number in `text` between `before` and the next `after`.
fn number_between(text: &str, before: &str, after: &str) -> f64 {
    text.split(before)
        .nth(1)
        .and_then(|r| r.split(after).next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no number after '{before}' in: {text}"))
}

/// Item 4: parameters that asked for 180 GB (a 0.1-ms autocorrelation hop over 256
/// channels) or for 22 GB of cross-correlation lags are refused before any allocation,
/// with exit 1 and a message naming them, where they aborted the process (exit 134).
#[test]
fn parameters_beyond_the_work_limit_are_refused_before_allocating() {
    let wav = tmp("work-in.wav");
    write_wav(&wav, 2, 44100, 44100, tone);
    let out_file = tmp("work.npz");
    let run = |params: &[&str]| {
        let mut args = vec!["extract", wav.to_str().expect("path"), "-o"];
        args.push(out_file.to_str().expect("path"));
        args.extend_from_slice(params);
        afe(&args)
    };
    let out = run(&[
        "-r",
        "autocorrelation",
        "-p",
        "ac_wSizeSec=0.2",
        "-p",
        "ac_hSizeSec=0.0001",
        "-p",
        "fb_nChannels=256",
    ]);
    assert_clear_error(
        &out,
        "request 'autocorrelation' would make the graph compute about ",
        &out_file,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("(its autocorrelation alone ")
            && err.contains(
                "over the limit of 2.0e9; parameters set: ac_hSizeSec=0.0001, ac_wSizeSec=0.2, \
                 fb_nChannels=256: a longer hop, a shorter window, fewer channels, lags or bins \
                 lower it, or raise the limit with the environment variable AFE_WORK_LIMIT"
            ),
        "{err}"
    );
    // the estimate is at least the lags written: 10^4 frames/s x 256 channels x 8821 lags
    // per ear
    let estimate = number_between(&err, "compute about ", " ");
    assert!(estimate >= 2.0 * 1e4 * 256.0 * 8821.0, "{estimate:e}");
    let out = run(&[
        "-r",
        "crosscorrelation",
        "-p",
        "cc_wSizeSec=1",
        "-p",
        "cc_maxDelaySec=1",
        "-p",
        "cc_hSizeSec=0.001",
    ]);
    assert_clear_error(
        &out,
        "request 'crosscorrelation' would make the graph compute about ",
        &out_file,
    );
    // the limit moves with AFE_WORK_LIMIT
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_afe"));
    let out = cmd
        .args(["extract", wav.to_str().expect("path"), "-r", "ild", "-o"])
        .arg(&out_file)
        .env("AFE_WORK_LIMIT", "1e6")
        .output()
        .expect("run afe");
    assert_clear_error(&out, "over the limit of 1.0e6", &out_file);
}

/// Item 4: outputs beyond the address space left under `ulimit -v` are refused with the
/// memory message (such an allocation aborted the process: `memory allocation of
/// 21895721848 bytes failed`, exit 134).
#[test]
fn outputs_beyond_ulimit_v_are_refused_not_aborted() {
    let wav = tmp("ulimit-in.wav");
    write_wav(&wav, 2, 44100, 441_000, tone);
    let out_file = tmp("ulimit.npz");
    let script = format!(
        "ulimit -v 4000000 && exec '{}' extract '{}' -o '{}' -r crosscorrelation \
         -p cc_wSizeSec=0.1 -p cc_maxDelaySec=0.1 -p cc_hSizeSec=0.002",
        env!("CARGO_BIN_EXE_afe"),
        wav.display(),
        out_file.display()
    );
    let out = std::process::Command::new("sh")
        .args(["-c", &script])
        .env_remove("AFE_MEMORY_AVAILABLE_GB")
        .output()
        .expect("run sh");
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    // 10 s of 500 frames/s of 32 channels of thousands of lags: gigabytes
    assert_clear_error(&out, "keeping the outputs would take ", &out_file);
    let err = String::from_utf8_lossy(&out.stderr);
    let need = number_between(&err, "would take ", " GB");
    assert!(need > 8.0, "{err}");
    let available = number_between(&err, "more than the ", " GB");
    assert!(available <= 4.1, "{err}");
}

/// Item 8: a parameter file is read up to a bound, so a wrong path such as /dev/zero is
/// refused at once instead of filling the memory.
#[test]
fn a_parameter_file_is_read_up_to_a_bound() {
    let wav = tmp("bounded-in.wav");
    write_wav(&wav, 2, 16000, 1600, tone);
    let out_file = tmp("bounded.npz");
    let start = Instant::now();
    let out = afe(&[
        "extract",
        wav.to_str().expect("path"),
        "-r",
        "ild",
        "--params",
        "/dev/zero",
        "-o",
        out_file.to_str().expect("path"),
    ]);
    assert!(
        start.elapsed() < Duration::from_secs(10),
        "{:?}",
        start.elapsed()
    );
    assert_clear_error(
        &out,
        "parameter file '/dev/zero' is larger than 1024 KiB",
        &out_file,
    );
}

/// Item 12: a trace that cannot be written (a full device) fails the run and leaves no
/// .npz either: a run's outputs are written together or not at all.
#[test]
fn an_unwritable_trace_leaves_no_npz() {
    let wav = tmp("trace-in.wav");
    write_wav(&wav, 2, 16000, 3200, tone);
    let npz = tmp("trace.npz");
    let out = afe(&[
        "extract",
        wav.to_str().expect("path"),
        "-r",
        "ild",
        "--threads",
        "2",
        "--trace",
        "/dev/full",
        "-o",
        npz.to_str().expect("path"),
    ]);
    assert_clear_error(&out, "cannot write '/dev/full'", &npz);
    let dir = npz.parent().expect("dir");
    let partial: Vec<String> = std::fs::read_dir(dir)
        .expect("dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("trace.npz") && n.contains("partial"))
        .collect();
    assert!(partial.is_empty(), "{partial:?}");
}

/// Item 12: messages blame the value that is wrong, and never an option not given.
#[test]
fn messages_name_what_is_wrong() {
    let short = tmp("short.wav");
    write_wav(&short, 2, 16000, 8000, tone);
    let fig = tmp("short.png");
    let out = afe(&[
        "plot",
        short.to_str().expect("path"),
        "-r",
        "ratemap,duet",
        "-o",
        fig.to_str().expect("path"),
    ]);
    assert_clear_error(&out, "duet_mono has no frame to draw", &fig);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("--at"), "{err}");

    let npz = tmp("bins.npz");
    let out = afe(&[
        "extract",
        short.to_str().expect("path"),
        "-r",
        "duet",
        "-p",
        "duet_binsDelta=1000000000",
        "-o",
        npz.to_str().expect("path"),
    ]);
    assert_clear_error(&out, "1000000000 for parameter 'duet_binsDelta'", &npz);

    let out = afe(&[
        "stream",
        "--source",
        "synth:ild_db=1e9",
        "--for",
        "0.1",
        "-r",
        "ild",
        "-o",
        npz.to_str().expect("path"),
    ]);
    assert_clear_error(
        &out,
        "ild_db=1e9: interaural level differences beyond ±200 dB",
        &npz,
    );
}
