//! Whether the outputs of a whole signal fit the machine's memory, checked before the
//! computation starts: a warning above half of the memory available, an error
//! ([`Error::OutputsTooLarge`]) above all of it. The memory available is the least of the
//! kernel's `MemAvailable`, a cgroup's limit and `ulimit -v`'s, or the environment
//! variable `AFE_MEMORY_AVAILABLE_GB` where set (a test's, or a share of your choosing).

use afe_core::error::WAYS_OUT;
use afe_core::{Error, Result};
use afe_graph::work::size;
use afe_graph::Manager;

use crate::npy::Dtype;

pub use afe_graph::work::check_settings;

/// Bytes the requested outputs of `manager` (every intermediate one too with `all`) take
/// for a signal of `samples` input samples per ear, stored as `dtype`.
pub fn output_bytes(manager: &mut Manager, samples: u64, all: bool, dtype: Dtype) -> f64 {
    manager.set_keep_all(all);
    let per_value = match dtype {
        Dtype::Float64 => 8.0,
        Dtype::Float32 => 4.0,
    };
    let fs = manager.fs();
    manager
        .signals(all)
        .iter()
        .map(|s| {
            let frames = (samples as f64 * s.info.fs_hz / fs).ceil();
            frames * s.info.width() as f64 * per_value
        })
        .sum()
}

/// Memory available to this process in bytes, where known: `AFE_MEMORY_AVAILABLE_GB`
/// where set, else the least of the kernel's `MemAvailable`, the room left under the
/// cgroup's `memory.max` (a container's share) and the room left under the address-space
/// limit (`ulimit -v`), beyond which an allocation would fail and abort the process (see
/// [`afe_graph::work::memory_available`], which refuses a value of
/// `AFE_MEMORY_AVAILABLE_GB` that is not a positive number; here such a value gives the
/// machine's own figure, and [`check`] and the CLI refuse it).
pub fn available_bytes() -> Option<f64> {
    afe_graph::work::memory_available().unwrap_or_else(|_| afe_graph::work::memory_measured())
}

/// Checks outputs of `bytes` against the memory available: `Ok(None)` when they take
/// less than half of it (or it is unknown), `Ok(Some(warning))` up to all of it, an
/// [`Error::OutputsTooLarge`] beyond.
pub fn check(bytes: f64) -> Result<Option<String>> {
    let Some(available) = afe_graph::work::memory_available()? else {
        return Ok(None);
    };
    let (need, available_text) = (size(bytes), size(available));
    if bytes > available {
        return Err(Error::OutputsTooLarge {
            need,
            available: available_text,
        });
    }
    Ok((bytes > available / 2.0).then(|| {
        format!(
            "the outputs will take {need}, more than half of the {available_text} of memory \
             available: {WAYS_OUT}"
        )
    }))
}
