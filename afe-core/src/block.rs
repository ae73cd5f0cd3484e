//! Time-major sample blocks and the description of the signal they carry.

/// What a signal's frames contain, which fixes its array layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SignalKind {
    /// One value per sample: `[time]`.
    TimeDomain,
    /// One value per frequency channel: `[time_or_frame, channel]`.
    TimeFrequency,
    /// One value per channel and lag: `[frame, channel, lag]`.
    Correlation,
}

/// Static description of a processor output: kind, rate, channel and lag axes.
#[derive(Debug, Clone, PartialEq)]
pub struct SignalInfo {
    /// Layout of one frame.
    pub kind: SignalKind,
    /// Nominal rate of the output in Hz (`fs` for full-rate signals, `1/hop` for framed ones).
    pub fs_hz: f64,
    /// Centre frequency of each channel in Hz (empty for time-domain signals).
    pub cf_hz: Vec<f64>,
    /// Lag of each correlation column in seconds (empty unless `kind` is `Correlation`).
    pub lags_s: Vec<f64>,
    /// Rate in Hz of the audio this signal was computed from (equal to `fs_hz` for
    /// full-rate signals; framed signals keep the rate their frames were cut at).
    pub audio_fs_hz: f64,
}

impl SignalInfo {
    /// A time-domain signal at `fs_hz`.
    pub fn time_domain(fs_hz: f64) -> Self {
        SignalInfo {
            kind: SignalKind::TimeDomain,
            fs_hz,
            cf_hz: Vec::new(),
            lags_s: Vec::new(),
            audio_fs_hz: fs_hz,
        }
    }

    /// A full-rate time-frequency signal at `fs_hz` with the given centre frequencies.
    pub fn time_frequency(fs_hz: f64, cf_hz: Vec<f64>) -> Self {
        SignalInfo {
            kind: SignalKind::TimeFrequency,
            fs_hz,
            cf_hz,
            lags_s: Vec::new(),
            audio_fs_hz: fs_hz,
        }
    }

    /// The same channels framed at nominal rate `frame_rate_hz` (audio rate kept).
    pub fn framed(&self, frame_rate_hz: f64) -> Self {
        SignalInfo {
            kind: SignalKind::TimeFrequency,
            fs_hz: frame_rate_hz,
            cf_hz: self.cf_hz.clone(),
            lags_s: Vec::new(),
            audio_fs_hz: self.audio_fs_hz,
        }
    }

    /// Number of frequency channels (1 for a time-domain signal).
    pub fn channels(&self) -> usize {
        match self.kind {
            SignalKind::TimeDomain => 1,
            _ => self.cf_hz.len(),
        }
    }

    /// Number of values in one frame (one row of the time-major block).
    pub fn width(&self) -> usize {
        match self.kind {
            SignalKind::TimeDomain => 1,
            SignalKind::TimeFrequency => self.cf_hz.len(),
            SignalKind::Correlation => self.cf_hz.len() * self.lags_s.len(),
        }
    }

    /// The shape of one frame as array dimensions (`[]`, `[channels]` or `[channels, lags]`).
    pub fn frame_shape(&self) -> Vec<usize> {
        match self.kind {
            SignalKind::TimeDomain => Vec::new(),
            SignalKind::TimeFrequency => vec![self.cf_hz.len()],
            SignalKind::Correlation => vec![self.cf_hz.len(), self.lags_s.len()],
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
}

impl Block {
    /// An empty block whose rows hold `width` values.
    pub fn new(width: usize) -> Self {
        Block {
            data: Vec::new(),
            width,
        }
    }

    /// A block holding `data` as rows of `width` values.
    ///
    /// # Panics
    /// If `data.len()` is not a multiple of `width`.
    pub fn from_vec(data: Vec<f64>, width: usize) -> Self {
        assert!(
            width > 0 && data.len() % width == 0,
            "block data length {} is not a multiple of its width {width}",
            data.len()
        );
        Block { data, width }
    }

    /// Values per row.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Number of rows (samples or frames).
    pub fn frames(&self) -> usize {
        self.data.len().checked_div(self.width).unwrap_or(0)
    }

    /// True when the block holds no rows.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// All values, row after row.
    pub fn as_slice(&self) -> &[f64] {
        &self.data
    }

    /// All values, row after row, mutable.
    pub fn as_mut_slice(&mut self) -> &mut [f64] {
        &mut self.data
    }

    /// Row `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.data[i * self.width..(i + 1) * self.width]
    }

    /// Iterator over the rows.
    pub fn rows(&self) -> std::slice::ChunksExact<'_, f64> {
        self.data.chunks_exact(self.width.max(1))
    }

    /// Makes the block `frames` rows long, zero-filled, and returns its values.
    ///
    /// Does not allocate once the block has held that many values before.
    pub fn reset_to(&mut self, frames: usize) -> &mut [f64] {
        self.data.clear();
        self.data.resize(frames * self.width, 0.0);
        &mut self.data
    }

    /// Makes the block `frames` rows long without clearing it, for a caller that then
    /// writes every value: rows it held before keep stale values, new ones are zero.
    ///
    /// Does not allocate once the block has held that many values before.
    pub fn resize_to(&mut self, frames: usize) -> &mut [f64] {
        self.data.resize(frames * self.width, 0.0);
        &mut self.data
    }

    /// Appends the rows of `other`.
    ///
    /// # Panics
    /// If `other` has another width.
    pub fn extend_from(&mut self, other: &Block) {
        assert_eq!(self.width, other.width, "appending rows of another width");
        self.data.extend_from_slice(&other.data);
    }

    /// Removes every row, keeping the capacity.
    pub fn clear(&mut self) {
        self.data.clear();
    }

    /// Consumes the block, returning its values row after row.
    pub fn into_vec(self) -> Vec<f64> {
        self.data
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn correlation_width_is_channels_times_lags() {
        let info = SignalInfo {
            kind: SignalKind::Correlation,
            fs_hz: 100.0,
            cf_hz: vec![100.0, 200.0],
            lags_s: vec![-1.0, 0.0, 1.0],
            audio_fs_hz: 1000.0,
        };
        assert_eq!(info.width(), 6);
        assert_eq!(info.frame_shape(), vec![2, 3]);
    }
}
