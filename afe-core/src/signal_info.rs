//! The description of the signal a processor output carries: its layout, rates, axes,
//! unit, framing window, scale and where it is NaN.

use serde::{Deserialize, Serialize};

use crate::axis::Axis;
use crate::from_above::FromAbove;

/// What a signal's frames contain (the AFE's signal classes, spec 00-overview §7); the
/// axes of a frame are the description's own ([`SignalInfo::axes`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SignalKind {
    /// One value per sample: `[time]`.
    #[default]
    TimeDomain,
    /// One value per frequency channel: `[time_or_frame, channel]`.
    TimeFrequency,
    /// One value per channel and lag: `[frame, channel, lag]`.
    Correlation,
    /// One value per channel and modulation channel: `[frame, channel, modulation]`.
    Modulation,
    /// Named features: `[frame, feature]`.
    Feature,
    /// A complex spectrum: `[frame, bin]`, each value stored as a (real, imaginary) pair.
    Spectrum,
    /// A 0/1 value per channel: `[frame, channel]`.
    BinaryMask,
    /// A 2-D histogram per block of frames over attenuation and delay bins (DUET):
    /// `[frame, alpha, delta]`.
    DuetHistogram,
}

impl SignalKind {
    /// The AFE's name of the signal class (`TimeFrequencySignal`, ...).
    pub fn afe_class(self) -> &'static str {
        match self {
            SignalKind::TimeDomain => "TimeDomainSignal",
            SignalKind::TimeFrequency => "TimeFrequencySignal",
            SignalKind::Correlation => "CorrelationSignal",
            SignalKind::Modulation => "ModulationSignal",
            SignalKind::Feature => "FeatureSignal",
            SignalKind::Spectrum => "STFTSignal",
            SignalKind::BinaryMask => "BinaryMask",
            SignalKind::DuetHistogram => "DuetHistogramSignal",
        }
    }

    /// Name of the outermost array axis: `time` for time-domain signals,
    /// `time_or_frame` for time-frequency ones (sample-rate or framed), `frame` otherwise.
    pub fn time_axis(self) -> &'static str {
        match self {
            SignalKind::TimeDomain => "time",
            SignalKind::TimeFrequency => "time_or_frame",
            _ => "frame",
        }
    }
}

/// How a signal's values are best drawn, so that plots and views need not know the
/// request that made it. [`SignalKind`] and the axes give the layout; this gives the
/// scale.
///
/// Its serde form is tagged by `draw` with the names of [`DrawAs::as_str`], e.g.
/// `{"draw": "power-decibels", "range_db": 60.0}`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "draw", rename_all = "kebab-case")]
pub enum DrawAs {
    /// Values on a linear sequential scale from their smallest to their largest.
    #[default]
    Linear,
    /// Signed values (cues such as ILD and ITD), on a diverging scale centred on zero.
    Signed,
    /// Powers (ratemap): drawn as `10·log10(v)` over `range_db` decibels below the
    /// peak.
    PowerDecibels {
        /// The range drawn below the peak, in dB.
        range_db: f64,
    },
    /// Amplitudes of a wide dynamic range (waveforms, envelopes, spectrum magnitudes):
    /// a live view draws `20·log10|v|` over `range_db` decibels below its running peak;
    /// a figure of the whole signal draws them linearly (spectra in dB over the range).
    AmplitudeDecibels {
        /// The range drawn below the peak, in dB.
        range_db: f64,
    },
    /// One value per frame drawn as a line over time, NaN values being gaps (pitch).
    Trajectory,
}

impl DrawAs {
    /// The name of the drawing, as in its serde form: `linear`, `signed`,
    /// `power-decibels`, `amplitude-decibels` or `trajectory`.
    pub fn as_str(self) -> &'static str {
        match self {
            DrawAs::Linear => "linear",
            DrawAs::Signed => "signed",
            DrawAs::PowerDecibels { .. } => "power-decibels",
            DrawAs::AmplitudeDecibels { .. } => "amplitude-decibels",
            DrawAs::Trajectory => "trajectory",
        }
    }

    /// The range in dB below the peak of a drawing in decibels, `None` otherwise.
    pub fn range_db(self) -> Option<f64> {
        match self {
            DrawAs::PowerDecibels { range_db } | DrawAs::AmplitudeDecibels { range_db } => {
                Some(range_db)
            }
            DrawAs::Linear | DrawAs::Signed | DrawAs::Trajectory => None,
        }
    }
}

/// Static description of a processor output: kind, rate, the axes of a frame with the
/// value at each index, and the facts a consumer needs to label and draw it (unit,
/// framing window, scale, where it is NaN).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SignalInfo {
    /// What the frames contain.
    pub kind: SignalKind,
    /// Nominal rate of the output in Hz (`fs` for full-rate signals, `1/hop` for framed ones).
    pub fs_hz: f64,
    /// The axes of one frame, outermost first (none for a time-domain signal): a frame
    /// holds the product of their lengths values (twice that for a complex spectrum).
    pub axes: Vec<Axis>,
    /// Rate in Hz of the audio this signal was computed from (equal to `fs_hz` for
    /// full-rate signals; framed signals keep the rate their frames were cut at).
    pub audio_fs_hz: f64,
    /// Whether this output is fed back to a processor lower in the chain (the MOC's
    /// gains for the DRNL) rather than being a signal of its own: it is not listed
    /// among a graph's signals.
    pub feedback: bool,
    /// The signal's own name when a processor has several outputs of different kinds,
    /// e.g. `precedence_itd`; `None` names it after the request.
    pub name: Option<&'static str>,
    /// Unit of the values (`"dB"`, `"s"`, `"Hz"`, ...), `""` when dimensionless or when
    /// the AFE gives none.
    pub unit: &'static str,
    /// Length in seconds of the window each frame was cut with (from the processor that
    /// cut them, e.g. `rm_wSizeSec`; signals derived from framed ones keep it); `None`
    /// for sample-rate signals.
    pub window_s: Option<f64>,
    /// How the values are best drawn.
    pub display: DrawAs,
    /// Where the values are NaN from finite input, as the AFE's are (docs/conformance.md),
    /// in a sentence a reader of the metadata sees; `None` where they never are.
    pub nan_where: Option<&'static str>,
    /// For sources tracked about a head: where a frame holds them, drawn from above
    /// ([`crate::plan::Panel::FromAbove`]); `None` otherwise.
    pub from_above: Option<FromAbove>,
}

impl SignalInfo {
    /// A time-domain signal at `fs_hz`.
    pub fn time_domain(fs_hz: f64) -> Self {
        SignalInfo {
            fs_hz,
            audio_fs_hz: fs_hz,
            ..SignalInfo::default()
        }
    }

    /// A full-rate time-frequency signal at `fs_hz` with the given centre frequencies.
    pub fn time_frequency(fs_hz: f64, cf_hz: Vec<f64>) -> Self {
        SignalInfo {
            kind: SignalKind::TimeFrequency,
            fs_hz,
            axes: vec![Axis::Channels(cf_hz)],
            audio_fs_hz: fs_hz,
            ..SignalInfo::default()
        }
    }

    /// The same channels framed at nominal rate `frame_rate_hz` (audio rate and framing
    /// window kept: a processor that cuts frames of its own sets its window with
    /// [`SignalInfo::with_window_s`]); unit and drawing start from the defaults.
    pub fn framed(&self, frame_rate_hz: f64) -> Self {
        SignalInfo {
            kind: SignalKind::TimeFrequency,
            fs_hz: frame_rate_hz,
            axes: vec![Axis::Channels(self.cf_hz().to_vec())],
            audio_fs_hz: self.audio_fs_hz,
            window_s: self.window_s,
            ..SignalInfo::default()
        }
    }

    /// The same channels as a correlation over `lags_s` (seconds) at `frame_rate_hz`.
    pub fn correlation(&self, frame_rate_hz: f64, lags_s: Vec<f64>) -> Self {
        self.framed(frame_rate_hz)
            .with_axes(SignalKind::Correlation, [Axis::Lags(lags_s)])
    }

    /// Named features at `frame_rate_hz`, computed from audio at `audio_fs_hz`.
    pub fn feature(frame_rate_hz: f64, audio_fs_hz: f64, features: Vec<String>) -> Self {
        SignalInfo {
            kind: SignalKind::Feature,
            fs_hz: frame_rate_hz,
            axes: vec![Axis::Features(features)],
            audio_fs_hz,
            ..SignalInfo::default()
        }
    }

    /// The same signal as a `kind` whose frames have `more` axes inside the ones it has.
    pub fn with_axes(mut self, kind: SignalKind, more: impl IntoIterator<Item = Axis>) -> Self {
        self.kind = kind;
        self.axes.extend(more);
        self
    }

    /// The same signal under its own name `name` (see [`SignalInfo::name`]).
    pub fn named(self, name: &'static str) -> Self {
        SignalInfo {
            name: Some(name),
            ..self
        }
    }

    /// The same signal, NaN where `nan_where` says (see [`SignalInfo::nan_where`]).
    pub fn nan_where(self, nan_where: &'static str) -> Self {
        SignalInfo {
            nan_where: Some(nan_where),
            ..self
        }
    }

    /// The same signal with values in `unit` (see [`SignalInfo::unit`]).
    pub fn with_unit(self, unit: &'static str) -> Self {
        SignalInfo { unit, ..self }
    }

    /// The same signal cut into frames with a window of `window_s` seconds.
    pub fn with_window_s(self, window_s: f64) -> Self {
        SignalInfo {
            window_s: Some(window_s),
            ..self
        }
    }

    /// The same signal, drawn as `display`.
    pub fn drawn_as(self, display: DrawAs) -> Self {
        SignalInfo { display, ..self }
    }

    /// The same signal drawn from above as sources about a head, laid out as `scene`.
    pub fn drawn_from_above(self, scene: FromAbove) -> Self {
        SignalInfo {
            from_above: Some(scene),
            ..self
        }
    }

    /// Seconds between frames of a framed signal (`1 / fs_hz`), `None` for sample-rate
    /// signals (whose rate is the audio's).
    pub fn hop_s(&self) -> Option<f64> {
        (self.fs_hz != self.audio_fs_hz).then(|| 1.0 / self.fs_hz)
    }

    /// The values of the first axis `pick` accepts, empty where there is none.
    fn values_of(&self, pick: impl Fn(&Axis) -> Option<&Vec<f64>>) -> &[f64] {
        self.axes.iter().find_map(pick).map_or(&[], Vec::as_slice)
    }

    /// Centre frequency of each channel in Hz; for a spectrum, the frequency of each
    /// bin (empty when the frames have neither).
    pub fn cf_hz(&self) -> &[f64] {
        self.values_of(|a| match a {
            Axis::Channels(v) | Axis::Bins(v) => Some(v),
            _ => None,
        })
    }

    /// Lag of each correlation column in s (empty without a lag axis).
    pub fn lags_s(&self) -> &[f64] {
        self.values_of(|a| match a {
            Axis::Lags(v) => Some(v),
            _ => None,
        })
    }

    /// Centre frequency of each modulation channel in Hz (empty without one).
    pub fn mod_cf_hz(&self) -> &[f64] {
        self.values_of(|a| match a {
            Axis::Modulation(v) => Some(v),
            _ => None,
        })
    }

    /// Name of each feature column, in output order (empty without a feature axis).
    pub fn features(&self) -> &[String] {
        self.axes.iter().find_map(Axis::labels).unwrap_or_default()
    }

    /// The frame's axis named `name` (see [`Axis::name`]), if it has one.
    pub fn axis(&self, name: &str) -> Option<&Axis> {
        self.axes.iter().find(|a| a.name() == name)
    }

    /// Number of frequency channels (1 for a time-domain signal, 0 for frames without
    /// a channel or bin axis, such as features and histograms).
    pub fn channels(&self) -> usize {
        match self.kind {
            SignalKind::TimeDomain => 1,
            _ => self.cf_hz().len(),
        }
    }

    /// Whether the values are complex ((real, imaginary) pairs in the block).
    pub fn is_complex(&self) -> bool {
        self.kind == SignalKind::Spectrum
    }

    /// Number of `f64` values in one frame (one row of the time-major block).
    pub fn width(&self) -> usize {
        let values: usize = self.axes.iter().map(Axis::len).product();
        if self.is_complex() {
            2 * values
        } else {
            values
        }
    }

    /// The shape of one frame as array dimensions (`[]`, `[channels]`, `[channels, lags]`,
    /// ...); a complex value counts as one element.
    pub fn frame_shape(&self) -> Vec<usize> {
        self.axes.iter().map(Axis::len).collect()
    }

    /// Names of the array axes, outermost first: time (or frame), then the frame's.
    pub fn axis_names(&self) -> Vec<&'static str> {
        std::iter::once(self.kind.time_axis())
            .chain(self.axes.iter().map(Axis::name))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constructors_set_the_kind_the_rates_and_the_axes() {
        let t = SignalInfo::time_domain(16000.0);
        assert_eq!(
            (t.kind, t.fs_hz, t.audio_fs_hz),
            (SignalKind::TimeDomain, 16000.0, 16000.0)
        );
        assert_eq!((t.width(), t.channels(), t.frame_shape()), (1, 1, vec![]));
        let tf = SignalInfo::time_frequency(16000.0, vec![100.0, 200.0, 400.0]);
        assert_eq!(
            (tf.kind, tf.fs_hz, tf.audio_fs_hz),
            (SignalKind::TimeFrequency, 16000.0, 16000.0)
        );
        assert_eq!(
            (tf.width(), tf.channels(), tf.frame_shape()),
            (3, 3, vec![3])
        );
        let framed = tf.clone().named("x").framed(100.0);
        assert_eq!(
            (framed.fs_hz, framed.audio_fs_hz, framed.name),
            (100.0, 16000.0, None)
        );
        assert_eq!(
            (framed.kind, framed.cf_hz()),
            (SignalKind::TimeFrequency, tf.cf_hz())
        );
        let named = tf.named("precedence_itd");
        assert_eq!((named.name, named.fs_hz), (Some("precedence_itd"), 16000.0));
        let f = SignalInfo::feature(50.0, 44100.0, vec!["a".into()]);
        assert_eq!(
            (f.kind, f.fs_hz, f.audio_fs_hz, f.features()),
            (SignalKind::Feature, 50.0, 44100.0, &["a".to_string()][..])
        );
        let mask = SignalInfo {
            kind: SignalKind::BinaryMask,
            ..framed.clone()
        };
        assert_eq!(
            (mask.width(), mask.channels(), mask.frame_shape()),
            (3, 3, vec![3])
        );
        assert!(!mask.is_complex());
        let spectrum = SignalInfo {
            kind: SignalKind::Spectrum,
            axes: vec![Axis::Bins(vec![0.0, 100.0, 200.0])],
            ..framed.clone()
        };
        assert_eq!((spectrum.width(), spectrum.frame_shape()), (6, vec![3]));
        assert_eq!(spectrum.cf_hz(), [0.0, 100.0, 200.0]);
        // features and histograms have no channels
        assert_eq!(f.channels(), 0);
        let classes = [
            (SignalKind::TimeDomain, "TimeDomainSignal", "time"),
            (
                SignalKind::TimeFrequency,
                "TimeFrequencySignal",
                "time_or_frame",
            ),
            (SignalKind::Correlation, "CorrelationSignal", "frame"),
            (SignalKind::Modulation, "ModulationSignal", "frame"),
            (SignalKind::Feature, "FeatureSignal", "frame"),
            (SignalKind::Spectrum, "STFTSignal", "frame"),
            (SignalKind::BinaryMask, "BinaryMask", "frame"),
            (SignalKind::DuetHistogram, "DuetHistogramSignal", "frame"),
        ];
        for (kind, class, time) in classes {
            assert_eq!((kind.afe_class(), kind.time_axis()), (class, time));
        }
    }

    /// The serde tag of each drawing is its `as_str` name, and the dB range rides along.
    #[test]
    fn drawings_name_themselves_as_serde_does() {
        let all = [
            DrawAs::Linear,
            DrawAs::Signed,
            DrawAs::PowerDecibels { range_db: 60.0 },
            DrawAs::AmplitudeDecibels { range_db: 80.0 },
            DrawAs::Trajectory,
        ];
        for d in all {
            let v = serde_json::to_value(d).expect("serialisable");
            assert_eq!(v["draw"], d.as_str(), "{d:?}");
            assert_eq!(v.get("range_db").and_then(|r| r.as_f64()), d.range_db());
            assert_eq!(serde_json::from_value::<DrawAs>(v).expect("read back"), d);
        }
        assert_eq!(SignalInfo::default().display, DrawAs::Linear);
    }

    /// Framing keeps the window the frames were cut with; unit and drawing belong to
    /// each new signal.
    #[test]
    fn framing_keeps_the_window_and_resets_unit_and_drawing() {
        let tf = SignalInfo::time_frequency(16000.0, vec![100.0]);
        assert_eq!((tf.window_s, tf.hop_s(), tf.unit), (None, None, ""));
        let rm = tf
            .framed(100.0)
            .with_window_s(0.02)
            .with_unit("dB")
            .drawn_as(DrawAs::Signed);
        assert_eq!((rm.window_s, rm.hop_s()), (Some(0.02), Some(0.01)));
        let derived = rm.correlation(100.0, vec![0.0]);
        assert_eq!(
            (derived.window_s, derived.unit, derived.display),
            (Some(0.02), "", DrawAs::Linear)
        );
    }

    #[test]
    fn widths_shapes_and_axis_names_follow_the_axes() {
        let tf = SignalInfo::time_frequency(1000.0, vec![100.0, 200.0]);
        let cc = tf.correlation(100.0, vec![-1.0, 0.0, 1.0]);
        assert_eq!((cc.width(), cc.frame_shape()), (6, vec![2, 3]));
        assert_eq!(
            (cc.audio_fs_hz, cc.lags_s()),
            (1000.0, &[-1.0, 0.0, 1.0][..])
        );
        assert_eq!(cc.axis_names(), ["frame", "channel", "lag"]);
        let ams = tf.framed(100.0).with_axes(
            SignalKind::Modulation,
            [Axis::Modulation(vec![4.0, 8.0, 16.0])],
        );
        assert_eq!((ams.width(), ams.frame_shape()), (6, vec![2, 3]));
        assert_eq!(ams.mod_cf_hz(), [4.0, 8.0, 16.0]);
        let pitch = SignalInfo::feature(100.0, 1000.0, vec!["pitch".into(), "rawPitch".into()]);
        assert_eq!((pitch.width(), pitch.channels()), (2, 0));
        assert_eq!(pitch.axis_names(), ["frame", "feature"]);
        let duet = SignalInfo {
            kind: SignalKind::DuetHistogram,
            axes: vec![
                Axis::Attenuation(vec![-0.5, 0.0, 0.5]),
                Axis::Delay(vec![-1.0, -0.5, 0.0, 0.5, 1.0]),
            ],
            ..SignalInfo::default()
        };
        assert_eq!((duet.width(), duet.frame_shape()), (15, vec![3, 5]));
        assert_eq!(
            (duet.channels(), duet.axis_names()),
            (0, vec!["frame", "alpha", "delta"])
        );
        assert_eq!(SignalInfo::time_domain(8000.0).axis_names(), ["time"]);
    }
}
