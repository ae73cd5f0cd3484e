//! What the window/hop processors share: the checks of their lengths, and the framing of
//! both ears for the binaural ones.

use afe_core::framing::{hop_samples, window_samples, Frame, FrameBuffer};
use afe_core::{Error, Result};

/// Longest window, in samples (about 6 minutes at 44.1 kHz): beyond is a unit mistake.
pub const MAX_WINDOW: usize = 1 << 24;

/// Most values a frame buffer may hold (a window of rows over all channels): 2^24
/// values, 128 MiB, e.g. 12 s of 32 channels at 44.1 kHz. A longer window is refused
/// rather than allocated (found by fuzzing: a ratemap window of minutes over 32
/// channels asked for 600 MB).
pub const MAX_FRAME_VALUES: usize = 1 << 24;

/// Most values a processor's per-window working buffers may hold beyond its frame buffer:
/// 2^26 values, 512 MiB (found by fuzzing: the precedence model keeps eight values per
/// window sample and channel, 1.6 GB for a 23-s window over 32 channels).
pub const MAX_WORK_VALUES: usize = 1 << 26;

/// Refuses a window whose working buffers (`values` f64 values) would exceed
/// [`MAX_WORK_VALUES`], naming the window parameter `w` (AFE name, value in s), what
/// they grow with (`this window over 32 channels`) and what makes them smaller.
pub fn check_work(w: (&str, f64), values: usize, what: &str, remedy: &str) -> Result<()> {
    if values <= MAX_WORK_VALUES {
        return Ok(());
    }
    Err(Error::invalid(
        w.0,
        w.1,
        format!(
            "{what} would need {} MiB of working memory (at most {} MiB): {remedy}",
            values / (1 << 17),
            MAX_WORK_VALUES / (1 << 17)
        ),
    ))
}

/// Refuses a frame buffer of `ws` rows of `width` values beyond [`MAX_FRAME_VALUES`],
/// naming the window parameter `w` (AFE name, value in s).
pub fn check_frame_values(w: (&str, f64), ws: usize, width: usize) -> Result<()> {
    if ws.saturating_mul(width.max(1)) <= MAX_FRAME_VALUES {
        return Ok(());
    }
    Err(Error::invalid(w.0, w.1, format!(
            "a window of {ws} samples over {width} channels would buffer {} MiB (at most {} MiB): shorten the window or use fewer channels",
            ws.saturating_mul(width) / (1 << 17),
            MAX_FRAME_VALUES / (1 << 17)
        )))
}

/// Window and hop lengths in samples at `fs`, checked: `0 < W, H ≤ MAX_WINDOW`. A hop
/// longer than the window is accepted, as by the AFE: frames then leave gaps.
///
/// `w` and `h` are `(AFE parameter name, value in s)`.
pub fn check_framing(
    w: (&str, f64),
    h: (&str, f64),
    fs: f64,
    width: usize,
) -> Result<(usize, usize)> {
    let ws = window_samples(w.1, fs);
    let hs = hop_samples(h.1, fs);
    if w.1 <= 0.0 || !(2..=MAX_WINDOW).contains(&ws) {
        return Err(Error::invalid(
            w.0,
            w.1,
            format!("the window must span between 2 and {MAX_WINDOW} samples at {fs} Hz"),
        ));
    }
    check_frame_values(w, ws, width)?;
    if h.1 <= 0.0 || !(1..=MAX_WINDOW).contains(&hs) {
        return Err(Error::invalid(
            h.0,
            h.1,
            format!("the hop must span between 1 and {MAX_WINDOW} samples at {fs} Hz"),
        ));
    }
    Ok((ws, hs))
}

/// Left and right inputs framed identically (the binaural window processors: the two
/// inputs always have the same length, so they always hold the same number of frames).
#[derive(Debug, Clone)]
pub struct EarFrames {
    /// The left ear's buffer, then the right's.
    ears: [FrameBuffer; 2],
}

impl EarFrames {
    /// Buffers for `width`-value rows, frames of `window` rows every `hop` rows.
    pub fn new(width: usize, window: usize, hop: usize) -> Self {
        let ear = || FrameBuffer::new(width, window, hop);
        EarFrames {
            ears: [ear(), ear()],
        }
    }

    /// Number of complete frame pairs over the kept rows and the new chunks.
    pub fn available(&self, left: &[f64], right: &[f64]) -> usize {
        self.ears[0]
            .available(left)
            .min(self.ears[1].available(right))
    }

    /// Frame pair `k` over the kept rows and the new chunks.
    pub fn frame<'a>(
        &'a self,
        (left, right): (&'a [f64], &'a [f64]),
        k: usize,
    ) -> (Frame<'a>, Frame<'a>) {
        (self.ears[0].frame(left, k), self.ears[1].frame(right, k))
    }

    /// Drops `frames` frame pairs and keeps what later frames need of the new chunks.
    pub fn advance(&mut self, left: &[f64], right: &[f64], frames: usize) {
        self.ears[0].advance(left, frames);
        self.ears[1].advance(right, frames);
    }

    /// Values per row.
    pub fn width(&self) -> usize {
        self.ears[0].width()
    }

    /// Counts rows only, for both ears (see [`FrameBuffer::count_only`]).
    pub fn count_only(&mut self) {
        self.ears.iter_mut().for_each(FrameBuffer::count_only);
    }

    /// The left ear's buffer, then the right's (what a part of a split processor holds
    /// of its state, [`afe_core::ChannelSplit::part_frames`]).
    pub fn buffers(&self) -> &[FrameBuffer] {
        &self.ears
    }

    /// Both ears' buffers over the columns that the parts' buffers (each
    /// [`EarFrames::buffers`]) make together (see [`FrameBuffer::joined`]); `None` unless
    /// every part holds two.
    pub fn joined(parts: &[&[FrameBuffer]]) -> Option<Self> {
        if parts.is_empty() || parts.iter().any(|p| p.len() != 2) {
            return None;
        }
        let ear = |e: usize| {
            let of_ear: Vec<&FrameBuffer> = parts.iter().map(|p| &p[e]).collect();
            FrameBuffer::joined(&of_ear)
        };
        Some(EarFrames {
            ears: [ear(0), ear(1)],
        })
    }

    /// A copy that frames and keeps only `columns` of both ears (see
    /// [`FrameBuffer::columns`]).
    pub fn columns(&self, columns: std::ops::Range<usize>) -> Self {
        EarFrames {
            ears: [
                self.ears[0].columns(columns.clone()),
                self.ears[1].columns(columns),
            ],
        }
    }

    /// Forgets the kept rows of both ears.
    pub fn reset(&mut self) {
        self.ears.iter_mut().for_each(FrameBuffer::reset);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_under_two_samples_is_refused_and_the_memory_limit_is_inclusive() {
        let h = ("rm_hSizeSec", 0.01);
        let e = check_framing(("rm_wSizeSec", 1e-6), h, 44100.0, 1)
            .expect_err("no sample")
            .to_string();
        assert!(e.contains("between 2 and"), "{e}");
        // 1024 samples over 2^14 channels is exactly MAX_FRAME_VALUES.
        let w = ("rm_wSizeSec", 1.0);
        assert_eq!(
            check_framing(w, h, 1024.0, MAX_FRAME_VALUES / 1024).expect("at the limit"),
            (1024, 10)
        );
        assert!(check_framing(w, h, 1024.0, MAX_FRAME_VALUES / 1024 + 1).is_err());
    }

    #[test]
    fn counting_only_counts_the_same_frames_from_no_values() {
        let full = EarFrames::new(3, 4, 2);
        let mut counter = full.clone();
        counter.count_only();
        let x: Vec<f64> = (0..30).map(f64::from).collect();
        assert_eq!(counter.available(&x, &x), 4);
        assert_eq!(full.available(&x, &x), 4);
        let (l, r) = counter.frame((&x, &x), 1);
        assert_eq!((l.width(), r.width()), (0, 0));
        let (l, r) = full.frame((&x, &x), 1);
        assert_eq!((l.width(), r.width()), (3, 3));
    }

    #[test]
    fn a_window_too_long_for_memory_is_refused_by_name() {
        let w = ("rm_wSizeSec", 0.02);
        let h = ("rm_hSizeSec", 0.01);
        assert_eq!(check_framing(w, h, 44100.0, 32).expect("fine"), (882, 441));
        // 100 s at 96 kHz over 32 channels: 2.3 GiB, refused before any allocation
        let long = ("rm_wSizeSec", 100.0);
        let e = check_framing(long, h, 96000.0, 32)
            .expect_err("too long")
            .to_string();
        assert!(e.contains("rm_wSizeSec") && e.contains("MiB"), "{e}");
        // the same window over one channel fits
        assert!(check_framing(("rm_wSizeSec", 10.0), h, 44100.0, 1).is_ok());
        // a hop longer than the window, as the AFE accepts it; a zero hop is refused
        assert_eq!(
            check_framing(w, ("rm_hSizeSec", 0.05), 44100.0, 32).expect("gaps"),
            (882, 2205)
        );
        let e = check_framing(w, ("rm_hSizeSec", 1e-6), 44100.0, 32)
            .expect_err("zero")
            .to_string();
        assert!(e.contains("rm_hSizeSec") && e.contains("0.000001"), "{e}");
    }
}
