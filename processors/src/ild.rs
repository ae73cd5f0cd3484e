//! `ild`: interaural level difference per channel and frame, right re left, in dB
//! (spec 17-ild).

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::power::frame_power;
use afe_core::window::{window, Window};
use afe_core::{Block, DrawAs, Processor, Result, SignalInfo};

use crate::framed::{check_framing, EarFrames};

afe_core::params! {
    /// Parameters of the ILD, under their AFE names.
    pub struct IldParams / IldNames {
        /// window applied to each frame
        #[afe = "ild_wname"]
        pub wname: Window = Window::Hann,
        /// window length
        #[afe = "ild_wSizeSec", unit = "s"]
        pub w_size_sec: f64 = 0.02,
        /// hop between frames
        #[afe = "ild_hSizeSec", unit = "s"]
        pub h_size_sec: f64 = 0.01,
    }
}

/// The ILD: left and right IHC `[time][channel]` in, `[frame][channel]` dB out.
#[derive(Debug, Clone)]
pub struct Ild {
    win: Vec<f64>,
    frames: EarFrames,
    power_l: Vec<f64>,
    power_r: Vec<f64>,
}

impl Ild {
    /// Builds the ILD for the IHC signal `input` (the same for both ears).
    pub fn new(params: &IldParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        let (w, h) = check_framing(
            (IldParams::NAMES.w_size_sec, params.w_size_sec),
            (IldParams::NAMES.h_size_sec, params.h_size_sec),
            input.fs_hz,
            input.channels(),
        )?;
        let nc = input.channels();
        let ild = Ild {
            win: window(params.wname, w),
            frames: EarFrames::new(nc, w, h),
            power_l: vec![0.0; nc],
            power_r: vec![0.0; nc],
        };
        let info = input
            .framed(1.0 / params.h_size_sec)
            .with_unit(Self::OUTPUT_UNIT)
            .with_window_s(params.w_size_sec)
            .drawn_as(DrawAs::Signed);
        Ok((ild, info))
    }
}

impl Processor for Ild {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let ears = (inputs[0].as_slice(), inputs[1].as_slice());
        let n = self.frames.available(ears.0, ears.1);
        let nc = self.power_l.len();
        let out = outputs[0].resize_to(n);
        for (k, row) in out.chunks_exact_mut(nc).enumerate() {
            let (left, right) = self.frames.frame(ears, k);
            frame_power(&self.win, left, &mut self.power_l);
            frame_power(&self.win, right, &mut self.power_r);
            for ((v, pl), pr) in row.iter_mut().zip(&self.power_l).zip(&self.power_r) {
                *v = 10.0 * ((pr + f64::EPSILON) / (pl + f64::EPSILON)).log10();
            }
        }
        self.frames.advance(ears.0, ears.1, n);
    }

    fn reset(&mut self) {
        self.frames.reset();
    }
}

impl Descriptor for Ild {
    type Params = IldParams;
    const NAME: &'static str = "ild";
    const DEPENDENCY: &'static str = "innerhaircell";
    const EARS: Ears = Ears::Binaural;
    const DESCRIPTION: &'static str =
        "interaural level difference, right re left, per frame and channel";
    const OUTPUT_UNIT: &'static str = "dB";

    fn build(params: &IldParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Ild::new(params, &inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }
}

/// The registry entry of `ild`.
pub static REQUEST: RequestDef = request_def::<Ild>();

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn right_louder_by_6_db() {
        let info = SignalInfo::time_frequency(1000.0, vec![100.0, 200.0]);
        let (mut ild, _) = Ild::new(&IldParams::default(), &info).expect("valid");
        let l = Block::from_vec(vec![1.0; 200], 2);
        let r = Block::from_vec(vec![2.0; 200], 2);
        let mut out = vec![Block::new(2)];
        ild.process(&[&l, &r], &mut out);
        assert_eq!(out[0].frames(), 9);
        for v in out[0].as_slice() {
            assert!((v - 20.0 * 2f64.log10()).abs() < 1e-12);
        }
        let silent = Block::from_vec(vec![0.0; 200], 2);
        ild.reset();
        ild.process(&[&silent, &silent], &mut out);
        assert!(out[0].as_slice().iter().all(|v| *v == 0.0));
    }
}
