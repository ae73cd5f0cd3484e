//! How an output is drawn, decided once from its description: the panel (waveforms, a
//! line, an image over time, or one frame as an image), its scale and its labelled axes.
//! `afe-plot`, `afe.plot` and the live page follow the plan as renderers; none of them
//! looks at a request's name or a signal's kind.

use serde::Serialize;

use crate::axis::Axis;
use crate::from_above::FromAbove;
use crate::signal_info::{DrawAs, SignalInfo, SignalKind};

/// Range in dB below the peak of spectra that give none of their own.
const SPECTRUM_RANGE_DB: f64 = 80.0;

/// The drawing plan of one signal (see [`SignalInfo::plan`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Plan {
    /// What the panel shows.
    pub panel: Panel,
    /// The scale the values are drawn on.
    pub scale: Scale,
    /// What runs up: an image's rows (over time, the frame's only axis; for a frame, its
    /// first axis) or the channels of stacked waveforms; `None` for lines.
    pub rows: Option<PlanAxis>,
    /// What runs across a frame's image (its second axis); `None` where time does.
    pub across: Option<PlanAxis>,
    /// The values' label (a colour bar's or a line's), with their unit.
    pub values: String,
    /// Whether an image over time keeps the largest magnitude of the samples each of its
    /// columns holds (audio-rate signals) rather than the largest value.
    pub peaks: bool,
    /// Whether each value is complex: drawn by its magnitude.
    pub complex: bool,
    /// For [`Panel::FromAbove`]: where a frame holds the sources and the head.
    pub from_above: Option<FromAbove>,
}

/// What a panel shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Panel {
    /// Audio-rate values over time: one line, or a channel's trace each, stacked; a
    /// renderer that does not stack draws them as [`Panel::OverTime`] on the plan's scale.
    Waveforms,
    /// The first value of each frame over time, as a line with gaps where it is NaN.
    Line,
    /// The frames over time as an image: time across, the rows up.
    OverTime,
    /// One frame (by default the middle one; live, the latest) as an image.
    Frame,
    /// Sources about a head seen from above (live, the latest frame), as the plan's
    /// [`FromAbove`] places them; over a whole signal, their azimuths over time.
    FromAbove,
}

/// The scale values are drawn on.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "scale", rename_all = "kebab-case")]
pub enum Scale {
    /// Smallest to largest value, on a sequential colour map.
    Linear,
    /// Centred on zero, on a diverging colour map.
    Signed,
    /// `10·log10(v)`, `range_db` below the peak.
    PowerDecibels {
        /// The range drawn below the peak, in dB.
        range_db: f64,
    },
    /// `20·log10|v|`, `range_db` below the peak.
    AmplitudeDecibels {
        /// The range drawn below the peak, in dB.
        range_db: f64,
    },
    /// 0 or 1, light grey to black.
    Mask,
    /// Each row on its own scale, as z-scores over time (rows of different quantities).
    ZScores,
    /// Sequential, or centred on zero where a value drawn is negative.
    Auto,
}

/// An axis as drawn: its title, the value at each index in the unit of the title (for
/// an image's extent) and a tick label for each index.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlanAxis {
    /// Title, with the unit drawn (`"lag (ms)"`).
    pub label: String,
    /// The value at each index in the unit of the title (the index itself for an axis
    /// of names).
    pub values: Vec<f64>,
    /// A label for each index.
    pub ticks: Vec<String>,
}

impl PlanAxis {
    /// `axis` as drawn: lags in ms, frequencies in whole Hz, names as they are.
    pub fn of(axis: &Axis) -> Self {
        if let Some(names) = axis.labels() {
            return PlanAxis {
                label: axis.quantity().to_string(),
                values: (0..names.len()).map(|k| k as f64).collect(),
                ticks: names.to_vec(),
            };
        }
        let (factor, unit) = match axis {
            Axis::Lags(_) => (1e3, "ms"),
            _ => (1.0, axis.unit()),
        };
        let values: Vec<f64> = axis
            .values()
            .unwrap_or_default()
            .iter()
            .map(|v| factor * v)
            .collect();
        let ticks = values.iter().map(|&v| tick(v, unit)).collect();
        PlanAxis {
            label: titled(axis.quantity(), unit),
            values,
            ticks,
        }
    }
}

/// `quantity (unit)`, or the quantity alone when it has no unit.
fn titled(quantity: &str, unit: &str) -> String {
    if unit.is_empty() {
        quantity.to_string()
    } else {
        format!("{quantity} ({unit})")
    }
}

/// A tick label: whole numbers of Hz and degrees, two decimals otherwise unless whole.
fn tick(v: f64, unit: &str) -> String {
    if matches!(unit, "Hz" | "deg") || v.fract() == 0.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.2}")
    }
}

impl SignalInfo {
    /// How the signal is drawn, from this description alone (see [`Plan`]).
    pub fn plan(&self) -> Plan {
        Plan::of(self)
    }
}

impl Plan {
    /// The plan of `info`: its axes decide the panel, its drawing the scale.
    pub fn of(info: &SignalInfo) -> Self {
        let audio_rate = info.fs_hz == info.audio_fs_hz;
        let plain = Plan {
            panel: Panel::OverTime,
            scale: Self::scale(info.display),
            rows: None,
            across: None,
            values: info.unit.to_string(),
            peaks: audio_rate,
            complex: info.is_complex(),
            from_above: None,
        };
        if let Some(scene) = info.from_above {
            return Plan {
                panel: Panel::FromAbove,
                values: titled("azimuth", "deg"),
                from_above: Some(scene),
                ..plain
            };
        }
        match info.axes.as_slice() {
            _ if info.display == DrawAs::Trajectory => Plan {
                panel: Panel::Line,
                values: match info.features().first() {
                    Some(first) => titled(first, info.unit),
                    None => info.unit.to_string(),
                },
                ..plain
            },
            [] => Plan {
                panel: Panel::Waveforms,
                values: "amplitude".to_string(),
                ..plain
            },
            [axis] => {
                let rows = Some(PlanAxis::of(axis));
                if info.is_complex() {
                    let range_db = info.display.range_db().unwrap_or(SPECTRUM_RANGE_DB);
                    Plan {
                        scale: Scale::AmplitudeDecibels { range_db },
                        values: "dB".to_string(),
                        rows,
                        ..plain
                    }
                } else if info.kind == SignalKind::BinaryMask {
                    Plan {
                        scale: Scale::Mask,
                        values: "mask".to_string(),
                        rows,
                        ..plain
                    }
                } else if axis.labels().is_some() {
                    Plan {
                        scale: Scale::ZScores,
                        values: "z-score".to_string(),
                        rows,
                        ..plain
                    }
                } else if audio_rate
                    && matches!(
                        info.display,
                        DrawAs::Linear | DrawAs::AmplitudeDecibels { .. }
                    )
                {
                    Plan {
                        panel: Panel::Waveforms,
                        rows,
                        ..plain
                    }
                } else {
                    Plan { rows, ..plain }
                }
            }
            [up, across, ..] => Plan {
                panel: Panel::Frame,
                scale: Scale::Auto,
                rows: Some(PlanAxis::of(up)),
                across: Some(PlanAxis::of(across)),
                peaks: false,
                ..plain
            },
        }
    }

    /// The scale of a drawing over time.
    fn scale(display: DrawAs) -> Scale {
        match display {
            DrawAs::Linear | DrawAs::Trajectory => Scale::Linear,
            DrawAs::Signed => Scale::Signed,
            DrawAs::PowerDecibels { range_db } => Scale::PowerDecibels { range_db },
            DrawAs::AmplitudeDecibels { range_db } => Scale::AmplitudeDecibels { range_db },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axis::OtherAxis;

    fn tf() -> SignalInfo {
        SignalInfo::time_frequency(16000.0, vec![100.0, 200.5])
    }

    #[test]
    fn audio_rate_channels_are_waveforms_and_framed_powers_an_image_in_db() {
        let ihc = tf().plan();
        assert_eq!(
            (ihc.panel, ihc.scale, ihc.peaks),
            (Panel::Waveforms, Scale::Linear, true)
        );
        let rows = ihc.rows.expect("channels up");
        assert_eq!(
            (rows.label.as_str(), &rows.ticks[..]),
            (
                "centre frequency (Hz)",
                &["100".to_string(), "200".to_string()][..]
            )
        );
        let rm = tf()
            .framed(100.0)
            .drawn_as(DrawAs::PowerDecibels { range_db: 60.0 })
            .plan();
        assert_eq!(
            (rm.panel, rm.scale, rm.peaks),
            (
                Panel::OverTime,
                Scale::PowerDecibels { range_db: 60.0 },
                false
            )
        );
        let td = SignalInfo::time_domain(16000.0).plan();
        assert_eq!((td.panel, td.rows), (Panel::Waveforms, None));
    }

    #[test]
    fn two_axes_draw_a_frame_whatever_they_are() {
        let cc = tf().correlation(100.0, vec![-0.001, 0.0, 0.001]).plan();
        assert_eq!((cc.panel, cc.scale), (Panel::Frame, Scale::Auto));
        let across = cc.across.expect("lags across");
        assert_eq!(
            (across.label.as_str(), across.values[0]),
            ("lag (ms)", -1.0)
        );
        let band = Axis::Other(OtherAxis {
            name: "band",
            quantity: "band",
            unit: "",
            values: vec![1.0, 2.0],
        });
        let custom = tf()
            .framed(10.0)
            .with_axes(SignalKind::TimeFrequency, [band])
            .plan();
        assert_eq!(custom.panel, Panel::Frame);
        assert_eq!(custom.across.expect("band across").ticks, ["1", "2"]);
    }

    #[test]
    fn masks_features_spectra_and_trajectories_have_their_scales() {
        let mask = SignalInfo {
            kind: SignalKind::BinaryMask,
            ..tf().framed(100.0)
        };
        assert_eq!(mask.plan().scale, Scale::Mask);
        let feats = SignalInfo::feature(100.0, 16000.0, vec!["a".into(), "b".into()]);
        let plan = feats.plan();
        assert_eq!((plan.panel, plan.scale), (Panel::OverTime, Scale::ZScores));
        assert_eq!(plan.rows.expect("features up").ticks, ["a", "b"]);
        let pitch = SignalInfo::feature(100.0, 16000.0, vec!["pitch".into()])
            .with_unit("Hz")
            .drawn_as(DrawAs::Trajectory)
            .plan();
        assert_eq!(
            (pitch.panel, pitch.values.as_str()),
            (Panel::Line, "pitch (Hz)")
        );
        let stft = SignalInfo {
            kind: SignalKind::Spectrum,
            axes: vec![Axis::Bins(vec![0.0, 8000.0])],
            ..tf().framed(100.0)
        };
        let plan = stft.plan();
        assert_eq!(
            (plan.scale, plan.complex),
            (
                Scale::AmplitudeDecibels {
                    range_db: SPECTRUM_RANGE_DB
                },
                true
            )
        );
        let v = serde_json::to_value(&plan).expect("serialisable");
        assert_eq!(
            (v["panel"].as_str(), v["scale"]["scale"].as_str()),
            (Some("over-time"), Some("amplitude-decibels"))
        );
    }

    #[test]
    fn sources_about_a_head_are_drawn_from_above_as_their_description_places_them() {
        let scene = FromAbove {
            slots: 2,
            slot_width: 3,
            id: 0,
            azimuth: 1,
            uncertainty: 2,
            resolved: 2,
            head_yaw: 6,
            suggested_yaw: 7,
        };
        let names = (0..8).map(|k| format!("v{k}")).collect();
        let plan = SignalInfo::feature(50.0, 16000.0, names)
            .drawn_from_above(scene)
            .plan();
        assert_eq!(
            (plan.panel, plan.from_above, plan.values.as_str()),
            (Panel::FromAbove, Some(scene), "azimuth (deg)")
        );
        let v = serde_json::to_value(&plan).expect("serialisable");
        assert_eq!(v["panel"], "from-above");
        assert_eq!(v["from_above"]["head_yaw"], 6);
        let plain = serde_json::to_value(tf().plan()).expect("serialisable");
        assert!(plain["from_above"].is_null());
    }
}
