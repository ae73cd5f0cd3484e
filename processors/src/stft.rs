//! `stft`: short-time Fourier transform of the pre-processed ear signal, periodic
//! Hamming window, 50 % overlap, values rounded to single precision (spec 30-stft).

use std::f64::consts::PI;
use std::sync::Arc;

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::framing::{window_samples, FrameBuffer};
use afe_core::{Axis, Block, DrawAs, Error, Processor, Result, SignalInfo, SignalKind};
use afe_fft::RealToComplex;
use num_complex::Complex64;

afe_core::params! {
    /// Parameters of the STFT, under their AFE names.
    pub struct StftParams / StftNames {
        /// window length (the hop is half of it)
        #[afe = "stft_wSizeSec", unit = "s"]
        pub w_size_sec: f64 = 0.02,
        /// keep the NFFT/2 bins from DC up (Nyquist and negative frequencies dropped)
        #[afe = "stft_isPruned"]
        pub is_pruned: bool = true,
    }
}

/// The STFT of one ear: time signal `[time][1]` in, `[frame][bin]` complex out, each bin
/// a (re, im) pair.
pub struct Stft {
    win: Vec<f64>,
    bins: usize,
    frames: FrameBuffer,
    fft: Arc<dyn RealToComplex<f64>>,
    time: Vec<f64>,
    spectrum: Vec<Complex64>,
    scratch: Vec<Complex64>,
}

impl std::fmt::Debug for Stft {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Stft")
            .field("window", &self.win.len())
            .field("bins", &self.bins)
            .finish_non_exhaustive()
    }
}

/// Longest STFT window in samples (2^20: 24 s at 44.1 kHz): its FFT of 2^21 points
/// already takes about 100 MB of buffers. Found by fuzzing: the general limit let a
/// window of minutes ask for gigabytes.
const MAX_STFT_WINDOW: usize = 1 << 20;

impl Stft {
    /// Builds the STFT for the time-domain signal `input`.
    ///
    /// `W = 2·round(wSizeSec·fs/2)`, hop `W/2`, FFT length `2^nextpow2(2W − 1)`. The bins
    /// are labelled with their true frequencies `k·fs/NFFT` (MATLAB labels the pruned
    /// bins one bin higher, `(k + 1)·fs/NFFT`; its unpruned label vector is unusable).
    pub fn new(params: &StftParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        let fs = input.fs_hz;
        let w = window_samples(params.w_size_sec, fs);
        if params.w_size_sec <= 0.0 || !(2..=MAX_STFT_WINDOW).contains(&w) {
            return Err(Error::invalid(StftParams::NAMES.w_size_sec, params.w_size_sec, format!(
                    "the window must span between 2 and {MAX_STFT_WINDOW} samples at {fs} Hz (its FFT is twice as long)"
                )));
        }
        let win: Vec<f64> = (0..w)
            .map(|k| 0.54 - 0.46 * (2.0 * PI * k as f64 / w as f64).cos())
            .collect();
        let nfft = (2 * w - 1).next_power_of_two();
        let bins = if params.is_pruned { nfft / 2 } else { nfft };
        let fft = afe_fft::real_forward(nfft);
        let stft = Stft {
            win,
            bins,
            frames: FrameBuffer::new(1, w, w / 2),
            time: fft.make_input_vec(),
            spectrum: fft.make_output_vec(),
            scratch: fft.make_scratch_vec(),
            fft,
        };
        let info = SignalInfo {
            kind: SignalKind::Spectrum,
            fs_hz: 2.0 / params.w_size_sec,
            axes: vec![Axis::Bins(
                (0..bins).map(|k| k as f64 * fs / nfft as f64).collect(),
            )],
            audio_fs_hz: input.audio_fs_hz,
            unit: Self::OUTPUT_UNIT,
            window_s: Some(params.w_size_sec),
            display: DrawAs::AmplitudeDecibels { range_db: 80.0 },
            ..SignalInfo::default()
        };
        Ok((stft, info))
    }
}

/// `x` rounded to single precision, as the AFE stores its STFT.
fn single(x: f64) -> f64 {
    f64::from(x as f32)
}

impl Processor for Stft {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let input = inputs[0].as_slice();
        let n = self.frames.available(input);
        let width = 2 * self.bins;
        let out = outputs[0].resize_to(n);
        let nfft = self.time.len();
        for (k, row) in out.chunks_exact_mut(width).enumerate() {
            let frame = self.frames.frame(input, k);
            for ((t, w), x) in self.time.iter_mut().zip(&self.win).zip(frame.rows()) {
                *t = w * x[0];
            }
            self.time[self.win.len()..].fill(0.0);
            // The buffers come from the plan, so their lengths match and this cannot fail.
            let _ = self.fft.process_with_scratch(
                &mut self.time,
                &mut self.spectrum,
                &mut self.scratch,
            );
            for (b, pair) in row.chunks_exact_mut(2).enumerate() {
                // Bins above NFFT/2 are the conjugates of the bins below.
                let z = if b <= nfft / 2 {
                    self.spectrum[b]
                } else {
                    self.spectrum[nfft - b].conj()
                };
                pair[0] = single(z.re);
                pair[1] = single(z.im);
            }
        }
        self.frames.advance(input, n);
    }

    fn reset(&mut self) {
        self.frames.reset();
    }
}

impl Descriptor for Stft {
    type Params = StftParams;
    const NAME: &'static str = "stft";
    const DEPENDENCY: &'static str = "time";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str =
        "short-time Fourier transform (Hamming window, 50 % overlap), complex per bin";
    const OUTPUT_UNIT: &'static str = "";

    fn build(params: &StftParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Stft::new(params, &inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }
}

/// The registry entry of `stft`.
pub static REQUEST: RequestDef = request_def::<Stft>();

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn signal(len: usize) -> Vec<f64> {
        (0..len)
            .map(|t| (0.05 * t as f64).sin() + 0.3 * (0.71 * t as f64 * t as f64).cos())
            .collect()
    }

    fn run(stft: &mut Stft, x: &[f64], chunks: &[usize]) -> Vec<f64> {
        let then_the_rest = chunks.iter().copied().chain([usize::MAX]);
        crate::testing::feed(stft, x, 1, 2 * stft.bins, then_the_rest)
    }

    #[test]
    fn sizes_and_labels_at_44k() {
        let info = SignalInfo::time_domain(44100.0);
        let (stft, out) = Stft::new(&StftParams::default(), &info).expect("valid");
        assert_eq!(
            (stft.win.len(), stft.time.len(), stft.bins),
            (882, 2048, 1024)
        );
        assert_eq!(out.width(), 2048);
        assert_eq!(out.fs_hz, 100.0);
        assert_eq!(out.cf_hz()[1], 44100.0 / 2048.0);
    }

    #[test]
    fn a_bin_centred_tone_peaks_in_its_bin_and_matches_a_direct_dft() {
        let fs = 16000.0;
        let (mut stft, _) =
            Stft::new(&StftParams::default(), &SignalInfo::time_domain(fs)).expect("valid");
        // W = 320, NFFT = 1024: bin 64 is 1 kHz.
        let x: Vec<f64> = (0..640)
            .map(|t| (2.0 * PI * 1000.0 * t as f64 / fs).cos())
            .collect();
        let out = run(&mut stft, &x, &[]);
        assert_eq!(out.len(), 3 * 1024);
        let mag = |b: usize| out[2 * b].hypot(out[2 * b + 1]);
        let peak = (0..512).max_by(|&a, &b| mag(a).total_cmp(&mag(b)));
        assert_eq!(peak, Some(64));
        let frame: Vec<f64> = stft.win.iter().zip(&x).map(|(w, v)| w * v).collect();
        let want = crate::testing::plain_dft(&frame, 1024);
        for b in [0, 17, 64, 511] {
            let (re, im) = (want[b].re, want[b].im);
            assert!((out[2 * b] - re).abs() < 1e-5 && (out[2 * b + 1] - im).abs() < 1e-5);
            assert_eq!(out[2 * b], f64::from(out[2 * b] as f32));
        }
    }

    #[test]
    fn reset_starts_the_framing_over() {
        let info = SignalInfo::time_domain(8000.0);
        let (mut stft, _) = Stft::new(&StftParams::default(), &info).expect("valid");
        assert!(format!("{stft:?}").contains("window: 160"));
        let x = signal(500);
        let first = run(&mut stft, &x, &[]);
        stft.reset();
        assert_eq!(run(&mut stft, &x, &[]), first);
    }

    #[test]
    fn unpruned_bins_are_conjugate_symmetric() {
        let p = StftParams {
            is_pruned: false,
            ..StftParams::default()
        };
        let (mut stft, info) = Stft::new(&p, &SignalInfo::time_domain(8000.0)).expect("valid");
        assert_eq!(info.cf_hz().len(), 512);
        let out = run(&mut stft, &signal(400), &[]);
        for b in 1..256 {
            assert_eq!(out[2 * b], out[2 * (512 - b)]);
            assert_eq!(out[2 * b + 1], -out[2 * (512 - b) + 1]);
        }
    }

    #[test]
    fn bad_window_names_the_parameter() {
        for w in [0.0, -0.02, 1e-5, 1e9] {
            let p = StftParams {
                w_size_sec: w,
                ..StftParams::default()
            };
            let e = Stft::new(&p, &SignalInfo::time_domain(16000.0)).unwrap_err();
            assert!(e.to_string().contains("stft_wSizeSec"), "{e}");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, failure_persistence: None, ..ProptestConfig::default() })]

        #[test]
        fn any_chunking_is_bit_identical(
            chunks in prop::collection::vec(prop_oneof![Just(1usize), 1usize..200, 200usize..900], 1..20),
        ) {
            let x = signal(3000);
            let info = SignalInfo::time_domain(16000.0);
            let (mut a, _) = Stft::new(&StftParams::default(), &info).expect("valid");
            let (mut b, _) = Stft::new(&StftParams::default(), &info).expect("valid");
            prop_assert_eq!(run(&mut a, &x, &[]), run(&mut b, &x, &chunks));
        }
    }
}
