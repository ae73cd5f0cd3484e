//! Static figures of computed signals (`afe plot`): one panel per signal, drawn the way its
//! kind needs — images over time and centre frequency (powers in dB, signed cues on a
//! diverging map centred on zero, masks in grey), waveforms and pitch as lines, feature
//! vectors as z-scores, correlations, modulation spectra and the DUET histogram as images
//! at a chosen time — with axes in seconds and Hz and a colour bar with its unit. PNG or
//! SVG, chosen by the output's extension.
//!
//! Signals at the input's sampling rate (the filterbank, inner-hair-cell and adaptation
//! outputs: whatever `fs_hz` equals `audio_fs_hz` for) are drawn as the AFE's `waveplot`
//! draws them, one trace per channel stacked over the centre frequencies, or (with
//! [`Layout::waveforms`] off) as images of their largest magnitudes. Either way they are
//! first reduced to the figure's pixel columns by [`envelope`], which keeps the smallest
//! and the largest value of each column, so that no peak is lost.

use std::path::Path;

use afe_core::{DrawAs, SignalKind};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

use afe::Recorded;
use afe::Recorder;

/// Why a figure cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The output's extension names no format afe draws.
    #[error("cannot tell the figure's format from '{0}': name it .png or .svg")]
    Format(String),
    /// The time asked for lies outside a signal.
    #[error("--at {at} s is outside {key}, which spans {start:.3} to {end:.3} s")]
    At {
        /// The signal.
        key: String,
        /// The time asked for, in s.
        at: f64,
        /// First frame's time, in s.
        start: f64,
        /// Time after the last frame, in s.
        end: f64,
    },
    /// A signal drawn one frame at a time has no frame: the input is shorter than its
    /// first window.
    #[error(
        "{key} has no frame to draw: the input is shorter than its first window{}",
        window_s.map_or(String::new(), |w| format!(" ({w} s)"))
    )]
    NoFrame {
        /// The signal.
        key: String,
        /// Its window, in s.
        window_s: Option<f64>,
    },
    /// Nothing to draw.
    #[error("no signal to draw: the run produced no output")]
    Empty,
    /// The drawing backend failed.
    #[error("cannot draw the figure: {reason}")]
    Draw {
        /// What went wrong.
        reason: String,
    },
}

/// How the figure is laid out.
#[derive(Debug, Clone, Copy)]
pub struct Layout {
    /// Figure width in pixels.
    pub width: u32,
    /// Height of each panel in pixels.
    pub panel_height: u32,
    /// Time (s) at which correlations, modulation spectra and DUET histograms are drawn
    /// (`None`: the middle of the signal).
    pub at_s: Option<f64>,
    /// Audio-rate signals of several channels as stacked waveforms (`true`) or as images
    /// of their largest magnitude per pixel column, in dB where their display gives a
    /// range (`false`).
    pub waveforms: bool,
}

impl Default for Layout {
    fn default() -> Self {
        Layout {
            width: 1000,
            panel_height: 230,
            at_s: None,
            waveforms: true,
        }
    }
}

/// The AFE's `wavPlotZoom` default: the largest magnitude of a stacked waveform lies half
/// this many channel spacings from its channel's line.
const WAV_PLOT_ZOOM: f64 = 5.0;

/// Longest image axis drawn, in cells: longer signals are reduced by block maxima.
const MAX_COLUMNS: usize = 1000;
/// Dynamic range (dB below the peak) of spectra that do not give their own.
const SPECTRUM_RANGE_DB: f64 = 80.0;

/// The font for text in bitmaps (DejaVu Sans Mono, see `assets/fonts/LICENSE`).
static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSansMono.ttf");

/// A colour scale.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Map {
    /// Dark blue to yellow, for magnitudes.
    Sequential,
    /// Blue, white, red around zero, for signed cues.
    Diverging,
    /// Light grey to black, for binary masks.
    Grey,
}

impl Map {
    fn color(self, u: f64) -> RGBColor {
        let stops: &[(u8, u8, u8)] = match self {
            Map::Sequential => &[
                (68, 1, 84),
                (59, 82, 139),
                (33, 145, 140),
                (94, 201, 98),
                (253, 231, 37),
            ],
            Map::Diverging => &[(33, 102, 172), (247, 247, 247), (178, 24, 43)],
            Map::Grey => &[(240, 240, 240), (0, 0, 0)],
        };
        let u = if u.is_finite() {
            u.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let x = u * (stops.len() - 1) as f64;
        let i = (x.floor() as usize).min(stops.len() - 2);
        let f = x - i as f64;
        let mix = |a: u8, b: u8| (f64::from(a) + f * (f64::from(b) - f64::from(a))).round() as u8;
        let (a, b) = (stops[i], stops[i + 1]);
        RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
    }
}

/// An image panel: `rows × cols` values, row `r` drawn at height `r` (bottom up).
#[derive(Debug, Clone)]
struct Image {
    values: Vec<f64>,
    rows: usize,
    cols: usize,
    /// The horizontal extent of the columns.
    x: (f64, f64),
    x_label: String,
    /// Label of each row (centre frequencies, feature names), shown for a few rows.
    row_labels: Vec<String>,
    y_label: String,
    lo: f64,
    hi: f64,
    map: Map,
    unit: String,
}

/// One panel's content.
#[derive(Debug, Clone)]
enum Content {
    Image(Image),
    /// A line over time (waveform, pitch); NaN values are gaps.
    Line {
        x: Vec<f64>,
        y: Vec<f64>,
        y_label: String,
        /// Line width in pixels: 1 for a waveform's envelope, whose steep reversals a
        /// wider line would draw with spikes (mitred joins) far beyond the values.
        stroke: u32,
    },
    /// Stacked waveforms: channel `k`'s trace runs around height `k` over the times `x`.
    Waves {
        x: Vec<f64>,
        traces: Vec<Vec<f64>>,
        /// Centre frequency of each channel.
        row_labels: Vec<String>,
        /// How far (in channel spacings) the traces may reach beyond the outer channels.
        reach: f64,
    },
}

/// A titled panel.
#[derive(Debug, Clone)]
struct Panel {
    title: String,
    content: Content,
}

/// The figure's file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// A PNG bitmap (text in the bundled font).
    Png,
    /// An SVG drawing.
    Svg,
}

impl Format {
    /// The format `path`'s extension names (`.png` or `.svg`, any case).
    pub fn of(path: &Path) -> Result<Format, PlotError> {
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("png") => Ok(Format::Png),
            Some(e) if e.eq_ignore_ascii_case("svg") => Ok(Format::Svg),
            _ => Err(PlotError::Format(path.display().to_string())),
        }
    }
}

/// Draws every signal of `rec`, one panel each, and returns the encoded figure.
pub fn render(rec: &Recorder, format: Format, layout: &Layout) -> Result<Vec<u8>, PlotError> {
    let panels = rec
        .signals()
        .iter()
        .map(|s| panel(s, layout))
        .collect::<Result<Vec<_>, _>>()?;
    if panels.is_empty() {
        return Err(PlotError::Empty);
    }
    let (w, h) = (layout.width, layout.panel_height * panels.len() as u32);
    let failed = |reason: String| PlotError::Draw { reason };
    // text is measured (and in a PNG drawn) with the bundled font
    static REGISTER: std::sync::Once = std::sync::Once::new();
    REGISTER.call_once(|| {
        // it parses: checked by the tests
        let _ = register_font("sans-serif", FontStyle::Normal, FONT);
    });
    match format {
        Format::Png => {
            let mut rgb = vec![0u8; 3 * w as usize * h as usize];
            {
                let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
                draw_all(&root, &panels).map_err(failed)?;
                root.present().map_err(|e| failed(e.to_string()))?;
            }
            let mut png_bytes = Vec::new();
            let mut encoder = png::Encoder::new(&mut png_bytes, w, h);
            encoder.set_color(png::ColorType::Rgb);
            encoder.set_depth(png::BitDepth::Eight);
            encoder
                .write_header()
                .and_then(|mut writer| writer.write_image_data(&rgb))
                .map_err(|e| failed(e.to_string()))?;
            Ok(png_bytes)
        }
        Format::Svg => {
            let mut svg = String::new();
            {
                let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
                draw_all(&root, &panels).map_err(failed)?;
                root.present().map_err(|e| failed(e.to_string()))?;
            }
            Ok(svg.into_bytes())
        }
    }
}

/// The time of each row of `s`, in s.
fn times(s: &Recorded) -> impl Iterator<Item = f64> + '_ {
    let first = s.description["first_time_s"].as_f64().unwrap_or(0.0);
    (0..s.data.frames()).map(move |k| first + k as f64 / s.info.fs_hz)
}

/// The span of `s` over time: first row to one hop after the last, in s.
fn span(s: &Recorded) -> (f64, f64) {
    let first = s.description["first_time_s"].as_f64().unwrap_or(0.0);
    let end = first + s.data.frames().max(1) as f64 / s.info.fs_hz;
    (first, end)
}

fn unit_of(s: &Recorded) -> String {
    s.description["unit"]
        .as_str()
        .unwrap_or_default()
        .to_string()
}

fn cf_labels(cf: &[f64]) -> Vec<String> {
    cf.iter().map(|f| format!("{f:.0}")).collect()
}

/// Reduces `rows × cols` values (row-major, one row per frame) to at most
/// [`MAX_COLUMNS`] frames by the largest |value| of each block, transposed so that each
/// image row is a channel.
fn over_time(values: &[f64], frames: usize, width: usize, abs_max: bool) -> (Vec<f64>, usize) {
    let block = frames.div_ceil(MAX_COLUMNS).max(1);
    let cols = frames.div_ceil(block);
    let mut out = vec![f64::NAN; width * cols];
    for col in 0..cols {
        let rows = col * block..((col + 1) * block).min(frames);
        for ch in 0..width {
            let cell = &mut out[ch * cols + col];
            for r in rows.clone() {
                let v = values[r * width + ch];
                let v = if abs_max { v.abs() } else { v };
                if v.is_finite() && !(cell.is_finite() && *cell >= v) {
                    *cell = v;
                }
            }
        }
    }
    (out, cols)
}

/// The rows of a `frames × width` signal (row-major) reduced to at most `columns`
/// columns, as `(starts, lo, hi)`: the first row of each column, and the smallest and the
/// largest value of each channel over the column's rows (`columns × width`, row-major;
/// NaN ignored, and left only where a column holds nothing else). With no more rows than
/// columns each row is its own column.
pub fn envelope(
    values: &[f64],
    frames: usize,
    width: usize,
    columns: usize,
) -> (Vec<usize>, Vec<f64>, Vec<f64>) {
    let cols = frames.min(columns.max(1));
    let starts: Vec<usize> = (0..cols).map(|c| c * frames / cols).collect();
    let mut lo = vec![f64::NAN; cols * width];
    let mut hi = vec![f64::NAN; cols * width];
    for (c, &start) in starts.iter().enumerate() {
        let end = starts.get(c + 1).copied().unwrap_or(frames);
        let (lo, hi) = (
            &mut lo[c * width..(c + 1) * width],
            &mut hi[c * width..(c + 1) * width],
        );
        for row in values[start * width..end * width].chunks_exact(width) {
            for ((l, h), &v) in lo.iter_mut().zip(hi.iter_mut()).zip(row) {
                // min and max take the number where one side is NaN
                *l = l.min(v);
                *h = h.max(v);
            }
        }
    }
    (starts, lo, hi)
}

/// Whether `s` is a waveform: values at the input's sampling rate, drawn on a linear or
/// an amplitude-in-dB scale, of the time-domain or time-frequency kind.
fn is_waveform(s: &Recorded) -> bool {
    matches!(
        s.info.kind,
        SignalKind::TimeDomain | SignalKind::TimeFrequency
    ) && s.info.fs_hz == s.info.audio_fs_hz
        && matches!(
            s.info.display,
            DrawAs::Linear | DrawAs::AmplitudeDecibels { .. }
        )
}

/// The channels of an audio-rate signal as the AFE's `waveplot` stacks them: each
/// channel brought to zero mean and unit variance, all on one scale on which the largest
/// magnitude lies `WAV_PLOT_ZOOM / 2` channel spacings from its channel's line; each trace
/// runs down and up every pixel column, from its smallest value to its largest.
fn stacked(s: &Recorded, columns: usize) -> Content {
    let (frames, width) = (s.data.frames(), s.data.width());
    let values = s.data.as_slice();
    let (starts, lo, hi) = envelope(values, frames, width, columns);
    let t: Vec<f64> = times(s).collect();
    let x: Vec<f64> = starts.iter().flat_map(|&k| [t[k], t[k]]).collect();
    let n = frames.max(1) as f64;
    let moments: Vec<(f64, f64)> = (0..width)
        .map(|ch| {
            let col = || values.iter().skip(ch).step_by(width);
            let mean = col().sum::<f64>() / n;
            let sd = (col().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
            (mean, if sd.is_finite() && sd > 0.0 { sd } else { 1.0 })
        })
        .collect();
    let normal = |i: usize, v: f64| (v - moments[i % width].0) / moments[i % width].1;
    let peak = lo
        .iter()
        .chain(&hi)
        .enumerate()
        .map(|(i, v)| normal(i, *v).abs())
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let scale = if peak > 0.0 {
        0.5 * WAV_PLOT_ZOOM / peak
    } else {
        0.0
    };
    let traces = (0..width)
        .map(|ch| {
            (0..starts.len())
                .flat_map(|c| [lo[c * width + ch], hi[c * width + ch]])
                .map(|v| ch as f64 + scale * normal(ch, v))
                .collect()
        })
        .collect();
    Content::Waves {
        x,
        traces,
        row_labels: channel_labels(s, width),
        reach: 0.5 * WAV_PLOT_ZOOM,
    }
}

/// Labels of a signal's channels: centre frequencies, or channel numbers.
fn channel_labels(s: &Recorded, width: usize) -> Vec<String> {
    if s.info.cf_hz.len() == width {
        cf_labels(&s.info.cf_hz)
    } else {
        (0..width).map(|c| c.to_string()).collect()
    }
}

fn finite_range(values: &[f64]) -> (f64, f64) {
    let (lo, hi) = values
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    if lo.is_finite() && hi > lo {
        (lo, hi)
    } else if lo.is_finite() {
        (lo - 0.5, lo + 0.5)
    } else {
        (0.0, 1.0)
    }
}

/// A range centred on zero that holds every finite value.
fn symmetric(values: &[f64]) -> (f64, f64) {
    let (lo, hi) = finite_range(values);
    let lim = lo.abs().max(hi.abs()).max(f64::MIN_POSITIVE);
    (-lim, lim)
}

/// The frame of `s` nearest to `at` (default: the middle), with its time.
fn frame_at(s: &Recorded, at: Option<f64>) -> Result<(usize, f64), PlotError> {
    let (start, end) = span(s);
    let frames = s.data.frames();
    if frames == 0 {
        return Err(PlotError::NoFrame {
            key: s.key.clone(),
            window_s: s.info.window_s,
        });
    }
    let k = match at {
        Some(t) if !(start..=end).contains(&t) => {
            return Err(PlotError::At {
                key: s.key.clone(),
                at: t,
                start,
                end,
            })
        }
        Some(t) => (((t - start) * s.info.fs_hz).floor().max(0.0) as usize).min(frames - 1),
        None => frames / 2,
    };
    Ok((k, start + k as f64 / s.info.fs_hz))
}

/// What to draw for signal `s`.
fn panel(s: &Recorded, layout: &Layout) -> Result<Panel, PlotError> {
    let at = layout.at_s;
    let columns = layout.width as usize;
    let name = s.description["name"].as_str().unwrap_or(&s.key).to_string();
    let unit = unit_of(s);
    let frames = s.data.frames();
    let width = s.data.width();
    let values = s.data.as_slice();
    let time_label = "time (s)".to_string();
    let mut title = s.key.clone();
    let content = match s.info.kind {
        SignalKind::TimeDomain if width == 1 => {
            let (x, y) = line_reduced(s, columns);
            Content::Line {
                x,
                y,
                y_label: "amplitude".into(),
                stroke: 1,
            }
        }
        _ if is_waveform(s) && layout.waveforms && frames > 0 => stacked(s, columns),
        SignalKind::TimeDomain | SignalKind::TimeFrequency | SignalKind::BinaryMask => {
            let full_rate = frames > MAX_COLUMNS && s.info.fs_hz == s.info.audio_fs_hz;
            let (mut cells, cols) = over_time(values, frames, width, full_rate);
            let (lo, hi, map, unit) =
                if let (true, Some(range_db)) = (full_rate, s.info.display.range_db()) {
                    // largest magnitudes of a wide dynamic range, in dB
                    cells
                        .iter_mut()
                        .for_each(|v| *v = 20.0 * v.max(1e-300).log10());
                    let peak = finite_range(&cells).1;
                    let unit = "dB (largest |value|)".to_string();
                    (peak - range_db, peak, Map::Sequential, unit)
                } else if let DrawAs::PowerDecibels { range_db } = s.info.display {
                    cells
                        .iter_mut()
                        .for_each(|v| *v = 10.0 * v.max(1e-30).log10());
                    let peak = finite_range(&cells).1;
                    (peak - range_db, peak, Map::Sequential, "dB".to_string())
                } else if s.info.kind == SignalKind::BinaryMask {
                    (0.0, 1.0, Map::Grey, "mask".to_string())
                } else if s.info.display == DrawAs::Signed {
                    let (lo, hi) = symmetric(&cells);
                    (lo, hi, Map::Diverging, unit)
                } else {
                    let (lo, hi) = finite_range(&cells);
                    let unit = if full_rate {
                        format!("largest |value| {unit}")
                    } else {
                        unit
                    };
                    (lo, hi, Map::Sequential, unit)
                };
            let row_labels = channel_labels(s, width);
            Content::Image(Image {
                values: cells,
                rows: width,
                cols,
                x: span(s),
                x_label: time_label,
                row_labels,
                y_label: "centre frequency (Hz)".into(),
                lo,
                hi,
                map,
                unit,
            })
        }
        SignalKind::Spectrum => {
            // (re, im) pairs per bin: magnitudes in dB
            let bins = s.info.cf_hz.len();
            let mags: Vec<f64> = values
                .chunks_exact(2)
                .map(|z| 20.0 * z[0].hypot(z[1]).max(1e-12).log10())
                .collect();
            let (cells, cols) = over_time(&mags, frames, bins, false);
            let peak = finite_range(&cells).1;
            Content::Image(Image {
                values: cells,
                rows: bins,
                cols,
                x: span(s),
                x_label: time_label,
                row_labels: cf_labels(&s.info.cf_hz),
                y_label: "frequency (Hz)".into(),
                lo: peak - s.info.display.range_db().unwrap_or(SPECTRUM_RANGE_DB),
                hi: peak,
                map: Map::Sequential,
                unit: "dB".into(),
            })
        }
        SignalKind::Feature if s.info.display == DrawAs::Trajectory => Content::Line {
            x: times(s).collect(),
            y: values.chunks_exact(width).map(|row| row[0]).collect(),
            stroke: 2,
            y_label: format!(
                "{} ({unit})",
                s.info
                    .features
                    .first()
                    .map_or(name.as_str(), String::as_str)
            ),
        },
        SignalKind::Feature => {
            // each feature on its own scale: z-scores over time
            let mut z = values.to_vec();
            for f in 0..width {
                let col: Vec<f64> = (0..frames)
                    .map(|k| values[k * width + f])
                    .filter(|v| v.is_finite())
                    .collect();
                let n = col.len().max(1) as f64;
                let mean = col.iter().sum::<f64>() / n;
                let sd = (col.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
                for k in 0..frames {
                    let v = &mut z[k * width + f];
                    *v = (*v - mean) / if sd > 0.0 { sd } else { 1.0 };
                }
            }
            let (cells, cols) = over_time(&z, frames, width, false);
            let (lo, hi) = symmetric(&cells);
            Content::Image(Image {
                values: cells,
                rows: width,
                cols,
                x: span(s),
                x_label: time_label,
                row_labels: s.info.features.clone(),
                y_label: "feature".into(),
                lo,
                hi,
                map: Map::Diverging,
                unit: "z-score".into(),
            })
        }
        SignalKind::Correlation | SignalKind::Modulation | SignalKind::DuetHistogram => {
            let (k, when) = frame_at(s, at)?;
            title = format!("{} at {when:.3} s", s.key);
            let frame = &values[k * width..(k + 1) * width];
            let shape = s.info.frame_shape();
            let (rows, cols) = (shape[0], shape[1]);
            let (x, x_label, row_labels, y_label) = match s.info.kind {
                SignalKind::Correlation => {
                    let lags = &s.info.lags_s;
                    (
                        (1e3 * lags[0], 1e3 * lags[lags.len() - 1]),
                        "lag (ms)".to_string(),
                        cf_labels(&s.info.cf_hz),
                        "centre frequency (Hz)".to_string(),
                    )
                }
                SignalKind::Modulation => {
                    let m = &s.info.mod_cf_hz;
                    (
                        (m[0], m[m.len() - 1]),
                        "modulation frequency (Hz), channel by channel".to_string(),
                        cf_labels(&s.info.cf_hz),
                        "centre frequency (Hz)".to_string(),
                    )
                }
                _ => {
                    let d = &s.info.delta_samples;
                    (
                        (d[0], d[d.len() - 1]),
                        "delay (samples)".to_string(),
                        s.info.alpha.iter().map(|a| format!("{a:.2}")).collect(),
                        "attenuation α".to_string(),
                    )
                }
            };
            let (lo, hi, map) = match finite_range(frame) {
                (lo, _) if lo < 0.0 => {
                    let (lo, hi) = symmetric(frame);
                    (lo, hi, Map::Diverging)
                }
                (lo, hi) => (lo, hi, Map::Sequential),
            };
            Content::Image(Image {
                values: frame.to_vec(),
                rows,
                cols,
                x,
                x_label,
                row_labels,
                y_label,
                lo,
                hi,
                map,
                unit: if unit.is_empty() {
                    "value".into()
                } else {
                    unit
                },
            })
        }
    };
    Ok(Panel { title, content })
}

/// A waveform reduced to the minimum and maximum of each of at most `columns` columns
/// ([`envelope`]), running down and up each column.
fn line_reduced(s: &Recorded, columns: usize) -> (Vec<f64>, Vec<f64>) {
    let values = s.data.as_slice();
    let t: Vec<f64> = times(s).collect();
    let (starts, lo, hi) = envelope(values, values.len(), 1, columns);
    let x = starts.iter().flat_map(|&k| [t[k], t[k]]).collect();
    let y = lo.iter().zip(&hi).flat_map(|(l, h)| [*l, *h]).collect();
    (x, y)
}

fn draw_all<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    panels: &[Panel],
) -> Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    for (area, p) in root.split_evenly((panels.len(), 1)).iter().zip(panels) {
        draw_panel(area, p).map_err(|e| format!("{}: {e}", p.title))?;
    }
    Ok(())
}

type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> DrawResult<DB> {
    let (w, _) = area.dim_in_pixel();
    let (main, bar) = area.split_horizontally(w.saturating_sub(110));
    match &p.content {
        Content::Line {
            x,
            y,
            y_label,
            stroke,
        } => {
            let (x0, x1) = finite_range(x);
            let (y0, y1) = finite_range(y);
            let pad = 0.05 * (y1 - y0);
            let (y0, y1) = (y0 - pad, y1 + pad);
            let mut chart = ChartBuilder::on(&main)
                .caption(&p.title, ("sans-serif", 15))
                .margin(6)
                .x_label_area_size(32)
                .y_label_area_size(70)
                .build_cartesian_2d(x0..x1, y0..y1)?;
            chart
                .configure_mesh()
                .disable_mesh()
                .x_desc("time (s)")
                .y_desc(y_label.as_str())
                .label_style(("sans-serif", 11))
                .draw()?;
            // NaN values (unvoiced pitch) break the line
            let segments = x.iter().zip(y).map(|(a, b)| (*a, *b)).collect::<Vec<_>>();
            for run in segments.split(|(_, v)| !v.is_finite()) {
                if run.len() == 1 {
                    chart.draw_series(std::iter::once(Circle::new(run[0], 2, BLUE.filled())))?;
                } else if !run.is_empty() {
                    let style = BLUE.stroke_width(*stroke);
                    chart.draw_series(LineSeries::new(run.iter().copied(), style))?;
                }
            }
        }
        Content::Waves {
            x,
            traces,
            row_labels,
            reach,
        } => {
            let (x0, x1) = finite_range(x);
            let rows = traces.len() as f64;
            let mut chart = ChartBuilder::on(&main)
                .caption(&p.title, ("sans-serif", 15))
                .margin(6)
                .x_label_area_size(32)
                .y_label_area_size(70)
                .build_cartesian_2d(x0..x1, -0.5 - reach..rows - 0.5 + reach)?;
            chart
                .configure_mesh()
                .disable_mesh()
                .x_desc("time (s)")
                .y_desc("centre frequency (Hz)")
                .y_labels(6.min(traces.len()) + 2)
                .y_label_formatter(&|v| {
                    // only the channels' own lines are labelled
                    let i = v.round();
                    match row_labels.get(i as usize) {
                        Some(label) if (v - i).abs() < 1e-6 && i >= 0.0 => label.clone(),
                        _ => String::new(),
                    }
                })
                .label_style(("sans-serif", 11))
                .draw()?;
            for trace in traces {
                let points: Vec<(f64, f64)> =
                    x.iter().copied().zip(trace.iter().copied()).collect();
                for run in points.split(|(_, v)| !v.is_finite()) {
                    chart
                        .draw_series(LineSeries::new(run.iter().copied(), BLUE.stroke_width(1)))?;
                }
            }
        }
        Content::Image(img) => {
            let (x0, x1) = if img.x.1 > img.x.0 {
                img.x
            } else {
                (img.x.0, img.x.0 + 1.0)
            };
            let rows = img.rows.max(1) as f64;
            let labels = &img.row_labels;
            let mut chart = ChartBuilder::on(&main)
                .caption(&p.title, ("sans-serif", 15))
                .margin(6)
                .x_label_area_size(32)
                .y_label_area_size(70)
                .build_cartesian_2d(x0..x1, -0.5..rows - 0.5)?;
            chart
                .configure_mesh()
                .disable_mesh()
                .x_desc(img.x_label.as_str())
                .y_desc(img.y_label.as_str())
                .y_labels(6.min(img.rows))
                .y_label_formatter(&|v| {
                    let i = v.round().max(0.0) as usize;
                    labels.get(i).cloned().unwrap_or_default()
                })
                .label_style(("sans-serif", 11))
                .draw()?;
            let dx = (x1 - x0) / img.cols.max(1) as f64;
            let scale = |v: f64| (v - img.lo) / (img.hi - img.lo);
            chart.draw_series((0..img.rows).flat_map(|r| {
                (0..img.cols).map(move |c| {
                    let v = img.values[r * img.cols + c];
                    let color = if v.is_finite() {
                        img.map.color(scale(v))
                    } else {
                        RGBColor(200, 200, 200)
                    };
                    let x = x0 + c as f64 * dx;
                    let y = r as f64 - 0.5;
                    Rectangle::new([(x, y), (x + dx, y + 1.0)], color.filled())
                })
            }))?;
            draw_bar(&bar, img)?;
        }
    }
    Ok(())
}

/// `v` to a hundredth of the order of magnitude of a scale spanning `span`.
fn tick(v: f64, span: f64) -> String {
    let decimals = (1.0 - span.abs().max(1e-300).log10().floor()).clamp(0.0, 12.0) as usize;
    format!("{v:.decimals$}")
}

/// A vertical colour bar from `lo` to `hi`, labelled with the unit.
fn draw_bar<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, img: &Image) -> DrawResult<DB> {
    let (lo, hi) = (img.lo, img.hi);
    let mut chart = ChartBuilder::on(area)
        .margin_top(28)
        .margin_bottom(36)
        .margin_right(10)
        .y_label_area_size(58)
        .build_cartesian_2d(0.0..1.0, lo..hi)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(img.unit.as_str())
        .y_labels(5)
        .y_label_formatter(&|v| tick(*v, hi - lo))
        .label_style(("sans-serif", 10))
        .draw()?;
    let steps = 64;
    let step = (hi - lo) / steps as f64;
    chart.draw_series((0..steps).map(|i| {
        let v = lo + (i as f64 + 0.5) * step;
        let y = lo + i as f64 * step;
        Rectangle::new(
            [(0.0, y), (1.0, y + step)],
            img.map.color((v - lo) / (hi - lo)).filled(),
        )
    }))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_maps_run_from_their_first_stop_to_their_last() {
        assert_eq!(Map::Sequential.color(0.0), RGBColor(68, 1, 84));
        assert_eq!(Map::Sequential.color(1.0), RGBColor(253, 231, 37));
        assert_eq!(Map::Diverging.color(0.5), RGBColor(247, 247, 247));
        assert_eq!(Map::Grey.color(2.0), RGBColor(0, 0, 0));
        assert_eq!(Map::Grey.color(f64::NAN), RGBColor(240, 240, 240));
    }

    #[test]
    fn long_signals_are_reduced_by_block_maxima_per_channel() {
        // 2500 frames of 2 channels: blocks of 3 frames, 834 columns
        let values: Vec<f64> = (0..5000)
            .map(|i| if i % 2 == 0 { -(i as f64) } else { 1.0 })
            .collect();
        let (cells, cols) = over_time(&values, 2500, 2, true);
        assert_eq!(cols, 834);
        assert_eq!(cells[0], 4.0); // |-(0)|, |-(2)|, |-(4)|: the largest of the first block
        assert_eq!(cells[cols], 1.0);
        assert_eq!(finite_range(&[f64::NAN, 2.0, -1.0]), (-1.0, 2.0));
        assert_eq!(finite_range(&[3.0, 3.0]), (2.5, 3.5));
    }

    #[test]
    fn the_envelope_keeps_each_columns_smallest_and_largest_value() {
        // 10 007 rows of 2 channels into 333 columns of 30 or 31 rows
        let mut values: Vec<f64> = (0..20_014).map(|i| ((i * 7919) % 1000) as f64).collect();
        values[2 * 5003 + 1] = 4e3; // a one-row peak
        values[2 * 17] = f64::NAN; // ignored beside the column's other values
        let (starts, lo, hi) = envelope(&values, 10_007, 2, 333);
        assert_eq!(starts.len(), 333);
        for (c, &start) in starts.iter().enumerate() {
            let end = starts.get(c + 1).copied().unwrap_or(10_007);
            assert!((30..=31).contains(&(end - start)));
            for ch in 0..2 {
                let column: Vec<f64> = (start..end)
                    .map(|r| values[2 * r + ch])
                    .filter(|v| v.is_finite())
                    .collect();
                let (l, h) = finite_range(&column);
                assert_eq!((lo[2 * c + ch], hi[2 * c + ch]), (l, h), "column {c}");
            }
        }
        assert_eq!(hi.iter().copied().fold(0.0, f64::max), 4e3);
        // no more rows than columns: each row its own column
        let (starts, lo, hi) = envelope(&values[..20], 10, 2, 333);
        assert_eq!(starts, (0..10).collect::<Vec<_>>());
        assert_eq!((&lo[2..], &hi[2..]), (&values[2..20], &values[2..20]));
    }

    /// `requests` on a 16-channel filterbank of 0.2 s of noise at 16 kHz.
    fn recorded(requests: &[&str]) -> Recorder {
        let x: Vec<f64> = (0..3200u64)
            .map(|i| ((i.wrapping_mul(2_654_435_761) % 1000) as f64 - 500.0) / 1e3)
            .collect();
        let job = afe::extract::Job {
            requests: requests.iter().map(|r| r.to_string()).collect(),
            params: [("fb_nChannels".to_string(), serde_json::json!(16))].into(),
            ..afe::extract::Job::default()
        };
        let mut mgr = afe::Manager::new(16000.0, 1).expect("a mono manager");
        afe::extract::run_with(&mut mgr, &job, &[&x]).expect("the run")
    }

    #[test]
    fn audio_rate_channels_are_stacked_waveforms_unless_images_are_asked() {
        let rec = recorded(&["innerhaircell", "ratemap"]);
        let layout = Layout::default();
        let [ihc, ratemap] = rec.signals() else {
            panic!("two signals")
        };
        match panel(ihc, &layout).expect("a panel").content {
            Content::Waves {
                x,
                traces,
                row_labels,
                reach,
            } => {
                // 3200 samples to 1000 columns, down and up each: 2000 points a trace
                assert_eq!((x.len(), traces.len(), reach), (2000, 16, 2.5));
                assert_eq!(row_labels[0], format!("{:.0}", ihc.info.cf_hz[0]));
                // channel k runs around height k, its largest value at most 2.5 away
                for (k, trace) in traces.iter().enumerate() {
                    assert!(trace.iter().all(|y| (y - k as f64).abs() <= 2.5 + 1e-9));
                }
                let farthest = traces
                    .iter()
                    .enumerate()
                    .flat_map(|(k, t)| t.iter().map(move |y| (y - k as f64).abs()))
                    .fold(0.0, f64::max);
                assert!((farthest - 2.5).abs() < 1e-9);
            }
            _ => panic!("the hair cell's output is not drawn as waveforms"),
        }
        assert!(matches!(
            panel(ratemap, &layout).expect("a panel").content,
            Content::Image(_)
        ));
        let images = Layout {
            waveforms: false,
            ..layout
        };
        match panel(ihc, &images).expect("a panel").content {
            Content::Image(img) => {
                assert_eq!((img.rows, img.unit.as_str()), (16, "dB (largest |value|)"));
                assert!((img.hi - img.lo - 60.0).abs() < 1e-9);
            }
            _ => panic!("no image of the hair cell's output"),
        }
        assert!(!render(&rec, Format::Png, &layout)
            .expect("a PNG")
            .is_empty());
    }

    #[test]
    fn bar_ticks_resolve_a_hundredth_of_their_scale() {
        assert_eq!(tick(-40.0, 60.0), "-40");
        assert_eq!(tick(0.0008, 0.0016), "0.0008");
        assert_eq!(tick(0.97, 0.04), "0.970");
    }

    #[test]
    fn the_bundled_font_parses() {
        assert!(register_font("afe-test", FontStyle::Normal, FONT).is_ok());
    }
}
