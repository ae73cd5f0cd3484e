//! Whether the outputs of a whole signal fit the machine's memory, checked before the
//! computation starts: a warning above half of the memory available, an error
//! ([`Error::OutputsTooLarge`]) above all of it. The memory available is the least of the
//! kernel's `MemAvailable`, a cgroup's limit and `ulimit -v`'s, or the environment
//! variable `AFE_MEMORY_AVAILABLE_GB` where set (a test's, or a share of your choosing).

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

/// Memory available to this process in bytes, where known: `AFE_MEMORY_AVAILABLE_GB`
/// where set, else the least of the kernel's `MemAvailable`, the room left under the
/// cgroup's `memory.max` (a container's share) and the room left under the address-space
/// limit (`ulimit -v`), beyond which an allocation would fail and abort the process.
pub fn available_bytes() -> Option<f64> {
    if let Some(gb) = std::env::var("AFE_MEMORY_AVAILABLE_GB")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
    {
        return Some(gb * 1e9);
    }
    [mem_available(), cgroup_room(), address_space_room()]
        .into_iter()
        .flatten()
        .reduce(f64::min)
}

/// The kernel's `MemAvailable`, bytes.
fn mem_available() -> Option<f64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    kib_field(&info, "MemAvailable:")
}

/// A `name  N kB` line of a `/proc` file, in bytes.
fn kib_field(text: &str, name: &str) -> Option<f64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024.0)
}

/// `memory.max` minus what this process's cgroup (v2) holds beyond its page cache
/// (`memory.current` less `memory.stat`'s `file`, which the kernel reclaims), bytes;
/// `None` without a limit.
fn cgroup_room() -> Option<f64> {
    let group = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let path = group.lines().find_map(|l| l.strip_prefix("0::"))?;
    let dir = std::path::Path::new("/sys/fs/cgroup").join(path.trim_start_matches('/'));
    let read = |name: &str| std::fs::read_to_string(dir.join(name)).ok();
    let max: f64 = read("memory.max")?.trim().parse().ok()?;
    let current: f64 = read("memory.current")
        .and_then(|t| t.trim().parse().ok())
        .unwrap_or(0.0);
    let cache: f64 = read("memory.stat")
        .and_then(|t| {
            t.lines()
                .find_map(|l| l.strip_prefix("file "))
                .and_then(|v| v.trim().parse().ok())
        })
        .unwrap_or(0.0);
    Some((max - (current - cache).max(0.0)).max(0.0))
}

/// The soft address-space limit minus the address space in use (`VmSize`), bytes;
/// `None` without a limit.
fn address_space_room() -> Option<f64> {
    let (soft, _) = nix::sys::resource::getrlimit(nix::sys::resource::Resource::RLIMIT_AS).ok()?;
    if soft == nix::sys::resource::RLIM_INFINITY {
        return None;
    }
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let used = kib_field(&status, "VmSize:").unwrap_or(0.0);
    Some((soft as f64 - used).max(0.0))
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
