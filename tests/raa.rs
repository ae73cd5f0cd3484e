//! The Room Acoustic Analyzer against the AFE's `afeRAA` run under GNU Octave on
//! `data/raa_speech_16k.wav` (`data/oracle_raa/README.md`): every predictor within 1e-6
//! relative, every array within 1e-6 of its largest magnitude, the direct-stream masks
//! and the integers exactly; and the errors of inputs that `afeRAA` cannot take.

use std::collections::BTreeMap;
use std::path::Path;

use afe::raa::{raa, Raa, RaaConstants, RaaError};

use crate::common;
use common::{afe, afe_under_ulimit, assert_clear_error, npz_arrays, tmp, tone, write_wav};

/// The reference arrays by name (shape, values as float64).
fn reference() -> BTreeMap<String, (Vec<usize>, Vec<f64>)> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/oracle_raa/raa_speech_16k.npz");
    npz_arrays(&path)
        .into_iter()
        .map(|(name, shape, data)| (name, (shape, data)))
        .collect()
}

/// The reference input.
fn input() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/raa_speech_16k.wav")
}

fn computed() -> Raa {
    let wav = input();
    let audio = afe::wav::read_wav(&wav).expect("wav");
    let ears: Vec<&[f64]> = audio.channels.iter().map(Vec::as_slice).collect();
    raa(&ears, audio.fs, &RaaConstants::default()).expect("raa")
}

/// `max|out − ref| / max|ref|` over a whole field.
fn field_error(out: &[f64], reference: &[f64]) -> f64 {
    assert_eq!(out.len(), reference.len());
    let diff = out
        .iter()
        .zip(reference)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    diff / reference.iter().map(|v| v.abs()).fold(0.0, f64::max)
}

#[test]
fn raa_matches_the_afe_on_every_field() {
    let r = reference();
    let out = computed();
    let scalar = |name: &str| r[name].1[0];

    // the reference was made with the AFE's constants, which are the defaults
    let constants = serde_json::to_value(RaaConstants::default()).expect("json");
    for (name, value) in constants.as_object().expect("object") {
        assert_eq!(
            value.as_f64(),
            Some(scalar(&format!("parConf_{name}"))),
            "{name}"
        );
    }

    for f in out.par.fields() {
        let want = scalar(&format!("par_{}", f.name));
        let rel = (f.value - want).abs() / want.abs();
        eprintln!(
            "par.{:6} {:.12} (AFE {want:.12}) rel {rel:.2e}",
            f.name, f.value
        );
        assert!(
            rel <= 1e-6,
            "par.{}: {} vs the AFE's {want}: {rel:e}",
            f.name,
            f.value
        );
    }

    let psi = &out.psi;
    assert_eq!(psi.fs, scalar("psi_fs"));
    assert_eq!(psi.num_samples as f64, scalar("psi_numSamples"));
    assert_eq!(psi.num_bands as f64, scalar("psi_numBands"));
    assert_eq!(psi.itd_num_frames as f64, scalar("psi_itdNumFrames"));

    let arrays: BTreeMap<&str, (Vec<usize>, &[f64])> = psi
        .arrays()
        .into_iter()
        .map(|(name, shape, data)| (name, (shape, data)))
        .collect();
    // the masks, exactly: where the direct stream is nonzero
    for (ear, stream) in [("L", "PsiLdir"), ("R", "PsiRdir")] {
        let (shape, mask) = &r[&format!("dirmask_{ear}")];
        let (out_shape, direct) = &arrays[stream];
        assert_eq!(out_shape, shape, "{stream}");
        let differ = direct
            .iter()
            .zip(mask)
            .filter(|(d, m)| (**d != 0.0) != (**m == 1.0))
            .count();
        assert_eq!(differ, 0, "direct mask of {ear}: {differ} samples differ");
    }
    // every array, the four streams rebuilt from Psi and the masks
    let rebuilt = |base: &str, ear: &str, keep: bool| {
        let (_, psi) = &r[base];
        let (_, mask) = &r[&format!("dirmask_{ear}")];
        let values: Vec<f64> = psi
            .iter()
            .zip(mask)
            .map(|(v, m)| if (*m == 1.0) == keep { *v } else { 0.0 })
            .collect();
        values
    };
    let mut want: BTreeMap<&str, (Vec<usize>, Vec<f64>)> = BTreeMap::new();
    for name in [
        "PsiL", "PsiR", "ITD", "ITDdir", "ITDrev", "f", "t_psi", "t_itd",
    ] {
        want.insert(name, r[name].clone());
    }
    for (name, base, ear, keep) in [
        ("PsiLdir", "PsiL", "L", true),
        ("PsiRdir", "PsiR", "R", true),
        ("PsiLrev", "PsiL", "L", false),
        ("PsiRrev", "PsiR", "R", false),
    ] {
        want.insert(name, (r[base].0.clone(), rebuilt(base, ear, keep)));
    }
    assert_eq!(arrays.len(), want.len());
    for (name, (shape, values)) in &want {
        let (out_shape, out) = &arrays[name];
        assert_eq!(out_shape, shape, "shape of {name}");
        let err = field_error(out, values);
        eprintln!("psi.{name:8} max|out - AFE| / max|AFE| = {err:.2e}");
        assert!(err <= 1e-6, "psi.{name}: {err:e}");
    }
}

#[test]
fn raa_json_names_every_predictor_and_scalar_as_the_afe() {
    let json = computed().to_json();
    let par: Vec<&str> = json["par"]
        .as_object()
        .expect("par")
        .keys()
        .map(String::as_str)
        .collect();
    let afe_names = [
        "BL", "sREV", "FL", "pClar", "sClar", "Llow", "ITDf", "pASW", "sASW", "ITDb", "pLEV",
        "sLEV",
    ];
    assert_eq!(par, afe_names);
    assert_eq!(json["psi"]["numSamples"], 48000);
    assert_eq!(json["psi"]["itdNumFrames"], 119);
}

/// A binaural test signal of `n` samples at 16 kHz: bursts of a sum of tones, 100 ms on
/// and 150 ms off (so that Psi has both peaks and dips), the right ear a little louder.
fn signal(n: usize) -> (Vec<f64>, Vec<f64>) {
    let x = |t: usize| {
        if t % 4000 >= 1600 {
            return 0.0;
        }
        let t = t as f64;
        0.3 * ((0.11 * t).sin() + (0.37 * t).sin() * (0.0013 * t).cos() + (0.071 * t).sin())
    };
    let left: Vec<f64> = (0..n).map(x).collect();
    let right: Vec<f64> = left.iter().map(|v| 1.2 * v).collect();
    (left, right)
}

fn run(ears: &[&[f64]], fs: f64, constants: &RaaConstants) -> Result<Raa, RaaError> {
    raa(ears, fs, constants)
}

#[test]
fn bad_inputs_are_refused_naming_what_is_wrong() {
    let c = RaaConstants::default();
    let (l, r) = signal(3200);
    let message = |res: Result<Raa, RaaError>| res.expect_err("refused").to_string();

    let e = message(run(&[&l], 16000.0, &c));
    assert!(e.contains("two channels") && e.contains("got 1"), "{e}");
    let e = message(run(&[&l, &r, &r], 16000.0, &c));
    assert!(e.contains("got 3"), "{e}");
    let e = message(run(&[&[], &[]], 16000.0, &c));
    assert_eq!(e, "the input signal is empty");
    let e = message(run(&[&l, &r[..100]], 16000.0, &c));
    assert!(e.contains("3200 samples left, 100 right"), "{e}");
    let mut nan = r.clone();
    nan[7] = f64::NAN;
    let e = message(run(&[&l, &nan], 16000.0, &c));
    assert!(e.contains("sample 7 of the right ear is NaN"), "{e}");
    for fs in [8000.0, 0.0, -1.0, f64::NAN, 2e6] {
        let e = message(run(&[&l, &r], fs, &c));
        assert!(e.contains("more than 8000 Hz"), "{fs}: {e}");
    }
    let e = message(run(&[&l[..1000], &r[..1000]], 16000.0, &c));
    assert!(
        e.contains("1000 samples") && e.contains("at least 1200"),
        "{e}"
    );
}

#[test]
fn a_band_with_no_peak_or_no_dip_is_refused_as_the_afe_fails() {
    let (l, r) = signal(3200);
    let no_peak = RaaConstants {
        mu_psi: 1e6,
        ..RaaConstants::default()
    };
    let e = run(&[&l, &r], 16000.0, &no_peak).expect_err("no peak");
    assert!(
        matches!(
            e,
            RaaError::NoPeakOrDip {
                kind: "peak",
                ear: "left",
                band: 0,
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string()
            .contains("give mu_psi a lower value (now 1000000)"),
        "{e}"
    );
    let no_dip = RaaConstants {
        mu_psi_dip: -1e6,
        ..RaaConstants::default()
    };
    let e = run(&[&l, &r], 16000.0, &no_dip).expect_err("no dip");
    assert!(
        matches!(e, RaaError::NoPeakOrDip { kind: "dip", .. }),
        "{e}"
    );
    assert!(e.to_string().contains("mu_psi_dip a higher value"), "{e}");
}

#[test]
fn the_direct_and_reverberant_streams_add_up_to_psi() {
    let (l, r) = signal(16000);
    let out = run(&[&l, &r], 16000.0, &RaaConstants::default()).expect("raa");
    let p = &out.psi;
    for (psi, dir, rev) in [
        (&p.psi_l, &p.psi_l_dir, &p.psi_l_rev),
        (&p.psi_r, &p.psi_r_dir, &p.psi_r_rev),
    ] {
        for ((v, d), r) in psi
            .as_slice()
            .iter()
            .zip(dir.as_slice())
            .zip(rev.as_slice())
        {
            assert!(*d == 0.0 || *r == 0.0);
            assert_eq!(d + r, *v);
        }
    }
    for ((i, d), r) in p
        .itd
        .as_slice()
        .iter()
        .zip(p.itd_dir.as_slice())
        .zip(p.itd_rev.as_slice())
    {
        assert_eq!(d + r, *i);
    }
    // scaled predictors are sigmoids
    for f in out.par.fields().iter().filter(|f| f.name.starts_with('s')) {
        assert!((0.0..=1.0).contains(&f.value), "{}: {}", f.name, f.value);
    }
}

#[test]
fn the_cli_prints_the_predictors_as_json_and_writes_psi() {
    let out_file = tmp("raa.npz");
    let input = input();
    let out = afe(&[
        "raa",
        input.to_str().expect("path"),
        "--json",
        "-o",
        out_file.to_str().expect("path"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let printed: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let lib = computed();
    assert_eq!(printed, lib.to_json());
    let r = reference();
    for f in lib.par.fields() {
        let cli = printed["par"][f.name].as_f64().expect("number");
        let want = r[&format!("par_{}", f.name)].1[0];
        assert!(
            (cli - want).abs() <= 1e-6 * want.abs(),
            "{}: {cli} vs {want}",
            f.name
        );
    }
    let saved: BTreeMap<String, (Vec<usize>, Vec<f64>)> = npz_arrays(&out_file)
        .into_iter()
        .map(|(name, shape, data)| (name, (shape, data)))
        .collect();
    for (name, shape, data) in lib.psi.arrays() {
        assert_eq!(saved[name], (shape, data.to_vec()), "{name}");
    }
    assert_eq!(saved["itdNumFrames"], (vec![], vec![119.0]));
    assert_eq!(saved["par_sLEV"].1, vec![lib.par.s_lev]);
}

#[test]
fn the_cli_table_names_each_predictor_with_its_unit() {
    let input = input();
    let out = afe(&["raa", input.to_str().expect("path"), "-p", "T_min=0.0631"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .find(|l| l.starts_with("sREV "))
        .expect("sREV line");
    assert!(
        line.contains("0.993193419") && line.contains("reverberance"),
        "{line}"
    );
    assert!(
        text.lines()
            .any(|l| l.starts_with("BL ") && l.contains(" MU ")),
        "{text}"
    );
    assert!(text.contains("samples x 0.025 s"), "{text}");
}

#[test]
fn the_cli_refuses_a_mono_file_and_a_misspelt_constant() {
    let mono = tmp("raa_mono.wav");
    write_wav(&mono, 1, 16000, 4000, tone);
    let out_file = tmp("raa_refused.npz");
    let o = out_file.to_str().expect("path");
    let out = afe(&["raa", mono.to_str().expect("path"), "-o", o]);
    assert_clear_error(&out, "two channels (left, right): got 1", &out_file);
    let input = input();
    let out = afe(&[
        "raa",
        input.to_str().expect("path"),
        "-p",
        "t_min=0.1",
        "-o",
        o,
    ]);
    assert_clear_error(
        &out,
        "unknown RAA constant 't_min' (did you mean 'T_min'?)",
        &out_file,
    );
}

/// Probe finding 6 of issue 57: `nu_ASW = -1` printed `"pASW": null` with exit 0, and 12
/// other values of the constants gave NaN or infinite predictors. Every constant, with
/// every hostile value, gives either finite predictors or an error naming it, its value
/// and the range accepted.
#[test]
fn every_constant_gives_finite_predictors_or_a_clear_error() {
    let audio = afe::wav::read_wav(&input()).expect("wav");
    let ears: Vec<&[f64]> = audio.channels.iter().map(|c| &c[..16000]).collect();
    let hostile = [
        -1.0,
        0.0,
        1e-300,
        -1e-300,
        1e30,
        -1e30,
        1e308,
        -1e308,
        f64::MAX,
    ];
    let mut refused = 0;
    for name in RaaConstants::names() {
        for value in hostile {
            let map = [(name.to_string(), serde_json::json!(value))]
                .into_iter()
                .collect();
            let outcome = RaaConstants::from_params(&map)
                .and_then(|c| raa(&ears, audio.fs, &c).map(|r| r.par));
            match outcome {
                Ok(par) => {
                    for f in par.fields() {
                        assert!(
                            f.value.is_finite(),
                            "{name}={value}: {} {}",
                            f.name,
                            f.value
                        );
                    }
                }
                Err(RaaError::ConstantOutOfRange {
                    name: refused_name,
                    value: got,
                    ..
                }) => {
                    assert_eq!((refused_name, got), (name, value));
                    refused += 1;
                }
                // a threshold beyond every sample: afeRAA fails there too
                Err(e @ RaaError::NoPeakOrDip { .. }) => {
                    assert!(name.starts_with("mu_psi"), "{name}={value}: {e}");
                }
                Err(e) => panic!("{name}={value}: {e}"),
            }
        }
    }
    // the magnitudes over 1e9 of every constant, and the signs the formulas exclude
    assert!(refused >= 15 * 4, "{refused} refused");
    // the constants made directly, not parsed, are checked too
    let direct = RaaConstants {
        mu_lev: -1e308,
        ..RaaConstants::default()
    };
    let e = raa(&ears, audio.fs, &direct).expect_err("refused");
    assert_eq!(
        e.to_string(),
        "RAA constant mu_LEV = -1e308: the predictors are finite for values from -1e9 up to \
         1e9 (the AFE's value: 0.0276)"
    );
}

/// The CLI refuses an out-of-range constant in one line with exit 1 (it printed
/// `"pASW": null` and exited 0), and a NaN as not a number.
#[test]
fn the_cli_refuses_a_constant_outside_its_range() {
    let input = input();
    let out_file = tmp("raa_range.npz");
    let o = out_file.to_str().expect("path");
    let i = input.to_str().expect("path");
    for (arg, needle) in [
        (
            "nu_ASW=-1",
            "RAA constant nu_ASW = -1: the predictors are finite for values from 0 up to 1e9",
        ),
        (
            "mu_psi=-1",
            "RAA constant mu_psi = -1: the predictors are finite for values above 0",
        ),
        (
            "mu_psi_dip=0.5",
            "mu_psi_dip = 0.5: the predictors are finite for values from -1e9 below mu_psi (0.34)",
        ),
        ("T_min=-0.1", "T_min = -0.1"),
        ("nu_LEV=NaN", "'nu_LEV'"),
    ] {
        let out = afe(&["raa", i, "--json", "-p", arg, "-o", o]);
        assert_eq!(out.status.code(), Some(1), "{arg}");
        assert!(out.stdout.is_empty(), "{arg}");
        assert_clear_error(&out, needle, &out_file);
    }
}

/// Issue 57, finding 3: 10 minutes at 16 kHz aborted after 60 s at 7.4 GB, at once under
/// `ulimit -v` 2 GB. The RAA's memory is estimated by the signal's length and a signal
/// beyond the memory available refused at once, naming what it needs, what is available
/// and the longest excerpt that fits: 60 s (about 0.9 GB) under an address-space limit
/// of 600 MB, and the reference file with 50 MB set available.
#[test]
fn a_signal_too_long_for_the_memory_is_refused_before_the_raa_runs() {
    let long = tmp("raa_sixty.wav");
    write_wav(&long, 2, 16000, 60 * 16000, tone);
    let out_file = tmp("raa_memory.npz");
    let started = std::time::Instant::now();
    let (long_s, out_s) = (long.display().to_string(), out_file.display().to_string());
    let out = afe_under_ulimit(Some(600_000), &["raa", &long_s, "-o", &out_s], &[]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert_clear_error(
        &out,
        "the RAA of 60.0 s of signal would take about ",
        &out_file,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("MB available: analyse an excerpt of at most "),
        "{err}"
    );
    assert!(started.elapsed() < std::time::Duration::from_secs(10));
    let input = input();
    let out = common::afe_env(
        &["raa", input.to_str().expect("path")],
        &[("AFE_MEMORY_AVAILABLE_GB", Path::new("0.05"))],
    );
    assert_clear_error(
        &out,
        "more than the 50.0 MB available: analyse an excerpt of at most ",
        &out_file,
    );
    // the estimate covers the whole run: 1.05 times what it counts, and 64 MB
    let per_second = afe::raa::memory_bytes(16000) - afe::raa::memory_bytes(0);
    assert!(per_second > 13e6 && per_second < 14.5e6, "{per_second}");
}
