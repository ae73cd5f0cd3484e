//! Criterion benchmark of the concurrent scheduler against the sequential executor: two
//! binaural request sets ({ratemap, ild, itd, ic} at default parameters and with a
//! 64-channel filterbank) on 1 s of the example signal, fed in chunks of 441 (10 ms) and
//! 4410 (100 ms) samples, pipelined (`submit_chunk` / `collect_chunk`), with
//! `threads` = 0 (sequential), 1 (the token protocol's overhead: the calling thread
//! alone runs every node through it) and 2 (the caller and one worker).
//!
//! Throughput is in audio samples per ear: divide by 44100 for the real-time factor.
//!
//! ```text
//! cargo bench --bench scheduler -- --warm-up-time 1 --measurement-time 3
//! ```

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use afe::{Manager, ParamMap};
use criterion::{criterion_main, BenchmarkId, Criterion, Throughput};
use serde_json::json;

fn example() -> (f64, Vec<f64>, Vec<f64>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/example_binaural.wav");
    let audio = afe::wav::read_wav(&path).expect("data/example_binaural.wav");
    let mut ch = audio.channels.into_iter();
    let (left, right) = (ch.next().expect("left"), ch.next().expect("right"));
    (audio.fs, left, right)
}

fn manager(fs: f64, threads: usize) -> Manager {
    let mut mgr = Manager::with_threads(fs, 2, threads).expect("manager");
    let big: ParamMap = [("fb_nChannels".to_string(), json!(64))]
        .into_iter()
        .collect();
    for p in [ParamMap::new(), big] {
        for r in ["ratemap", "ild", "itd", "ic"] {
            mgr.add_request(r, &p).expect("request");
        }
    }
    mgr
}

/// Feeds the signal in chunks, two in flight, and counts the output frames.
fn stream(mgr: &mut Manager, left: &[f64], right: &[f64], chunk: usize) -> usize {
    mgr.reset().expect("reset");
    let mut frames = 0;
    for (l, r) in left.chunks(chunk).zip(right.chunks(chunk)) {
        mgr.submit_chunk(&[l, r]).expect("submit");
        if mgr.in_flight() >= mgr.pipeline_depth() {
            mgr.collect_chunk().expect("collect");
            frames += mgr.signals(false)[0].new.frames();
        }
    }
    while mgr.in_flight() > 0 {
        mgr.collect_chunk().expect("collect");
        frames += mgr.signals(false)[0].new.frames();
    }
    frames
}

fn scheduler(c: &mut Criterion) {
    let (fs, left, right) = example();
    let mut group = c.benchmark_group("scheduler");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(3));
    group.throughput(Throughput::Elements(left.len() as u64));
    for chunk in [441, 4410] {
        for threads in [0, 1, 2] {
            let mut mgr = manager(fs, threads);
            let id = BenchmarkId::new(format!("chunk{chunk}"), format!("threads{threads}"));
            group.bench_function(id, |b| {
                b.iter(|| black_box(stream(&mut mgr, black_box(&left), black_box(&right), chunk)))
            });
        }
    }
    group.finish();
}

mod groups {
    use super::scheduler;
    criterion::criterion_group!(benches, scheduler);
}

criterion_main!(groups::benches);
