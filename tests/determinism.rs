//! The concurrent scheduler gives output bit-identical to the sequential executor, for
//! every thread count, request set and chunking; run-time edits keep that property.

use std::time::Duration;

use afe::{Manager, ParamMap, Recorder};
use proptest::prelude::*;
use serde_json::json;

const FS: f64 = 16000.0;

fn signal(len: usize) -> (Vec<f64>, Vec<f64>) {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let x: Vec<f64> = (0..len + 12)
        .map(|t| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            0.3 * (0.07 * t as f64).sin() + 0.1 * ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5)
        })
        .collect();
    (x[12..].to_vec(), x[..len].iter().map(|v| 0.7 * v).collect())
}

fn identical(a: &Recorder, b: &Recorder) -> Result<(), String> {
    if a.signals().len() != b.signals().len() {
        return Err(format!(
            "{} vs {} signals",
            a.signals().len(),
            b.signals().len()
        ));
    }
    for (x, y) in a.signals().iter().zip(b.signals()) {
        let same = x.key == y.key
            && x.shape() == y.shape()
            && x.data
                .as_slice()
                .iter()
                .zip(y.data.as_slice())
                .all(|(p, q)| p.to_bits() == q.to_bits() || (p.is_nan() && q.is_nan()));
        if !same {
            return Err(format!("{} differs", x.key));
        }
    }
    Ok(())
}

fn params(pairs: &[(&str, serde_json::Value)]) -> ParamMap {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect()
}

/// {ratemap, ild, itd, ic} at default parameters, and again with a 64-channel filterbank
/// and other windows (a second binaural request set).
fn place_requests(mgr: &mut Manager) {
    let big = params(&[
        ("fb_nChannels", json!(64)),
        ("cc_maxDelaySec", json!(0.0007)),
        ("ild_wname", json!("hamming")),
    ]);
    for p in [ParamMap::new(), big] {
        for r in ["ratemap", "ild", "itd", "ic"] {
            mgr.add_request(r, &p).expect("request");
        }
    }
}

fn manager(threads: usize) -> Manager {
    let mut mgr = Manager::with_threads(FS, 2, threads).expect("manager");
    mgr.set_stall_timeout(Duration::from_secs(20));
    mgr.set_keep_all(true);
    mgr
}

/// Feeds `left/right` in chunks cycling through `sizes`, pipelined, recording everything.
fn feed(mgr: &mut Manager, rec: &mut Recorder, left: &[f64], right: &[f64], sizes: &[usize]) {
    let mut start = 0;
    let mut k = 0;
    while start < left.len() {
        let end = (start + sizes[k % sizes.len()]).min(left.len());
        mgr.submit_chunk(&[&left[start..end], &right[start..end]])
            .expect("submit");
        if mgr.in_flight() >= mgr.pipeline_depth() {
            mgr.collect_chunk().expect("collect");
            rec.record(mgr);
        }
        start = end;
        k += 1;
    }
    while mgr.in_flight() > 0 {
        mgr.collect_chunk().expect("collect");
        rec.record(mgr);
    }
}

fn run(threads: usize, sizes: &[usize], left: &[f64], right: &[f64]) -> Recorder {
    let mut mgr = manager(threads);
    place_requests(&mut mgr);
    let mut rec = Recorder::new(true);
    feed(&mut mgr, &mut rec, left, right, sizes);
    rec
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 16, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn every_thread_count_matches_sequential(
        sizes in prop::collection::vec(prop_oneof![Just(1usize), 1usize..200, 160usize..2000], 1..8),
    ) {
        let (left, right) = signal(4800);
        let reference = run(0, &sizes, &left, &right);
        for threads in [1, 2, 3, 4, 8] {
            let got = run(threads, &sizes, &left, &right);
            prop_assert_eq!(identical(&reference, &got), Ok(()), "threads {}", threads);
        }
    }
}

/// Every registered request at once (from the registry, so each new processor is covered
/// when it is listed), in uneven chunks: every thread count gives the sequential output.
#[test]
fn every_registered_request_matches_sequential() {
    let (left, right) = signal(9000);
    let sizes = [1000, 37, 2205, 1, 441, 3000];
    let run = |threads: usize| {
        let mut mgr = manager(threads);
        for r in afe::requests() {
            mgr.add_request(r.name, &ParamMap::new())
                .unwrap_or_else(|e| panic!("{}: {e}", r.name));
        }
        let mut rec = Recorder::new(true);
        feed(&mut mgr, &mut rec, &left, &right, &sizes);
        rec
    };
    let reference = run(0);
    assert_eq!(
        reference.signals().len(),
        reference
            .signals()
            .iter()
            .map(|s| &s.key)
            .collect::<std::collections::BTreeSet<_>>()
            .len()
    );
    for threads in [1, 2, 3] {
        assert_eq!(
            identical(&reference, &run(threads)),
            Ok(()),
            "threads {threads}"
        );
    }
}

#[test]
fn whole_signal_and_process_chunk_match_sequential() {
    let (left, right) = signal(8000);
    let mut seq = manager(0);
    place_requests(&mut seq);
    seq.set_keep_all(true);
    seq.process_signal(&[&left, &right]).expect("process");
    let mut a = Recorder::new(true);
    a.record(&seq);
    for threads in [1, 2, 4] {
        let mut par = manager(threads);
        place_requests(&mut par);
        par.set_keep_all(true);
        par.process_signal(&[&left, &right]).expect("process");
        let mut b = Recorder::new(true);
        b.record(&par);
        assert_eq!(identical(&a, &b), Ok(()), "threads {threads}");
    }
}

/// A whole signal through every registered request, through all but the MOC (whose
/// feedback makes the whole chain take the signal in one call), and through all with the
/// AGC (whose pre-processing then reads the input in one call), with the invariant part
/// in blocks on the workers, pitch absorbing them, and the nodes that take the signal
/// in one call run on several threads as their parents finish: the sequential
/// executor's outputs, every intermediate signal among them, bit for bit.
#[test]
fn every_registered_request_whole_signal_matches_sequential() {
    let (left, right) = signal(9000);
    let agc = params(&[("pp_bNormalizeRMS", json!(true))]);
    for (skip, p) in [
        (None, ParamMap::new()),
        (Some("moc"), ParamMap::new()),
        (Some("moc"), agc),
    ] {
        let run = |threads: usize| {
            let mut mgr = manager(threads);
            for r in afe::requests().iter().filter(|r| Some(r.name) != skip) {
                mgr.add_request(r.name, &p)
                    .unwrap_or_else(|e| panic!("{}: {e}", r.name));
            }
            mgr.process_signal(&[&left, &right]).expect("process");
            let mut rec = Recorder::new(true);
            rec.record(&mgr);
            rec
        };
        let reference = run(0);
        assert!(
            reference.signals().len() >= 40,
            "{}",
            reference.signals().len()
        );
        for threads in [1, 2, 3] {
            assert_eq!(
                identical(&reference, &run(threads)),
                Ok(()),
                "without {skip:?}, {p:?}, threads {threads}"
            );
        }
    }
}

/// Adding a request mid-stream: the existing requests go on unchanged, and the new one
/// gives from then on what a manager with both requests from the start gives once its new
/// nodes are reset at the same point (new nodes start from a fresh state).
#[test]
fn adding_and_removing_requests_mid_stream() {
    let (left, right) = signal(9600);
    let (head, tail) = (4800, 9600);
    for threads in [0, 2] {
        // A: ratemap from the start, ild added at sample 4800
        let mut a = manager(threads);
        let rm = a.add_request("ratemap", &ParamMap::new()).expect("ok");
        let mut rec_a_head = Recorder::new(false);
        feed(
            &mut a,
            &mut rec_a_head,
            &left[..head],
            &right[..head],
            &[480],
        );
        let ild = a.add_request("ild", &ParamMap::new()).expect("ok");
        let mut rec_a_tail = Recorder::new(false);
        feed(
            &mut a,
            &mut rec_a_tail,
            &left[head..tail],
            &right[head..tail],
            &[480],
        );

        // B: ratemap alone over the whole stream
        let mut b = manager(threads);
        b.add_request("ratemap", &ParamMap::new()).expect("ok");
        let mut rec_b = Recorder::new(false);
        feed(&mut b, &mut rec_b, &left, &right, &[480]);
        let whole = rec_b.get("ratemap_left").expect("ratemap");
        let mut joined = rec_a_head.get("ratemap_left").expect("head").data.clone();
        joined.extend_from(&rec_a_tail.get("ratemap_left").expect("tail").data);
        assert_eq!(
            whole.data, joined,
            "ratemap must not notice the new request"
        );

        // ILD is new in A: it starts from an empty frame buffer at sample 4800, on the
        // IHC it shares, whose state ran on. Reference: a fresh ILD processor fed the tail
        // of an undisturbed IHC.
        let mut c = manager(threads);
        c.add_request("innerhaircell", &ParamMap::new())
            .expect("ok");
        let mut rec_c = Recorder::new(true);
        feed(&mut c, &mut rec_c, &left, &right, &[480]);
        let ihc_l = rec_c.get("innerhaircell_left").expect("ihc").data.clone();
        let ihc_r = rec_c.get("innerhaircell_right").expect("ihc").data.clone();
        let cf = rec_c.get("innerhaircell_left").expect("ihc").info.clone();
        let (mut fresh, _) = afe_processors::ild::Ild::new(&Default::default(), &cf).expect("ild");
        let nc = cf.cf_hz().len();
        let tail_l = afe::Block::from_vec(ihc_l.as_slice()[head * nc..].to_vec(), nc);
        let tail_r = afe::Block::from_vec(ihc_r.as_slice()[head * nc..].to_vec(), nc);
        let mut out = vec![afe::Block::new(nc)];
        afe_core::Processor::process(&mut fresh, &[&tail_l, &tail_r], &mut out);
        assert_eq!(
            rec_a_tail.get("ild_mono").expect("ild").data,
            out[0],
            "threads {threads}"
        );

        // removing ratemap frees its nodes and leaves ild running
        let before = a.processor_count();
        a.remove_request(rm).expect("remove");
        assert_eq!(a.processor_count(), before - 2);
        a.process_chunk(&[&left[..960], &right[..960]])
            .expect("process");
        assert_eq!(a.request_signals(ild).expect("ild")[0].new.frames(), 6);
        assert!(a.request_signals(rm).is_err());
    }
}

/// A split cross-correlation goes on across edits: at every edit its parts are dropped
/// and their state taken back, and the next table splits it again. Its cues must be those
/// of an undisturbed sequential run, whatever the thread count.
#[test]
fn a_split_node_keeps_its_state_across_edits() {
    let (left, right) = signal(8000);
    let mut want = manager(0);
    want.add_request("itd", &ParamMap::new()).expect("ok");
    let mut rec_want = Recorder::new(false);
    feed(&mut want, &mut rec_want, &left, &right, &[441, 97]);
    let want = rec_want.get("itd_mono").expect("itd").data.clone();
    assert!(want.frames() > 40);
    for threads in [2, 3, 4] {
        let mut m = manager(threads);
        m.add_request("itd", &ParamMap::new()).expect("ok");
        let mut got = afe::Block::new(want.width());
        let mut ratemap = None;
        // an edit after each slice: a request added, then removed
        for bounds in [0, 1313, 2900, 5003, 8000].windows(2) {
            let mut rec = Recorder::new(false);
            let (a, b) = (bounds[0], bounds[1]);
            feed(&mut m, &mut rec, &left[a..b], &right[a..b], &[441, 97]);
            got.extend_from(&rec.get("itd_mono").expect("itd").data);
            match ratemap.take() {
                None => ratemap = Some(m.add_request("ratemap", &ParamMap::new()).expect("ok")),
                Some(rm) => m.remove_request(rm).expect("remove"),
            }
        }
        assert_eq!(got, want, "threads {threads}");
    }
}

/// Modifying a parameter rebuilds and resets that processor and everything above it; the
/// rest keeps its state.
#[test]
fn modify_parameter_resets_the_processor_and_its_dependants() {
    let (left, right) = signal(6400);
    for threads in [0, 3] {
        let mut a = manager(threads);
        let rm = a.add_request("ratemap", &ParamMap::new()).expect("ok");
        let ild = a.add_request("ild", &ParamMap::new()).expect("ok");
        let mut rec = Recorder::new(false);
        feed(&mut a, &mut rec, &left[..3200], &right[..3200], &[320]);
        a.modify_parameter(rm, "rm_decaySec", json!(0.02))
            .expect("modify");
        let mut after = Recorder::new(false);
        feed(&mut a, &mut after, &left[3200..], &right[3200..], &[320]);

        // reference for ratemap: a fresh ratemap (decay 20 ms) fed the IHC of the tail
        let mut b = manager(threads);
        b.add_request("innerhaircell", &ParamMap::new())
            .expect("ok");
        let mut ihc = Recorder::new(true);
        feed(&mut b, &mut ihc, &left, &right, &[320]);
        let info = ihc.get("innerhaircell_left").expect("ihc").info.clone();
        let nc = info.cf_hz().len();
        let p = afe_processors::ratemap::RatemapParams {
            decay_sec: 0.02,
            ..Default::default()
        };
        let (mut fresh, _) = afe_processors::ratemap::Ratemap::new(&p, &info).expect("ratemap");
        let tail = afe::Block::from_vec(
            ihc.get("innerhaircell_left").expect("ihc").data.as_slice()[3200 * nc..].to_vec(),
            nc,
        );
        let mut out = vec![afe::Block::new(nc)];
        afe_core::Processor::process(&mut fresh, &[&tail], &mut out);
        assert_eq!(
            after.get("ratemap_left").expect("ratemap").data,
            out[0],
            "threads {threads}"
        );

        // ild was not touched: its output over the whole stream equals an undisturbed run
        let mut c = manager(threads);
        c.add_request("ild", &ParamMap::new()).expect("ok");
        let mut rc = Recorder::new(false);
        feed(&mut c, &mut rc, &left, &right, &[320]);
        let mut joined = rec.get("ild_mono").expect("ild").data.clone();
        joined.extend_from(&after.get("ild_mono").expect("ild").data);
        assert_eq!(rc.get("ild_mono").expect("ild").data, joined);
        assert!(
            a.modify_parameter(ild, "fb_lowFreqHz", json!(100)).is_err(),
            "grid is fixed"
        );
        // a ratemap parameter is no parameter of the ILD's chain
        let e = a
            .modify_parameter(ild, "rm_wSizeSec", json!(1))
            .expect_err("not in the ild chain")
            .to_string();
        assert!(e.contains("no processor of request"), "{e}");
        let e = a
            .modify_parameter(ild, "rm_wSizeSecs", json!(1))
            .expect_err("misspelt")
            .to_string();
        assert!(e.contains("rm_wSizeSec"), "did you mean: {e}");
    }
}

/// Without `set_keep_all`, each executor shows only the requested signals after a chunk
/// (the concurrent one copies nothing else), with the same values as when every signal
/// is kept.
#[test]
fn by_default_only_the_requested_signals_are_shown_with_the_same_values() {
    let (left, right) = signal(4800);
    let sizes = [441, 1000, 17];
    let requested = ["ratemap_left", "ratemap_right", "itd_mono", "ic_mono"];
    let reference = run(0, &sizes, &left, &right);
    for threads in [0, 2] {
        let mut mgr = Manager::with_threads(FS, 2, threads).expect("manager");
        for r in ["ratemap", "itd", "ic"] {
            mgr.add_request(r, &ParamMap::new()).expect("request");
        }
        let mut rec = Recorder::new(true);
        feed(&mut mgr, &mut rec, &left, &right, &sizes);
        let keys: Vec<&str> = rec.signals().iter().map(|s| s.key.as_str()).collect();
        assert_eq!(keys, requested, "{threads} threads");
        for s in rec.signals() {
            let want = reference.get(&s.key).expect("kept in the reference");
            assert_eq!(s.data.as_slice(), want.data.as_slice(), "{}", s.key);
        }
    }
}

/// Sound, then silence long enough for the filters' states to decay below the smallest
/// normal number: every thread flushes those subnormals to zero (they cost an Intel core a
/// microcode assist each), so no output holds one, chunked or whole, and every thread
/// count still gives the sequential output. The caller's thread gets its own setting back.
#[test]
fn silence_after_sound_leaves_no_subnormal_on_any_thread() {
    if !afe_core::denormals::flushing() {
        return eprintln!("AFE_KEEP_SUBNORMALS is set: subnormals are kept on purpose");
    }
    let (mut left, mut right) = signal(32000);
    for x in [&mut left, &mut right] {
        x[4000..].fill(0.0);
    }
    let subnormals = |rec: &Recorder| -> Vec<String> {
        rec.signals()
            .iter()
            .filter(|s| s.data.as_slice().iter().any(|v| v.is_subnormal()))
            .map(|s| s.key.clone())
            .collect()
    };
    let run = |threads: usize, whole: bool| {
        let mut mgr = manager(threads);
        for r in afe::requests() {
            mgr.add_request(r.name, &ParamMap::new())
                .unwrap_or_else(|e| panic!("{}: {e}", r.name));
        }
        let mut rec = Recorder::new(true);
        if whole {
            mgr.process_signal(&[&left, &right]).expect("process");
            rec.record(&mgr);
        } else {
            feed(&mut mgr, &mut rec, &left, &right, &[441, 1000, 37]);
        }
        rec
    };
    // the silence is long enough: the decays reach the subnormals' threshold
    let smallest = |rec: &Recorder| {
        rec.signals()
            .iter()
            .flat_map(|s| s.data.as_slice().iter())
            .filter(|v| **v != 0.0)
            .fold(f64::INFINITY, |m, v| m.min(v.abs()))
    };
    for whole in [false, true] {
        let reference = run(0, whole);
        assert!(smallest(&reference) < 1e-300, "{}", smallest(&reference));
        assert_eq!(
            subnormals(&reference),
            Vec::<String>::new(),
            "whole {whole}"
        );
        let two = run(2, whole);
        assert_eq!(identical(&reference, &two), Ok(()), "whole {whole}");
        assert_eq!(subnormals(&two), Vec::<String>::new(), "whole {whole}");
    }
    let halved = std::hint::black_box(f64::MIN_POSITIVE) * std::hint::black_box(0.5);
    assert!(
        halved.is_subnormal(),
        "the caller's floating-point setting restored"
    );
}

/// The AVX2 clones that `AFE_NO_AVX512=1` switches an AVX-512 CPU to give the AVX-512
/// kernels' bits, for every representation whose processors have kernels (the gammatone
/// and DRNL filterbanks, DF2T lanes, adaptation, frame power, autocorrelation, pitch,
/// cross-correlation, precedence, AMS, Gabor). Where the CPU has no AVX-512 both runs
/// take the AVX2 clones and the test says so.
#[test]
fn the_avx2_clones_give_the_avx512_kernels_bits() {
    #[cfg(target_arch = "x86_64")]
    let avx512 = std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512vl");
    #[cfg(not(target_arch = "x86_64"))]
    let avx512 = false;
    if !avx512 {
        eprintln!("no AVX-512 here: both runs take the AVX2 clones");
    }
    let input = crate::common::tmp("paths.wav");
    let (l, r) = signal(8000);
    crate::common::write_wav(&input, 2, FS as u32, l.len(), |i| {
        [l[i / 2], r[i / 2]][i % 2] as f32
    });
    let requests = "ratemap,ild,itd,ic,crosscorrelation,precedence,pitch,amsFeatures,gabor,moc";
    let run = |switch: &str| {
        let out = crate::common::tmp(&format!("paths-{switch}.npz"));
        let done = crate::common::afe_env(
            &[
                "extract",
                input.to_str().expect("utf-8 path"),
                "-r",
                requests,
                "-o",
                out.to_str().expect("utf-8 path"),
            ],
            &[("AFE_NO_AVX512", std::path::Path::new(switch))],
        );
        assert!(done.status.success(), "{done:?}");
        crate::common::npz_arrays(&out)
    };
    let (wide, narrow) = (run("0"), run("1"));
    // the switched run took the AVX2 clones (the dispatch reports the clone it picked)
    let bench = crate::common::afe_env(
        &[
            "bench",
            input.to_str().expect("utf-8 path"),
            "-r",
            "ild",
            "--repeat",
            "1",
            "--json",
        ],
        &[("AFE_NO_AVX512", std::path::Path::new("1"))],
    );
    let host: serde_json::Value = serde_json::from_slice(&bench.stdout).expect("bench json");
    assert_eq!(host["host"]["simd"], "avx2", "{host}");
    assert_eq!(wide.len(), narrow.len());
    assert!(wide.len() >= 12, "{} arrays", wide.len());
    for ((name, shape, a), (other, other_shape, b)) in wide.iter().zip(&narrow) {
        assert_eq!((name, shape), (other, other_shape));
        let same = a
            .iter()
            .zip(b)
            .all(|(p, q)| p.to_bits() == q.to_bits() || (p.is_nan() && q.is_nan()));
        assert!(same, "{name} differs between the AVX-512 and AVX2 kernels");
    }
}
