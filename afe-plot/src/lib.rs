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
//!
//! Each panel's model (what is drawn, on which scales and axes) is computed from the
//! signal's description in `panel`; `draw` renders the models with plotters.

mod draw;
mod panel;

use std::path::Path;

use afe::Recorder;

pub use panel::envelope;

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
        .map(|s| panel::panel(s, layout))
        .collect::<Result<Vec<_>, _>>()?;
    if panels.is_empty() {
        return Err(PlotError::Empty);
    }
    draw::figure(&panels, format, layout.width, layout.panel_height)
}
