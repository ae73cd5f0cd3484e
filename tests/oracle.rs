//! Conformance with the MATLAB Two!Ears AFE: every public oracle case of the implemented
//! requests, against the trimmed golden arrays in `data/golden/` (always) and against the
//! full oracle when `AFE_ORACLE_DIR` points to it (`../shared/oracle`).
//!
//! The metric is the oracle's `compare.py`: per frequency channel, max |out − ref| over
//! max |ref|, worst channel; NaN on both sides counts as equal.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use afe::npy::{decode, Array};
use afe::wav::read_wav;
use afe::{Manager, ParamMap, Recorder};
use serde_json::Value;

/// Default relative tolerance per channel (the acceptance criterion).
const TOL: f64 = 1e-6;
/// ITD may flip by a correlation period at non-adjacent near-ties (spec zz N8).
const ITD_OUTLIER_FRACTION: f64 = 0.001;
/// The oracle's middle-ear reference ran Octave's `fir2`, which differs from MATLAB's
/// (spec 01-P14: 5.7e−2 expected); afe implements MATLAB's. Bounded so it cannot drift.
const MIDDLE_EAR_BOUND: f64 = 0.06;

struct Case {
    name: String,
    input: PathBuf,
    requests: Vec<String>,
    params: ParamMap,
    chunks: Vec<usize>,
    /// (output key, reference file, full shape)
    signals: Vec<(String, PathBuf, Vec<usize>)>,
}

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/golden")
}

fn supported(meta: &Value) -> bool {
    let known = [
        "time",
        "filterbank",
        "innerhaircell",
        "ratemap",
        "ild",
        "crosscorrelation",
        "itd",
        "ic",
    ];
    meta["requests"]
        .as_array()
        .is_some_and(|r| r.iter().all(|x| known.contains(&x.as_str().unwrap_or(""))))
        && meta["nondefault_params"]["fb_type"] != "drnl"
}

fn case_from(
    meta: &Value,
    input: PathBuf,
    file_root: &Path,
    signal_list: &[(String, String, Vec<usize>)],
) -> Case {
    Case {
        name: meta["case"].as_str().unwrap_or("?").to_string(),
        input,
        requests: meta["requests"]
            .as_array()
            .expect("requests")
            .iter()
            .map(|v| v.as_str().expect("request name").to_string())
            .collect(),
        params: meta["nondefault_params"]
            .as_object()
            .expect("params")
            .clone()
            .into_iter()
            .collect(),
        chunks: if meta["mode"] == "chunks" {
            meta["chunk_sizes_used"]
                .as_array()
                .expect("chunk sizes")
                .iter()
                .map(|v| v.as_u64().expect("chunk size") as usize)
                .collect()
        } else {
            Vec::new()
        },
        signals: signal_list
            .iter()
            .map(|(k, f, s)| (k.clone(), file_root.join(f), s.clone()))
            .collect(),
    }
}

fn golden_cases() -> Vec<Case> {
    let dir = golden_dir();
    let text = std::fs::read_to_string(dir.join("cases.json")).expect("data/golden/cases.json");
    let cases: Vec<Value> = serde_json::from_str(&text).expect("valid cases.json");
    cases
        .iter()
        .map(|c| {
            let signals: Vec<(String, String, Vec<usize>)> = c["signals"]
                .as_array()
                .expect("signals")
                .iter()
                .map(|s| {
                    (
                        s["key"].as_str().expect("key").to_string(),
                        s["file"].as_str().expect("file").to_string(),
                        shape(&s["shape"]),
                    )
                })
                .collect();
            let input = dir.join(c["input"].as_str().expect("input"));
            case_from(c, input, &dir, &signals)
        })
        .collect()
}

fn shape(v: &Value) -> Vec<usize> {
    v.as_array()
        .expect("shape")
        .iter()
        .map(|d| d.as_u64().expect("dimension") as usize)
        .collect()
}

fn oracle_cases(oracle: &Path) -> Vec<Case> {
    let mut out = Vec::new();
    let ref_dir = oracle.join("ref");
    for input in std::fs::read_dir(&ref_dir).expect("oracle ref/").flatten() {
        let input_name = input.file_name().to_string_lossy().to_string();
        let mut cases: Vec<PathBuf> = std::fs::read_dir(input.path())
            .expect("oracle cases")
            .flatten()
            .map(|e| e.path().join("meta.json"))
            .filter(|p| p.is_file())
            .collect();
        cases.sort();
        for meta_path in cases {
            let meta: Value =
                serde_json::from_str(&std::fs::read_to_string(&meta_path).expect("meta"))
                    .expect("json");
            if !supported(&meta) {
                continue;
            }
            let mut seen = std::collections::BTreeSet::new();
            let signals: Vec<(String, String, Vec<usize>)> = meta["signals"]
                .as_array()
                .expect("signals")
                .iter()
                .filter(|s| s["name"] != "input" && s["file"].is_string())
                .map(|s| {
                    let key = format!(
                        "{}_{}",
                        s["name"].as_str().expect("name"),
                        s["channel"].as_str().expect("channel")
                    );
                    (
                        key,
                        s["file"].as_str().expect("file").to_string(),
                        shape(&s["shape"]),
                    )
                })
                .filter(|(k, _, _)| seen.insert(k.clone()))
                .collect();
            let input_wav = oracle.join("inputs").join(format!("{input_name}.wav"));
            out.push(case_from(&meta, input_wav, &input.path(), &signals));
        }
    }
    out
}

/// Runs a case as the oracle did: one `process_signal`, or its exact chunk sequence.
fn run_case(case: &Case) -> Recorder {
    let audio = read_wav(&case.input).expect("oracle input");
    let mut mgr = Manager::new(audio.fs, audio.channels.len()).expect("manager");
    for r in &case.requests {
        mgr.add_request(r, &case.params).expect("request");
    }
    let mut rec = Recorder::new(true);
    let ears: Vec<&[f64]> = audio.channels.iter().map(Vec::as_slice).collect();
    if case.chunks.is_empty() {
        mgr.process_signal(&ears).expect("process");
        rec.record(&mgr);
    } else {
        let mut start = 0;
        for &n in &case.chunks {
            let part: Vec<&[f64]> = ears.iter().map(|e| &e[start..start + n]).collect();
            mgr.process_chunk(&part).expect("process");
            rec.record(&mgr);
            start += n;
        }
    }
    rec
}

/// compare.py's metric over the first `reference.shape[0]` rows of `out`; also returns
/// the fraction of entries over `tol`.
fn rel_error(out: &[f64], reference: &Array, tol: f64) -> (f64, f64) {
    let rows = reference.shape[0];
    let per_row = reference.data.len() / rows.max(1);
    let channels = reference.shape.get(1).copied().unwrap_or(1);
    let inner = per_row / channels.max(1);
    let channel_of = |i: usize| (i % per_row) / inner.max(1);
    let mut scale = vec![0.0f64; channels];
    for (i, r) in reference.data.iter().enumerate() {
        if !r.is_nan() {
            let c = channel_of(i);
            scale[c] = scale[c].max(r.abs());
        }
    }
    let (mut worst, mut over) = (0.0f64, 0usize);
    for (i, (o, r)) in out.iter().zip(&reference.data).enumerate() {
        let diff = if o.is_nan() && r.is_nan() {
            0.0
        } else {
            let d = (o - r).abs();
            if d.is_nan() {
                f64::INFINITY
            } else {
                d
            }
        };
        let s = scale[channel_of(i)];
        let e = diff / if s > 0.0 { s } else { 1e-300 };
        worst = worst.max(e);
        over += usize::from(e > tol);
    }
    (worst, over as f64 / reference.data.len().max(1) as f64)
}

fn check(cases: &[Case]) {
    assert!(!cases.is_empty(), "no oracle case found");
    let mut failures = Vec::new();
    let mut report = BTreeMap::new();
    for case in cases {
        let rec = run_case(case);
        for (key, file, full_shape) in &case.signals {
            let Some(out) = rec.get(key) else {
                failures.push(format!("{}: {key} missing", case.name));
                continue;
            };
            if &out.shape() != full_shape {
                failures.push(format!(
                    "{}: {key} shape {:?} != {full_shape:?}",
                    case.name,
                    out.shape()
                ));
                continue;
            }
            let bytes = std::fs::read(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
            let reference = decode(&bytes).expect("npy");
            let (rel, frac) = rel_error(out.data.as_slice(), &reference, TOL);
            let ok = if case.name == "pp_bMiddleEarFiltering" {
                rel <= MIDDLE_EAR_BOUND
            } else if key.starts_with("itd") {
                frac <= ITD_OUTLIER_FRACTION
            } else {
                rel <= TOL
            };
            report.insert(format!("{}/{key}", case.name), rel);
            if !ok {
                failures.push(format!(
                    "{}: {key} rel {rel:.3e} ({:.4}% over {TOL})",
                    case.name,
                    100.0 * frac
                ));
            }
        }
    }
    for (k, v) in &report {
        println!("{k:<55} rel {v:.3e}");
    }
    assert!(
        failures.is_empty(),
        "oracle mismatches:\n{}",
        failures.join("\n")
    );
}

#[test]
fn golden_cases_match_the_matlab_afe() {
    let cases = golden_cases();
    assert!(cases.len() >= 27, "only {} golden cases", cases.len());
    check(&cases);
}

#[test]
fn full_oracle_matches_when_available() {
    let Some(dir) = std::env::var_os("AFE_ORACLE_DIR") else {
        eprintln!("AFE_ORACLE_DIR not set: full-oracle comparison skipped");
        return;
    };
    check(&oracle_cases(Path::new(&dir)));
}
