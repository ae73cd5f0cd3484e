//! `pitch`: frame-wise fundamental frequency from the summary autocorrelation, with a
//! confidence, a threshold relative to the recent maximum confidence and median smoothing
//! (spec 22-pitch).
//!
//! Not chunk-invariant, as in the AFE: the threshold uses the largest confidence of the
//! last 5 s including later frames of the same chunk, and the median filter runs over
//! each chunk on its own with zero padding at both ends.

use std::cmp::Ordering;
use std::collections::VecDeque;

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::{Block, DrawAs, Error, Processor, Result, SignalInfo, SignalKind, WholeSignal};

afe_core::params! {
    /// Parameters of the pitch estimator, under their AFE names.
    pub struct PitchParams / PitchNames {
        /// lowest and highest plausible pitch
        #[afe = "pi_rangeHz", unit = "Hz"]
        pub range_hz: Vec<f64> = vec![80.0, 400.0],
        /// confidence threshold, fraction of the largest confidence of the last 5 s
        #[afe = "pi_confThres"]
        pub conf_thres: f64 = 0.7,
        /// order in frames of the median filter smoothing the pitch (rounded)
        #[afe = "pi_medianOrder"]
        pub median_order: f64 = 3.0,
    }
}

/// Names of the output columns, in order.
pub const PITCH_FEATURES: [&str; 3] = ["pitch", "rawPitch", "confidence"];

/// Seconds of past confidences the threshold looks at.
const CONFIDENCE_MEMORY_SEC: f64 = 5.0;

afe_core::simd_kernel!(
    fma,
    /// The summary autocorrelation of one frame (`row`, one run of `lags` values per
    /// channel): the mean over channels of lags `first..first + sacf.len()`, into `sacf`.
    fn summary(sacf: &mut [f64], row: &[f64], lags: usize, first: usize) {
        sacf.fill(0.0);
        let channels = row.len() / lags;
        for acf in row.chunks_exact(lags) {
            for (s, v) in sacf.iter_mut().zip(&acf[first..]) {
                *s += v;
            }
        }
        for s in sacf.iter_mut() {
            *s /= channels as f64;
        }
    }
);

/// The pitch estimator of one ear: autocorrelation `[frame][channel][lag]` in,
/// `[frame][pitch, rawPitch, confidence]` out.
#[derive(Debug, Clone)]
pub struct Pitch {
    conf_thres: f64,
    median_order: usize,
    lags: usize,
    /// The lags within the pitch range: first index and their values in s.
    first_lag: usize,
    lag_sec: Vec<f64>,
    /// Non-negative peak confidences of the most recent frames that had a peak.
    history: VecDeque<f64>,
    history_len: usize,
    /// Per-chunk scratch: summary ACF over the valid lags, and per frame the raw pitch,
    /// the confidence and the thresholded pitch.
    sacf: Vec<f64>,
    raw: Vec<f64>,
    conf: Vec<f64>,
    voiced: Vec<f64>,
    window: Vec<f64>,
}

impl Pitch {
    /// Builds the estimator for the autocorrelation signal `input` (its `lags_s`, in s).
    pub fn new(params: &PitchParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        if input.kind != SignalKind::Correlation || input.lags_s().is_empty() {
            return Err(Error::InvalidInput(
                "pitch reads an autocorrelation (a correlation signal with lags)".into(),
            ));
        }
        let bad = |name: &str, value: String, reason: &str| Error::invalid(name, value, reason);
        let [fmin, fmax] = params.range_hz[..] else {
            return Err(bad(
                PitchParams::NAMES.range_hz,
                format!("{:?}", params.range_hz),
                "expected two frequencies [lowest, highest] in Hz",
            ));
        };
        if !(fmin > 0.0 && fmin < fmax) {
            return Err(bad(
                PitchParams::NAMES.range_hz,
                format!("{:?}", params.range_hz),
                "expected 0 < lowest < highest (Hz)",
            ));
        }
        if !(0.0..=1.0).contains(&params.conf_thres) {
            return Err(bad(
                PitchParams::NAMES.conf_thres,
                params.conf_thres.to_string(),
                "must be between 0 and 1 (a fraction of the recent maximum confidence)",
            ));
        }
        let order = params.median_order.round();
        if !(1.0..=1e6).contains(&order) {
            return Err(bad(
                PitchParams::NAMES.median_order,
                params.median_order.to_string(),
                "must round to a frame count between 1 and 1e6",
            ));
        }
        // The AFE bounds the lags by min(1/fmin, number of lags), seconds against a count.
        let lags = input.lags_s().len();
        let upper = (1.0 / fmin).min(lags as f64);
        let valid: Vec<usize> = (0..lags)
            .filter(|&k| input.lags_s()[k] >= 1.0 / fmax && input.lags_s()[k] <= upper)
            .collect();
        let (Some(&first), Some(&last)) = (valid.first(), valid.last()) else {
            return Err(bad(
                PitchParams::NAMES.range_hz,
                format!("{:?}", params.range_hz),
                &format!(
                    "no autocorrelation lag (up to {} s) lies within the range",
                    input.lags_s()[lags - 1]
                ),
            ));
        };
        let history_len = (CONFIDENCE_MEMORY_SEC * input.fs_hz).ceil().max(1.0) as usize;
        let pitch = Pitch {
            conf_thres: params.conf_thres,
            median_order: order as usize,
            lags,
            first_lag: first,
            lag_sec: input.lags_s()[first..=last].to_vec(),
            history: VecDeque::with_capacity(history_len),
            history_len,
            sacf: vec![0.0; last + 1 - first],
            raw: Vec::new(),
            conf: Vec::new(),
            voiced: Vec::new(),
            window: vec![0.0; order as usize],
        };
        let features = PITCH_FEATURES.iter().map(|s| s.to_string()).collect();
        let info = SignalInfo {
            window_s: input.window_s,
            ..SignalInfo::feature(input.fs_hz, input.audio_fs_hz, features)
        }
        .with_unit(Self::OUTPUT_UNIT)
        .drawn_as(DrawAs::Trajectory)
        .nan_where(
            "in the first column where a frame is unvoiced (the raw pitch and the confidence \
             stay numbers)",
        );
        Ok((pitch, info))
    }
}

/// The largest peak of `x` (spec 01-P8: interior local maxima, plateaus reported at
/// their centre, left of centre for even lengths) as `(value, index)`, the first one on
/// ties; NaN values are never larger. `None` without a peak.
fn largest_peak(x: &[f64]) -> Option<(f64, usize)> {
    let n = x.len();
    let mut best: Option<(f64, usize)> = None;
    let mut i = 0;
    while i + 1 < n {
        if x[i + 1] > x[i] {
            // a rise lands at `a`; the plateau runs while there is neither rise nor fall
            let a = i + 1;
            let mut b = a;
            while b + 1 < n && matches!(x[b + 1].partial_cmp(&x[b]), Some(Ordering::Equal) | None) {
                b += 1;
            }
            if b + 1 < n && x[b + 1] < x[b] {
                let k = a + (b - a) / 2;
                if best.is_none_or(|(v, _)| x[k] > v) {
                    best = Some((x[k], k));
                }
            }
            i = b;
        } else {
            i += 1;
        }
    }
    best
}

/// Median of `v` (mean of the two middle values for an even count); sorts `v`.
fn median(v: &mut [f64]) -> f64 {
    v.sort_unstable_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

impl Processor for Pitch {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        self.absorb(inputs);
        self.finish(outputs);
    }

    fn whole_signal(&mut self) -> Option<&mut dyn WholeSignal> {
        Some(self)
    }

    /// Also forgets the past confidences (the AFE keeps them across resets, which mixes
    /// an earlier run into the threshold of the next).
    fn reset(&mut self) {
        self.history.clear();
        self.raw.clear();
        self.conf.clear();
    }
}

impl WholeSignal for Pitch {
    /// The per-frame part: the SACF's largest peak gives the raw pitch and confidence,
    /// and the confidence joins the history.
    fn absorb(&mut self, inputs: &[&Block]) {
        let nl = self.lags;
        for row in inputs[0].rows() {
            summary(&mut self.sacf, row, nl, self.first_lag);
            let (conf, raw) = match largest_peak(&self.sacf) {
                Some((v, k)) => {
                    if self.history.len() == self.history_len {
                        self.history.pop_front();
                    }
                    self.history.push_back(v.max(0.0));
                    (v, if v > 0.0 { 1.0 / self.lag_sec[k] } else { 0.0 })
                }
                None => (0.0, 0.0),
            };
            self.conf.push(conf.max(0.0));
            self.raw.push(raw);
        }
    }

    /// The per-chunk part over the absorbed frames: the threshold from the history
    /// (which holds this chunk's frames too) and the zero-padded median.
    fn finish(&mut self, outputs: &mut [Block]) {
        let frames = self.raw.len();
        // No peak ever: no history, and every raw pitch is 0 anyway.
        let thr = self.conf_thres * self.history.iter().fold(0.0f64, |a, v| a.max(*v));
        self.voiced.clear();
        let voiced = self.conf.iter().zip(&self.raw);
        self.voiced
            .extend(voiced.map(|(c, r)| if *c >= thr { *r } else { 0.0 }));
        // Frames before the centre: (n − 1)/2 for an odd order n, n/2 for an even one
        // (spec 01-P10), both ⌊n/2⌋.
        let before = self.median_order / 2;
        let out = outputs[0].resize_to(frames);
        for (t, o) in out.chunks_exact_mut(PITCH_FEATURES.len()).enumerate() {
            for (i, w) in self.window.iter_mut().enumerate() {
                *w = (t + i)
                    .checked_sub(before)
                    .and_then(|s| self.voiced.get(s))
                    .copied()
                    .unwrap_or(0.0);
            }
            let smooth = median(&mut self.window);
            o[0] = if smooth == 0.0 { f64::NAN } else { smooth };
            o[1] = self.raw[t];
            o[2] = self.conf[t];
        }
        self.raw.clear();
        self.conf.clear();
    }
}

impl Descriptor for Pitch {
    type Params = PitchParams;
    const NAME: &'static str = "pitch";
    const DEPENDENCY: &'static str = "autocorrelation";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str =
        "pitch per frame from the summary autocorrelation, raw pitch and confidence";
    const OUTPUT_UNIT: &'static str = "Hz";

    fn build(params: &PitchParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Pitch::new(params, &inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }

    /// The AFE's pitch thresholds and smooths per chunk.
    fn chunk_invariant(_: &PitchParams) -> bool {
        false
    }
}

/// The registry entry of `pitch`.
pub static REQUEST: RequestDef = request_def::<Pitch>();

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peaks_follow_the_voicebox_definition() {
        assert_eq!(largest_peak(&[0.0, 1.0, 0.0]), Some((1.0, 1)));
        // end points are never peaks; a rise into the end is not a peak
        assert_eq!(largest_peak(&[3.0, 1.0, 2.0]), None);
        assert_eq!(largest_peak(&[1.0, 1.0, 1.0]), None);
        assert_eq!(largest_peak(&[1.0, 1.0, 1.0, 0.0]), None);
        // plateaus: centre, left of centre for an even length
        assert_eq!(largest_peak(&[0.0, 2.0, 2.0, 2.0, 0.0]), Some((2.0, 2)));
        assert_eq!(
            largest_peak(&[0.0, 2.0, 2.0, 2.0, 2.0, 0.0]),
            Some((2.0, 2))
        );
        // a shoulder (plateau followed by a rise) is not a peak
        assert_eq!(largest_peak(&[0.0, 1.0, 1.0, 2.0, 0.0]), Some((2.0, 3)));
        // the largest peak, the first on ties
        let x = [0.0, 1.0, 0.0, 3.0, 0.0, 3.0, 0.0];
        assert_eq!(largest_peak(&x), Some((3.0, 3)));
        // NaN: no comparison holds
        assert_eq!(largest_peak(&[f64::NAN; 5]), None);
    }

    #[test]
    fn median_is_zero_padded() {
        let mut w = [3.0, 1.0, 2.0];
        assert_eq!(median(&mut w), 2.0);
        let mut w = [4.0, 1.0, 0.0, 2.0];
        assert_eq!(median(&mut w), 1.5);
        let mut w = [3.0, 1.0, 2.0, 5.0, 4.0];
        assert_eq!(median(&mut w), 3.0);
        let mut w = [7.0, 1.0];
        assert_eq!(median(&mut w), 4.0);
    }

    /// An autocorrelation input of `nc` channels over lags `k/fs`, k < `nl`.
    fn acf_info(fs: f64, nc: usize, nl: usize) -> SignalInfo {
        SignalInfo::time_frequency(fs, vec![500.0; nc])
            .correlation(100.0, (0..nl).map(|k| k as f64 / fs).collect())
    }

    /// One frame whose ACF (every channel) peaks at lag `lag` with height `h`.
    fn frame(nc: usize, nl: usize, lag: usize, h: f64) -> Vec<f64> {
        let acf: Vec<f64> = (0..nl)
            .map(|k| {
                if k == 0 {
                    1.0
                } else if k == lag {
                    h
                } else {
                    0.0
                }
            })
            .collect();
        acf.repeat(nc)
    }

    fn run(p: &PitchParams, chunks: &[Vec<Vec<f64>>], nc: usize, nl: usize) -> Vec<[f64; 3]> {
        let (mut pitch, info) = Pitch::new(p, &acf_info(1000.0, nc, nl)).expect("valid");
        assert_eq!(info.features(), PITCH_FEATURES);
        let mut out = vec![Block::new(3)];
        let mut all = Vec::new();
        for chunk in chunks {
            let block = Block::from_vec(chunk.concat(), nc * nl);
            pitch.process(&[&block], &mut out);
            all.extend(out[0].rows().map(|r| [r[0], r[1], r[2]]));
        }
        all
    }

    fn same(a: f64, b: f64) -> bool {
        a == b || (a.is_nan() && b.is_nan())
    }

    #[test]
    fn threshold_and_median_act_per_chunk() {
        // fs 1 kHz, range 80–400 Hz: lags 3..12. Frames 0–3 voiced at 5 lags (200 Hz),
        // frame 4 weak, frame 5 without a peak.
        let (nc, nl) = (2, 20);
        let frames = vec![
            frame(nc, nl, 5, 0.9),
            frame(nc, nl, 5, 0.8),
            frame(nc, nl, 5, 0.9),
            frame(nc, nl, 4, 0.9),
            frame(nc, nl, 5, 0.3),
            frame(nc, nl, 0, 0.0),
        ];
        let p = PitchParams::default();
        let whole = run(&p, std::slice::from_ref(&frames), nc, nl);
        let want_raw = [200.0, 200.0, 200.0, 250.0, 200.0, 0.0];
        let want_conf = [0.9, 0.8, 0.9, 0.9, 0.3, 0.0];
        // thr = 0.63: frame 4 is unvoiced; median of 3, zero-padded, smooths out frame 3
        let want_pitch = [200.0, 200.0, 200.0, 200.0, f64::NAN, f64::NAN];
        for (t, o) in whole.iter().enumerate() {
            assert!(same(o[0], want_pitch[t]), "frame {t}: {o:?}");
            assert_eq!((o[1], o[2]), (want_raw[t], want_conf[t]), "frame {t}");
        }
        // In two chunks, the median restarts at the boundary; the threshold remembers.
        let split = run(&p, &[frames[..3].to_vec(), frames[3..].to_vec()], nc, nl);
        let want_split = [200.0, 200.0, 200.0, f64::NAN, f64::NAN, f64::NAN];
        for (t, o) in split.iter().enumerate() {
            assert!(same(o[0], want_split[t]), "frame {t}: {o:?}");
        }
        // A later chunk's frames count towards the threshold of earlier frames of the
        // same chunk: with a strong frame last, 0.8 falls below 0.7·2.
        let mut louder = frames.clone();
        louder[5] = frame(nc, nl, 5, 2.0);
        let out = run(&p, &[louder], nc, nl);
        assert!(out[1][0].is_nan() && out[1][1] == 200.0);
        // and the registry knows that the output depends on the chunking
        assert!(!<Pitch as Descriptor>::chunk_invariant(&p));
    }

    /// Even orders take one frame more before the centre than after (spec 01-P10).
    #[test]
    fn even_median_orders_centre_left() {
        let (nc, nl) = (1, 20);
        // Raw pitch 200, 250, 200, 250, 200 Hz, all voiced.
        let frames: Vec<Vec<f64>> = (0..5).map(|t| frame(nc, nl, 5 - t % 2, 0.9)).collect();
        let smoothed = |order: f64| -> Vec<f64> {
            let p = PitchParams {
                median_order: order,
                ..Default::default()
            };
            let out = run(&p, std::slice::from_ref(&frames), nc, nl);
            out.iter().map(|o| o[0]).collect()
        };
        // n = 2: the mean of frames k − 1 and k, with a zero before the first.
        assert_eq!(smoothed(2.0), [100.0, 225.0, 225.0, 225.0, 225.0]);
        // n = 4: frames k − 2 ..= k + 1.
        assert_eq!(smoothed(4.0), [100.0, 200.0, 225.0, 225.0, 200.0]);
    }

    /// A peak of height 0 has no pitch (and no confidence), as in the AFE.
    #[test]
    fn a_peak_of_zero_is_unvoiced() {
        let (nc, nl) = (1, 20);
        let acf: Vec<f64> = (0..nl)
            .map(|k| match k {
                0 => 1.0,
                5 => 0.0,
                _ => -1.0,
            })
            .collect();
        let out = run(&PitchParams::default(), &[vec![acf]], nc, nl);
        assert!(
            out[0][0].is_nan() && out[0][1] == 0.0 && out[0][2] == 0.0,
            "{out:?}"
        );
    }

    /// Absorbing blocks and finishing once gives one call's output, whatever the blocks.
    #[test]
    fn absorbed_blocks_give_one_calls_output() {
        let (nc, nl) = (2, 20);
        let frames: Vec<Vec<f64>> = (0..9)
            .map(|t| frame(nc, nl, 4 + t % 3, 0.3 + 0.1 * t as f64))
            .collect();
        let p = PitchParams::default();
        let whole = run(&p, std::slice::from_ref(&frames), nc, nl);
        let (mut pitch, _) = Pitch::new(&p, &acf_info(1000.0, nc, nl)).expect("valid");
        assert!(pitch.whole_signal().is_some());
        for part in [&frames[..2], &frames[2..3], &frames[3..]] {
            pitch.absorb(&[&Block::from_vec(part.concat(), nc * nl)]);
        }
        let mut out = vec![Block::new(3)];
        pitch.finish(&mut out);
        let got: Vec<u64> = out[0].as_slice().iter().map(|v| v.to_bits()).collect();
        let want: Vec<u64> = whole.iter().flatten().map(|v| v.to_bits()).collect();
        assert_eq!(got, want);
    }

    #[test]
    fn silence_and_reset() {
        let (nc, nl) = (1, 20);
        let nan = vec![f64::NAN; nc * nl];
        let out = run(&PitchParams::default(), &[vec![nan.clone(), nan]], nc, nl);
        assert!(out
            .iter()
            .all(|o| o[0].is_nan() && o[1] == 0.0 && o[2] == 0.0));
        // reset forgets the confidences: a weak frame is voiced again afterwards
        let (mut pitch, _) =
            Pitch::new(&PitchParams::default(), &acf_info(1000.0, nc, nl)).expect("valid");
        let mut out = vec![Block::new(3)];
        let strong = Block::from_vec(frame(nc, nl, 5, 1.0), nc * nl);
        let weak = Block::from_vec(
            [
                frame(nc, nl, 5, 0.2),
                frame(nc, nl, 5, 0.2),
                frame(nc, nl, 5, 0.2),
            ]
            .concat(),
            nc * nl,
        );
        pitch.process(&[&strong], &mut out);
        pitch.process(&[&weak], &mut out);
        assert!(out[0].row(1)[0].is_nan());
        pitch.reset();
        pitch.process(&[&weak], &mut out);
        assert_eq!(out[0].row(1)[0], 200.0);
    }

    #[test]
    fn bad_parameters_are_errors_naming_them() {
        let info = acf_info(1000.0, 2, 20);
        let cases = [
            (vec![80.0], 0.7, 3.0, "pi_rangeHz"),
            (vec![400.0, 80.0], 0.7, 3.0, "pi_rangeHz"),
            (vec![1.0, 2.0], 0.7, 3.0, "pi_rangeHz"),
            (vec![80.0, 400.0], 1.5, 3.0, "pi_confThres"),
            (vec![80.0, 400.0], 0.7, 0.2, "pi_medianOrder"),
        ];
        for (range_hz, conf_thres, median_order, name) in cases {
            let p = PitchParams {
                range_hz,
                conf_thres,
                median_order,
            };
            let e = Pitch::new(&p, &info).expect_err(name).to_string();
            assert!(e.contains(name), "{e}");
        }
    }
}
