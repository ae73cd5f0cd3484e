//! `ratemap`: leaky-integrated IHC envelope averaged over overlapping windows, in power
//! or magnitude (spec 16-ratemap).

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::filter::Df2t;
use afe_core::framing::FrameBuffer;
use afe_core::power::frame_power;
use afe_core::window::{window, WINDOW_NAMES};
use afe_core::{Block, DrawAs, ParamKind, ParamSpec, Params, Processor, Result, SignalInfo};
use serde::{Deserialize, Serialize};

use crate::framed::check_framing;

/// Parameters of the ratemap, under their AFE names.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RatemapParams {
    /// Window name (AFE `rm_wname`).
    #[serde(rename = "rm_wname")]
    pub wname: String,
    /// Window length in s (AFE `rm_wSizeSec`).
    #[serde(rename = "rm_wSizeSec")]
    pub w_size_sec: f64,
    /// Hop in s (AFE `rm_hSizeSec`).
    #[serde(rename = "rm_hSizeSec")]
    pub h_size_sec: f64,
    /// `'power'` (mean of squares) or `'magnitude'` (mean) (AFE `rm_scaling`).
    #[serde(rename = "rm_scaling")]
    pub scaling: String,
    /// Leaky-integrator time constant in s (AFE `rm_decaySec`).
    #[serde(rename = "rm_decaySec")]
    pub decay_sec: f64,
}

impl Default for RatemapParams {
    fn default() -> Self {
        RatemapParams {
            wname: "hann".into(),
            w_size_sec: 0.02,
            h_size_sec: 0.01,
            scaling: "power".into(),
            decay_sec: 0.008,
        }
    }
}

impl Params for RatemapParams {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec {
            name: "rm_wname",
            kind: ParamKind::Choice(WINDOW_NAMES),
            unit: "",
            description: "window applied to each frame",
        },
        ParamSpec {
            name: "rm_wSizeSec",
            kind: ParamKind::Number,
            unit: "s",
            description: "window length",
        },
        ParamSpec {
            name: "rm_hSizeSec",
            kind: ParamKind::Number,
            unit: "s",
            description: "hop between frames",
        },
        ParamSpec {
            name: "rm_scaling",
            kind: ParamKind::Choice(&["power", "magnitude"]),
            unit: "",
            description: "average the squared ('power') or plain ('magnitude') envelope",
        },
        ParamSpec {
            name: "rm_decaySec",
            kind: ParamKind::Number,
            unit: "s",
            description: "leaky-integrator time constant",
        },
    ];
}

/// The ratemap of one ear: IHC `[time][channel]` in, `[frame][channel]` out.
#[derive(Debug, Clone)]
pub struct Ratemap {
    power: bool,
    win: Vec<f64>,
    leaky: Df2t,
    frames: FrameBuffer,
    scratch: Vec<f64>,
}

impl Ratemap {
    /// Builds the ratemap for the IHC signal `input`.
    pub fn new(params: &RatemapParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        let fs = input.fs_hz;
        let (w, h) = check_framing(
            ("rm_wSizeSec", params.w_size_sec),
            ("rm_hSizeSec", params.h_size_sec),
            fs,
            input.channels(),
        )?;
        if params.decay_sec <= 0.0 {
            return Err(afe_core::Error::InvalidParameter {
                name: "rm_decaySec".into(),
                value: params.decay_sec.to_string(),
                reason: "must be > 0 s".into(),
            });
        }
        let win = window(&params.wname, w, "rm_wname")?;
        let d = (-1.0 / (fs * params.decay_sec)).exp();
        let nc = input.channels();
        let rm = Ratemap {
            power: params.scaling == "power",
            win,
            leaky: Df2t::new(&[1.0 - d], &[1.0, -d], nc),
            frames: FrameBuffer::new(nc, w, h),
            scratch: Vec::new(),
        };
        let info = input
            .framed(1.0 / params.h_size_sec)
            .with_unit(Self::OUTPUT_UNIT)
            .with_window_s(params.w_size_sec)
            .drawn_as(DrawAs::PowerDecibels { range_db: 60.0 });
        Ok((rm, info))
    }
}

impl Processor for Ratemap {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let nc = inputs[0].width();
        let input = inputs[0].as_slice();
        self.scratch.resize(input.len(), 0.0);
        self.leaky.process_from(input, &mut self.scratch);
        let n = self.frames.available(&self.scratch);
        let out = outputs[0].reset_to(n);
        let w_len = self.win.len() as f64;
        for (k, row) in out.chunks_exact_mut(nc).enumerate() {
            let frame = self.frames.frame(&self.scratch, k);
            if self.power {
                frame_power(&self.win, frame, row);
                continue;
            }
            for (w, z) in self.win.iter().zip(frame.rows()) {
                for (acc, v) in row.iter_mut().zip(z) {
                    *acc += w * v;
                }
            }
            for v in row.iter_mut() {
                *v /= w_len;
            }
        }
        self.frames.advance(&self.scratch, n);
    }

    fn reset(&mut self) {
        self.leaky.reset();
        self.frames.reset();
    }
}

impl Descriptor for Ratemap {
    type Params = RatemapParams;
    const NAME: &'static str = "ratemap";
    const DEPENDENCY: &'static str = "innerhaircell";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str =
        "auditory spectrogram: smoothed IHC envelope per frame and channel";
    const OUTPUT_UNIT: &'static str = "";

    fn build(params: &RatemapParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Ratemap::new(params, &inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }
}

/// The registry entry of `ratemap`.
pub static REQUEST: RequestDef = request_def::<Ratemap>();

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_match_struct() {
        afe_core::params::check_param_specs::<RatemapParams>();
    }

    #[test]
    fn magnitude_scaling_is_the_windowed_mean_and_reset_starts_over() {
        let fs = 1000.0;
        let info = SignalInfo::time_frequency(fs, vec![100.0, 200.0]);
        let p = RatemapParams {
            scaling: "magnitude".into(),
            ..Default::default()
        };
        let (mut rm, _) = Ratemap::new(&p, &info).expect("valid");
        let x = Block::from_vec([2.0, 3.0].repeat(1000), 2);
        let mut out = vec![Block::new(2)];
        rm.process(&[&x], &mut out);
        // Once the integrator settles, each channel is its value times the window's mean.
        let win = window("hann", 20, "").expect("hann");
        let mean = win.iter().sum::<f64>() / 20.0;
        let last = out[0].row(out[0].frames() - 1).to_vec();
        assert!((last[0] - 2.0 * mean).abs() < 1e-9, "{last:?}");
        assert!((last[1] - 3.0 * mean).abs() < 1e-9, "{last:?}");
        let first = out[0].as_slice().to_vec();
        rm.reset();
        rm.process(&[&x], &mut out);
        assert_eq!(out[0].as_slice(), first);
    }

    #[test]
    fn constant_input_gives_windowed_mean_power() {
        let fs = 1000.0;
        let info = SignalInfo::time_frequency(fs, vec![100.0]);
        let p = RatemapParams {
            wname: "rectwin".into(),
            ..Default::default()
        };
        let (mut rm, out_info) = Ratemap::new(&p, &info).expect("valid");
        assert_eq!(out_info.fs_hz, 100.0);
        let x = Block::from_vec(vec![2.0; 1000], 1);
        let mut out = vec![Block::new(1)];
        rm.process(&[&x], &mut out);
        // W = 20, H = 10: (1000 − 10)/10 = 99 frames; once the integrator settles, 4.
        assert_eq!(out[0].frames(), 99);
        assert!((out[0].row(98)[0] - 4.0).abs() < 1e-9);
    }
}
