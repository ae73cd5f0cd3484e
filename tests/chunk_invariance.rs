//! Chunk invariance: wherever the AFE is chunk-invariant, any chunking of the input gives
//! output bit-identical to one call, including a first chunk shorter than W − H and
//! chunks of a single sample (spec 00-overview §9, §11).

use afe::{Manager, ParamMap, Recorder};
use proptest::prelude::*;
use serde_json::json;

/// A deterministic binaural test signal: a tone and a pseudo-random noise, the right
/// ear delayed and softer.
fn signal(fs: f64, len: usize) -> (Vec<f64>, Vec<f64>) {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut noise = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let x: Vec<f64> = (0..len + 8)
        .map(|t| 0.3 * (2.0 * std::f64::consts::PI * 440.0 * t as f64 / fs).sin() + 0.2 * noise())
        .collect();
    (x[8..].to_vec(), x[..len].iter().map(|v| 0.5 * v).collect())
}

fn run(
    fs: f64,
    requests: &[&str],
    params: &ParamMap,
    left: &[f64],
    right: &[f64],
    chunks: Option<&[usize]>,
) -> Recorder {
    let mut mgr = Manager::new(fs, 2).expect("manager");
    mgr.set_keep_all(true);
    for r in requests {
        mgr.add_request(r, params).expect("request");
    }
    let mut rec = Recorder::new(true);
    match chunks {
        // one call on a fresh manager (`process_signal` would run a long signal in blocks)
        None => {
            mgr.process_chunk(&[left, right]).expect("process");
            rec.record(&mgr);
        }
        Some(sizes) => {
            let mut start = 0;
            let mut k = 0;
            while start < left.len() {
                let end = (start + sizes[k % sizes.len()]).min(left.len());
                mgr.process_chunk(&[&left[start..end], &right[start..end]])
                    .expect("process");
                rec.record(&mgr);
                start = end;
                k += 1;
            }
        }
    }
    rec
}

fn assert_identical(a: &Recorder, b: &Recorder) {
    assert_eq!(a.signals().len(), b.signals().len());
    for (x, y) in a.signals().iter().zip(b.signals()) {
        assert_eq!(x.key, y.key);
        assert_eq!(x.shape(), y.shape(), "{}", x.key);
        let same = x
            .data
            .as_slice()
            .iter()
            .zip(y.data.as_slice())
            .all(|(p, q)| p.to_bits() == q.to_bits() || (p.is_nan() && q.is_nan()));
        assert!(same, "{} differs between chunkings", x.key);
    }
}

fn params(pairs: &[(&str, serde_json::Value)]) -> ParamMap {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect()
}

/// Every registered request that is chunk-invariant at its defaults (spec 00-overview
/// §11), from the registry, so that a new processor is covered as soon as it is listed.
fn invariant_requests() -> Vec<&'static str> {
    afe::requests()
        .iter()
        .filter(|r| {
            (r.configure)(&(r.defaults)())
                .expect("defaults are valid")
                .chunk_invariant()
        })
        .map(|r| r.name)
        .collect()
}

/// Parameter sets covering every chunk-invariant option of the core processors, and
/// every chunk-invariant request at its defaults.
fn configurations() -> Vec<(Vec<&'static str>, ParamMap)> {
    vec![
        (invariant_requests(), ParamMap::new()),
        (
            vec!["ratemap", "crosscorrelation"],
            params(&[
                ("rm_scaling", json!("magnitude")),
                ("rm_wname", json!("hamming")),
                ("cc_wSizeSec", json!(0.04)),
                ("cc_hSizeSec", json!(0.02)),
                ("fb_nChannels", json!(8)),
                ("fb_bAlign", json!(true)),
            ]),
        ),
        (
            // hops longer than the windows, as the AFE accepts them: gaps between frames
            vec!["ratemap", "ild", "crosscorrelation", "autocorrelation"],
            params(&[
                ("rm_hSizeSec", json!(0.035)),
                ("ild_wSizeSec", json!(0.01)),
                ("ild_hSizeSec", json!(0.027)),
                ("cc_hSizeSec", json!(0.031)),
                ("ac_hSizeSec", json!(0.05)),
                ("fb_nChannels", json!(8)),
            ]),
        ),
        (
            vec!["innerhaircell", "ild"],
            params(&[
                ("ihc_method", json!("breebart")),
                ("pp_bRemoveDC", json!(1)),
                ("pp_bPreEmphasis", json!(1)),
                ("pp_bLevelScaling", json!(1)),
                ("pp_refSPLdB", json!([90, 95])),
                ("pp_bMiddleEarFiltering", json!(1)),
                ("fb_nERBs", json!(3)),
            ]),
        ),
        (
            vec!["onsetStrength", "offsetStrength", "spectralFeatures"],
            params(&[
                ("fb_nChannels", json!(6)),
                ("sf_requests", json!(["variation", "flux", "rolloff"])),
            ]),
        ),
        (
            // Short STFT windows and blocks, so that 4000 samples hold several histograms.
            vec!["duet"],
            params(&[
                ("duet_wSTFTSec", json!(0.01)),
                ("duet_wDUETSec", json!(0.05)),
                ("duet_hDUETSec", json!(0.02)),
                ("duet_binsAlpha", json!(9)),
            ]),
        ),
        (
            vec!["ratemap", "ild", "crosscorrelation"],
            params(&[("fb_type", json!("drnl")), ("fb_nChannels", json!(10))]),
        ),
        (
            vec!["adaptation", "autocorrelation"],
            params(&[
                ("fb_type", json!("drnl")),
                ("fb_model", json!("MAP")),
                ("fb_cfHz", json!([300, 1200, 5000])),
            ]),
        ),
        (
            vec!["innerhaircell", "butterworth"],
            params(&[
                ("ihc_method", json!("halfwave")),
                ("bw_type", json!("bandpass")),
                ("bw_cutoffHz", json!([300, 3000])),
                ("fb_cfHz", json!([250, 1000, 4000])),
            ]),
        ),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, failure_persistence: None, ..ProptestConfig::default() })]

    /// Random chunk sizes, the first often shorter than W − H, single samples included.
    #[test]
    fn any_chunking_is_bit_identical(
        first in 1usize..500,
        sizes in prop::collection::vec(prop_oneof![Just(1usize), 1usize..64, 64usize..1200], 1..24),
        fs in prop_oneof![Just(16000.0), Just(22050.0), Just(44100.0)],
    ) {
        let (left, right) = signal(fs, 4000);
        let mut chunking = vec![first];
        chunking.extend(sizes);
        for (requests, p) in configurations() {
            let whole = run(fs, &requests, &p, &left, &right, None);
            let chunked = run(fs, &requests, &p, &left, &right, Some(&chunking));
            assert_identical(&whole, &chunked);
        }
    }

    /// The AGC is chunk-invariant once it has been seeded from a first chunk at least
    /// `round(pp_intTimeSecRMS·fs)` samples long.
    #[test]
    fn agc_after_seeding_is_bit_identical(
        sizes in prop::collection::vec(1usize..700, 1..16),
    ) {
        let fs = 16000.0;
        let (left, right) = signal(fs, 6000);
        let p = params(&[("pp_bNormalizeRMS", json!(true)), ("pp_intTimeSecRMS", json!(0.1))]);
        let mut chunking = vec![1600];
        chunking.extend(sizes);
        let whole = run(fs, &["ratemap"], &p, &left, &right, None);
        let chunked = run(fs, &["ratemap"], &p, &left, &right, Some(&chunking));
        assert_identical(&whole, &chunked);
    }
}

/// A whole signal through the AGC runs in blocks (bounded memory), the first holding the
/// seeding time, and still gives one call's output bit for bit: seeding shorter than a
/// block, longer than one, and longer than the signal.
#[test]
fn a_whole_signal_through_the_agc_runs_in_blocks_as_one_call() {
    let fs = 16000.0;
    let (left, right) = signal(fs, 20000);
    for tau in [0.1, 0.4, 2.0] {
        let p = params(&[
            ("pp_bNormalizeRMS", json!(true)),
            ("pp_intTimeSecRMS", json!(tau)),
        ]);
        let one_call = run(fs, &["ratemap", "ild"], &p, &left, &right, None);
        let mut mgr = Manager::new(fs, 2).expect("manager");
        mgr.add_request("ratemap", &p).expect("request");
        mgr.add_request("ild", &p).expect("request");
        assert!(!mgr.is_chunk_invariant());
        assert_eq!(mgr.one_call_prefix(), Some((tau * fs).ceil() as usize + 1));
        mgr.set_keep_all(true);
        mgr.process_signal(&[&left, &right]).expect("process");
        let mut whole = Recorder::new(true);
        whole.record_whole(&mut mgr);
        assert_identical(&one_call, &whole);
        let job = afe::extract::Job {
            requests: vec!["ratemap".into(), "ild".into()],
            params: p,
            all: true,
            ..Default::default()
        };
        let extracted = afe::extract::run(&job, fs, &[&left, &right]).expect("extract");
        assert_identical(&one_call, &extracted);
    }
}

/// A seeding time longer than any signal makes the whole signal the first block: one
/// call for a short signal, a clear refusal where its blocks would pass the memory limit.
#[test]
fn an_agc_seeded_over_the_whole_signal_is_one_call_within_the_limit() {
    let fs = 16000.0;
    let (left, right) = signal(fs, 9000);
    let p = params(&[
        ("pp_bNormalizeRMS", json!(true)),
        ("pp_intTimeSecRMS", json!(1e300)),
    ]);
    let one_call = run(fs, &["ild"], &p, &left, &right, None);
    let mut mgr = Manager::new(fs, 2).expect("manager");
    mgr.add_request("ild", &p).expect("request");
    assert_eq!(mgr.one_call_prefix(), Some(usize::MAX));
    mgr.process_signal(&[&left, &right]).expect("process");
    let mut whole = Recorder::new(false);
    whole.record_whole(&mut mgr);
    let got = whole.get("ild_mono").expect("ild");
    let want = one_call.get("ild_mono").expect("ild");
    assert_eq!(got.data.as_slice(), want.data.as_slice());
    assert!(matches!(
        mgr.check_whole_signal(3600 * 16000),
        Err(afe::Error::WholeSignalTooLarge { .. })
    ));
}

/// A long chunk goes through a chunk-invariant graph in blocks: the same values as short
/// chunks (both executors), the stream's frame count and time carry on after it, and its
/// intermediate signals are not held.
#[test]
fn a_long_chunk_runs_in_blocks_with_the_same_output_and_timing() {
    let fs = 16000.0;
    let (left, right) = signal(fs, 70000);
    let requests = ["ratemap", "itd"];
    let short = run(
        fs,
        &requests,
        &ParamMap::new(),
        &left,
        &right,
        Some(&[1000]),
    );
    for threads in [0, 2] {
        let mut mgr = Manager::with_threads(fs, 2, threads).expect("manager");
        for r in requests {
            mgr.add_request(r, &ParamMap::new()).expect("request");
        }
        let mut rec = Recorder::new(false);
        let cut = 60000;
        mgr.process_chunk(&[&left[..cut], &right[..cut]])
            .expect("long chunk");
        assert_eq!(
            mgr.signals(true).len(),
            3,
            "only the requested signals are kept"
        );
        let first = mgr.signals(false)[0].new.frames() as u64;
        assert!(first > 300, "{first} ratemap frames in 3.75 s");
        rec.record(&mgr);
        mgr.process_chunk(&[&left[cut..], &right[cut..]])
            .expect("short chunk");
        let next = &mgr.signals(false)[0];
        assert_eq!(next.first_frame, first, "{threads} threads");
        assert_eq!(next.first_time_s, first as f64 * 0.01, "{threads} threads");
        rec.record(&mgr);
        for r in rec.signals() {
            let want = short.get(&r.key).expect("recorded");
            assert_eq!(
                r.data.as_slice(),
                want.data.as_slice(),
                "{} ({threads} threads)",
                r.key
            );
        }
    }
}

/// |analytic signal| of `x` by a direct DFT (MATLAB's `hilbert`, spec 01-P5), written
/// independently of the FFT the processor uses.
fn hilbert_envelope_by_dft(x: &[f64]) -> Vec<f64> {
    use std::f64::consts::PI;
    let n = x.len();
    let spectrum: Vec<(f64, f64)> = (0..n)
        .map(|k| {
            x.iter().enumerate().fold((0.0, 0.0), |(re, im), (t, v)| {
                let w = -2.0 * PI * ((k * t) % n) as f64 / n as f64;
                (re + v * w.cos(), im + v * w.sin())
            })
        })
        .collect();
    let weight = |k: usize| match k {
        0 => 1.0,
        k if 2 * k == n => 1.0,
        k if 2 * k < n => 2.0,
        _ => 0.0,
    };
    (0..n)
        .map(|t| {
            let (re, im) = (0..n).fold((0.0, 0.0), |(re, im), k| {
                let w = 2.0 * PI * ((k * t) % n) as f64 / n as f64;
                let (a, b) = spectrum[k];
                let h = weight(k);
                (
                    re + h * (a * w.cos() - b * w.sin()),
                    im + h * (a * w.sin() + b * w.cos()),
                )
            });
            (re * re + im * im).sqrt() / n as f64
        })
        .collect()
}

/// The Hilbert IHC transforms each chunk on its own, as the AFE does: every chunk's
/// envelope is that of its own stretch of the (chunk-invariant) filterbank output.
#[test]
fn hilbert_methods_depend_on_the_chunking_as_in_the_afe() {
    let fs = 16000.0;
    let (left, right) = signal(fs, 2600);
    let p = params(&[("ihc_method", json!("hilbert")), ("fb_nChannels", json!(6))]);
    let chunked = run(fs, &["innerhaircell"], &p, &left, &right, Some(&[1000]));
    let fb = chunked.get("filterbank_left").expect("recorded");
    let ihc = chunked.get("innerhaircell_left").expect("recorded");
    assert_eq!(fb.shape(), ihc.shape());
    let nc = fb.info.cf_hz().len();
    let (fb, ihc) = (fb.data.as_slice(), ihc.data.as_slice());
    for (start, end) in [(0, 1000), (1000, 2000), (2000, 2600)] {
        for c in 0..nc {
            let column: Vec<f64> = (start..end).map(|t| fb[t * nc + c]).collect();
            let want = hilbert_envelope_by_dft(&column);
            let scale = want.iter().fold(0.0f64, |a, v| a.max(*v));
            for (t, w) in (start..end).zip(&want) {
                let got = ihc[t * nc + c];
                assert!(
                    (got - w).abs() <= 1e-11 * scale,
                    "sample {t}, channel {c}: {got} vs {w}"
                );
            }
        }
    }
    let whole = run(fs, &["innerhaircell"], &p, &left, &right, None);
    assert_ne!(
        whole
            .get("innerhaircell_left")
            .expect("recorded")
            .data
            .as_slice(),
        ihc,
        "one transform over the whole signal differs at the chunk boundaries"
    );
}

/// With processors that depend on chunk boundaries in the graph (every registered request
/// is placed), `process_signal` still equals one call bit for bit, on both executors:
/// the invariant chain runs in blocks, the others once on the joined signal.
#[test]
fn process_signal_with_per_chunk_processors_equals_one_call() {
    let fs = 16000.0;
    let len = 3 * afe::extract::WHOLE_SIGNAL_BLOCK + 1234;
    let (left, right) = signal(fs, len);
    let all: Vec<&str> = afe::requests().iter().map(|r| r.name).collect();
    let p = params(&[("ihc_method", json!("hilbert"))]);
    for params in [ParamMap::new(), p] {
        let want = run(fs, &all, &params, &left, &right, None);
        for threads in [0, 2] {
            let mut mgr = Manager::with_threads(fs, 2, threads).expect("manager");
            for r in &all {
                mgr.add_request(r, &params).expect("request");
            }
            assert!(!mgr.is_chunk_invariant());
            mgr.set_keep_all(true);
            mgr.process_signal(&[&left, &right]).expect("process");
            let mut got = Recorder::new(true);
            got.record(&mgr);
            assert_identical(&want, &got);
        }
    }
}

#[test]
fn process_signal_resets_state_between_calls() {
    let fs = 16000.0;
    let (left, right) = signal(fs, 3000);
    let mut mgr = Manager::new(fs, 2).expect("manager");
    mgr.add_request("ratemap", &ParamMap::new())
        .expect("request");
    mgr.process_signal(&[&left, &right]).expect("process");
    let first = mgr.signals(false)[0].new.clone();
    mgr.process_signal(&[&left, &right]).expect("process");
    assert_eq!(&first, mgr.signals(false)[0].new);
}

/// Without `set_keep_all`, `process_signal` joins only the requested signals (the
/// intermediate ones are not there to take memory), with the same values as one call,
/// and `record_whole` moves them out of the manager.
#[test]
fn process_signal_keeps_only_the_requested_signals_by_default() {
    let fs = 16000.0;
    let len = 2 * afe::extract::WHOLE_SIGNAL_BLOCK + 99;
    let (left, right) = signal(fs, len);
    for requests in [&["ratemap", "itd"][..], &["ratemap", "pitch"][..]] {
        let want = run(fs, requests, &ParamMap::new(), &left, &right, None);
        for threads in [0, 2] {
            let mut mgr = Manager::with_threads(fs, 2, threads).expect("manager");
            for r in requests {
                mgr.add_request(r, &ParamMap::new()).expect("request");
            }
            mgr.process_signal(&[&left, &right]).expect("process");
            let keys: Vec<String> = mgr.signals(true).iter().map(|s| s.key()).collect();
            assert!(
                !keys.iter().any(|k| k.starts_with("filterbank")),
                "{keys:?}"
            );
            let mut got = Recorder::new(false);
            got.record_whole(&mut mgr);
            assert!(mgr.signals(false).is_empty(), "moved out of the manager");
            assert!(!got.signals().is_empty());
            for s in got.signals() {
                let w = want.get(&s.key).expect("requested signal");
                let bits = |b: &afe::Block| b.as_slice().iter().map(|v| v.to_bits()).collect();
                let (a, b): (Vec<u64>, Vec<u64>) = (bits(&s.data), bits(&w.data));
                assert_eq!(a, b, "{} with {requests:?}", s.key);
            }
        }
    }
}

#[test]
fn process_signal_in_blocks_equals_one_call() {
    // Longer than three blocks and not a multiple of one; every intermediate signal too,
    // on the sequential and the concurrent executor, and again after the blocks (the
    // joined outputs must not leak into the next chunk).
    let fs = 16000.0;
    let len = 3 * afe::extract::WHOLE_SIGNAL_BLOCK + 1234;
    let (left, right) = signal(fs, len);
    let requests = ["ratemap", "ild", "itd", "ic"];
    let want = run(fs, &requests, &ParamMap::new(), &left, &right, None);
    for threads in [0, 2] {
        let mut mgr = Manager::with_threads(fs, 2, threads).expect("manager");
        for r in requests {
            mgr.add_request(r, &ParamMap::new()).expect("request");
        }
        mgr.set_keep_all(true);
        mgr.process_signal(&[&left, &right]).expect("process");
        let mut got = Recorder::new(true);
        got.record(&mgr);
        assert_identical(&want, &got);
        assert_eq!(
            got.get("filterbank_left").expect("recorded").shape(),
            vec![len, 31]
        );
        mgr.process_chunk(&[&left[..100], &right[..100]])
            .expect("process");
        assert_eq!(mgr.signals(true)[0].new.frames(), 100, "{threads} threads");
    }
}
