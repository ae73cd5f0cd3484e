//! The MOC's feedback to a DRNL filterbank (spec 28-moc): the attenuation measured on the
//! first ratemap frame of chunk k sets the DRNL's non-linear gain from chunk k+1 on; both
//! executors agree at every thread count; a whole signal is one call, without feedback.

use std::time::Duration;

use afe::{Manager, ParamMap};
use serde_json::json;

const FS: f64 = 44100.0;
/// 10-ms chunks, as the AFE's MOC demo runs.
const CHUNK: usize = 441;

/// Speech-like test signal at a level where the MOC attenuates: a tone burst train with
/// noise, the right ear softer.
fn signal(len: usize) -> (Vec<f64>, Vec<f64>) {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut noise = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let left: Vec<f64> = (0..len)
        .map(|t| {
            let s = t as f64 / FS;
            let burst = if (s * 8.0).fract() < 0.5 { 1.0 } else { 0.1 };
            burst * (0.05 * (2.0 * std::f64::consts::PI * 1000.0 * s).sin() + 0.02 * noise())
        })
        .collect();
    let right = left.iter().map(|v| 0.5 * v).collect();
    (left, right)
}

fn drnl() -> ParamMap {
    [("fb_type".to_string(), json!("drnl"))]
        .into_iter()
        .collect()
}

fn manager(threads: usize, requests: &[&str], params: &ParamMap) -> Manager {
    let mut m = Manager::with_threads(FS, 2, threads).expect("manager");
    m.set_stall_timeout(Duration::from_secs(20));
    m.set_keep_all(true);
    for r in requests {
        m.add_request(r, params).expect("request");
    }
    m
}

/// Every signal's new output of each chunk, by key, in 10-ms chunks.
fn stream(m: &mut Manager, left: &[f64], right: &[f64]) -> Vec<Vec<(String, Vec<f64>)>> {
    left.chunks(CHUNK)
        .zip(right.chunks(CHUNK))
        .map(|(l, r)| {
            m.process_chunk(&[l, r]).expect("chunk");
            m.signals(true)
                .iter()
                .map(|s| (s.key(), s.new.as_slice().to_vec()))
                .collect()
        })
        .collect()
}

fn get<'a>(chunk: &'a [(String, Vec<f64>)], key: &str) -> &'a [f64] {
    &chunk
        .iter()
        .find(|(k, _)| k == key)
        .unwrap_or_else(|| panic!("{key} missing"))
        .1
}

#[test]
fn attenuation_of_chunk_k_first_shows_in_the_filterbank_of_chunk_k_plus_1() {
    let (left, right) = signal(30 * CHUNK);
    let with = stream(&mut manager(0, &["moc"], &drnl()), &left, &right);
    let without = stream(&mut manager(0, &["filterbank"], &drnl()), &left, &right);
    // the first chunk whose first MOC frame attenuates some channel
    let first = with
        .iter()
        .position(|c| {
            let moc = get(c, "moc_left");
            !moc.is_empty() && moc[..31].iter().any(|a| *a > 0.0)
        })
        .expect("the MOC attenuates this signal");
    for (k, (a, b)) in with.iter().zip(&without).enumerate() {
        let same = get(a, "filterbank_left") == get(b, "filterbank_left");
        assert_eq!(same, k <= first, "chunk {k} (first attenuation in {first})");
    }
}

#[test]
fn both_executors_agree_at_every_thread_count() {
    let (left, right) = signal(20 * CHUNK + 100);
    let requests = ["moc", "ild", "ratemap"];
    let reference = stream(&mut manager(0, &requests, &drnl()), &left, &right);
    for threads in [1, 2, 4] {
        let got = stream(&mut manager(threads, &requests, &drnl()), &left, &right);
        for (k, (a, b)) in reference.iter().zip(&got).enumerate() {
            assert_eq!(a.len(), b.len());
            for ((ka, va), (kb, vb)) in a.iter().zip(b) {
                assert_eq!(ka, kb);
                assert!(
                    va.iter().zip(vb).all(|(x, y)| x.to_bits() == y.to_bits()),
                    "{ka}, chunk {k}, {threads} threads"
                );
            }
        }
    }
}

/// `process_signal` is the AFE's one call: the DRNL output is that of a DRNL without MOC.
#[test]
fn a_whole_signal_is_processed_without_feedback() {
    let (left, right) = signal(8000);
    for threads in [0, 2] {
        let mut with = manager(threads, &["moc"], &drnl());
        with.set_keep_all(true);
        with.process_signal(&[&left, &right]).expect("whole");
        let mut without = manager(threads, &["filterbank"], &drnl());
        without.process_signal(&[&left, &right]).expect("whole");
        let a = with.signals(true);
        let b = without.signals(false);
        let fb = |s: &[afe::Signal<'_>]| {
            s.iter()
                .find(|s| s.key() == "filterbank_left")
                .map(|s| s.new.as_slice().to_vec())
        };
        assert_eq!(fb(&a), fb(&b));
        assert!(a
            .iter()
            .any(|s| s.key() == "moc_left" && s.new.frames() > 0));
    }
}

/// Two MOCs with other parameters cannot both drive one filterbank; removing the MOC
/// mid-stream leaves the filterbank running.
#[test]
fn one_moc_per_filterbank_and_removal_mid_stream() {
    let mut m = manager(2, &[], &drnl());
    let h = m.add_request("moc", &drnl()).expect("moc");
    let mut other = drnl();
    other.insert("moc_maxAttenuationdB".into(), json!(20));
    let e = m
        .add_request("moc", &other)
        .expect_err("second moc")
        .to_string();
    assert!(e.contains("feedback") && e.contains("moc"), "{e}");
    let fb = m.add_request("filterbank", &drnl()).expect("filterbank");
    let (left, right) = signal(10 * CHUNK);
    m.process_chunk(&[&left[..4 * CHUNK], &right[..4 * CHUNK]])
        .expect("chunk");
    m.remove_request(h).expect("remove");
    m.process_chunk(&[&left[4 * CHUNK..], &right[4 * CHUNK..]])
        .expect("chunk");
    assert_eq!(
        m.request_signals(fb).expect("fb")[0].new.frames(),
        6 * CHUNK
    );
}
