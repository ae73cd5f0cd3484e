//! `amsFeatures`: amplitude-modulation spectrogram of the IHC envelope, with a bank of
//! IIR modulation filters (`log`) or an FFT with linearly spaced triangular weights
//! (`lin`), after a decimation without anti-aliasing filter (specs 15-ams-modulation and
//! 31-downSampler).

use std::sync::Arc;

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::filter::Df2t;
use afe_core::framing::FrameBuffer;
use afe_core::window::{window, Window};
use afe_core::{Axis, Block, Error, ParamKind, Processor, Result, SignalInfo, SignalKind};
use afe_fft::RealToComplex;
use num_complex::Complex64;

use crate::framed::{check_frame_values, MAX_WINDOW};

mod design;
mod down_sampler;
mod frame_sums;
#[cfg(test)]
mod tests;

use design::{lin_weights, log_bank};
use down_sampler::DownSampler;
use frame_sums::{abs_sums, HopSums};

afe_core::choices! {
    /// How the modulation bands are computed.
    pub enum AmsFbType {
        /// Log-spaced IIR modulation filters; each band is the mean |filter output| over a
        /// frame.
        Log = "log",
        /// Linearly spaced triangular weights on the magnitude spectrum of each frame.
        Lin = "lin",
    }
}

afe_core::params! {
    /// Parameters of the modulation spectrogram, under their AFE names.
    pub struct AmsParams / AmsNames {
        /// log-spaced IIR modulation filters ('log') or linear FFT triangles ('lin')
        #[afe = "ams_fbType"]
        pub fb_type: AmsFbType = AmsFbType::Log,
        /// number of modulation bands
        #[afe = "ams_nFilters", kind = ParamKind::Count]
        pub n_filters: usize = 15,
        /// lowest modulation frequency
        #[afe = "ams_lowFreqHz", unit = "Hz"]
        pub low_freq_hz: f64 = 4.0,
        /// highest modulation frequency
        #[afe = "ams_highFreqHz", unit = "Hz"]
        pub high_freq_hz: f64 = 1024.0,
        /// explicit modulation centre frequencies ('log' only; empty: from the range)
        #[afe = "ams_cfHz", unit = "Hz"]
        pub cf_hz: Vec<f64> = Vec::new(),
        /// decimation factor of the envelope (no anti-aliasing filter)
        #[afe = "ams_dsRatio", kind = ParamKind::Count]
        pub ds_ratio: usize = 4,
        /// frame length
        #[afe = "ams_wSizeSec", unit = "s"]
        pub w_size_sec: f64 = 0.032,
        /// hop between frames
        #[afe = "ams_hSizeSec", unit = "s"]
        pub h_size_sec: f64 = 0.016,
        /// window applied to each frame
        #[afe = "ams_wname"]
        pub wname: Window = Window::Rectwin,
    }
}

/// Most modulation filters (the AFE uses 9 to 15): beyond, the features of every
/// channel and band would not fit in memory (fuzzing asked for 2^32 filters).
const MAX_FILTERS: usize = 1000;

/// The band computation of one variant.
enum Bands {
    /// One IIR filter per band over all audio channels.
    Log { filters: Vec<Df2t> },
    /// Triangular weights `(first bin, weights)` per band over `|FFT|/nfft`.
    Lin {
        weights: Vec<(usize, Vec<f64>)>,
        fft: Arc<dyn RealToComplex<f64>>,
        time: Vec<f64>,
        spectrum: Vec<Complex64>,
        magnitude: Vec<f64>,
        scratch: Vec<Complex64>,
    },
}

/// The modulation spectrogram of one ear: IHC `[time][channel]` in,
/// `[frame][channel × modulation band]` out (band index fastest).
pub struct AmsFeatures {
    channels: usize,
    bands: usize,
    win: Vec<f64>,
    down: DownSampler,
    kind: Bands,
    frames: FrameBuffer,
    decimated: Vec<f64>,
    /// The log filterbank's output, `[time][band][channel]`: one block of [`ROWS`] rows
    /// where the hop sums take it, the whole chunk where frames are windowed.
    banded: Vec<f64>,
    /// One frame's sums per `[band][channel]`.
    sums: Vec<f64>,
    /// The frame sums from hop sums, for the log filterbank with a window of ones two
    /// hops long (the default); then `frames` and `sums` stay empty.
    hop_sums: Option<HopSums>,
    /// Values filtered or transformed per second of input before framing (see
    /// [`Processor::hidden_work_per_second`]).
    hidden_work: f64,
}

impl std::fmt::Debug for AmsFeatures {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AmsFeatures")
            .field("channels", &self.channels)
            .field("bands", &self.bands)
            .field("window", &self.win.len())
            .finish_non_exhaustive()
    }
}

impl AmsFeatures {
    /// Builds the modulation spectrogram for the IHC signal `input`.
    pub fn new(params: &AmsParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        let p = params;
        check_bank(p)?;
        let fs_ds = input.fs_hz / p.ds_ratio as f64;
        let (w, h) = framing(p, fs_ds)?;
        let win = window(p.wname, w);
        let ones_over_two_hops = w == 2 * h && win.iter().all(|v| *v == 1.0);
        let channels = input.channels();
        // the frame buffer's row: every band of every channel ('log') or every channel
        // ('lin'); the sums over two rectangular hops replace it
        let framed_width = match p.fb_type {
            AmsFbType::Log if ones_over_two_hops => 0,
            AmsFbType::Log if p.cf_hz.is_empty() => channels * p.n_filters,
            AmsFbType::Log => channels * p.cf_hz.len(),
            AmsFbType::Lin => channels,
        };
        check_frame_values((AmsParams::NAMES.w_size_sec, p.w_size_sec), w, framed_width)?;
        let (mod_cf_hz, kind, width, hidden_work) = bands(p, fs_ds, (w, h), channels)?;
        let hop_sums =
            (ones_over_two_hops && p.fb_type == AmsFbType::Log).then(|| HopSums::new(width, h));
        // the framing path's buffers, empty where the hop sums replace it
        let framed = if hop_sums.is_some() { 0 } else { width };
        let ams = AmsFeatures {
            channels,
            bands: mod_cf_hz.len(),
            win,
            down: DownSampler {
                ratio: p.ds_ratio,
                skip: 0,
            },
            kind,
            frames: FrameBuffer::new(framed, w, h),
            decimated: Vec::new(),
            banded: Vec::new(),
            sums: vec![0.0; framed],
            hop_sums,
            hidden_work,
        };
        let info = input
            .framed(fs_ds / h as f64)
            .with_unit(Self::OUTPUT_UNIT)
            .with_window_s(p.w_size_sec)
            .with_axes(SignalKind::Modulation, [Axis::Modulation(mod_cf_hz)]);
        Ok((ams, info))
    }
}

/// Refuses a modulation bank the parameters cannot give: no decimation, too many
/// filters, a band that is empty or starts at 0 Hz.
fn check_bank(p: &AmsParams) -> Result<()> {
    if p.ds_ratio == 0 {
        return Err(Error::invalid(
            AmsParams::NAMES.ds_ratio,
            0,
            "must be a positive integer",
        ));
    }
    if p.cf_hz.len() > MAX_FILTERS {
        return Err(Error::invalid(
            AmsParams::NAMES.cf_hz,
            format!("{} frequencies", p.cf_hz.len()),
            format!("at most {MAX_FILTERS} modulation centre frequencies"),
        ));
    }
    if p.n_filters == 0 || p.n_filters > MAX_FILTERS {
        return Err(Error::invalid(
            AmsParams::NAMES.n_filters,
            p.n_filters,
            format!("must be a positive integer, at most {MAX_FILTERS}"),
        ));
    }
    if p.low_freq_hz <= 0.0 {
        return Err(Error::invalid(
            AmsParams::NAMES.low_freq_hz,
            p.low_freq_hz,
            "must be > 0 Hz",
        ));
    }
    if p.high_freq_hz <= p.low_freq_hz {
        return Err(Error::invalid(
            AmsParams::NAMES.high_freq_hz,
            p.high_freq_hz,
            format!("must be above ams_lowFreqHz = {} Hz", p.low_freq_hz),
        ));
    }
    Ok(())
}

/// The frame and hop, samples at the decimated rate `fs_ds` (Hz), refused beyond
/// [`MAX_WINDOW`] or below a sample.
fn framing(p: &AmsParams, fs_ds: f64) -> Result<(usize, usize)> {
    let beyond = |name, value, what, least| {
        Error::invalid(
            name,
            value,
            format!(
                "the {what} must span between {least} and {MAX_WINDOW} samples at the \
                 decimated rate {fs_ds} Hz"
            ),
        )
    };
    let w = (2.0 * (p.w_size_sec * fs_ds / 2.0).round()).max(0.0) as usize;
    if p.w_size_sec <= 0.0 || !(2..=MAX_WINDOW).contains(&w) {
        return Err(beyond(
            AmsParams::NAMES.w_size_sec,
            p.w_size_sec,
            "frame",
            2,
        ));
    }
    let h = (w as f64 / (p.w_size_sec / p.h_size_sec)).round();
    if p.h_size_sec <= 0.0 || !(1.0..=MAX_WINDOW as f64).contains(&h) {
        return Err(beyond(AmsParams::NAMES.h_size_sec, p.h_size_sec, "hop", 1));
    }
    Ok((w, h as usize))
}

/// The modulation bands of `channels` channels at the decimated rate `fs_ds` (Hz), framed
/// by `(w, h)` samples: their centre frequencies, the bank, the output's width and the
/// values the bank computes per second that the output does not show.
fn bands(
    p: &AmsParams,
    fs_ds: f64,
    (w, h): (usize, usize),
    channels: usize,
) -> Result<(Vec<f64>, Bands, usize, f64)> {
    Ok(match p.fb_type {
        AmsFbType::Log => {
            let (mf, filters) = log_bank(p, fs_ds, channels)?;
            let width = channels * mf.len();
            // every band filters every channel at the decimated rate
            (mf, Bands::Log { filters }, width, fs_ds * width as f64)
        }
        AmsFbType::Lin => {
            if !p.cf_hz.is_empty() {
                return Err(Error::invalid(
                    AmsParams::NAMES.cf_hz,
                    format!("{:?}", p.cf_hz),
                    "explicit centre frequencies need ams_fbType = 'log'",
                ));
            }
            let nfft = (2 * w).next_power_of_two();
            let (centres, weights) =
                lin_weights(p.n_filters, p.low_freq_hz, p.high_freq_hz, fs_ds, nfft);
            let fft = afe_fft::real_forward(nfft);
            let kind = Bands::Lin {
                weights,
                time: fft.make_input_vec(),
                spectrum: fft.make_output_vec(),
                magnitude: vec![0.0; nfft / 2 + 1],
                scratch: fft.make_scratch_vec(),
                fft,
            };
            // one transform of every channel per frame
            let work = fs_ds / h as f64 * nfft as f64 * channels as f64;
            (centres, kind, channels, work)
        }
    })
}

/// Rows of the decimated signal filtered by every band before the next rows.
const ROWS: usize = 64;

/// Filters the rows `x` (`[time][channel]`, `nc` channels) by every band into `rows`
/// (`[time][band][channel]`); the filters keep their state.
fn filter_block(filters: &mut [Df2t], x: &[f64], rows: &mut [f64], nc: usize) {
    let stride = nc * filters.len();
    for (j, filter) in filters.iter_mut().enumerate() {
        filter.process_into_rows(x, &mut rows[j * nc..], stride);
    }
}

impl Processor for AmsFeatures {
    fn hidden_work_per_second(&self) -> f64 {
        self.hidden_work
    }

    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let nc = self.channels;
        let nb = self.bands;
        self.down.run(inputs[0].as_slice(), nc, &mut self.decimated);
        let w_len = self.win.len() as f64;
        match &mut self.kind {
            Bands::Log { filters } => {
                let width = (nc * nb).max(1);
                if let Some(hop_sums) = &mut self.hop_sums {
                    // Block by block of rows: every band's filter writes its columns of a
                    // block that stays in cache, and the hop sums take the block before
                    // the next is filtered, so the bands are never all in memory.
                    let rows = self.decimated.len() / nc.max(1);
                    let out = outputs[0].reset_to(hop_sums.frames_after(rows));
                    let mut at = 0;
                    self.banded.resize(ROWS * width, 0.0);
                    for x in self.decimated.chunks((ROWS * nc).max(1)) {
                        let n = x.len() / nc.max(1);
                        let block = &mut self.banded[..n * width];
                        filter_block(filters, x, block, nc);
                        let len = hop_sums.frames_after(n) * width;
                        hop_sums.run(block, &mut out[at..at + len], (nc, nb), w_len);
                        at += len;
                    }
                    return;
                }
                self.banded.resize(self.decimated.len() * nb, 0.0);
                let blocks = self
                    .decimated
                    .chunks((ROWS * nc).max(1))
                    .zip(self.banded.chunks_mut((ROWS * width).max(1)));
                for (x, rows) in blocks {
                    filter_block(filters, x, rows, nc);
                }
                let input = &self.banded;
                let n = self.frames.available(input);
                let out = outputs[0].reset_to(n);
                for (k, row) in out.chunks_exact_mut(nc * nb).enumerate() {
                    abs_sums(&mut self.sums, &self.win, self.frames.frame(input, k));
                    // band-major sums into the channel-major output row
                    for (j, sums) in self.sums.chunks_exact(nc).enumerate() {
                        for (c, v) in sums.iter().enumerate() {
                            row[c * nb + j] = v / w_len;
                        }
                    }
                }
                self.frames.advance(input, n);
            }
            Bands::Lin {
                weights,
                fft,
                time,
                spectrum,
                magnitude,
                scratch,
            } => {
                let input = &self.decimated;
                let n = self.frames.available(input);
                let nfft = time.len() as f64;
                let out = outputs[0].reset_to(n);
                for (k, row) in out.chunks_exact_mut(nc * nb).enumerate() {
                    let frame = self.frames.frame(input, k);
                    for c in 0..nc {
                        for ((t, w), z) in time.iter_mut().zip(&self.win).zip(frame.rows()) {
                            *t = w * z[c];
                        }
                        time[self.win.len()..].fill(0.0);
                        // Buffers made by the plan: the lengths match, this cannot fail.
                        let _ = fft.process_with_scratch(time, spectrum, scratch);
                        for (m, s) in magnitude.iter_mut().zip(spectrum.iter()) {
                            *m = (s / nfft).norm();
                        }
                        for (j, (first, tri)) in weights.iter().enumerate() {
                            row[c * nb + j] = tri
                                .iter()
                                .zip(&magnitude[*first..])
                                .map(|(a, b)| a * b)
                                .sum();
                        }
                    }
                }
                self.frames.advance(input, n);
            }
        }
    }

    /// Back to the state after construction: the AFE keeps its filter states and the
    /// decimation phase across a reset (a second offline run continues them); afe resets
    /// them, so that every run starts alike.
    fn reset(&mut self) {
        self.down.skip = 0;
        self.frames.reset();
        if let Some(hop_sums) = &mut self.hop_sums {
            hop_sums.reset();
        }
        if let Bands::Log { filters } = &mut self.kind {
            for f in filters {
                f.reset();
            }
        }
    }
}

impl Descriptor for AmsFeatures {
    type Params = AmsParams;
    const NAME: &'static str = "amsFeatures";
    const DEPENDENCY: &'static str = "innerhaircell";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str =
        "amplitude-modulation spectrogram: IHC envelope energy per frame, channel and modulation band";
    const OUTPUT_UNIT: &'static str = "";

    fn build(params: &AmsParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = AmsFeatures::new(params, &inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }
}

/// The registry entry of `amsFeatures`.
pub static REQUEST: RequestDef = request_def::<AmsFeatures>();
