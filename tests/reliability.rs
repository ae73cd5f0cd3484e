//! Issue 44 (reliability, part 2), the command line's items: a work and memory budget
//! instead of an abort (4), bounded reads (8), several outputs written together or not at
//! all (12), and messages that name what is wrong (12).

use crate::common;

use std::time::{Duration, Instant};

use common::{afe, afe_under_ulimit, assert_clear_error, tmp, tone, write_wav};

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

/// An address-space limit (kB), the arguments and the environment of one run.
type Case<'a> = (u64, &'a [&'a str], &'a [(&'a str, &'a str)]);

/// Issue 57, finding 2: a whole signal that processors take in one call (the MOC's
/// chain, the Hilbert hair cell) aborted under `ulimit -v` (`memory allocation of
/// 218736000 bytes failed`, SIGABRT), within the fixed limit of 2 GB and with it raised
/// to 100 GB. It is refused before the computation, naming what it needs and the memory
/// available (20 s at 44.1 kHz under 1 GB; 1024 channels of 1 s under 1.5 GB; 256 channels of 20 s
/// under 6 GB with the limit raised).
#[test]
fn whole_signals_beyond_the_memory_available_are_refused_not_aborted() {
    let wav = tmp("twenty.wav");
    write_wav(&wav, 2, 44100, 20 * 44100, tone);
    let one = tmp("one.wav");
    write_wav(&one, 2, 44100, 44100, tone);
    let out_file = tmp("whole-memory.npz");
    let (w, s, o) = (
        wav.to_str().expect("path"),
        one.to_str().expect("path"),
        out_file.to_str().expect("path"),
    );
    let cases: [Case; 4] = [
        (1_000_000, &["extract", w, "-r", "moc", "-o", o], &[]),
        (
            1_000_000,
            &[
                "extract",
                w,
                "-r",
                "ratemap",
                "-p",
                "ihc_method=hilbert",
                "-o",
                o,
            ],
            &[],
        ),
        (
            1_500_000,
            &[
                "extract",
                s,
                "-r",
                "moc",
                "-p",
                "fb_nChannels=1024",
                "-o",
                o,
            ],
            &[],
        ),
        (
            6_000_000,
            &["extract", w, "-r", "moc", "-p", "fb_nChannels=256", "-o", o],
            &[("AFE_WHOLE_SIGNAL_LIMIT_MB", "100000")],
        ),
    ];
    for (limit, args, env) in cases {
        let started = Instant::now();
        let out = afe_under_ulimit(Some(limit), args, env);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {out:?}");
        assert_clear_error(
            &out,
            "processing the signal in one call would take about ",
            &out_file,
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("of memory available: feed it in chunks"),
            "{err}"
        );
        let need = number_between(&err, "would take about ", " GB");
        let available = number_between(&err, "more than the ", " ")
            * if err.contains("MB of memory available") {
                1e-3
            } else {
                1.0
            };
        assert!(
            need > available && available <= limit as f64 * 1.024e-6,
            "{err}"
        );
        assert!(started.elapsed() < Duration::from_secs(20), "{args:?}");
    }
}

/// The estimate bounds the memory a whole-signal call takes: under address-space limits
/// from 250 MB to 1.3 GB, 5 s of the MOC's chain and of the Hilbert hair cell (one and
/// two threads) are either computed or refused with the message, never aborted; and
/// with the check passed by a large `AFE_MEMORY_AVAILABLE_GB`, the allocation that fails
/// is an error naming what it was for, not an abort.
#[test]
fn whole_signals_under_any_address_space_limit_are_computed_or_refused() {
    let wav = tmp("five.wav");
    write_wav(&wav, 2, 44100, 5 * 44100, tone);
    let out_file = tmp("five.npz");
    let (w, o) = (
        wav.to_str().expect("path"),
        out_file.to_str().expect("path"),
    );
    let (mut computed, mut refused) = (0, 0);
    for request in [
        &["-r", "moc"][..],
        &["-r", "ratemap", "-p", "ihc_method=hilbert"],
    ] {
        for threads in ["0", "2"] {
            for limit_mb in (250..=1300).step_by(150) {
                let mut args = vec!["extract", w, "-o", o, "--threads", threads];
                args.extend_from_slice(request);
                let out = afe_under_ulimit(Some(limit_mb * 1000), &args, &[]);
                let err = String::from_utf8_lossy(&out.stderr);
                match out.status.code() {
                    Some(0) => computed += 1,
                    Some(1) => {
                        assert!(
                            err.contains("of memory available"),
                            "{args:?} {limit_mb}: {err}"
                        );
                        refused += 1;
                    }
                    _ => panic!("{args:?} under {limit_mb} MB: {out:?}"),
                }
                let _ = std::fs::remove_file(&out_file);
            }
        }
    }
    assert!(
        computed > 0 && refused > 0,
        "{computed} computed, {refused} refused"
    );
    let out = afe_under_ulimit(
        Some(400_000),
        &["extract", w, "-o", o, "-r", "moc"],
        &[("AFE_MEMORY_AVAILABLE_GB", "1000")],
    );
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert_clear_error(&out, "could not allocate ", &out_file);
    assert!(String::from_utf8_lossy(&out.stderr).contains("the memory is short"));
}

/// Issue 57, minor: bad values of the limit variables (`abc`, `0`, `-1`, `nan`) were taken
/// or ignored silently. Each is refused in one line naming the variable, its value and
/// what it accepts, exit 1, before any work.
#[test]
fn bad_values_of_the_limit_variables_are_refused_by_name() {
    let wav = tmp("settings.wav");
    write_wav(&wav, 2, 16000, 1600, tone);
    let out_file = tmp("settings.npz");
    let (w, o) = (
        wav.to_str().expect("path"),
        out_file.to_str().expect("path"),
    );
    for variable in [
        "AFE_MEMORY_AVAILABLE_GB",
        "AFE_WORK_LIMIT",
        "AFE_OUTPUT_LIMIT",
        "AFE_WHOLE_SIGNAL_LIMIT_MB",
    ] {
        for value in ["abc", "0", "-1", "nan", "inf"] {
            let out = afe_under_ulimit(
                None,
                &["extract", w, "-r", "ild", "-o", o],
                &[(variable, value)],
            );
            assert_eq!(out.status.code(), Some(1), "{variable}={value}");
            let needle = format!(
                "the environment variable {variable} is \"{value}\": it must be a positive"
            );
            assert_clear_error(&out, &needle, &out_file);
        }
        // an accepted value runs
        let value = if variable == "AFE_MEMORY_AVAILABLE_GB" {
            "4"
        } else {
            "1e9"
        };
        let value = if variable == "AFE_WHOLE_SIGNAL_LIMIT_MB" {
            "4096"
        } else {
            value
        };
        let out = afe_under_ulimit(
            None,
            &["extract", w, "-r", "ild", "-o", o],
            &[(variable, value)],
        );
        assert!(out.status.success(), "{variable}={value}: {out:?}");
        std::fs::remove_file(&out_file).expect("written");
    }
    let out = afe_under_ulimit(
        None,
        &["extract", w, "-r", "ild", "-o", o],
        &[("AFE_WHOLE_SIGNAL_LIMIT_MB", "4.5")],
    );
    assert_clear_error(&out, "a positive whole number of MB", &out_file);
}
