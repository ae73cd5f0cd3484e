//! Checks shared by the window/hop processors.

use afe_core::framing::{hop_samples, window_samples};
use afe_core::{Error, Result};

/// Longest window, in samples (about 6 minutes at 44.1 kHz): beyond is a unit mistake.
pub const MAX_WINDOW: usize = 1 << 24;

/// Window and hop lengths in samples at `fs`, checked: `0 < H ≤ W ≤ MAX_WINDOW`.
///
/// `w` and `h` are `(AFE parameter name, value in s)`.
pub fn check_framing(w: (&str, f64), h: (&str, f64), fs: f64) -> Result<(usize, usize)> {
    let ws = window_samples(w.1, fs);
    let hs = hop_samples(h.1, fs);
    if w.1 <= 0.0 || !(2..=MAX_WINDOW).contains(&ws) {
        return Err(Error::InvalidParameter {
            name: w.0.into(),
            value: w.1.to_string(),
            reason: format!("the window must span between 2 and {MAX_WINDOW} samples at {fs} Hz"),
        });
    }
    if h.1 <= 0.0 || hs == 0 || hs > ws {
        return Err(Error::InvalidParameter {
            name: h.0.into(),
            value: h.1.to_string(),
            reason: format!(
                "the hop must be at least one sample at {fs} Hz and at most the window ({} = {} s)",
                w.0, w.1
            ),
        });
    }
    Ok((ws, hs))
}
