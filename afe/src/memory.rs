//! Whether the outputs of a whole signal fit the machine's memory, checked before the
//! computation starts: a warning above half of the memory available, an error
//! ([`Error::OutputsTooLarge`]) above all of it. The memory available is the kernel's
//! `MemAvailable`, or the environment variable `AFE_MEMORY_AVAILABLE_GB` where set (a
//! container's share, or a test's).

use afe_core::error::WAYS_OUT;
use afe_core::{Error, Result};
use afe_graph::Manager;

use crate::npy::Dtype;

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

/// Memory available to this process in bytes, where known.
pub fn available_bytes() -> Option<f64> {
    if let Some(gb) = std::env::var("AFE_MEMORY_AVAILABLE_GB")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
    {
        return Some(gb * 1e9);
    }
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024.0)
}

/// Checks outputs of `bytes` against the memory available: `Ok(None)` when they take
/// less than half of it (or it is unknown), `Ok(Some(warning))` up to all of it, an
/// [`Error::OutputsTooLarge`] beyond.
pub fn check(bytes: f64) -> Result<Option<String>> {
    let Some(available) = available_bytes() else {
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

/// A size in bytes as GB, MB or kB (decimal), to a tenth.
fn size(bytes: f64) -> String {
    match bytes {
        b if b >= 1e9 => format!("{:.1} GB", b / 1e9),
        b if b >= 1e6 => format!("{:.1} MB", b / 1e6),
        b => format!("{:.1} kB", b / 1e3),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_read_in_the_unit_that_fits() {
        assert_eq!(size(7.2e9), "7.2 GB");
        assert_eq!(size(48_360.0), "48.4 kB");
        assert_eq!(size(3.25e6), "3.2 MB");
    }
}
