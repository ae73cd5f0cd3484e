//! `amsFeatures`: amplitude-modulation spectrogram of the IHC envelope, with a bank of
//! IIR modulation filters (`log`) or an FFT with linearly spaced triangular weights
//! (`lin`), after a decimation without anti-aliasing filter (specs 15-ams-modulation and
//! 31-downSampler).

use std::sync::Arc;

use afe_core::butter::{butter, ButterType};
use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::erb::linspace;
use afe_core::filter::Df2t;
use afe_core::framing::{Frame, FrameBuffer};
use afe_core::window::{window, WINDOW_NAMES};
use afe_core::{
    Block, Error, ParamKind, ParamSpec, Params, Processor, Result, SignalInfo, SignalKind,
};
use realfft::num_complex::Complex64;
use realfft::{RealFftPlanner, RealToComplex};
use serde::{Deserialize, Serialize};

use crate::framed::{check_frame_values, MAX_WINDOW};

/// How the modulation bands are computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum AmsFbType {
    /// Log-spaced IIR modulation filters; each band is the mean |filter output| over a
    /// frame.
    #[serde(rename = "log")]
    Log,
    /// Linearly spaced triangular weights on the magnitude spectrum of each frame.
    #[serde(rename = "lin")]
    Lin,
}

/// Parameters of the modulation spectrogram, under their AFE names.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AmsParams {
    /// Filterbank type (AFE `ams_fbType`).
    #[serde(rename = "ams_fbType")]
    pub fb_type: AmsFbType,
    /// Number of modulation bands (AFE `ams_nFilters`).
    #[serde(rename = "ams_nFilters")]
    pub n_filters: usize,
    /// Lowest modulation centre frequency in Hz (`log`), or the lower edge of the
    /// triangles (`lin`) (AFE `ams_lowFreqHz`).
    #[serde(rename = "ams_lowFreqHz")]
    pub low_freq_hz: f64,
    /// Highest modulation centre frequency in Hz (`log`), or the upper edge of the
    /// triangles (`lin`) (AFE `ams_highFreqHz`).
    #[serde(rename = "ams_highFreqHz")]
    pub high_freq_hz: f64,
    /// Explicit modulation centre frequencies in Hz, `log` only; empty = from the range
    /// (AFE `ams_cfHz`, which crashes in the AFE itself).
    #[serde(rename = "ams_cfHz")]
    pub cf_hz: Vec<f64>,
    /// Decimation factor applied to the envelope first (AFE `ams_dsRatio`).
    #[serde(rename = "ams_dsRatio")]
    pub ds_ratio: usize,
    /// Frame length in s (AFE `ams_wSizeSec`).
    #[serde(rename = "ams_wSizeSec")]
    pub w_size_sec: f64,
    /// Frame hop in s (AFE `ams_hSizeSec`).
    #[serde(rename = "ams_hSizeSec")]
    pub h_size_sec: f64,
    /// Window applied to each frame (AFE `ams_wname`).
    #[serde(rename = "ams_wname")]
    pub wname: String,
}

impl Default for AmsParams {
    fn default() -> Self {
        AmsParams {
            fb_type: AmsFbType::Log,
            n_filters: 15,
            low_freq_hz: 4.0,
            high_freq_hz: 1024.0,
            cf_hz: Vec::new(),
            ds_ratio: 4,
            w_size_sec: 0.032,
            h_size_sec: 0.016,
            wname: "rectwin".into(),
        }
    }
}

impl Params for AmsParams {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec {
            name: "ams_fbType",
            kind: ParamKind::Choice(&["log", "lin"]),
            unit: "",
            description:
                "log-spaced IIR modulation filters ('log') or linear FFT triangles ('lin')",
        },
        ParamSpec {
            name: "ams_nFilters",
            kind: ParamKind::Count,
            unit: "",
            description: "number of modulation bands",
        },
        ParamSpec {
            name: "ams_lowFreqHz",
            kind: ParamKind::Number,
            unit: "Hz",
            description: "lowest modulation frequency",
        },
        ParamSpec {
            name: "ams_highFreqHz",
            kind: ParamKind::Number,
            unit: "Hz",
            description: "highest modulation frequency",
        },
        ParamSpec {
            name: "ams_cfHz",
            kind: ParamKind::Numbers,
            unit: "Hz",
            description:
                "explicit modulation centre frequencies ('log' only; empty: from the range)",
        },
        ParamSpec {
            name: "ams_dsRatio",
            kind: ParamKind::Count,
            unit: "",
            description: "decimation factor of the envelope (no anti-aliasing filter)",
        },
        ParamSpec {
            name: "ams_wSizeSec",
            kind: ParamKind::Number,
            unit: "s",
            description: "frame length",
        },
        ParamSpec {
            name: "ams_hSizeSec",
            kind: ParamKind::Number,
            unit: "s",
            description: "hop between frames",
        },
        ParamSpec {
            name: "ams_wname",
            kind: ParamKind::Choice(WINDOW_NAMES),
            unit: "",
            description: "window applied to each frame",
        },
    ];
}

/// Most modulation filters (the AFE uses 9 to 15): beyond, the features of every
/// channel and band would not fit in memory (fuzzing asked for 2^32 filters).
const MAX_FILTERS: usize = 1000;

/// Keeps the stream samples whose global index is a multiple of the ratio, whatever the
/// chunking (spec 31-downSampler).
#[derive(Debug, Clone, PartialEq)]
struct DownSampler {
    ratio: usize,
    /// Index, in the next chunk, of its first sample to keep.
    skip: usize,
}

impl DownSampler {
    /// Appends the kept rows (`width` values each) of `input` to `out` (cleared first).
    fn run(&mut self, input: &[f64], width: usize, out: &mut Vec<f64>) {
        out.clear();
        let n = input.len() / width.max(1);
        if n <= self.skip {
            self.skip -= n;
            return;
        }
        let kept = (n - self.skip - 1) / self.ratio + 1;
        for i in 0..kept {
            let r = self.skip + i * self.ratio;
            out.extend_from_slice(&input[r * width..(r + 1) * width]);
        }
        self.skip = self.skip + kept * self.ratio - n;
    }
}

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

/// Frame sums for a rectangular window two hops long (the AFE's default), from the sums
/// of each hop's rows: frame `k` is hop `k`'s sum plus hop `k + 1`'s. Each row is summed
/// once and none is kept between chunks, where framing sums every row twice and copies
/// the rows of the next frame at each chunk. The values differ from one running sum over
/// the frame in rounding only (two partial sums added), and like it they do not depend on
/// the chunking.
#[derive(Debug, Clone)]
struct HopSums {
    /// Rows per hop.
    hop: usize,
    /// The sum of the current hop's rows so far, `[band][channel]`.
    current: Vec<f64>,
    /// How many rows `current` holds.
    rows: usize,
    /// The last complete hop's sum, valid once `has_last`.
    last: Vec<f64>,
    has_last: bool,
}

impl HopSums {
    fn new(width: usize, hop: usize) -> Self {
        HopSums {
            hop,
            current: vec![0.0; width],
            rows: 0,
            last: vec![0.0; width],
            has_last: false,
        }
    }

    /// Frames completed by `rows` more rows.
    fn frames_after(&self, rows: usize) -> usize {
        let hops = (self.rows + rows) / self.hop;
        (hops + usize::from(self.has_last)).saturating_sub(1)
    }

    /// Sums the rows of `banded` (`[time][band][channel]`) into hops, and writes each
    /// completed frame's sum divided by `w_len` into the rows of `out`
    /// (`[frame][channel][band]`, [`HopSums::frames_after`] of them). Allocates nothing.
    fn run(&mut self, banded: &[f64], out: &mut [f64], (nc, nb): (usize, usize), w_len: f64) {
        let mut rows = banded.chunks_exact(self.current.len().max(1));
        let mut frames = out.chunks_exact_mut((nc * nb).max(1));
        loop {
            for row in rows.by_ref().take(self.hop - self.rows) {
                add_abs(&mut self.current, 1.0, row);
                self.rows += 1;
            }
            if self.rows < self.hop {
                return;
            }
            // the first hop completes no frame, so it takes no output row
            let frame = if self.has_last { frames.next() } else { None };
            if let Some(frame) = frame {
                let hops = self
                    .last
                    .chunks_exact(nc)
                    .zip(self.current.chunks_exact(nc));
                for (j, (a, b)) in hops.enumerate() {
                    for (c, (a, b)) in a.iter().zip(b).enumerate() {
                        frame[c * nb + j] = (a + b) / w_len;
                    }
                }
            }
            std::mem::swap(&mut self.current, &mut self.last);
            self.current.fill(0.0);
            self.has_last = true;
            self.rows = 0;
        }
    }

    fn reset(&mut self) {
        self.current.fill(0.0);
        self.rows = 0;
        self.has_last = false;
    }
}

afe_core::simd_kernel!(
    fma,
    /// `acc += |w·row|`, element by element: one row of a frame's sums, weighted by its
    /// window value (the hop sums add whole rows with `w = 1`, which changes no bit).
    fn add_abs(acc: &mut [f64], w: f64, row: &[f64]) {
        for (a, v) in acc.iter_mut().zip(row) {
            *a += (w * v).abs();
        }
    }
);

impl std::fmt::Debug for AmsFeatures {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AmsFeatures")
            .field("channels", &self.channels)
            .field("bands", &self.bands)
            .field("window", &self.win.len())
            .finish_non_exhaustive()
    }
}

/// Log-spaced (or explicit) centre frequencies and one Butterworth filter per band: a
/// first-order low-pass for the first, first-order band-passes (Q = 1) for the others.
fn log_bank(p: &AmsParams, fs_ds: f64, channels: usize) -> Result<(Vec<f64>, Vec<Df2t>)> {
    let mf = if p.cf_hz.is_empty() {
        linspace(p.low_freq_hz.log2(), p.high_freq_hz.log2(), p.n_filters)
            .into_iter()
            .map(|e| 2f64.powf(e))
            .collect()
    } else {
        if p.cf_hz.iter().any(|f| *f <= 0.0) {
            return Err(Error::invalid(
                "ams_cfHz",
                format!("{:?}", p.cf_hz),
                "centre frequencies must be > 0 Hz",
            ));
        }
        p.cf_hz.clone()
    };
    let nyq = fs_ds / 2.0;
    // Band edges of quality factor Q = 1: f·(√(1 + 1/(4Q²)) ∓ 1/(2Q)).
    let root = 1.25f64.sqrt();
    // Names what the user has: the range's top (saying when it is the default) or the
    // explicit centre, the band that reaches Nyquist, and what would fit.
    let too_high = |f: f64, edge: f64| {
        let (name, value, given) = if p.cf_hz.is_empty() {
            let default = AmsParams::default().high_freq_hz;
            let which = if p.high_freq_hz == default {
                // taken back by the graph if the request set it (afe_core::params::unless_set)
                afe_core::params::DEFAULT_NOTE
            } else {
                ""
            };
            let given = format!("with ams_highFreqHz = {}{which}, ", p.high_freq_hz);
            ("ams_highFreqHz", p.high_freq_hz, given)
        } else {
            ("ams_cfHz", f, String::new())
        };
        let fs = fs_ds * p.ds_ratio as f64;
        Error::invalid(
            name,
            value,
            format!(
                "{given}the modulation band centred at {f:.1} Hz reaches {edge:.1} Hz, not below the \
                 Nyquist frequency ({nyq} Hz) of the envelope decimated by ams_dsRatio = {} \
                 ({fs} Hz / {}): keep the centre frequencies below {:.1} Hz (a band-pass \
                 reaches {:.3} times its centre) or lower ams_dsRatio",
                p.ds_ratio,
                p.ds_ratio,
                nyq / (root + 0.5),
                root + 0.5,
            ),
        )
    };
    let mut filters = Vec::with_capacity(mf.len());
    for (j, &f) in mf.iter().enumerate() {
        let w0 = f / nyq;
        if w0 >= 1.0 {
            return Err(too_high(f, f));
        }
        let (b, a) = if j == 0 {
            butter(1, &[w0], ButterType::Low)
        } else {
            let f1 = f * (root - 0.5);
            let f2 = f * (root + 0.5);
            if f2 / nyq >= 1.0 {
                return Err(too_high(f, f2));
            }
            butter(1, &[f1 / nyq, f2 / nyq], ButterType::BandPass)
        };
        filters.push(Df2t::new(&b, &a, channels));
    }
    Ok((mf, filters))
}

/// Centre frequencies and triangular weights of `p` bands spaced linearly between
/// `fl` and `fh` on the bins `k·fs/nfft`, `k = 0..nfft/2` (the AFE's `melbankm` on a
/// linear axis).
fn lin_weights(
    p: usize,
    fl: f64,
    fh: f64,
    fs: f64,
    nfft: usize,
) -> (Vec<f64>, Vec<(usize, Vec<f64>)>) {
    let delta = (fh - fl) / (p + 1) as f64;
    let centres = (1..=p).map(|j| fl + j as f64 * delta).collect();
    let weights = (1..=p)
        .map(|j| {
            let w: Vec<(usize, f64)> = (0..=nfft / 2)
                .filter_map(|k| {
                    let f = k as f64 * fs / nfft as f64;
                    let q = (f - fl) / delta;
                    let v = 1.0 - (q - j as f64).abs();
                    (f > fl && f < fh && v > 0.0).then_some((k, v))
                })
                .collect();
            let first = w.first().map_or(0, |(k, _)| *k);
            (first, w.into_iter().map(|(_, v)| v).collect())
        })
        .collect();
    (centres, weights)
}

/// Per column of `frame`, the sum over its rows of `|w·x|` with the window `win`, into `sums`.
fn abs_sums(sums: &mut [f64], win: &[f64], frame: Frame<'_>) {
    sums.fill(0.0);
    for (w, z) in win.iter().zip(frame.rows()) {
        add_abs(sums, *w, z);
    }
}

impl AmsFeatures {
    /// Builds the modulation spectrogram for the IHC signal `input`.
    pub fn new(params: &AmsParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        let p = params;
        if p.ds_ratio == 0 {
            return Err(Error::invalid(
                "ams_dsRatio",
                0,
                "must be a positive integer",
            ));
        }
        if p.cf_hz.len() > MAX_FILTERS {
            return Err(Error::invalid(
                "ams_cfHz",
                format!("{} frequencies", p.cf_hz.len()),
                format!("at most {MAX_FILTERS} modulation centre frequencies"),
            ));
        }
        if p.n_filters == 0 || p.n_filters > MAX_FILTERS {
            return Err(Error::invalid(
                "ams_nFilters",
                p.n_filters,
                format!("must be a positive integer, at most {MAX_FILTERS}"),
            ));
        }
        if p.low_freq_hz <= 0.0 {
            return Err(Error::invalid(
                "ams_lowFreqHz",
                p.low_freq_hz,
                "must be > 0 Hz",
            ));
        }
        if p.high_freq_hz <= p.low_freq_hz {
            return Err(Error::invalid(
                "ams_highFreqHz",
                p.high_freq_hz,
                format!("must be above ams_lowFreqHz = {} Hz", p.low_freq_hz),
            ));
        }
        let fs_ds = input.fs_hz / p.ds_ratio as f64;
        let w = (2.0 * (p.w_size_sec * fs_ds / 2.0).round()).max(0.0) as usize;
        if p.w_size_sec <= 0.0 || !(2..=MAX_WINDOW).contains(&w) {
            return Err(Error::invalid(
                "ams_wSizeSec",
                p.w_size_sec,
                format!(
                    "the frame must span between 2 and {MAX_WINDOW} samples at the decimated \
                     rate {fs_ds} Hz"
                ),
            ));
        }
        let h = (w as f64 / (p.w_size_sec / p.h_size_sec)).round();
        if p.h_size_sec <= 0.0 || !(1.0..=MAX_WINDOW as f64).contains(&h) {
            return Err(Error::invalid(
                "ams_hSizeSec",
                p.h_size_sec,
                format!(
                    "the hop must span between 1 and {MAX_WINDOW} samples at the decimated \
                     rate {fs_ds} Hz"
                ),
            ));
        }
        let h = h as usize;
        let win = window(&p.wname, w, "ams_wname")?;
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
        check_frame_values(("ams_wSizeSec", p.w_size_sec), w, framed_width)?;
        let (mod_cf_hz, kind, width, hidden_work) = match p.fb_type {
            AmsFbType::Log => {
                let (mf, filters) = log_bank(p, fs_ds, channels)?;
                let width = channels * mf.len();
                // every band filters every channel at the decimated rate
                (mf, Bands::Log { filters }, width, fs_ds * width as f64)
            }
            AmsFbType::Lin => {
                if !p.cf_hz.is_empty() {
                    return Err(Error::invalid(
                        "ams_cfHz",
                        format!("{:?}", p.cf_hz),
                        "explicit centre frequencies need ams_fbType = 'log'",
                    ));
                }
                let nfft = (2 * w).next_power_of_two();
                let (centres, weights) =
                    lin_weights(p.n_filters, p.low_freq_hz, p.high_freq_hz, fs_ds, nfft);
                let fft = RealFftPlanner::<f64>::new().plan_fft_forward(nfft);
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
        };
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
        let info = SignalInfo {
            kind: SignalKind::Modulation,
            mod_cf_hz,
            ..input
                .framed(fs_ds / h as f64)
                .with_unit(Self::OUTPUT_UNIT)
                .with_window_s(p.w_size_sec)
        };
        Ok((ams, info))
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn ihc(fs: f64, channels: usize) -> SignalInfo {
        SignalInfo::time_frequency(fs, (0..channels).map(|c| 100.0 * (c + 1) as f64).collect())
    }

    /// Positive envelopes with a few modulation rates.
    fn envelope(len: usize, channels: usize) -> Vec<f64> {
        (0..len)
            .flat_map(|t| {
                (0..channels).map(move |c| {
                    let t = t as f64;
                    1.0 + (0.01 * (c + 1) as f64 * t).sin() + 0.5 * (0.37 * t * t / 1e3).cos()
                })
            })
            .collect()
    }

    fn run(ams: &mut AmsFeatures, x: &[f64], nc: usize, chunks: &[usize]) -> Vec<f64> {
        let width = ams.channels * ams.bands;
        let then_the_rest = chunks.iter().copied().chain([usize::MAX]);
        crate::testing::feed(ams, x, nc, width, then_the_rest)
    }

    #[test]
    fn specs_match_struct() {
        afe_core::params::check_param_specs::<AmsParams>();
    }

    #[test]
    fn derived_sizes_follow_the_spec() {
        for (fs, w, h, rate) in [
            (16000.0, 128, 64, 62.5),
            (44100.0, 352, 176, 11025.0 / 176.0),
        ] {
            let (ams, info) = AmsFeatures::new(&AmsParams::default(), &ihc(fs, 3)).expect("valid");
            assert_eq!((ams.win.len(), ams.frames.window()), (w, w));
            assert_eq!(info.fs_hz, rate, "hop {h}");
            assert_eq!(info.width(), 3 * 15);
            assert_eq!(info.mod_cf_hz[0], 4.0);
            assert!((info.mod_cf_hz[14] - 1024.0).abs() < 1e-9);
        }
        let lin = AmsParams {
            fb_type: AmsFbType::Lin,
            ..AmsParams::default()
        };
        let (ams, info) = AmsFeatures::new(&lin, &ihc(44100.0, 2)).expect("valid");
        assert!((info.mod_cf_hz[0] - 67.75).abs() < 1e-12);
        let Bands::Lin { time, .. } = &ams.kind else {
            panic!("lin bank expected")
        };
        assert_eq!(time.len(), 1024);
    }

    #[test]
    fn downsampling_keeps_multiples_of_the_ratio_whatever_the_chunking() {
        let mut d = DownSampler { ratio: 4, skip: 0 };
        let mut kept = Vec::new();
        let mut out = Vec::new();
        let mut start = 0;
        for len in [10, 1, 1, 3, 7, 0, 2, 9] {
            let x: Vec<f64> = (start..start + len).map(|i| i as f64).collect();
            d.run(&x, 1, &mut out);
            kept.extend_from_slice(&out);
            start += len;
        }
        let expect: Vec<f64> = (0..start).step_by(4).map(|i| i as f64).collect();
        assert_eq!(kept, expect);
    }

    #[test]
    fn a_constant_envelope_lands_in_the_lowest_band() {
        let fs = 16000.0;
        let (mut ams, _) = AmsFeatures::new(&AmsParams::default(), &ihc(fs, 1)).expect("valid");
        let out = run(&mut ams, &vec![1.0; 64000], 1, &[]);
        let last = &out[out.len() - 15..];
        assert!((last[0] - 1.0).abs() < 1e-6, "{last:?}");
        assert!(last[1..].iter().all(|v| *v < 0.05), "{last:?}");
    }

    #[test]
    fn a_modulated_envelope_peaks_at_its_rate_in_both_banks() {
        let fs = 16000.0;
        // 64 Hz modulation: log band 7 (4·2^(8/14·7) = 64 Hz; band 0, the low-pass, holds
        // the mean and is left out); lin triangle 0 (67.75 Hz).
        let x: Vec<f64> = (0..64000)
            .map(|t| 1.0 + (2.0 * std::f64::consts::PI * 64.0 * t as f64 / fs).sin())
            .collect();
        for (fb_type, from, expect) in [(AmsFbType::Log, 1, 7), (AmsFbType::Lin, 0, 0)] {
            let p = AmsParams {
                fb_type,
                ..AmsParams::default()
            };
            let (mut ams, _) = AmsFeatures::new(&p, &ihc(fs, 1)).expect("valid");
            let out = run(&mut ams, &x, 1, &[]);
            let last = &out[out.len() - 15..];
            let top = (from..15).max_by(|&a, &b| last[a].total_cmp(&last[b]));
            assert_eq!(top, Some(expect), "{fb_type:?}: {last:?}");
        }
    }

    /// At 4 kHz the decimated rate is 1 kHz, so the default top band (1024 Hz) is above
    /// its Nyquist frequency: spec 15 weighs only bins `k ≤ nfft/2`, which leaves the
    /// bands whose lower edge `mc_{j−1} = 4 + 63.75·(j − 1)` Hz is at or above 500 Hz
    /// (`j ≥ 9`) silent, not an error.
    #[test]
    fn lin_bands_above_the_decimated_nyquist_frequency_are_silent() {
        let p = AmsParams {
            fb_type: AmsFbType::Lin,
            ..AmsParams::default()
        };
        let (mut ams, info) = AmsFeatures::new(&p, &ihc(4000.0, 2)).expect("valid");
        assert!(info.mod_cf_hz[14] > 500.0);
        let out = run(&mut ams, &envelope(8000, 2), 2, &[]);
        assert!(out.len() >= 2 * 15 * 50, "{} values", out.len());
        for band in out.chunks_exact(15) {
            assert!(band[..8].iter().all(|v| v.is_finite() && *v >= 0.0));
            assert!(band[7] > 0.0, "{band:?}");
            assert!(band[8..].iter().all(|&v| v == 0.0), "{band:?}");
        }
    }

    #[test]
    fn bands_past_nyquist_are_named_with_what_would_fit() {
        // 8 kHz input: the envelope decimated by 4 has its Nyquist frequency at 1000 Hz,
        // which the default band centred at 689.1 Hz reaches (edges 0.618 and 1.618 times
        // the centre: 1115.0 Hz)
        let err = AmsFeatures::new(&AmsParams::default(), &ihc(8000.0, 2))
            .expect_err("default bands reach 1657 Hz");
        let msg = err.to_string();
        assert!(
            msg.starts_with(
                "invalid value 1024 for parameter 'ams_highFreqHz': with ams_highFreqHz = 1024 \
                 (the default), the modulation band centred at 689.1 Hz reaches 1115.0 Hz"
            ),
            "{msg}"
        );
        for part in [
            "Nyquist frequency (1000 Hz)",
            "ams_dsRatio = 4 (8000 Hz / 4)",
            "below 618.0 Hz",
        ] {
            assert!(msg.contains(part), "{part}: {msg}");
        }
        // what the message says fits does fit
        let fits = AmsParams {
            high_freq_hz: 617.9,
            ..AmsParams::default()
        };
        assert!(AmsFeatures::new(&fits, &ihc(8000.0, 2)).is_ok());
        let over = AmsParams {
            high_freq_hz: 618.1,
            ..AmsParams::default()
        };
        assert!(AmsFeatures::new(&over, &ihc(8000.0, 2)).is_err());
        // an explicit centre is named as given
        let explicit = AmsParams {
            cf_hz: vec![10.0, 900.0],
            ..AmsParams::default()
        };
        let msg = AmsFeatures::new(&explicit, &ihc(8000.0, 2))
            .expect_err("900 Hz reaches 1456 Hz")
            .to_string();
        assert!(
            msg.starts_with("invalid value 900 for parameter 'ams_cfHz'"),
            "{msg}"
        );
    }

    /// Issue 44, item 4: a window of 1500 s over 32 channels and 15 bands asked for 61.5 GB;
    /// it is refused before anything is allocated, in the words of the other framed
    /// processors. The sums over two rectangular hops (no frame buffer) take any window
    /// the sample count allows, and a frame buffer up to the bound is accepted.
    #[test]
    fn a_window_whose_frame_buffer_exceeds_the_bound_is_refused() {
        let info = ihc(44100.0, 32);
        let long = AmsParams {
            w_size_sec: 1500.0,
            ..AmsParams::default()
        };
        let msg = AmsFeatures::new(&long, &info)
            .expect_err("61.5 GB")
            .to_string();
        assert!(
            msg.starts_with("invalid value 1500 for parameter 'ams_wSizeSec'")
                && msg.contains("over 480 channels would buffer")
                && msg.contains("shorten the window or use fewer channels"),
            "{msg}"
        );
        let lin = AmsParams {
            fb_type: AmsFbType::Lin,
            ..long.clone()
        };
        let msg = AmsFeatures::new(&lin, &info).expect_err("lin").to_string();
        assert!(msg.contains("over 32 channels would buffer"), "{msg}");
        let two_hops = AmsParams {
            h_size_sec: 750.0,
            ..long
        };
        assert!(AmsFeatures::new(&two_hops, &info).is_ok());
        // 4 channels × 15 bands × 2^19 samples (47.6 s at 11025 Hz) = 2^24 · 1.875: over;
        // a window of 2^18 samples (2^24 · 0.94) fits
        let at = |samples: f64| AmsParams {
            w_size_sec: samples / 11025.0,
            ..AmsParams::default()
        };
        assert!(AmsFeatures::new(&at(524_288.0), &ihc(44100.0, 4)).is_err());
        assert!(AmsFeatures::new(&at(262_144.0), &ihc(44100.0, 4)).is_ok());
    }

    #[test]
    fn bad_parameters_name_themselves() {
        let info = ihc(16000.0, 2);
        let d = AmsParams::default();
        let cases = [
            (
                // found by fuzzing: 2000 explicit frequencies asked for 1.3 GB
                "ams_cfHz",
                AmsParams {
                    cf_hz: vec![100.0; 2000],
                    ..d.clone()
                },
            ),
            (
                // found by fuzzing: 2^32 filters asked for 34 GB
                "ams_nFilters",
                AmsParams {
                    n_filters: 1 << 32,
                    ..d.clone()
                },
            ),
            (
                "ams_lowFreqHz",
                AmsParams {
                    low_freq_hz: 0.0,
                    ..d.clone()
                },
            ),
            (
                "ams_highFreqHz",
                AmsParams {
                    high_freq_hz: 2.0,
                    ..d.clone()
                },
            ),
            (
                "ams_highFreqHz",
                AmsParams {
                    high_freq_hz: 1900.0,
                    ..d.clone()
                },
            ),
            (
                "ams_wSizeSec",
                AmsParams {
                    w_size_sec: 0.0,
                    ..d.clone()
                },
            ),
            (
                "ams_hSizeSec",
                AmsParams {
                    h_size_sec: 1e9,
                    ..d.clone()
                },
            ),
            (
                "ams_hSizeSec",
                AmsParams {
                    h_size_sec: -1.0,
                    ..d.clone()
                },
            ),
            (
                "ams_dsRatio",
                AmsParams {
                    ds_ratio: 0,
                    ..d.clone()
                },
            ),
            (
                "ams_nFilters",
                AmsParams {
                    n_filters: 0,
                    ..d.clone()
                },
            ),
            (
                "ams_wname",
                AmsParams {
                    wname: "kaiser".into(),
                    ..d.clone()
                },
            ),
            (
                "ams_cfHz",
                AmsParams {
                    cf_hz: vec![4.0, -8.0],
                    ..d.clone()
                },
            ),
            (
                "ams_cfHz",
                AmsParams {
                    cf_hz: vec![4.0, 5000.0],
                    ..d.clone()
                },
            ),
            (
                "ams_cfHz",
                AmsParams {
                    cf_hz: vec![4.0],
                    fb_type: AmsFbType::Lin,
                    ..d.clone()
                },
            ),
        ];
        for (name, p) in cases {
            let e = AmsFeatures::new(&p, &info).unwrap_err().to_string();
            assert!(e.contains(name), "{name}: {e}");
        }
        let mut map = d.to_map();
        map.insert("ams_fbType".into(), serde_json::json!("mel"));
        let e = AmsParams::from_map(&map).unwrap_err().to_string();
        assert!(e.contains("ams_fbType"), "{e}");
    }

    /// Spec 15 written out for both banks: decimation by 3 (4800 → 1600 Hz), frames of
    /// 64 samples every 32 with a Hann window; `log`: five filters from 4 to 200 Hz run
    /// as difference equations on the Butterworth designs, mean |w·v| per frame; `lin`:
    /// six triangles from 20 to 500 Hz on a plain DFT of 128 points, over `nfft`.
    #[test]
    fn both_banks_match_the_spec_written_out() {
        use std::f64::consts::PI;
        let (fs, ratio, nc) = (4800.0, 3, 2);
        let x = envelope(3000, nc);
        let decimated: Vec<&[f64]> = x.chunks_exact(nc).step_by(ratio).collect();
        let (w, hop) = (64, 32);
        let hann: Vec<f64> = (0..w)
            .map(|k| 0.5 * (1.0 - (2.0 * PI * k as f64 / (w - 1) as f64).cos()))
            .collect();
        let frames = (decimated.len() - (w - hop)) / hop;
        let base = AmsParams {
            ds_ratio: ratio,
            w_size_sec: 0.04,
            h_size_sec: 0.02,
            wname: "hann".into(),
            ..AmsParams::default()
        };
        let compare = |p: &AmsParams, want: &[f64]| {
            let (mut ams, info) = AmsFeatures::new(p, &ihc(fs, nc)).expect("valid");
            assert_eq!(info.fs_hz, 50.0);
            let got = run(&mut ams, &x, nc, &[777]);
            assert_eq!(got.len(), want.len());
            let top = want.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
            let worst = got
                .iter()
                .zip(want)
                .map(|(g, v)| (g - v).abs())
                .fold(0.0, f64::max);
            assert!(
                worst <= 1e-12 * top,
                "{:?}: off by {worst} of {top}",
                p.fb_type
            );
        };

        // log: band j of channel c at out[t][c·5 + j].
        let (lo, hi, nb) = (4.0f64, 200.0f64, 5);
        let nyq = 800.0;
        let mut want = vec![0.0; frames * nc * nb];
        for j in 0..nb {
            let mf = lo * (hi / lo).powf(j as f64 / (nb - 1) as f64);
            let (b, a) = if j == 0 {
                butter(1, &[mf / nyq], ButterType::Low)
            } else {
                let edge = |s: f64| mf * (1.25f64.sqrt() + s * 0.5) / nyq;
                butter(1, &[edge(-1.0), edge(1.0)], ButterType::BandPass)
            };
            for c in 0..nc {
                let mut y = vec![0.0; decimated.len()];
                for n in 0..y.len() {
                    let mut acc = 0.0;
                    for m in 0..b.len().min(n + 1) {
                        acc += b[m] * decimated[n - m][c];
                        if m > 0 {
                            acc -= a[m] * y[n - m];
                        }
                    }
                    y[n] = acc / a[0];
                }
                for t in 0..frames {
                    let s: f64 = (0..w).map(|m| (hann[m] * y[t * hop + m]).abs()).sum();
                    want[(t * nc + c) * nb + j] = s / w as f64;
                }
            }
        }
        compare(
            &AmsParams {
                n_filters: nb,
                high_freq_hz: hi,
                ..base.clone()
            },
            &want,
        );

        // lin: triangles of Δ = 480/7 Hz on bins of 12.5 Hz.
        let (fl, fh, nb, nfft) = (20.0, 500.0, 6, 128);
        let delta = (fh - fl) / 7.0;
        let mut want = vec![0.0; frames * nc * nb];
        for c in 0..nc {
            for t in 0..frames {
                let frame: Vec<f64> = (0..w)
                    .map(|m| hann[m] * decimated[t * hop + m][c])
                    .collect();
                let magnitude: Vec<f64> = crate::testing::plain_dft(&frame, nfft)
                    .iter()
                    .map(|s| s.norm() / nfft as f64)
                    .collect();
                for j in 0..nb {
                    want[(t * nc + c) * nb + j] = (0..=nfft / 2)
                        .map(|k| {
                            let f = k as f64 * 1600.0 / nfft as f64;
                            let tri = 1.0 - ((f - fl) / delta - (j + 1) as f64).abs();
                            if f > fl && f < fh && tri > 0.0 {
                                tri * magnitude[k]
                            } else {
                                0.0
                            }
                        })
                        .sum();
                }
            }
        }
        compare(
            &AmsParams {
                fb_type: AmsFbType::Lin,
                n_filters: nb,
                low_freq_hz: fl,
                high_freq_hz: fh,
                ..base
            },
            &want,
        );
    }

    #[test]
    fn explicit_centre_frequencies_are_kept_and_debug_names_the_sizes() {
        let p = AmsParams {
            cf_hz: vec![5.0, 12.0, 40.0],
            ..AmsParams::default()
        };
        let (ams, info) = AmsFeatures::new(&p, &ihc(16000.0, 2)).expect("valid");
        assert_eq!(info.mod_cf_hz, [5.0, 12.0, 40.0]);
        assert_eq!(info.width(), 6);
        let shown = format!("{ams:?}");
        assert!(
            shown.contains("channels: 2")
                && shown.contains("bands: 3")
                && shown.contains("window: 128"),
            "{shown}"
        );
    }

    #[test]
    fn reset_restarts_the_stream() {
        let x = envelope(3000, 2);
        let (mut ams, _) =
            AmsFeatures::new(&AmsParams::default(), &ihc(16000.0, 2)).expect("valid");
        let first = run(&mut ams, &x, 2, &[1001]);
        ams.reset();
        assert_eq!(run(&mut ams, &x, 2, &[1001]), first);
    }

    #[test]
    fn hop_sums_give_the_framed_sums() {
        let x = envelope(4000, 3);
        let info = ihc(8000.0, 3);
        let p = AmsParams {
            high_freq_hz: 256.0,
            ..AmsParams::default()
        };
        let (mut hops, _) = AmsFeatures::new(&p, &info).expect("valid");
        assert!(
            hops.hop_sums.is_some(),
            "the default window is summed by hops"
        );
        // the same processor on the framing path, with that path's buffers
        let (mut framed, _) = AmsFeatures::new(&p, &info).expect("valid");
        let hop = framed.hop_sums.take().expect("summed by hops").hop;
        let width = framed.channels * framed.bands;
        framed.frames = FrameBuffer::new(width, framed.win.len(), hop);
        framed.sums = vec![0.0; width];
        let b = run(&mut framed, &x, 3, &[]);
        assert!(b.iter().any(|v| *v > 0.0));
        for chunks in [&[][..], &[1, 37, 200, 999][..]] {
            let a = run(&mut hops, &x, 3, chunks);
            hops.reset();
            assert_eq!(a.len(), b.len());
            for (i, (a, b)) in a.iter().zip(&b).enumerate() {
                assert!(
                    (a - b).abs() <= 1e-14 * b.abs(),
                    "value {i}: {a} against {b}"
                );
            }
        }
        for (wname, h_size_sec) in [("hann", 0.016), ("rectwin", 0.01)] {
            let other = AmsParams {
                wname: wname.into(),
                h_size_sec,
                ..p.clone()
            };
            let (a, _) = AmsFeatures::new(&other, &info).expect("valid");
            assert!(a.hop_sums.is_none(), "{wname}, hop {h_size_sec} s: framed");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 48, failure_persistence: None, ..ProptestConfig::default() })]

        #[test]
        fn any_chunking_is_bit_identical(
            chunks in prop::collection::vec(prop_oneof![Just(1usize), 1usize..100, 100usize..1500], 1..20),
            lin in any::<bool>(),
            ratio in 1usize..6,
        ) {
            let x = envelope(4000, 9);
            let p = AmsParams {
                fb_type: if lin { AmsFbType::Lin } else { AmsFbType::Log },
                ds_ratio: ratio,
                high_freq_hz: 256.0,
                ..AmsParams::default()
            };
            let info = ihc(8000.0, 9);
            let (mut a, _) = AmsFeatures::new(&p, &info).expect("valid");
            let (mut b, _) = AmsFeatures::new(&p, &info).expect("valid");
            prop_assert_eq!(run(&mut a, &x, 9, &[]), run(&mut b, &x, 9, &chunks));
        }
    }
}
