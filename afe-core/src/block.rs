//! Time-major sample blocks and the description of the signal they carry.

use serde::{Deserialize, Serialize};

use crate::huge_pages;

/// What a signal's frames contain, which fixes its array layout (the AFE's signal
/// classes, spec 00-overview §7).
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

    /// Names of the array axes, outermost first (`time` or `frame` first).
    pub fn axes(self) -> &'static [&'static str] {
        match self {
            SignalKind::TimeDomain => &["time"],
            SignalKind::TimeFrequency => &["time_or_frame", "channel"],
            SignalKind::Correlation => &["frame", "channel", "lag"],
            SignalKind::Modulation => &["frame", "channel", "modulation"],
            SignalKind::Feature => &["frame", "feature"],
            SignalKind::Spectrum => &["frame", "bin"],
            SignalKind::BinaryMask => &["frame", "channel"],
            SignalKind::DuetHistogram => &["frame", "alpha", "delta"],
        }
    }
}

/// How a signal's values are best drawn, so that plots and views need not know the
/// request that made it. [`SignalKind`] gives the layout; this gives the scale.
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

/// Static description of a processor output: kind, rate, the values along each axis,
/// and the facts a consumer needs to label and draw it (unit, framing window, scale).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SignalInfo {
    /// Layout of one frame.
    pub kind: SignalKind,
    /// Nominal rate of the output in Hz (`fs` for full-rate signals, `1/hop` for framed ones).
    pub fs_hz: f64,
    /// Centre frequency of each channel in Hz (empty for time-domain and feature
    /// signals); for a spectrum, the frequency of each bin.
    pub cf_hz: Vec<f64>,
    /// Lag of each correlation column in seconds (empty unless `kind` is `Correlation`).
    pub lags_s: Vec<f64>,
    /// Centre frequency of each modulation channel in Hz (empty unless `kind` is
    /// `Modulation`).
    pub mod_cf_hz: Vec<f64>,
    /// Name of each feature column, in output order (empty unless `kind` is `Feature`).
    pub features: Vec<String>,
    /// Centre of each attenuation bin, `|ρ| − 1/|ρ|` for the ear ratio `ρ` (empty
    /// unless `kind` is `DuetHistogram`).
    pub alpha: Vec<f64>,
    /// Centre of each delay bin in samples at `audio_fs_hz` (empty unless `kind` is
    /// `DuetHistogram`).
    pub delta_samples: Vec<f64>,
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
            cf_hz,
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
            cf_hz: self.cf_hz.clone(),
            audio_fs_hz: self.audio_fs_hz,
            window_s: self.window_s,
            ..SignalInfo::default()
        }
    }

    /// The same channels as a correlation over `lags_s` (seconds) at `frame_rate_hz`.
    pub fn correlation(&self, frame_rate_hz: f64, lags_s: Vec<f64>) -> Self {
        SignalInfo {
            kind: SignalKind::Correlation,
            lags_s,
            ..self.framed(frame_rate_hz)
        }
    }

    /// Named features at `frame_rate_hz`, computed from audio at `audio_fs_hz`.
    pub fn feature(frame_rate_hz: f64, audio_fs_hz: f64, features: Vec<String>) -> Self {
        SignalInfo {
            kind: SignalKind::Feature,
            fs_hz: frame_rate_hz,
            features,
            audio_fs_hz,
            ..SignalInfo::default()
        }
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

    /// Seconds between frames of a framed signal (`1 / fs_hz`), `None` for sample-rate
    /// signals (whose rate is the audio's).
    pub fn hop_s(&self) -> Option<f64> {
        (self.fs_hz != self.audio_fs_hz).then(|| 1.0 / self.fs_hz)
    }

    /// Number of frequency channels (1 for a time-domain signal, 0 for features and
    /// histograms).
    pub fn channels(&self) -> usize {
        match self.kind {
            SignalKind::TimeDomain => 1,
            SignalKind::Feature | SignalKind::DuetHistogram => 0,
            _ => self.cf_hz.len(),
        }
    }

    /// Whether the values are complex ((real, imaginary) pairs in the block).
    pub fn is_complex(&self) -> bool {
        self.kind == SignalKind::Spectrum
    }

    /// Number of `f64` values in one frame (one row of the time-major block).
    pub fn width(&self) -> usize {
        match self.kind {
            SignalKind::TimeDomain => 1,
            SignalKind::TimeFrequency | SignalKind::BinaryMask => self.cf_hz.len(),
            SignalKind::Correlation => self.cf_hz.len() * self.lags_s.len(),
            SignalKind::Modulation => self.cf_hz.len() * self.mod_cf_hz.len(),
            SignalKind::Feature => self.features.len(),
            SignalKind::Spectrum => 2 * self.cf_hz.len(),
            SignalKind::DuetHistogram => self.alpha.len() * self.delta_samples.len(),
        }
    }

    /// The shape of one frame as array dimensions (`[]`, `[channels]`, `[channels, lags]`,
    /// ...); a complex value counts as one element.
    pub fn frame_shape(&self) -> Vec<usize> {
        match self.kind {
            SignalKind::TimeDomain => Vec::new(),
            SignalKind::TimeFrequency | SignalKind::BinaryMask | SignalKind::Spectrum => {
                vec![self.cf_hz.len()]
            }
            SignalKind::Correlation => vec![self.cf_hz.len(), self.lags_s.len()],
            SignalKind::Modulation => vec![self.cf_hz.len(), self.mod_cf_hz.len()],
            SignalKind::Feature => vec![self.features.len()],
            SignalKind::DuetHistogram => vec![self.alpha.len(), self.delta_samples.len()],
        }
    }
}

/// A time-major block of `f64` values: `frames()` rows of `width()` values each.
///
/// Processors write their new output of a chunk into a block; the block keeps its
/// capacity between chunks so that steady-state processing does not allocate.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Block {
    data: Vec<f64>,
    width: usize,
    /// Values at the start that are sealed: kept, but neither shown nor written (see
    /// [`Block::seal`]).
    sealed: usize,
}

impl Block {
    /// An empty block whose rows hold `width` values.
    pub fn new(width: usize) -> Self {
        Block {
            data: Vec::new(),
            width,
            sealed: 0,
        }
    }

    /// An empty block of `width`-value rows with room for `frames` rows.
    pub fn with_room(width: usize, frames: usize) -> Self {
        let mut b = Block::new(width);
        b.reserve_frames(frames);
        b
    }

    /// An empty block as wide as this one, with as much room.
    pub fn empty_like(&self) -> Self {
        let mut b = Block::new(self.width);
        b.grow(self.data.capacity());
        b
    }

    /// Rows it holds without reallocating.
    pub fn room(&self) -> usize {
        (self.data.capacity() - self.sealed)
            .checked_div(self.width)
            .unwrap_or(0)
    }

    /// A block holding `data` as rows of `width` values.
    ///
    /// # Panics
    /// If `data.len()` is not a multiple of `width`.
    pub fn from_vec(data: Vec<f64>, width: usize) -> Self {
        assert!(
            width > 0 && data.len().is_multiple_of(width),
            "block data length {} is not a multiple of its width {width}",
            data.len()
        );
        Block {
            data,
            width,
            sealed: 0,
        }
    }

    /// Values per row.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Number of rows (samples or frames).
    pub fn frames(&self) -> usize {
        self.shown().len().checked_div(self.width).unwrap_or(0)
    }

    /// True when the block holds no rows.
    pub fn is_empty(&self) -> bool {
        self.data.len() == self.sealed
    }

    /// All values, row after row.
    pub fn as_slice(&self) -> &[f64] {
        self.shown()
    }

    /// All values, row after row, mutable.
    pub fn as_mut_slice(&mut self) -> &mut [f64] {
        &mut self.data[self.sealed..]
    }

    /// Row `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.shown()[i * self.width..(i + 1) * self.width]
    }

    /// Iterator over the rows.
    pub fn rows(&self) -> std::slice::ChunksExact<'_, f64> {
        self.shown().chunks_exact(self.width.max(1))
    }

    /// Makes the block `frames` rows long, zero-filled, and returns its values.
    ///
    /// Does not allocate once the block has held that many values before.
    pub fn reset_to(&mut self, frames: usize) -> &mut [f64] {
        self.data.truncate(self.sealed);
        self.resize_to(frames)
    }

    /// Makes the block `frames` rows long without clearing it, for a caller that then
    /// writes every value: rows it held before keep stale values, new ones are zero.
    ///
    /// Does not allocate once the block has held that many values before.
    pub fn resize_to(&mut self, frames: usize) -> &mut [f64] {
        let len = self.sealed + frames * self.width;
        self.grow(len.saturating_sub(self.data.len()));
        self.data.resize(len, 0.0);
        &mut self.data[self.sealed..]
    }

    /// Appends the rows of `other`.
    ///
    /// # Panics
    /// If `other` has another width.
    pub fn extend_from(&mut self, other: &Block) {
        assert_eq!(self.width, other.width, "appending rows of another width");
        self.grow(other.as_slice().len());
        self.data.extend_from_slice(other.as_slice());
    }

    /// Appends `values`, whole rows of `width()` values each.
    ///
    /// # Panics
    /// If `values` does not hold whole rows.
    pub fn extend_from_slice(&mut self, values: &[f64]) {
        assert_eq!(
            values.len() % self.width.max(1),
            0,
            "appending part of a row"
        );
        self.grow(values.len());
        self.data.extend_from_slice(values);
    }

    /// Makes room for `frames` more rows, so that appending them does not reallocate.
    pub fn reserve_frames(&mut self, frames: usize) {
        self.grow(frames.saturating_mul(self.width));
    }

    /// As [`Block::reserve_frames`] for exactly `frames` more rows, returning the
    /// allocator's refusal instead of aborting the process (the buffers sized by a whole
    /// signal's length).
    pub fn try_reserve_frames(
        &mut self,
        frames: usize,
    ) -> Result<(), std::collections::TryReserveError> {
        huge_pages::try_reserve(&mut self.data, frames.saturating_mul(self.width))
    }

    /// Makes room for `values` more values. A new allocation of 4 MiB or more is advised
    /// to the kernel for huge pages before anything is written to it (see `huge_pages`).
    fn grow(&mut self, values: usize) {
        huge_pages::reserve(&mut self.data, values);
    }

    /// Removes the first `frames` rows shown (all of them if there are fewer), keeping the
    /// capacity: a bounded history drops its oldest rows.
    pub fn drop_front(&mut self, frames: usize) {
        let values = frames.saturating_mul(self.width).min(self.shown().len());
        self.data.drain(self.sealed..self.sealed + values);
    }

    /// Removes every row, keeping the capacity.
    pub fn clear(&mut self) {
        self.data.truncate(self.sealed);
    }

    /// Seals the rows it holds: they stay, after the rows sealed before, but the block
    /// shows and writes only rows that come after them, as if empty. A whole signal's
    /// output is so written chunk after chunk in place, where the processor writes its
    /// chunk, instead of being copied there (see [`Block::unseal`]).
    pub fn seal(&mut self) {
        self.sealed = self.data.len();
    }

    /// Shows every row again, the sealed ones first.
    pub fn unseal(&mut self) {
        self.sealed = 0;
    }

    /// The values shown: those after the sealed ones.
    fn shown(&self) -> &[f64] {
        &self.data[self.sealed..]
    }

    /// Consumes the block, returning its values row after row (sealed ones included).
    pub fn into_vec(self) -> Vec<f64> {
        self.data
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drop_front_removes_the_oldest_rows_only() {
        let mut b = Block::from_vec((0..12).map(f64::from).collect(), 3);
        b.drop_front(1);
        assert_eq!(
            b.as_slice(),
            &[3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0]
        );
        b.drop_front(10);
        assert!(b.is_empty());
        assert_eq!(b.width(), 3);
    }

    #[test]
    fn rows_are_contiguous_and_reset_keeps_capacity() {
        let mut b = Block::from_vec(vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0], 3);
        assert_eq!(b.frames(), 2);
        assert_eq!(b.row(1), &[4.0, 5.0, 6.0]);
        let cap = b.data.capacity();
        assert_eq!(b.reset_to(1), &[0.0, 0.0, 0.0]);
        assert_eq!(b.data.capacity(), cap);
        assert_eq!(b.frames(), 1);
    }

    #[test]
    fn sealed_rows_stay_unseen_and_the_next_chunk_is_written_after_them() {
        let mut b = Block::with_room(2, 6);
        let room = b.room();
        b.resize_to(2).copy_from_slice(&[1.0, 2.0, 3.0, 4.0]);
        let at = b.as_slice().as_ptr();
        b.seal();
        assert!(b.is_empty() && b.frames() == 0 && b.rows().next().is_none());
        assert_eq!(b.room(), room - 2);
        // a processor's next chunk, as it writes it: cleared, then one row, then resized
        b.clear();
        b.reset_to(1).copy_from_slice(&[5.0, 6.0]);
        b.resize_to(2)[2..].copy_from_slice(&[7.0, 8.0]);
        assert_eq!(b.as_slice(), &[5.0, 6.0, 7.0, 8.0]);
        assert_eq!((b.frames(), b.row(1)), (2, &[7.0, 8.0][..]));
        b.as_mut_slice()[0] = 9.0;
        let mut copy = Block::new(2);
        copy.extend_from(&b);
        assert_eq!(copy.as_slice(), &[9.0, 6.0, 7.0, 8.0]);
        b.seal();
        b.unseal();
        assert_eq!(b.as_slice(), &[1.0, 2.0, 3.0, 4.0, 9.0, 6.0, 7.0, 8.0]);
        assert_eq!(b.as_slice().as_ptr(), at, "written in place, never moved");
        assert_eq!(b.frames(), 4);
    }

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
            (framed.kind, &framed.cf_hz),
            (SignalKind::TimeFrequency, &tf.cf_hz)
        );
        let named = tf.named("precedence_itd");
        assert_eq!((named.name, named.fs_hz), (Some("precedence_itd"), 16000.0));
        let f = SignalInfo::feature(50.0, 44100.0, vec!["a".into()]);
        assert_eq!(
            (f.kind, f.fs_hz, f.audio_fs_hz),
            (SignalKind::Feature, 50.0, 44100.0)
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
            ..framed.clone()
        };
        assert_eq!((spectrum.width(), spectrum.frame_shape()), (6, vec![3]));
        // features and histograms have no channels, whatever frequencies they carry
        for kind in [SignalKind::Feature, SignalKind::DuetHistogram] {
            let info = SignalInfo {
                kind,
                ..framed.clone()
            };
            assert_eq!(info.channels(), 0, "{kind:?}");
        }
        let classes = [
            (SignalKind::TimeDomain, "TimeDomainSignal", &["time"][..]),
            (
                SignalKind::TimeFrequency,
                "TimeFrequencySignal",
                &["time_or_frame", "channel"],
            ),
            (
                SignalKind::Correlation,
                "CorrelationSignal",
                &["frame", "channel", "lag"],
            ),
            (
                SignalKind::Modulation,
                "ModulationSignal",
                &["frame", "channel", "modulation"],
            ),
            (SignalKind::Feature, "FeatureSignal", &["frame", "feature"]),
            (SignalKind::Spectrum, "STFTSignal", &["frame", "bin"]),
            (SignalKind::BinaryMask, "BinaryMask", &["frame", "channel"]),
            (
                SignalKind::DuetHistogram,
                "DuetHistogramSignal",
                &["frame", "alpha", "delta"],
            ),
        ];
        for (kind, class, axes) in classes {
            assert_eq!((kind.afe_class(), kind.axes()), (class, axes));
        }
    }

    #[test]
    fn blocks_keep_their_room_and_width() {
        let mut b = Block::with_room(4, 10);
        assert_eq!((b.width(), b.frames(), b.room()), (4, 0, 10));
        assert!(b.is_empty());
        let like = b.empty_like();
        assert_eq!((like.width(), like.room()), (4, 10));
        b.reserve_frames(20);
        assert!(b.room() >= 20);
        assert_eq!(Block::new(0).room(), 0);
        assert_eq!(Block::new(0).frames(), 0);
        b.extend_from(&Block::from_vec(vec![1.0; 8], 4));
        assert!(!b.is_empty());
        b.as_mut_slice()[5] = 7.0;
        assert_eq!(b.as_slice(), [1.0, 1.0, 1.0, 1.0, 1.0, 7.0, 1.0, 1.0]);
        // resizing keeps the rows it held and zero-fills new ones
        assert_eq!(
            b.resize_to(3)[4..],
            [1.0, 7.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0]
        );
        assert_eq!(b.rows().nth(1), Some(&[1.0, 7.0, 1.0, 1.0][..]));
        let room = b.room();
        b.clear();
        assert_eq!((b.frames(), b.room()), (0, room));
        assert_eq!(Block::from_vec(vec![2.0, 3.0], 1).into_vec(), [2.0, 3.0]);
    }

    #[test]
    #[should_panic(expected = "not a multiple of its width")]
    fn from_vec_refuses_a_partial_row() {
        let _ = Block::from_vec(vec![1.0; 5], 2);
    }

    #[test]
    #[should_panic(expected = "another width")]
    fn extend_from_refuses_another_width() {
        Block::new(2).extend_from(&Block::new(3));
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
    fn widths_and_shapes_follow_the_kind() {
        let tf = SignalInfo::time_frequency(1000.0, vec![100.0, 200.0]);
        let cc = tf.correlation(100.0, vec![-1.0, 0.0, 1.0]);
        assert_eq!((cc.width(), cc.frame_shape()), (6, vec![2, 3]));
        assert_eq!(cc.audio_fs_hz, 1000.0);
        let ams = SignalInfo {
            kind: SignalKind::Modulation,
            mod_cf_hz: vec![4.0, 8.0, 16.0],
            ..tf.framed(100.0)
        };
        assert_eq!((ams.width(), ams.frame_shape()), (6, vec![2, 3]));
        let stft = SignalInfo {
            kind: SignalKind::Spectrum,
            ..tf.framed(100.0)
        };
        assert!(stft.is_complex());
        assert_eq!((stft.width(), stft.frame_shape()), (4, vec![2]));
        let pitch = SignalInfo::feature(100.0, 1000.0, vec!["pitch".into(), "rawPitch".into()]);
        assert_eq!((pitch.width(), pitch.channels()), (2, 0));
        assert_eq!(pitch.kind.axes(), &["frame", "feature"]);
        let duet = SignalInfo {
            kind: SignalKind::DuetHistogram,
            alpha: vec![-0.5, 0.0, 0.5],
            delta_samples: vec![-1.0, -0.5, 0.0, 0.5, 1.0],
            ..SignalInfo::default()
        };
        assert_eq!((duet.width(), duet.frame_shape()), (15, vec![3, 5]));
        assert_eq!(
            (duet.channels(), duet.kind.afe_class()),
            (0, "DuetHistogramSignal")
        );
    }
}
