//! `ild`: interaural level difference per channel and frame, right re left, in dB
//! (spec 17-ild).

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::power::frame_power;
use afe_core::window::{window, WINDOW_NAMES};
use afe_core::{Block, DrawAs, ParamKind, ParamSpec, Params, Processor, Result, SignalInfo};
use serde::{Deserialize, Serialize};

use crate::framed::{check_framing, EarFrames};

/// Parameters of the ILD, under their AFE names.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IldParams {
    /// Window name (AFE `ild_wname`).
    #[serde(rename = "ild_wname")]
    pub wname: String,
    /// Window length in s (AFE `ild_wSizeSec`).
    #[serde(rename = "ild_wSizeSec")]
    pub w_size_sec: f64,
    /// Hop in s (AFE `ild_hSizeSec`).
    #[serde(rename = "ild_hSizeSec")]
    pub h_size_sec: f64,
}

impl Default for IldParams {
    fn default() -> Self {
        IldParams {
            wname: "hann".into(),
            w_size_sec: 0.02,
            h_size_sec: 0.01,
        }
    }
}

impl Params for IldParams {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec {
            name: "ild_wname",
            kind: ParamKind::Choice(WINDOW_NAMES),
            unit: "",
            description: "window applied to each frame",
        },
        ParamSpec {
            name: "ild_wSizeSec",
            kind: ParamKind::Number,
            unit: "s",
            description: "window length",
        },
        ParamSpec {
            name: "ild_hSizeSec",
            kind: ParamKind::Number,
            unit: "s",
            description: "hop between frames",
        },
    ];
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
            ("ild_wSizeSec", params.w_size_sec),
            ("ild_hSizeSec", params.h_size_sec),
            input.fs_hz,
            input.channels(),
        )?;
        let nc = input.channels();
        let ild = Ild {
            win: window(&params.wname, w, "ild_wname")?,
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
    fn specs_match_struct() {
        afe_core::params::check_param_specs::<IldParams>();
    }

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
