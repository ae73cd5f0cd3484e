//! The outputs of `afe extract`: checked before the computation, never clobbering a link,
//! a device, the input or each other, and leaving no temporary file.

use crate::common;

use common::{afe, assert_clear_error, npz_arrays, tmp, tone, write_wav};

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
