//! `ic`: interaural coherence per channel and frame, the parabola-interpolated maximum of
//! the cross-correlation (spec 20-ic).

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::{Block, Processor, Result, SignalInfo};

use crate::correlation_peak::{correlation_input, parabolic_peak};

/// The IC extractor: `[frame][channel][lag]` in, `[frame][channel]` out.
#[derive(Debug, Clone)]
pub struct Ic {
    lags: usize,
}

impl Ic {
    /// Builds the IC for the cross-correlation signal `input`.
    pub fn new(input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        correlation_input(input, "ic")?;
        let ic = Ic {
            lags: input.lags_s().len(),
        };
        Ok((ic, input.framed(input.fs_hz).with_unit(Self::OUTPUT_UNIT)))
    }
}

impl Processor for Ic {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let ccf = inputs[0].as_slice();
        let frames = ccf.len() / (self.lags * outputs[0].width()).max(1);
        let out = outputs[0].reset_to(frames);
        for (o, y) in out.iter_mut().zip(ccf.chunks_exact(self.lags)) {
            *o = parabolic_peak(y).2;
        }
    }

    fn reset(&mut self) {}
}

impl Descriptor for Ic {
    type Params = afe_core::NoParams;
    const NAME: &'static str = "ic";
    const DEPENDENCY: &'static str = "crosscorrelation";
    const EARS: Ears = Ears::Binaural;
    const DESCRIPTION: &'static str = "interaural coherence per frame and channel";
    const OUTPUT_UNIT: &'static str = "";

    fn build(_: &afe_core::NoParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Ic::new(&inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }
}

/// The registry entry of `ic`.
pub static REQUEST: RequestDef = request_def::<Ic>();

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_value_per_frame_and_channel() {
        let info = SignalInfo::time_frequency(1000.0, vec![100.0, 200.0, 300.0])
            .correlation(100.0, vec![-1e-3, 0.0, 1e-3]);
        let (mut ic, _) = Ic::new(&info).expect("valid");
        // Two frames of three channels: the peak is the middle lag, value 0.1·(k + 1).
        let ccf: Vec<f64> = (0..6)
            .flat_map(|k| [0.0, 0.1 * (k + 1) as f64, 0.0])
            .collect();
        let mut out = vec![Block::new(3)];
        ic.process(&[&Block::from_vec(ccf, 9)], &mut out);
        assert_eq!(out[0].frames(), 2);
        for (k, v) in out[0].as_slice().iter().enumerate() {
            assert!((v - 0.1 * (k + 1) as f64).abs() < 1e-15, "{k}: {v}");
        }
    }

    #[test]
    fn interior_peak_is_the_vertex_and_edge_is_the_sample() {
        let info = SignalInfo::time_frequency(1000.0, vec![500.0, 600.0])
            .correlation(100.0, vec![-1e-3, 0.0, 1e-3]);
        let (mut ic, _) = Ic::new(&info).expect("valid");
        let ccf = Block::from_vec(vec![0.0, 1.0, 0.5, 0.9, 0.2, 0.1], 6);
        let mut out = vec![Block::new(2)];
        ic.process(&[&ccf], &mut out);
        assert!((out[0].as_slice()[0] - (1.0 + 0.25 * 0.5 / 6.0)).abs() < 1e-15);
        assert_eq!(out[0].as_slice()[1], 0.9);
    }
}
