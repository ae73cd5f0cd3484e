//! Issue 44 (reliability, part 2), the command line's items: bounded reads (8), several
//! outputs written together or not at all (12), and messages that name what is wrong (12).

mod common;

use std::time::{Duration, Instant};

use common::{afe, assert_clear_error, tmp, tone, write_wav};

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
