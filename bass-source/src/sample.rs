//! The sample types a port holds, and their one conversion to the AFE's input.

use std::sync::atomic::{AtomicI32, AtomicU32, AtomicU64, Ordering};

/// A sample type a [`Port`](crate::Port) can hold: `i32` (what BASS publishes and ALSA
/// captures), `f32` (float WAV files) or `f64` (synthesis, decoded files).
///
/// Each sample lives in one atomic cell, so that readers may copy while the writer
/// writes; the port's sequence counters and fences order these relaxed accesses and tell
/// a reader when its copy was overwritten.
pub trait Sample: Copy + Default + PartialEq + std::fmt::Debug + Send + Sync + 'static {
    /// The atomic cell holding one sample.
    type Cell: Send + Sync;

    /// A cell holding the zero sample.
    fn zero_cell() -> Self::Cell;

    /// Reads a cell (relaxed).
    fn load(cell: &Self::Cell) -> Self;

    /// Writes a cell (relaxed).
    fn store(cell: &Self::Cell, value: Self);

    /// The sample as AFE input, full scale = 1.0: an `i32` is divided by 2³¹ (so
    /// `i32::MIN` is −1.0), floats are taken as they are.
    fn to_f64(self) -> f64;
}

/// 2⁻³¹: an `i32` sample times this is in [−1, 1). A power of two, so the scaling is exact.
const I32_SCALE: f64 = 1.0 / 2_147_483_648.0;

impl Sample for i32 {
    type Cell = AtomicI32;

    fn zero_cell() -> AtomicI32 {
        AtomicI32::new(0)
    }

    fn load(cell: &AtomicI32) -> i32 {
        cell.load(Ordering::Relaxed)
    }

    fn store(cell: &AtomicI32, value: i32) {
        cell.store(value, Ordering::Relaxed);
    }

    fn to_f64(self) -> f64 {
        f64::from(self) * I32_SCALE
    }
}

impl Sample for f32 {
    type Cell = AtomicU32;

    fn zero_cell() -> AtomicU32 {
        AtomicU32::new(0)
    }

    fn load(cell: &AtomicU32) -> f32 {
        f32::from_bits(cell.load(Ordering::Relaxed))
    }

    fn store(cell: &AtomicU32, value: f32) {
        cell.store(value.to_bits(), Ordering::Relaxed);
    }

    fn to_f64(self) -> f64 {
        f64::from(self)
    }
}

impl Sample for f64 {
    type Cell = AtomicU64;

    fn zero_cell() -> AtomicU64 {
        AtomicU64::new(0)
    }

    fn load(cell: &AtomicU64) -> f64 {
        f64::from_bits(cell.load(Ordering::Relaxed))
    }

    fn store(cell: &AtomicU64, value: f64) {
        cell.store(value.to_bits(), Ordering::Relaxed);
    }

    fn to_f64(self) -> f64 {
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_scale_is_one() {
        assert_eq!(i32::MIN.to_f64(), -1.0);
        assert_eq!((1i32 << 30).to_f64(), 0.5);
        assert_eq!(0.25f32.to_f64(), 0.25);
        assert_eq!((-0.125f64).to_f64(), -0.125);
    }

    #[test]
    fn cells_round_trip_every_bit() {
        fn round_trip<S: Sample>(v: S) -> S {
            let c = S::zero_cell();
            assert_eq!(S::load(&c), S::default());
            S::store(&c, v);
            S::load(&c)
        }
        assert_eq!(round_trip(i32::MIN), i32::MIN);
        assert_eq!(round_trip(-1.5e-30f32).to_bits(), (-1.5e-30f32).to_bits());
        assert_eq!(round_trip(f64::MAX), f64::MAX);
    }
}
