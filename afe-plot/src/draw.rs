//! The plotters drawing: the panels of the model ([`crate::panel`]) onto a PNG bitmap or
//! an SVG drawing, each with its axes and, for images, a colour bar.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

use crate::panel::{finite_range, Content, Image, Map, Panel};
use crate::{Format, PlotError};

/// The font for text in bitmaps (DejaVu Sans Mono, see `assets/fonts/LICENSE`).
static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSansMono.ttf");

/// The figure of `panels`, one above the other in a `width`-pixel column, each
/// `panel_height` pixels high, encoded as `format`.
pub(crate) fn figure(
    panels: &[Panel],
    format: Format,
    width: u32,
    panel_height: u32,
) -> Result<Vec<u8>, PlotError> {
    let (w, h) = (width, panel_height * panels.len() as u32);
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
                draw_all(&root, panels).map_err(failed)?;
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
                draw_all(&root, panels).map_err(failed)?;
                root.present().map_err(|e| failed(e.to_string()))?;
            }
            Ok(svg.into_bytes())
        }
    }
}

/// The colours of the model's scales.
impl Map {
    /// The colour at `u` along the scale, from 0 to 1 (clamped; `u` not finite: 0).
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
        } => draw_line(&main, &p.title, x, y, y_label, *stroke),
        Content::Waves {
            x,
            traces,
            row_labels,
            reach,
        } => draw_waves(&main, &p.title, x, traces, row_labels, *reach),
        Content::Image(img) => {
            draw_image(&main, &p.title, img)?;
            draw_bar(&bar, img)
        }
    }
}

/// A line over time, broken where its values are NaN.
fn draw_line<DB: DrawingBackend>(
    main: &DrawingArea<DB, Shift>,
    title: &str,
    x: &[f64],
    y: &[f64],
    y_label: &str,
    stroke: u32,
) -> DrawResult<DB> {
    let (x0, x1) = finite_range(x);
    let (y0, y1) = finite_range(y);
    let pad = 0.05 * (y1 - y0);
    let (y0, y1) = (y0 - pad, y1 + pad);
    let mut chart = ChartBuilder::on(main)
        .caption(title, ("sans-serif", 15))
        .margin(6)
        .x_label_area_size(32)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("time (s)")
        .y_desc(y_label)
        .label_style(("sans-serif", 11))
        .draw()?;
    // NaN values (unvoiced pitch) break the line
    let segments = x.iter().zip(y).map(|(a, b)| (*a, *b)).collect::<Vec<_>>();
    for run in segments.split(|(_, v)| !v.is_finite()) {
        if run.len() == 1 {
            chart.draw_series(std::iter::once(Circle::new(run[0], 2, BLUE.filled())))?;
        } else if !run.is_empty() {
            let style = BLUE.stroke_width(stroke);
            chart.draw_series(LineSeries::new(run.iter().copied(), style))?;
        }
    }
    Ok(())
}

/// Stacked waveforms, each channel's trace around its own line.
fn draw_waves<DB: DrawingBackend>(
    main: &DrawingArea<DB, Shift>,
    title: &str,
    x: &[f64],
    traces: &[Vec<f64>],
    row_labels: &[String],
    reach: f64,
) -> DrawResult<DB> {
    let (x0, x1) = finite_range(x);
    let rows = traces.len() as f64;
    let mut chart = ChartBuilder::on(main)
        .caption(title, ("sans-serif", 15))
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
        let points: Vec<(f64, f64)> = x.iter().copied().zip(trace.iter().copied()).collect();
        for run in points.split(|(_, v)| !v.is_finite()) {
            chart.draw_series(LineSeries::new(run.iter().copied(), BLUE.stroke_width(1)))?;
        }
    }
    Ok(())
}

/// An image, one rectangle a cell, on its colour scale (cells without a value in grey).
fn draw_image<DB: DrawingBackend>(
    main: &DrawingArea<DB, Shift>,
    title: &str,
    img: &Image,
) -> DrawResult<DB> {
    let (x0, x1) = if img.x.1 > img.x.0 {
        img.x
    } else {
        (img.x.0, img.x.0 + 1.0)
    };
    let rows = img.rows.max(1) as f64;
    let labels = &img.row_labels;
    let mut chart = ChartBuilder::on(main)
        .caption(title, ("sans-serif", 15))
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
