//! The panel model: what each signal's panel shows, following the drawing plan its own
//! description gives ([`afe_core::Plan`]) — lines, stacked waveforms or images, with
//! their axes, labels and colour scales — and nothing of how it is drawn.

use afe::Recorded;
use afe_core::{Panel as Shows, Plan, PlanAxis, Scale};

use crate::{Layout, PlotError};

/// The AFE's `wavPlotZoom` default: the largest magnitude of a stacked waveform lies half
/// this many channel spacings from its channel's line.
const WAV_PLOT_ZOOM: f64 = 5.0;

/// Longest image axis drawn, in cells: longer signals are reduced by block maxima.
const MAX_COLUMNS: usize = 1000;

/// A colour scale (its colours are the drawing's: `draw`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Map {
    /// Dark blue to yellow, for magnitudes.
    Sequential,
    /// Blue, white, red around zero, for signed cues.
    Diverging,
    /// Light grey to black, for binary masks.
    Grey,
}

/// An image panel: `rows × cols` values, row `r` drawn at height `r` (bottom up).
#[derive(Debug, Clone)]
pub(crate) struct Image {
    pub(crate) values: Vec<f64>,
    pub(crate) rows: usize,
    pub(crate) cols: usize,
    /// The horizontal extent of the columns.
    pub(crate) x: (f64, f64),
    pub(crate) x_label: String,
    /// Label of each row (centre frequencies, feature names), shown for a few rows.
    pub(crate) row_labels: Vec<String>,
    pub(crate) y_label: String,
    pub(crate) lo: f64,
    pub(crate) hi: f64,
    pub(crate) map: Map,
    pub(crate) unit: String,
}

/// One panel's content.
#[derive(Debug, Clone)]
pub(crate) enum Content {
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
pub(crate) struct Panel {
    pub(crate) title: String,
    pub(crate) content: Content,
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

/// The channels of an audio-rate signal as the AFE's `waveplot` stacks them: each
/// channel brought to zero mean and unit variance, all on one scale on which the largest
/// magnitude lies `WAV_PLOT_ZOOM / 2` channel spacings from its channel's line; each trace
/// runs down and up every pixel column, from its smallest value to its largest.
fn stacked(s: &Recorded, rows: &PlanAxis, columns: usize) -> Content {
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
        row_labels: row_labels(rows, width),
        reach: 0.5 * WAV_PLOT_ZOOM,
    }
}

/// The tick label of each of `width` rows: the axis's, or row numbers where it has
/// another length.
fn row_labels(rows: &PlanAxis, width: usize) -> Vec<String> {
    if rows.ticks.len() == width {
        rows.ticks.clone()
    } else {
        (0..width).map(|c| c.to_string()).collect()
    }
}

pub(crate) fn finite_range(values: &[f64]) -> (f64, f64) {
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

/// What to draw for signal `s`: its plan ([`afe_core::Plan`]), followed.
pub(crate) fn panel(s: &Recorded, layout: &Layout) -> Result<Panel, PlotError> {
    let plan = s.info.plan();
    let columns = layout.width as usize;
    let content = match (plan.panel, &plan.rows) {
        (Shows::Waveforms, None) => waveform_line(s, columns),
        (Shows::Waveforms, Some(rows)) if layout.waveforms && s.data.frames() > 0 => {
            stacked(s, rows, columns)
        }
        (Shows::Waveforms | Shows::OverTime, _) => image_over_time(s, &plan),
        (Shows::Line, _) => trajectory(s, &plan),
        (Shows::FromAbove, _) => match plan.from_above {
            Some(scene) => azimuths_over_time(s, scene),
            None => image_over_time(s, &plan),
        },
        (Shows::Frame, _) => {
            let (k, when) = frame_at(s, layout.at_s)?;
            return Ok(Panel {
                title: format!("{} at {when:.3} s", s.key),
                content: frame_image(s, &plan, k),
            });
        }
    };
    Ok(Panel {
        title: s.key.clone(),
        content,
    })
}

/// A single-channel waveform as a line, reduced to the minimum and maximum of each of at
/// most `columns` columns ([`envelope`]), running down and up each column.
fn waveform_line(s: &Recorded, columns: usize) -> Content {
    let values = s.data.as_slice();
    let t: Vec<f64> = times(s).collect();
    let (starts, lo, hi) = envelope(values, values.len(), 1, columns);
    let x = starts.iter().flat_map(|&k| [t[k], t[k]]).collect();
    let y = lo.iter().zip(&hi).flat_map(|(l, h)| [*l, *h]).collect();
    Content::Line {
        x,
        y,
        y_label: "amplitude".into(),
        stroke: 1,
    }
}

/// The values' label of `plan`, `value` where it has none.
fn values_label(plan: &Plan) -> String {
    if plan.values.is_empty() {
        "value".to_string()
    } else {
        plan.values.clone()
    }
}

/// A signal over time and its rows as an image on its plan's scale, reduced to at most
/// [`MAX_COLUMNS`] columns (audio-rate signals by their largest magnitudes); complex
/// values by their magnitudes.
fn image_over_time(s: &Recorded, plan: &Plan) -> Content {
    let frames = s.data.frames();
    let mut values = if plan.complex {
        (s.data.as_slice().chunks_exact(2))
            .map(|z| z[0].hypot(z[1]))
            .collect()
    } else {
        s.data.as_slice().to_vec()
    };
    let width = values.len().checked_div(frames).unwrap_or(s.info.width());
    if plan.scale == Scale::ZScores {
        z_scores(&mut values, frames, width);
    }
    let peaks = plan.peaks && frames > MAX_COLUMNS;
    let (mut cells, cols) = over_time(&values, frames, width, peaks);
    let (lo, hi, map, unit) = over_time_scale(plan, &mut cells, peaks);
    let rows = plan.rows.as_ref();
    Content::Image(Image {
        values: cells,
        rows: width,
        cols,
        x: span(s),
        x_label: "time (s)".to_string(),
        row_labels: rows.map_or_else(Vec::new, |r| row_labels(r, width)),
        y_label: rows.map_or_else(String::new, |r| r.label.clone()),
        lo,
        hi,
        map,
        unit,
    })
}

/// The colour scale of [`image_over_time`]'s `cells` as `(lo, hi, map, unit)`, the cells
/// brought to dB where the plan's scale is in dB; `peaks` says the cells are largest
/// magnitudes.
fn over_time_scale(plan: &Plan, cells: &mut [f64], peaks: bool) -> (f64, f64, Map, String) {
    let unit = values_label(plan);
    match plan.scale {
        Scale::AmplitudeDecibels { range_db } => {
            cells
                .iter_mut()
                .for_each(|v| *v = 20.0 * v.abs().max(1e-300).log10());
            let peak = finite_range(cells).1;
            let unit = if peaks {
                "dB (largest |value|)".to_string()
            } else {
                "dB".to_string()
            };
            (peak - range_db, peak, Map::Sequential, unit)
        }
        Scale::PowerDecibels { range_db } => {
            cells
                .iter_mut()
                .for_each(|v| *v = 10.0 * v.max(1e-30).log10());
            let peak = finite_range(cells).1;
            (peak - range_db, peak, Map::Sequential, "dB".to_string())
        }
        Scale::Mask => (0.0, 1.0, Map::Grey, unit),
        Scale::Signed | Scale::ZScores => {
            let (lo, hi) = symmetric(cells);
            (lo, hi, Map::Diverging, unit)
        }
        Scale::Linear | Scale::Auto => {
            let (lo, hi) = finite_range(cells);
            let unit = if peaks {
                format!("largest |value| {unit}")
            } else {
                unit
            };
            (lo, hi, Map::Sequential, unit)
        }
    }
}

/// Each of the `width` columns of `frames` rows (row-major) brought to z-scores over
/// time, on its own scale: rows of different quantities (features) side by side.
fn z_scores(values: &mut [f64], frames: usize, width: usize) {
    for f in 0..width {
        let col: Vec<f64> = (0..frames)
            .map(|k| values[k * width + f])
            .filter(|v| v.is_finite())
            .collect();
        let n = col.len().max(1) as f64;
        let mean = col.iter().sum::<f64>() / n;
        let sd = (col.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
        for k in 0..frames {
            let v = &mut values[k * width + f];
            *v = (*v - mean) / if sd > 0.0 { sd } else { 1.0 };
        }
    }
}

/// The first value of each frame over time, as a line.
fn trajectory(s: &Recorded, plan: &Plan) -> Content {
    Content::Line {
        x: times(s).collect(),
        y: s.data
            .as_slice()
            .chunks_exact(s.data.width().max(1))
            .map(|row| row[0])
            .collect(),
        stroke: 2,
        y_label: if plan.values.is_empty() {
            s.key.clone()
        } else {
            plan.values.clone()
        },
    }
}

/// Every tracked source's azimuth over time as dots: each a run of its own between NaN
/// gaps, which the line drawing marks with a dot.
fn azimuths_over_time(s: &Recorded, scene: afe_core::FromAbove) -> Content {
    let (mut x, mut y) = (Vec::new(), Vec::new());
    let width = s.data.width().max(1);
    for (t, row) in times(s).zip(s.data.as_slice().chunks_exact(width)) {
        for slot in row.chunks_exact(scene.slot_width).take(scene.slots) {
            if slot[scene.azimuth].is_finite() {
                x.extend([t, t]);
                y.extend([slot[scene.azimuth], f64::NAN]);
            }
        }
    }
    Content::Line {
        x,
        y,
        stroke: 2,
        y_label: "azimuth (deg)".into(),
    }
}

/// Frame `k` as an image, its plan's first axis up and second across, on a diverging
/// scale where it holds negative values.
fn frame_image(s: &Recorded, plan: &Plan, k: usize) -> Content {
    let width = s.data.width();
    let frame = &s.data.as_slice()[k * width..(k + 1) * width];
    let (up, across) = (plan.rows.as_ref(), plan.across.as_ref());
    let rows = up.map_or(1, |a| a.values.len()).max(1);
    let extent = |a: &PlanAxis| match (a.values.first(), a.values.last()) {
        (Some(&first), Some(&last)) => (first, last),
        _ => (0.0, 1.0),
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
        cols: width / rows,
        x: across.map_or((0.0, 1.0), extent),
        x_label: across.map_or_else(String::new, |a| a.label.clone()),
        row_labels: up.map_or_else(Vec::new, |a| row_labels(a, rows)),
        y_label: up.map_or_else(String::new, |a| a.label.clone()),
        lo,
        hi,
        map,
        unit: values_label(plan),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{render, Format};
    use afe::Recorder;

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
                assert_eq!(row_labels[0], format!("{:.0}", ihc.info.cf_hz()[0]));
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
}
