//! `crosscorrelation`: normalised interaural cross-correlation per channel and frame over
//! lags −maxLag..maxLag (spec 18-crosscorrelation): by dot products over even and odd
//! samples for short lag ranges, by zero-padded real FFTs for long ones.

use std::ops::Range;

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::framing::FrameBuffer;
use afe_core::window::{window, Window};
use afe_core::{Block, ChannelSplit, Error, Part, Processor, Result, SignalInfo};

use crate::framed::{check_framing, check_work, EarFrames};

mod direct;
mod fft;

use direct::{direct_work, Direct, LANES};
use fft::FftEngine;

afe_core::params! {
    /// Parameters of the cross-correlation, under their AFE names.
    pub struct CrosscorrelationParams / CrosscorrelationNames {
        /// window applied to each frame
        #[afe = "cc_wname"]
        pub wname: Window = Window::Hann,
        /// window length
        #[afe = "cc_wSizeSec", unit = "s"]
        pub w_size_sec: f64 = 0.02,
        /// hop between frames
        #[afe = "cc_hSizeSec", unit = "s"]
        pub h_size_sec: f64 = 0.01,
        /// largest interaural lag computed
        #[afe = "cc_maxDelaySec", unit = "s"]
        pub max_delay_sec: f64 = 0.0011,
    }
}

/// The cross-correlation: left and right IHC in, `[frame][channel][lag]` out.
pub struct Crosscorrelation {
    frames: EarFrames,
    engine: Engine,
    /// The channels it outputs: all (`None`) or, as a part of a split, this range.
    part: Option<Range<usize>>,
}

/// How the lags are computed: the choice depends only on the configuration.
enum Engine {
    /// Dot products per lag (a two-parallel fast FIR), eight channels per SIMD vector:
    /// fastest for short lag ranges such as the default 99 lags.
    Direct(Direct),
    /// Zero-padded real FFTs per channel: fastest for long lag ranges.
    Fft(Box<FftEngine>),
}

impl std::fmt::Debug for Crosscorrelation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (method, w, max_lag) = match &self.engine {
            Engine::Direct(d) => ("direct", d.win.len(), d.max_lag),
            Engine::Fft(f) => ("fft", f.win.len(), f.max_lag),
        };
        f.debug_struct("Crosscorrelation")
            .field("method", &method)
            .field("window", &w)
            .field("max_lag", &max_lag)
            .finish_non_exhaustive()
    }
}

impl Crosscorrelation {
    /// Builds the cross-correlation for the IHC signal `input` (the same for both ears).
    pub fn new(params: &CrosscorrelationParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        let fs = input.fs_hz;
        let (w, h) = check_framing(
            (CrosscorrelationParams::NAMES.w_size_sec, params.w_size_sec),
            (CrosscorrelationParams::NAMES.h_size_sec, params.h_size_sec),
            fs,
            input.channels(),
        )?;
        let max_lag = (params.max_delay_sec * fs).ceil();
        if params.max_delay_sec < 0.0 || max_lag > w as f64 {
            return Err(Error::invalid(
                CrosscorrelationParams::NAMES.max_delay_sec,
                params.max_delay_sec,
                format!(
                    "must be ≥ 0 s and at most the window ({} s): longer lags are all zero",
                    params.w_size_sec
                ),
            ));
        }
        let max_lag = max_lag as usize;
        let win = window(params.wname, w);
        let nc = input.channels();
        let engine = if prefer_direct(w, max_lag) {
            // found by fuzzing: 1.4 GB for a long window when it kept every group's rows
            // (one group of channels at a time, few lags: the window is what counts)
            check_work(
                (CrosscorrelationParams::NAMES.w_size_sec, params.w_size_sec),
                direct_work(w, max_lag),
                &format!("this window of {w} samples"),
                "shorten the window",
            )?;
            Engine::Direct(Direct::new(win, max_lag, nc))
        } else {
            Engine::Fft(Box::new(FftEngine::new(win, max_lag)))
        };
        let cc = Crosscorrelation {
            frames: EarFrames::new(nc, w, h),
            engine,
            part: None,
        };
        let lags_s = (0..=2 * max_lag)
            .map(|i| (i as f64 - max_lag as f64) / fs)
            .collect();
        let info = input
            .correlation(1.0 / params.h_size_sec, lags_s)
            .with_unit(Self::OUTPUT_UNIT)
            .with_window_s(params.w_size_sec);
        Ok((cc, info))
    }
}

/// Whether dot products beat the FFT for a `w`-sample window and lags up to `max_lag`:
/// the direct method costs `3·(w/2)·(maxLag+1)` multiply-adds per channel, eight channels
/// at a time, the FFT about three transforms per channel. At 44.1 kHz (882-sample window)
/// this picks dot products for 99 and 443 lags, the FFT for 883 and beyond, which is
/// where the plain dot products measured faster and slower (`afe bench -r
/// crosscorrelation -p cc_maxDelaySec=…`, one core); the fast FIR moves the crossover
/// further out, not below.
fn prefer_direct(w: usize, max_lag: usize) -> bool {
    let nfft = (w + max_lag.min(w - 1)).next_power_of_two() as f64;
    let direct = (3 * (w / 2) * (max_lag + 1)) as f64 / LANES as f64;
    let fft = 3.0 * nfft * nfft.log2();
    direct <= fft
}

/// Whether a frame pair whose largest windowed magnitudes are `left` and `right` has
/// products that flushing subnormals to zero would change beyond the round-off (it
/// drops them whole) while IEEE arithmetic, the AFE's, keeps them: the decay after
/// digital silence, 300 dB and more below the signal, whose correlation's shape (its
/// peak, the ITD) the AFE still computes. Not where every product underflows to 0 in
/// IEEE arithmetic too (below 2^−1076), nor where the thread keeps subnormals.
pub(crate) fn in_subnormal_band(left: f64, right: f64) -> bool {
    // log2 of the largest product (the product itself could flush)
    let product = left.log2() + right.log2();
    left > 0.0
        && right > 0.0
        && (-1076.0..SUBNORMAL_PRODUCT_LOG2).contains(&product)
        && afe_core::denormals::flushing()
}

/// Whether the largest magnitudes `left` and `right` lie above [`in_subnormal_band`]'s
/// band, where larger maxima keep them (with a factor 2 to spare, so that the product's
/// rounding cannot disagree with the band's sum of logarithms).
pub(crate) fn above_subnormal_band(left: f64, right: f64) -> bool {
    left * right >= 2.0 * SUBNORMAL_PRODUCT_LOG2.exp2()
}

/// log2 of the largest product below which a frame pair is correlated in IEEE
/// arithmetic (1e−280: its products a window's edge away, 1e−10 smaller, stay normal).
const SUBNORMAL_PRODUCT_LOG2: f64 = -930.1;

impl Crosscorrelation {
    fn max_lag(&self) -> usize {
        match &self.engine {
            Engine::Direct(d) => d.max_lag,
            Engine::Fft(f) => f.max_lag,
        }
    }

    /// Channel ranges of up to `parts` parts over `nc` channels: for the direct method,
    /// whole groups, cut only where a group does not overlap the next (see
    /// [`vector_start`]), so each part's lanes are the groups of one call.
    ///
    /// [`vector_start`]: afe_core::lanes::vector_start
    fn part_ranges(&self, parts: usize, nc: usize) -> Vec<(Range<usize>, Range<usize>)> {
        match &self.engine {
            Engine::Direct(d) => {
                let groups = d.starts.len();
                let parts = parts.min(groups);
                // `p·groups/parts` rises strictly with `p`, from 1 to below `groups`
                let inner = (1..parts)
                    .map(|p| p * groups / parts)
                    .filter(|&g| d.starts[g] == g * LANES);
                let cuts: Vec<usize> = std::iter::once(0)
                    .chain(inner)
                    .chain(std::iter::once(groups))
                    .collect();
                cuts.windows(2)
                    .map(|w| {
                        let end = if w[1] == groups { nc } else { d.starts[w[1]] };
                        (d.starts[w[0]]..end, w[0]..w[1])
                    })
                    .collect()
            }
            Engine::Fft(_) => {
                let parts = parts.min(nc).max(1);
                (0..parts)
                    .map(|p| (p * nc / parts..(p + 1) * nc / parts, 0..0))
                    .collect()
            }
        }
    }
}

impl Processor for Crosscorrelation {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let nc = inputs[0].width();
        let ears = (inputs[0].as_slice(), inputs[1].as_slice());
        let n = self.frames.available(ears.0, ears.1);
        let nl = 2 * self.max_lag() + 1;
        let channels = self.part.clone().unwrap_or(0..nc);
        let out = outputs[0].resize_to(n);
        for (k, out) in out.chunks_exact_mut(channels.len() * nl).enumerate() {
            let (fl, fr) = self.frames.frame(ears, k);
            match &mut self.engine {
                Engine::Direct(d) => d.correlate(fl, fr, out),
                Engine::Fft(f) => {
                    for (c, o) in (0..channels.len()).zip(out.chunks_exact_mut(nl)) {
                        f.correlate(fl, fr, c, o);
                    }
                }
            }
        }
        self.frames.advance(ears.0, ears.1, n);
    }

    fn reset(&mut self) {
        self.frames.reset();
    }

    fn channel_split(&mut self) -> Option<&mut dyn ChannelSplit> {
        Some(self)
    }
}

impl ChannelSplit for Crosscorrelation {
    /// Splits the channels (whole groups of the direct method) into up to `parts` ranges.
    fn split(&self, parts: usize) -> Option<Vec<Part>> {
        let nc = self.frames.width();
        let ranges = self.part_ranges(parts, nc);
        if ranges.len() < 2 || self.part.is_some() {
            return None;
        }
        let nl = 2 * self.max_lag() + 1;
        let part = |(channels, groups): (Range<usize>, Range<usize>)| {
            let engine = match &self.engine {
                Engine::Direct(d) => Engine::Direct(d.part(groups)),
                Engine::Fft(f) => Engine::Fft(Box::new(FftEngine::new(f.win.clone(), f.max_lag))),
            };
            Part {
                widths: vec![channels.len() * nl],
                processor: Box::new(Crosscorrelation {
                    frames: self.frames.columns(channels.clone()),
                    engine,
                    part: Some(channels),
                }),
            }
        };
        Some(ranges.into_iter().map(part).collect())
    }

    /// Each output row is the parts' rows side by side. The parts keep the rows of their
    /// channels, so the join only counts rows (what [`ChannelSplit::rejoin`] takes back).
    fn join(&mut self, inputs: &[&Block], parts: &[&[Block]], outputs: &mut [Block]) {
        self.frames.count_only();
        let ears = (inputs[0].as_slice(), inputs[1].as_slice());
        let n = self.frames.available(ears.0, ears.1);
        let row_width = outputs[0].width();
        let out = outputs[0].resize_to(n);
        let mut at = 0;
        for part in parts {
            let width = part[0].width();
            for (row, share) in out.chunks_exact_mut(row_width).zip(part[0].rows()) {
                row[at..at + width].copy_from_slice(share);
            }
            at += width;
        }
        self.frames.advance(ears.0, ears.1, n);
    }

    fn part_frames(&mut self) -> &[FrameBuffer] {
        self.frames.buffers()
    }

    fn rejoin(&mut self, parts: &[&[FrameBuffer]]) {
        if let Some(frames) = EarFrames::joined(parts) {
            self.frames = frames;
        }
    }
}

impl Descriptor for Crosscorrelation {
    type Params = CrosscorrelationParams;
    const NAME: &'static str = "crosscorrelation";
    const DEPENDENCY: &'static str = "innerhaircell";
    const EARS: Ears = Ears::Binaural;
    const DESCRIPTION: &'static str =
        "normalised interaural cross-correlation per frame, channel and lag";
    const OUTPUT_UNIT: &'static str = "";

    fn build(params: &CrosscorrelationParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Crosscorrelation::new(params, &inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }
}

/// The registry entry of `crosscorrelation`.
pub static REQUEST: RequestDef = request_def::<Crosscorrelation>();

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::noise;

    /// Maxima above the subnormal band stay out of it as they grow (what lets precedence
    /// stop its scan early), and maxima in the band are not taken for above it.
    #[test]
    fn maxima_above_the_subnormal_band_stay_above_it() {
        let _flush = afe_core::denormals::FlushDenormals::enable();
        let magnitudes: Vec<f64> = (-330..=10).map(|e| 10f64.powf(e as f64 * 0.97)).collect();
        let (mut above, mut inside) = (0, 0);
        for &a in &magnitudes {
            for &b in &magnitudes {
                if in_subnormal_band(a, b) {
                    inside += 1;
                    assert!(!above_subnormal_band(a, b), "{a:e}·{b:e} is in the band");
                }
                if above_subnormal_band(a, b) {
                    above += 1;
                    for (ga, gb) in [(1.0, 1.0), (1.0, 3.0), (7.0, 1.0), (1e30, 1e10)] {
                        assert!(!in_subnormal_band(a * ga, b * gb), "{a:e}·{b:e} grown");
                    }
                }
            }
        }
        assert!(above > 0 && inside > 0, "{above} above, {inside} inside");
    }

    /// Parts over channel ranges, joined, give the unsplit output bit for bit, for the
    /// direct method (groups cut where they do not overlap) and the FFT, over chunks
    /// with and without complete frames, and so does the processor after it took its
    /// state back from the parts; where no cut is possible there is no split.
    #[test]
    fn split_parts_joined_equal_one_processor() {
        let direct = CrosscorrelationParams::default();
        // lags as long as a 100-ms window: the FFT method
        let fft = CrosscorrelationParams {
            w_size_sec: 0.1,
            h_size_sec: 0.05,
            max_delay_sec: 0.1,
            ..Default::default()
        };
        let cases = [
            (31, &direct, 2, 2),
            (32, &direct, 3, 3),
            (16, &direct, 2, 2),
            (16, &direct, 3, 2),
            (9, &direct, 2, 0),
            (6, &direct, 2, 0),
            (5, &fft, 2, 2),
        ];
        for (nc, p, parts, expected) in cases {
            let fs = 16000.0;
            let cf = (0..nc).map(|c| 100.0 * (c + 1) as f64).collect();
            let info = SignalInfo::time_frequency(fs, cf);
            let (mut whole, out_info) = Crosscorrelation::new(p, &info).expect("valid");
            let (mut joined, _) = Crosscorrelation::new(p, &info).expect("valid");
            assert_eq!(
                matches!(whole.engine, Engine::Fft(_)),
                std::ptr::eq(p, &fft),
                "{nc}"
            );
            let mut split: Option<Vec<Part>> = None;
            let mut made = 0;
            for (k, len) in [100, 400, 7, 1000, 3333, 1, 900].into_iter().enumerate() {
                let l = Block::from_vec(noise(len * nc, 2 * k as u64), nc);
                let r = Block::from_vec(noise(len * nc, 2 * k as u64 + 1), nc);
                let mut want = vec![Block::new(out_info.width())];
                whole.process(&[&l, &r], &mut want);
                // split after the first chunk, so that the parts start from a state
                if k == 1 {
                    split = joined.split(parts);
                    made = split.as_ref().map_or(0, Vec::len);
                }
                // the parts dropped after four chunks, their state taken back
                if k == 5 {
                    if let Some(mut split) = split.take() {
                        let shares: Vec<&[FrameBuffer]> = split
                            .iter_mut()
                            .filter_map(|p| p.processor.channel_split().map(|c| c.part_frames()))
                            .collect();
                        joined.rejoin(&shares);
                    }
                }
                let mut got = vec![Block::new(out_info.width())];
                match split.as_mut() {
                    Some(split) => {
                        let mut shares: Vec<Vec<Block>> = Vec::new();
                        for part in split.iter_mut() {
                            let mut out = vec![Block::new(part.widths[0])];
                            part.processor.process(&[&l, &r], &mut out);
                            shares.push(out);
                        }
                        let views: Vec<&[Block]> = shares.iter().map(Vec::as_slice).collect();
                        joined.join(&[&l, &r], &views, &mut got);
                    }
                    None => joined.process(&[&l, &r], &mut got),
                }
                assert_eq!(
                    got[0].as_slice(),
                    want[0].as_slice(),
                    "{nc} channels, chunk {k}"
                );
            }
            // 9 channels: groups at 0 and 1 overlap; 6: one group
            assert_eq!(made, expected, "{nc} channels");
        }
    }

    /// The cost model's crossover at 44.1 kHz (882-sample window, a 2048-point FFT from
    /// 143 lags on): dot products up to 407 lags each way (3·441·408/8 = 67,473 against
    /// 3·2048·11 = 67,584), the FFT from 408; below 143 lags the FFT has 1024 points.
    #[test]
    fn the_engine_follows_the_cost_model() {
        assert!(prefer_direct(882, 407) && !prefer_direct(882, 408));
        assert!(prefer_direct(882, 49) && !prefer_direct(882, 882));
        let info = SignalInfo::time_frequency(44100.0, vec![500.0; 2]);
        let (cc, _) =
            Crosscorrelation::new(&CrosscorrelationParams::default(), &info).expect("valid");
        assert_eq!(
            format!("{cc:?}"),
            "Crosscorrelation { method: \"direct\", window: 882, max_lag: 49, .. }"
        );
    }

    /// Direct evaluation of `Σ_n l[n+ℓ]·r[n] / (eps + sqrt(Σl²Σr²))`.
    fn direct(l: &[f64], r: &[f64], lag: isize) -> f64 {
        let w = l.len() as isize;
        let mut acc = 0.0;
        for n in 0..w {
            let m = n + lag;
            if (0..w).contains(&m) {
                acc += l[m as usize] * r[n as usize];
            }
        }
        let el: f64 = l.iter().map(|v| v * v).sum();
        let er: f64 = r.iter().map(|v| v * v).sum();
        acc / (f64::EPSILON + (el * er).sqrt())
    }

    #[test]
    fn matches_direct_correlation_and_finds_the_delay() {
        let fs = 1000.0;
        let info = SignalInfo::time_frequency(fs, vec![100.0]);
        let p = CrosscorrelationParams {
            max_delay_sec: 0.005,
            ..Default::default()
        };
        let (mut cc, out_info) = Crosscorrelation::new(&p, &info).expect("valid");
        assert_eq!(out_info.lags_s().len(), 11);
        // right = left delayed by 3 samples: peak at lag −3
        let x: Vec<f64> = (0..60).map(|i| ((i * 37) % 11) as f64).collect();
        let l = Block::from_vec(x[3..43].to_vec(), 1);
        let r = Block::from_vec(x[0..40].to_vec(), 1);
        let mut out = vec![Block::new(11)];
        cc.process(&[&l, &r], &mut out);
        assert_eq!(out[0].frames(), 3);
        let win = window(Window::Hann, 20);
        let lw: Vec<f64> = (0..20).map(|n| win[n] * l.as_slice()[n]).collect();
        let rw: Vec<f64> = (0..20).map(|n| win[n] * r.as_slice()[n]).collect();
        for (i, v) in out[0].row(0).iter().enumerate() {
            assert!((v - direct(&lw, &rw, i as isize - 5)).abs() < 1e-12);
        }
    }

    /// `reset` starts the framing over; taking back the state of no parts keeps it.
    #[test]
    fn reset_and_an_empty_rejoin() {
        let info = SignalInfo::time_frequency(1000.0, vec![100.0, 200.0]);
        let (mut cc, out_info) =
            Crosscorrelation::new(&CrosscorrelationParams::default(), &info).expect("valid");
        let x = |seed: usize| -> Block {
            Block::from_vec((0..70).map(|i| ((i * 31 + seed) % 17) as f64).collect(), 2)
        };
        let (l, r) = (x(1), x(4));
        let run = |cc: &mut Crosscorrelation| {
            let mut out = vec![Block::new(out_info.width())];
            cc.process(&[&l, &r], &mut out);
            out.remove(0)
        };
        let first = run(&mut cc);
        assert_eq!(first.frames(), 2);
        cc.rejoin(&[]);
        let second = run(&mut cc);
        assert_ne!(
            second, first,
            "the kept samples shift the second chunk's frames"
        );
        cc.reset();
        assert_eq!(run(&mut cc), first);
    }

    #[test]
    fn a_window_beyond_the_working_memory_is_refused_naming_what_shrinks_it() {
        // the direct engine holds one group of channels at a time: its memory grows with
        // the window, not with the channels
        let info = SignalInfo::time_frequency(44100.0, vec![500.0]);
        let params = |w_size_sec| CrosscorrelationParams {
            w_size_sec,
            h_size_sec: 1.0,
            max_delay_sec: 0.0,
            ..Default::default()
        };
        let e = Crosscorrelation::new(&params(64.0), &info)
            .expect_err("64 s")
            .to_string();
        assert!(
            e.contains("cc_wSizeSec")
                && e.contains("working memory")
                && e.contains("window of 2822400 samples")
                && e.contains("shorten the window")
                && !e.contains("channels"),
            "{e}"
        );
        assert!(Crosscorrelation::new(&params(30.0), &info).is_ok());
    }

    #[test]
    fn silent_frames_give_zero_not_nan() {
        let info = SignalInfo::time_frequency(1000.0, vec![100.0]);
        let (mut cc, _) =
            Crosscorrelation::new(&CrosscorrelationParams::default(), &info).expect("valid");
        let z = Block::from_vec(vec![0.0; 40], 1);
        // 1.1 ms at 1 kHz: lags −2..2
        let mut out = vec![Block::new(5)];
        cc.process(&[&z, &z], &mut out);
        assert_eq!(out[0].frames(), 3);
        assert!(out[0].as_slice().iter().all(|v| *v == 0.0));
    }
}
