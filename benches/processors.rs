//! Criterion benchmarks of the processing cost of each AFE request and of a typical
//! request set, on 1 s of the binaural example signal (`data/example_binaural.wav`,
//! 44.1 kHz, made by `tools/make_example_wav.py`).
//!
//! * One group per registered request (`time`, `filterbank`, ..., every name `afe list`
//!   shows), named after it: the manager holds that request alone,
//!   i.e. its whole chain from the input, which is what placing the request costs; the
//!   whole signal goes through `process_signal`. `time` runs with `pp_bNormalizeRMS = 1`
//!   so that the pre-processing has work to do.
//! * Group `chain`: `ratemap`, `ild`, `itd` and `ic` together at default parameters, fed
//!   whole and in chunks of 441 (10 ms) and 2205 (50 ms) samples through `process_chunk`.
//!   Group `all`: every registered request at once, fed the same way.
//! * Group `silence`: `pitch` and the `chain` set on the example with its last 0.6 s
//!   set to 0 (digital silence, where the filters' states decay towards the subnormal
//!   numbers), whole signal: against `pitch/whole` and `chain/whole`, what silence costs.
//! * Group `gammatone`: the filterbank kernel alone, one ear, 16/32/64 channels, in
//!   channel-samples per second.
//! * Group `drnl`: the DRNL filterbank alone (`casp`, `map`), one ear, 16/32 channels,
//!   in channel-samples per second.
//! * Group `stages`: each processor after the filterbank alone (`innerhaircell` and
//!   `ratemap`, `autocorrelation` and `adaptation` on one ear, `ild` and
//!   `crosscorrelation` on both), fed its real input (the example's IHC envelopes;
//!   `precedence`, on both ears, the filterbank output),
//!   16/32/64 channels, chunks of 441, 2205 and the whole signal; throughput in audio
//!   samples per ear.
//!
//! Only processing is timed: the managers are built and the input read beforehand.
//!
//! Throughput is in elements = audio samples per ear (sample frames), so criterion
//! reports samples/s; divide by 44100 to get seconds of audio processed per second of
//! wall time (the real-time factor: above 1 is faster than real time).
//!
//! ```text
//! cargo bench --bench processors -- --warm-up-time 1 --measurement-time 2
//! ```

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use afe::{Manager, ParamMap, RequestHandle};
use criterion::{criterion_main, BenchmarkId, Criterion, Throughput};

/// The request set of the `chain` group.
const CHAIN: &[&str] = &["ratemap", "ild", "itd", "ic"];

/// Chunk lengths of the `chain` group, in samples.
const CHUNKS: &[usize] = &[441, 2205];

/// The example signal: sampling rate and (left, right).
fn example() -> (f64, Vec<f64>, Vec<f64>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/example_binaural.wav");
    let audio = afe::wav::read_wav(&path).unwrap_or_else(|e| {
        panic!("{e} (run `python3 tools/make_example_wav.py` to make the example signal)")
    });
    let mut channels = audio.channels.into_iter();
    let (Some(left), Some(right), None) = (channels.next(), channels.next(), channels.next())
    else {
        panic!("{} must have exactly 2 channels", path.display());
    };
    (audio.fs, left, right)
}

/// A binaural manager holding `requests`, all with `params`.
fn manager(fs: f64, requests: &[&str], params: &ParamMap) -> (Manager, Vec<RequestHandle>) {
    let mut mgr = Manager::new(fs, 2).expect("44.1 kHz binaural manager");
    let handles = requests
        .iter()
        .map(|r| {
            mgr.add_request(r, params)
                .unwrap_or_else(|e| panic!("placing request '{r}': {e}"))
        })
        .collect();
    (mgr, handles)
}

/// Number of output frames of the last call, kept alive against dead-code elimination.
fn frames(mgr: &Manager, handles: &[RequestHandle]) -> usize {
    handles
        .iter()
        .flat_map(|h| mgr.request_signals(*h).expect("placed request"))
        .map(|s| s.new.frames())
        .sum()
}

/// Every registered request alone, at its defaults (the pre-processing with its AGC on,
/// since by default it copies its input).
fn per_request(c: &mut Criterion) {
    let (fs, left, right) = example();
    for name in afe::requests().iter().map(|r| r.name) {
        let mut params = ParamMap::new();
        if name == "time" {
            params.insert("pp_bNormalizeRMS".into(), serde_json::Value::Bool(true));
        }
        let (mut mgr, handles) = manager(fs, &[name], &params);
        let mut group = c.benchmark_group(name);
        group.sample_size(10);
        group.warm_up_time(Duration::from_secs(1));
        group.measurement_time(Duration::from_secs(3));
        group.throughput(Throughput::Elements(left.len() as u64));
        group.bench_function("whole", |b| {
            b.iter(|| {
                mgr.process_signal(&[black_box(&left), black_box(&right)])
                    .expect("processing the example");
                black_box(frames(&mgr, &handles))
            })
        });
        group.finish();
    }
}

/// The binaural chain `CHAIN` (group `chain`), and every registered request at once in
/// one manager (group `all`), in 10-ms and 50-ms chunks and on the whole signal.
fn chain(c: &mut Criterion) {
    let all: Vec<&str> = afe::requests().iter().map(|r| r.name).collect();
    for (name, requests) in [("chain", CHAIN), ("all", all.as_slice())] {
        request_set(c, name, requests);
    }
}

fn request_set(c: &mut Criterion, name: &str, requests: &[&str]) {
    let (fs, left, right) = example();
    let (mut mgr, handles) = manager(fs, requests, &ParamMap::new());
    let mut group = c.benchmark_group(name);
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(4));
    group.throughput(Throughput::Elements(left.len() as u64));
    group.bench_function("whole", |b| {
        b.iter(|| {
            mgr.process_signal(&[black_box(&left), black_box(&right)])
                .expect("processing the example");
            black_box(frames(&mgr, &handles))
        })
    });
    for &chunk in CHUNKS {
        group.bench_with_input(BenchmarkId::new("chunk", chunk), &chunk, |b, &chunk| {
            b.iter(|| {
                mgr.reset().expect("reset");
                let mut out = 0;
                for (l, r) in left.chunks(chunk).zip(right.chunks(chunk)) {
                    mgr.process_chunk(&[black_box(l), black_box(r)])
                        .expect("processing a chunk");
                    out += frames(&mgr, &handles);
                }
                black_box(out)
            })
        });
    }
    group.finish();
}

/// Group `silence`: see the module's doc.
fn silence(c: &mut Criterion) {
    let (fs, mut left, mut right) = example();
    let from = left.len() * 2 / 5;
    left[from..].fill(0.0);
    right[from..].fill(0.0);
    let mut group = c.benchmark_group("silence");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(3));
    group.throughput(Throughput::Elements(left.len() as u64));
    for (name, requests) in [("pitch", &["pitch"][..]), ("chain", CHAIN)] {
        let (mut mgr, handles) = manager(fs, requests, &ParamMap::new());
        group.bench_function(name, |b| {
            b.iter(|| {
                mgr.process_signal(&[black_box(&left), black_box(&right)])
                    .expect("processing the example");
                black_box(frames(&mgr, &handles))
            })
        });
    }
    group.finish();
}

/// Times filterbank `fb` (`channels` outputs) over one ear's signal `left` in chunks of
/// 441 (10 ms), 2205 (BASS default) and the whole signal, under `name/<chunk>`.
fn filterbank_chunks(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    name: &str,
    fb: &mut dyn afe_core::Processor,
    channels: u32,
    left: &[f64],
) {
    use afe_core::Block;
    group.throughput(Throughput::Elements(
        left.len() as u64 * u64::from(channels),
    ));
    for chunk in [441, 2205, left.len()] {
        let blocks: Vec<Block> = left
            .chunks(chunk)
            .map(|c| Block::from_vec(c.to_vec(), 1))
            .collect();
        let mut out = vec![Block::new(channels as usize)];
        group.bench_function(BenchmarkId::new(name, chunk), |b| {
            b.iter(|| {
                fb.reset();
                for x in &blocks {
                    fb.process(&[black_box(x)], &mut out);
                }
                black_box(out[0].frames())
            })
        });
    }
}

/// The gammatone filterbank alone, one ear, in channel-samples per second (one core):
/// 16/32/64 channels, chunks of 441 (10 ms), 2205 (BASS default) and the whole signal.
fn gammatone(c: &mut Criterion) {
    use afe_processors::filterbank::FilterbankParams;
    use afe_processors::gammatone::Gammatone;
    let (fs, left, _) = example();
    let mut group = c.benchmark_group("gammatone");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(2));
    for channels in [16u32, 32, 64] {
        let params = FilterbankParams {
            n_channels: Some(channels),
            ..FilterbankParams::default()
        };
        let (mut fb, _) = Gammatone::new(&params, fs).expect("filterbank");
        filterbank_chunks(
            &mut group,
            &format!("{channels}ch"),
            &mut fb,
            channels,
            &left,
        );
    }
    group.finish();
}

/// The DRNL filterbank alone (CASP and MAP), one ear, in channel-samples per second (one
/// core): 16/32 channels, chunks of 441 (10 ms), 2205 (BASS default) and the whole signal.
fn drnl(c: &mut Criterion) {
    use afe_processors::drnl::{Drnl, DrnlModel};
    use afe_processors::filterbank::{FbType, FilterbankParams};
    let (fs, left, _) = example();
    let mut group = c.benchmark_group("drnl");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(2));
    for (model, name) in [(DrnlModel::Casp, "casp"), (DrnlModel::Map, "map")] {
        for channels in [16u32, 32] {
            let params = FilterbankParams {
                fb_type: FbType::Drnl,
                model,
                n_channels: Some(channels),
                ..FilterbankParams::default()
            };
            let (mut fb, _) = Drnl::new(&params, fs).expect("filterbank");
            let id = format!("{name}/{channels}ch");
            filterbank_chunks(&mut group, &id, &mut fb, channels, &left);
        }
    }
    group.finish();
}

/// The processors after the filterbank, each alone on its real input (see the crate doc).
fn stages(c: &mut Criterion) {
    use afe_core::{Block, Processor, SignalInfo};
    use afe_processors::adaptation::{Adaptation, AdaptationParams};
    use afe_processors::autocorrelation::{Autocorrelation, AutocorrelationParams};
    use afe_processors::crosscorrelation::{Crosscorrelation, CrosscorrelationParams};
    use afe_processors::filterbank::FilterbankParams;
    use afe_processors::gammatone::Gammatone;
    use afe_processors::ihc::{Ihc, IhcParams};
    use afe_processors::ild::{Ild, IldParams};
    use afe_processors::precedence::{Precedence, PrecedenceParams};
    use afe_processors::ratemap::{Ratemap, RatemapParams};

    /// Runs `p` (outputs `infos`) over `inputs` (one signal per ear) cut into `chunk`-sample
    /// blocks.
    fn bench(
        group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
        id: BenchmarkId,
        (p, infos): (&mut dyn Processor, &[SignalInfo]),
        inputs: &[&Block],
        chunk: usize,
    ) {
        let width = inputs[0].width();
        let blocks: Vec<Vec<Block>> = inputs
            .iter()
            .map(|b| {
                b.as_slice()
                    .chunks(chunk * width)
                    .map(|c| Block::from_vec(c.to_vec(), width))
                    .collect()
            })
            .collect();
        let mut out: Vec<Block> = infos.iter().map(|i| Block::new(i.width())).collect();
        group.bench_function(id, |b| {
            b.iter(|| {
                p.reset();
                for k in 0..blocks[0].len() {
                    let ins: Vec<&Block> = blocks.iter().map(|ear| &ear[k]).collect();
                    p.process(black_box(&ins), &mut out);
                }
                black_box(out[0].frames())
            })
        });
    }

    let (fs, left, right) = example();
    let mut group = c.benchmark_group("stages");
    group.sample_size(10);
    group.warm_up_time(Duration::from_millis(500));
    group.measurement_time(Duration::from_secs(1));
    group.throughput(Throughput::Elements(left.len() as u64));
    for channels in [16u32, 32, 64] {
        let params = FilterbankParams {
            n_channels: Some(channels),
            ..FilterbankParams::default()
        };
        let mut fb_info = SignalInfo::time_domain(fs);
        let mut ihc_info = fb_info.clone();
        let (mut fb_in, mut ihc_in) = (Vec::new(), Vec::new());
        for ear in [&left, &right] {
            let (mut fb, info) = Gammatone::new(&params, fs).expect("filterbank");
            let (mut ihc, info2) = Ihc::new(&IhcParams::default(), &info).expect("ihc");
            let mut fb_out = vec![Block::new(info.width())];
            fb.process(&[&Block::from_vec(ear.clone(), 1)], &mut fb_out);
            let mut ihc_out = vec![Block::new(info2.width())];
            ihc.process(&[&fb_out[0]], &mut ihc_out);
            fb_in.push(fb_out.remove(0));
            ihc_in.push(ihc_out.remove(0));
            (fb_info, ihc_info) = (info, info2);
        }
        for chunk in [441, 2205, left.len()] {
            let id = |name: &str| BenchmarkId::new(format!("{name}/{channels}ch"), chunk);
            let binaural = [&ihc_in[0], &ihc_in[1]];
            let (mut ihc, info) = Ihc::new(&IhcParams::default(), &fb_info).expect("ihc");
            let p = (&mut ihc as &mut dyn Processor, &[info][..]);
            bench(&mut group, id("innerhaircell"), p, &[&fb_in[0]], chunk);
            let (mut rm, info) =
                Ratemap::new(&RatemapParams::default(), &ihc_info).expect("ratemap");
            bench(
                &mut group,
                id("ratemap"),
                (&mut rm, &[info]),
                &[&ihc_in[0]],
                chunk,
            );
            let (mut ild, info) = Ild::new(&IldParams::default(), &ihc_info).expect("ild");
            bench(&mut group, id("ild"), (&mut ild, &[info]), &binaural, chunk);
            let (mut cc, info) =
                Crosscorrelation::new(&CrosscorrelationParams::default(), &ihc_info)
                    .expect("crosscorrelation");
            bench(
                &mut group,
                id("crosscorrelation"),
                (&mut cc, &[info]),
                &binaural,
                chunk,
            );
            let (mut prec, infos) =
                Precedence::new(&PrecedenceParams::default(), &fb_info).expect("precedence");
            let filterbank = [&fb_in[0], &fb_in[1]];
            let p = (&mut prec as &mut dyn Processor, &infos[..]);
            bench(&mut group, id("precedence"), p, &filterbank, chunk);
            let (mut ac, info) = Autocorrelation::new(&AutocorrelationParams::default(), &ihc_info)
                .expect("autocorrelation");
            let p = (&mut ac as &mut dyn Processor, &[info][..]);
            bench(&mut group, id("autocorrelation"), p, &[&ihc_in[0]], chunk);
            let (mut adapt, info) =
                Adaptation::new(&AdaptationParams::default(), &ihc_info).expect("adaptation");
            let p = (&mut adapt as &mut dyn Processor, &[info][..]);
            bench(&mut group, id("adaptation"), p, &[&ihc_in[0]], chunk);
        }
    }
    group.finish();
}

/// The benchmark list (in a private module: the macro makes an undocumented `pub fn`).
mod list {
    use super::{chain, drnl, gammatone, per_request, silence, stages};
    use criterion::criterion_group;

    criterion_group!(
        benches,
        per_request,
        chain,
        silence,
        gammatone,
        drnl,
        stages
    );
}

criterion_main!(list::benches);
