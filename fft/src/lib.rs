//! Every FFT plan of the workspace is made here, at `f64`. rustfft's planner is generic:
//! each crate that calls it compiles its own copy of every algorithm it may choose (about
//! 700 KB of optimised code, half of `afe-core`'s and a quarter of `afe-processors`'),
//! and each crate's unit tests compile it once more. Planned through these functions,
//! it is compiled once, in this crate, which therefore holds no tests of its own (the
//! transforms are tested where they are used). Plans are the planners' own: the same
//! algorithm for a length, so the same numbers, as planning in place.

use std::sync::Arc;

pub use realfft::{ComplexToReal, RealToComplex};
pub use rustfft::Fft;

/// The complex forward transform of `n` points (unnormalised).
pub fn forward(n: usize) -> Arc<dyn Fft<f64>> {
    rustfft::FftPlanner::new().plan_fft_forward(n)
}

/// The complex inverse transform of `n` points (unnormalised: `n` times the inverse).
pub fn inverse(n: usize) -> Arc<dyn Fft<f64>> {
    rustfft::FftPlanner::new().plan_fft_inverse(n)
}

/// realfft's forward transform of `n` real values to `n / 2 + 1` bins.
pub fn real_forward(n: usize) -> Arc<dyn RealToComplex<f64>> {
    realfft::RealFftPlanner::new().plan_fft_forward(n)
}

/// realfft's inverse transform of `n / 2 + 1` bins to `n` real values (unnormalised).
pub fn real_inverse(n: usize) -> Arc<dyn ComplexToReal<f64>> {
    realfft::RealFftPlanner::new().plan_fft_inverse(n)
}
