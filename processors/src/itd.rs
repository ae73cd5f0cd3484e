//! `itd`: interaural time difference per channel and frame, the lag of the
//! cross-correlation maximum refined by a parabola (spec 19-itd). Positive = right leads.

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::{Block, DrawAs, Processor, Result, SignalInfo};

use crate::correlation_peak::{correlation_input, parabolic_peak};

/// The ITD extractor: `[frame][channel][lag]` in, `[frame][channel]` seconds out.
#[derive(Debug, Clone)]
pub struct Itd {
    lags: usize,
    audio_fs_hz: f64,
}

impl Itd {
    /// Builds the ITD for the cross-correlation signal `input`.
    pub fn new(input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        correlation_input(input, "itd")?;
        let itd = Itd {
            lags: input.lags_s().len(),
            audio_fs_hz: input.audio_fs_hz,
        };
        let info = input
            .framed(input.fs_hz)
            .with_unit(Self::OUTPUT_UNIT)
            .drawn_as(DrawAs::Signed);
        Ok((itd, info))
    }
}

impl Processor for Itd {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let ccf = inputs[0].as_slice();
        let half = (self.lags - 1) as f64 / 2.0;
        let frames = ccf.len() / (self.lags * outputs[0].width()).max(1);
        let out = outputs[0].reset_to(frames);
        for (o, y) in out.iter_mut().zip(ccf.chunks_exact(self.lags)) {
            let (i, delta, _) = parabolic_peak(y);
            *o = (i as f64 - half + delta) / self.audio_fs_hz;
        }
    }

    fn reset(&mut self) {}
}

impl Descriptor for Itd {
    type Params = afe_core::NoParams;
    const NAME: &'static str = "itd";
    const DEPENDENCY: &'static str = "crosscorrelation";
    const EARS: Ears = Ears::Binaural;
    const DESCRIPTION: &'static str =
        "interaural time difference per frame and channel (positive: right leads)";
    const OUTPUT_UNIT: &'static str = "s";

    fn build(_: &afe_core::NoParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Itd::new(&inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }
}

/// The registry entry of `itd`.
pub static REQUEST: RequestDef = request_def::<Itd>();

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolated_lag_per_frame_and_channel() {
        let info = SignalInfo::time_frequency(1000.0, vec![500.0, 600.0, 700.0])
            .correlation(100.0, vec![-2e-3, -1e-3, 0.0, 1e-3, 2e-3]);
        let (mut itd, _) = Itd::new(&info).expect("valid");
        // Peak at lag index 2 or 3 (−0 or +1 ms) with a vertex 1/3 lag to the right.
        let up = [0.0, 1.0, 2.0, 1.8, 0.0];
        let shifted = [0.0, 0.0, 1.0, 2.0, 1.8];
        let ccf: Vec<f64> = [up, shifted, up, shifted, up, shifted].concat();
        let mut out = vec![Block::new(3)];
        itd.process(&[&Block::from_vec(ccf, 15)], &mut out);
        assert_eq!(out[0].frames(), 2);
        for (k, v) in out[0].as_slice().iter().enumerate() {
            let want = ((k % 2) as f64 + 1.0 / 3.0) * 1e-3;
            assert!((v - want).abs() < 1e-15, "{k}: {v} vs {want}");
        }
    }

    #[test]
    fn only_a_cross_correlation_is_accepted() {
        let tf = SignalInfo::time_frequency(1000.0, vec![500.0]);
        for input in [tf.clone(), tf.correlation(100.0, Vec::new())] {
            let e = Itd::new(&input).expect_err("not a cross-correlation");
            assert!(
                e.to_string()
                    .contains("itd needs a cross-correlation input"),
                "{e}"
            );
        }
    }

    #[test]
    fn silent_frame_gives_minus_max_lag() {
        let info = SignalInfo::time_frequency(1000.0, vec![500.0])
            .correlation(100.0, vec![-2e-3, -1e-3, 0.0, 1e-3, 2e-3]);
        let (mut itd, _) = Itd::new(&info).expect("valid");
        let ccf = Block::from_vec(vec![0.0; 5], 5);
        let mut out = vec![Block::new(1)];
        itd.process(&[&ccf], &mut out);
        assert_eq!(out[0].as_slice(), &[-2e-3]);
    }
}
