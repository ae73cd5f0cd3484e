//! `innerhaircell`: envelope extraction per filterbank channel (spec 13-ihc).
//!
//! The Hilbert-based methods (`hilbert`, `joergensen`, `bernstein`) transform each chunk
//! on its own, as the AFE does, so they depend on the chunking; the others are
//! chunk-invariant.

use afe_core::butter::{butter, ButterType};
use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::filter::Df2t;
use afe_core::hilbert::Hilbert;
use afe_core::{Block, DrawAs, Processor, Result, SignalInfo};

afe_core::params! {
    /// Parameters of the inner-hair-cell stage, under their AFE names.
    pub struct IhcParams / IhcNames {
        /// inner-hair-cell envelope extraction method
        #[afe = "ihc_method"]
        pub method: Method = Method::Dau,
    }
}

afe_core::choices! {
    /// Envelope extraction methods of the AFE (spec 13-ihc), under their AFE names.
    pub enum Method {
        /// The filterbank output unchanged.
        None = "none",
        /// Half-wave rectification.
        Halfwave = "halfwave",
        /// Full-wave rectification.
        Fullwave = "fullwave",
        /// Squared signal.
        Square = "square",
        /// Hilbert envelope (per chunk).
        Hilbert = "hilbert",
        /// Hilbert envelope, then a 150 Hz first-order low-pass (Jørgensen & Dau).
        Joergensen = "joergensen",
        /// Half-wave rectification, then a 1 kHz second-order low-pass (Dau et al.).
        Dau = "dau",
        /// Half-wave rectification, then five 2 kHz first-order low-passes (Breebaart et
        /// al.).
        Breebart = "breebart",
        /// Compressed Hilbert envelope, squared and half-wave rectified, then a 425 Hz
        /// second-order low-pass (Bernstein et al.).
        Bernstein = "bernstein",
    }
}

impl Method {
    /// Whether the method transforms each chunk on its own (a Hilbert transform over the
    /// chunk), which makes the output depend on the chunking, as in the AFE.
    pub fn is_per_chunk(self) -> bool {
        matches!(
            self,
            Method::Hilbert | Method::Joergensen | Method::Bernstein
        )
    }

    /// Butterworth low-pass stage: (order, cut-off Hz, cascade count).
    fn lowpass(self) -> Option<(usize, f64, usize)> {
        match self {
            Method::Joergensen => Some((1, 150.0, 1)),
            Method::Dau => Some((2, 1000.0, 1)),
            Method::Breebart => Some((1, 2000.0, 5)),
            Method::Bernstein => Some((2, 425.0, 1)),
            _ => None,
        }
    }
}

/// The inner-hair-cell envelope of one ear: `[time][channel]` in and out.
pub struct Ihc {
    method: Method,
    channels: usize,
    lowpass: Vec<Df2t>,
    hilbert: Hilbert,
}

impl std::fmt::Debug for Ihc {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ihc")
            .field("method", &self.method)
            .finish_non_exhaustive()
    }
}

impl Ihc {
    /// Builds the stage for the filterbank signal `input`.
    pub fn new(params: &IhcParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        let method = params.method;
        let channels = input.channels();
        let lowpass = match method.lowpass() {
            Some((_, fc, _)) if fc >= input.fs_hz / 2.0 => {
                return Err(afe_core::Error::invalid(
                    IhcParams::NAMES.method,
                    format_args!("\"{method}\""),
                    format!(
                    "its {fc} Hz low-pass needs a sampling rate above {} Hz (the input has {} Hz)",
                    2.0 * fc,
                    input.fs_hz
                ),
                ))
            }
            Some((order, fc, count)) => {
                let (b, a) = butter(order, &[fc / (input.fs_hz / 2.0)], ButterType::Low);
                vec![Df2t::new(&b, &a, channels); count]
            }
            None => Vec::new(),
        };
        let ihc = Ihc {
            method,
            channels,
            lowpass,
            hilbert: Hilbert::new(),
        };
        let info = input
            .clone()
            .with_unit(Self::OUTPUT_UNIT)
            .drawn_as(DrawAs::AmplitudeDecibels { range_db: 60.0 });
        Ok((ihc, info))
    }

    /// Replaces every column of `data` by the magnitude of its analytic signal.
    fn hilbert_envelope(&mut self, data: &mut [f64], then: impl Fn(f64, f64) -> f64) {
        let nc = self.channels;
        let rows = data.len() / nc.max(1);
        for c in 0..nc {
            let column = (0..rows).map(|t| data[t * nc + c]);
            let analytic = self.hilbert.analytic(column);
            for (t, v) in analytic.iter().enumerate() {
                let x = &mut data[t * nc + c];
                *x = then(v.norm(), *x);
            }
        }
    }
}

/// `out[i] = f(input[i])`: the rectifications, in one pass from the input.
fn map_into(input: &[f64], out: &mut [f64], f: impl Fn(f64) -> f64) {
    for (o, x) in out.iter_mut().zip(input) {
        *o = f(*x);
    }
}

impl Processor for Ihc {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let input = inputs[0].as_slice();
        let data = outputs[0].resize_to(inputs[0].frames());
        if let (Method::Dau | Method::Breebart, Some((first, rest))) =
            (self.method, self.lowpass.split_first_mut())
        {
            // The rectification happens as the first low-pass stage reads its input.
            first.process_rectified_from(input, data);
            for f in rest {
                f.process(data);
            }
            return;
        }
        match self.method {
            Method::None => data.copy_from_slice(input),
            Method::Halfwave | Method::Dau | Method::Breebart => {
                map_into(input, data, |x| x.max(0.0))
            }
            Method::Fullwave => map_into(input, data, f64::abs),
            Method::Square => map_into(input, data, |x| x.abs() * x.abs()),
            Method::Hilbert | Method::Joergensen => {
                data.copy_from_slice(input);
                self.hilbert_envelope(data, |env, _| env);
            }
            Method::Bernstein => {
                data.copy_from_slice(input);
                self.hilbert_envelope(data, |env, x| {
                    // f64::max ignores NaN like MATLAB's max: silent samples (∞·0) give 0.
                    let v = (env.powf(-0.77) * x).max(0.0);
                    v * v
                });
            }
        }
        for f in &mut self.lowpass {
            f.process(data);
        }
    }

    fn reset(&mut self) {
        for f in &mut self.lowpass {
            f.reset();
        }
    }
}

impl Descriptor for Ihc {
    type Params = IhcParams;
    const NAME: &'static str = "innerhaircell";
    const DEPENDENCY: &'static str = "filterbank";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str = "inner-hair-cell envelope per frequency channel";
    const OUTPUT_UNIT: &'static str = "";

    fn build(params: &IhcParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Ihc::new(params, &inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }

    fn chunk_invariant(params: &IhcParams) -> bool {
        !params.method.is_per_chunk()
    }
}

/// The registry entry of `innerhaircell`.
pub static REQUEST: RequestDef = request_def::<Ihc>();

#[cfg(test)]
mod tests {
    use super::*;
    use afe_core::Params;

    fn run(method: Method, x: &[f64]) -> Vec<f64> {
        let info = SignalInfo::time_frequency(16000.0, vec![1000.0]);
        let params = IhcParams { method };
        let (mut ihc, _) = Ihc::new(&params, &info).expect("valid");
        let input = Block::from_vec(x.to_vec(), 1);
        let mut out = vec![Block::new(1)];
        ihc.process(&[&input], &mut out);
        out[0].as_slice().to_vec()
    }

    /// Two whole-cycle cosines (1 and 2 kHz at 16 kHz, amplitudes 1 and 3) in two
    /// channels, time-major: their Hilbert envelopes are the amplitudes exactly.
    fn two_tones(rows: usize) -> Vec<f64> {
        let w = 2.0 * std::f64::consts::PI / 16.0;
        (0..rows)
            .flat_map(|t| [(w * t as f64).cos(), 3.0 * (2.0 * w * t as f64).cos()])
            .collect()
    }

    fn run2(method: Method, x: &[f64]) -> Vec<f64> {
        let info = SignalInfo::time_frequency(16000.0, vec![1000.0, 2000.0]);
        let (mut ihc, _) = Ihc::new(&IhcParams { method }, &info).expect("valid");
        let mut out = vec![Block::new(2)];
        ihc.process(&[&Block::from_vec(x.to_vec(), 2)], &mut out);
        out[0].as_slice().to_vec()
    }

    /// `data` through `count` order-`order` Butterworth low-passes at `fc` Hz (16 kHz).
    fn lowpassed(mut data: Vec<f64>, order: usize, fc: f64, count: usize) -> Vec<f64> {
        let (b, a) = butter(order, &[fc / 8000.0], ButterType::Low);
        for _ in 0..count {
            Df2t::new(&b, &a, 2).process(&mut data);
        }
        data
    }

    fn assert_close(got: &[f64], want: &[f64], tol: f64) {
        assert_eq!(got.len(), want.len());
        for (i, (g, w)) in got.iter().zip(want).enumerate() {
            assert!((g - w).abs() <= tol, "value {i}: {g} vs {w}");
        }
    }

    #[test]
    fn hilbert_envelope_is_each_channels_amplitude() {
        let env = run2(Method::Hilbert, &two_tones(256));
        let want: Vec<f64> = (0..256).flat_map(|_| [1.0, 3.0]).collect();
        assert_close(&env, &want, 1e-12);
    }

    #[test]
    fn each_method_has_its_own_low_pass() {
        let x = two_tones(256);
        let amplitude: Vec<f64> = (0..256).flat_map(|_| [1.0, 3.0]).collect();
        assert_close(
            &run2(Method::Joergensen, &x),
            &lowpassed(amplitude.clone(), 1, 150.0, 1),
            1e-12,
        );
        let rectified: Vec<f64> = x.iter().map(|v| v.max(0.0)).collect();
        assert_close(
            &run2(Method::Breebart, &x),
            &lowpassed(rectified, 1, 2000.0, 5),
            1e-12,
        );
        // Bernstein: (max(env^−0.77·x, 0))² with the envelope the amplitude, then 425 Hz.
        let compressed: Vec<f64> = x
            .iter()
            .zip(&amplitude)
            .map(|(v, a)| (a.powf(-0.77) * v).max(0.0).powi(2))
            .collect();
        assert_close(
            &run2(Method::Bernstein, &x),
            &lowpassed(compressed, 2, 425.0, 1),
            1e-12,
        );
    }

    #[test]
    fn only_the_hilbert_methods_depend_on_the_chunking() {
        for (name, method) in [
            ("none", Method::None),
            ("halfwave", Method::Halfwave),
            ("fullwave", Method::Fullwave),
            ("square", Method::Square),
            ("hilbert", Method::Hilbert),
            ("joergensen", Method::Joergensen),
            ("dau", Method::Dau),
            ("breebart", Method::Breebart),
            ("bernstein", Method::Bernstein),
        ] {
            let per_chunk = matches!(name, "hilbert" | "joergensen" | "bernstein");
            assert_eq!(method.is_per_chunk(), per_chunk, "{name}");
            assert_eq!(
                <Ihc as Descriptor>::chunk_invariant(&IhcParams { method }),
                !per_chunk,
                "{name}"
            );
        }
    }

    #[test]
    fn reset_forgets_the_low_pass_state() {
        let info = SignalInfo::time_frequency(16000.0, vec![1000.0, 2000.0]);
        let (mut ihc, _) = Ihc::new(&IhcParams::default(), &info).expect("valid");
        let x = two_tones(64);
        let first = crate::testing::feed(&mut ihc, &x, 2, 2, [64]);
        ihc.reset();
        assert_eq!(crate::testing::feed(&mut ihc, &x, 2, 2, [64]), first);
        assert!(format!("{ihc:?}").contains("Dau"));
    }

    #[test]
    fn memoryless_methods() {
        let x = [-2.0, -0.5, 0.0, 0.5, 3.0];
        assert_eq!(run(Method::None, &x), x.to_vec());
        assert_eq!(run(Method::Halfwave, &x), vec![0.0, 0.0, 0.0, 0.5, 3.0]);
        assert_eq!(run(Method::Fullwave, &x), vec![2.0, 0.5, 0.0, 0.5, 3.0]);
        assert_eq!(run(Method::Square, &x), vec![4.0, 0.25, 0.0, 0.25, 9.0]);
    }

    #[test]
    fn lowpass_above_nyquist_is_rejected() {
        let info = SignalInfo::time_frequency(1600.0, vec![300.0]);
        let e = Ihc::new(&IhcParams::default(), &info).expect_err("1 kHz low-pass at 1.6 kHz");
        assert!(e.to_string().contains("above 2000 Hz"), "{e}");
        assert!(Ihc::new(
            &IhcParams {
                method: Method::Halfwave
            },
            &info
        )
        .is_ok());
    }

    #[test]
    fn bernstein_is_zero_on_silence_not_nan() {
        let y = run(Method::Bernstein, &[0.0; 32]);
        assert!(y.iter().all(|v| *v == 0.0));
    }

    #[test]
    fn dau_smooths_a_rectified_tone_to_its_mean() {
        let x: Vec<f64> = (0..16000)
            .map(|t| (2.0 * std::f64::consts::PI * 100.0 * t as f64 / 16000.0).sin())
            .collect();
        let y = run(Method::Dau, &x);
        let tail = &y[8000..];
        let mean = tail.iter().sum::<f64>() / tail.len() as f64;
        // mean of a half-wave rectified unit sine is 1/π
        assert!((mean - 1.0 / std::f64::consts::PI).abs() < 1e-3, "{mean}");
    }

    #[test]
    fn every_listed_name_parses_and_unknown_ones_are_errors() {
        for name in Method::NAMES {
            let map = [("ihc_method".to_string(), serde_json::json!(name))]
                .into_iter()
                .collect();
            let p = IhcParams::from_map(&map).expect("listed name");
            assert_eq!(serde_json::to_value(p.method).expect("name"), *name);
        }
        let map = [("ihc_method".to_string(), serde_json::json!("dauu"))]
            .into_iter()
            .collect();
        let e = IhcParams::from_map(&map).expect_err("unknown method");
        assert!(e.to_string().contains("ihc_method"), "{e}");
    }
}
