//! `ratemap`: leaky-integrated IHC envelope averaged over overlapping windows, in power
//! or magnitude (spec 16-ratemap).

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::filter::Df2t;
use afe_core::framing::FrameBuffer;
use afe_core::power::frame_power;
use afe_core::window::{window, Window};
use afe_core::{Block, DrawAs, Processor, Result, SignalInfo};

use crate::framed::check_framing;

afe_core::choices! {
    /// What the ratemap averages.
    pub enum Scaling {
        /// The squared envelope.
        Power = "power",
        /// The envelope itself.
        Magnitude = "magnitude",
    }
}

afe_core::params! {
    /// Parameters of the ratemap, under their AFE names.
    pub struct RatemapParams / RatemapNames {
        /// window applied to each frame
        #[afe = "rm_wname"]
        pub wname: Window = Window::Hann,
        /// window length
        #[afe = "rm_wSizeSec", unit = "s"]
        pub w_size_sec: f64 = 0.02,
        /// hop between frames
        #[afe = "rm_hSizeSec", unit = "s"]
        pub h_size_sec: f64 = 0.01,
        /// average the squared ('power') or plain ('magnitude') envelope
        #[afe = "rm_scaling"]
        pub scaling: Scaling = Scaling::Power,
        /// leaky-integrator time constant
        #[afe = "rm_decaySec", unit = "s"]
        pub decay_sec: f64 = 0.008,
    }
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
            (RatemapParams::NAMES.w_size_sec, params.w_size_sec),
            (RatemapParams::NAMES.h_size_sec, params.h_size_sec),
            fs,
            input.channels(),
        )?;
        if params.decay_sec <= 0.0 {
            return Err(afe_core::Error::invalid(
                RatemapParams::NAMES.decay_sec,
                params.decay_sec,
                "must be > 0 s",
            ));
        }
        let win = window(params.wname, w);
        let d = (-1.0 / (fs * params.decay_sec)).exp();
        let nc = input.channels();
        let rm = Ratemap {
            power: params.scaling == Scaling::Power,
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
    fn magnitude_scaling_is_the_windowed_mean_and_reset_starts_over() {
        let fs = 1000.0;
        let info = SignalInfo::time_frequency(fs, vec![100.0, 200.0]);
        let p = RatemapParams {
            scaling: Scaling::Magnitude,
            ..Default::default()
        };
        let (mut rm, _) = Ratemap::new(&p, &info).expect("valid");
        let x = Block::from_vec([2.0, 3.0].repeat(1000), 2);
        let mut out = vec![Block::new(2)];
        rm.process(&[&x], &mut out);
        // Once the integrator settles, each channel is its value times the window's mean.
        let win = window(Window::Hann, 20);
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
            wname: Window::Rectwin,
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
