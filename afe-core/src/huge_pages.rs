//! Transparent huge pages for long blocks: a whole signal's output is written once to
//! fresh memory, and on Linux each first write to a 4-KiB page is a fault (about 2 µs on
//! a virtual machine, a third of the time of a whole-signal run that keeps its outputs).
//! Advised, the kernel backs the buffer with 2-MiB pages where it finds free ones: one
//! fault per 512 pages. (Memory locked with `mlockall` is filled in when it is mapped,
//! before the advice; it stays on the pages it got.)

/// Allocations from this many bytes of capacity up are advised: below it, a buffer holds
/// at most one whole huge page, not worth a system call and a split mapping.
const MIN_BYTES: usize = 4 << 20;

/// The size of a huge page on x86-64 and on aarch64 with 4-KiB base pages (bytes).
const HUGE_PAGE: usize = 2 << 20;

/// `Vec::reserve` for `additional` more values (amortised: at least doubling), except
/// that a new allocation of [`MIN_BYTES`] or more is advised for huge pages before
/// anything is written to it: the values it held are copied in after the advice.
pub(crate) fn reserve(values: &mut Vec<f64>, additional: usize) {
    if values.capacity() - values.len() >= additional {
        return;
    }
    let needed = values.len().saturating_add(additional);
    let capacity = needed.max(values.capacity().saturating_mul(2));
    if capacity.saturating_mul(std::mem::size_of::<f64>()) < MIN_BYTES {
        values.reserve_exact(capacity - values.len());
        return;
    }
    let mut fresh = Vec::with_capacity(capacity);
    advise(&fresh);
    fresh.extend_from_slice(values);
    *values = fresh;
}

/// As [`reserve`], returning the allocator's refusal instead of aborting the process: for
/// the buffers sized by a whole signal's length, which may not fit the memory left.
pub(crate) fn try_reserve(
    values: &mut Vec<f64>,
    additional: usize,
) -> Result<(), std::collections::TryReserveError> {
    if values.capacity() - values.len() >= additional {
        return Ok(());
    }
    let needed = values.len().saturating_add(additional);
    if needed.saturating_mul(std::mem::size_of::<f64>()) < MIN_BYTES {
        return values.try_reserve_exact(additional);
    }
    let mut fresh = Vec::new();
    fresh.try_reserve_exact(needed)?;
    advise(&fresh);
    fresh.extend_from_slice(values);
    *values = fresh;
    Ok(())
}

/// The whole huge pages inside `bytes` bytes from address `start`: their first address
/// and length in bytes, if the allocation is large enough to be advised.
fn advised_range(start: usize, bytes: usize) -> Option<(usize, usize)> {
    if bytes < MIN_BYTES {
        return None;
    }
    let first = start.checked_next_multiple_of(HUGE_PAGE)?;
    let end = start.checked_add(bytes)? / HUGE_PAGE * HUGE_PAGE;
    (end > first).then(|| (first, end - first))
}

/// Asks the kernel to back the whole huge pages of `values`' allocation with huge pages,
/// where it allows that (`/sys/kernel/mm/transparent_hugepage/enabled` set to `always`
/// or `madvise`). A hint, true where the kernel took it; nothing else changes where it
/// is refused or unsupported.
fn advise(values: &Vec<f64>) -> bool {
    let bytes = values.capacity() * std::mem::size_of::<f64>();
    advised_range(values.as_ptr() as usize, bytes).is_some_and(|(first, len)| hint(first, len))
}

#[cfg(target_os = "linux")]
fn hint(first: usize, len: usize) -> bool {
    // SAFETY: `first..first + len` lies inside one live allocation of ours (see
    // `advised_range`). MADV_HUGEPAGE never touches the contents: it splits the mapping
    // at the range's ends and flags the range. (On such a split mapping glibc's `realloc`
    // cannot move the block with `mremap` and copies it instead; `reserve` copies anyway.)
    #[allow(unsafe_code)]
    let status = unsafe { libc::madvise(first as *mut libc::c_void, len, libc::MADV_HUGEPAGE) };
    status == 0
}

#[cfg(not(target_os = "linux"))]
fn hint(_first: usize, _len: usize) -> bool {
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_whole_huge_pages_of_large_allocations_are_advised() {
        assert_eq!(advised_range(HUGE_PAGE, MIN_BYTES - 1), None);
        assert_eq!(
            advised_range(HUGE_PAGE, MIN_BYTES),
            Some((HUGE_PAGE, MIN_BYTES))
        );
        // an allocation starting 16 bytes into a huge page: the next two whole ones
        assert_eq!(
            advised_range(HUGE_PAGE + 16, 3 * HUGE_PAGE),
            Some((2 * HUGE_PAGE, 2 * HUGE_PAGE))
        );
        assert_eq!(
            advised_range(HUGE_PAGE + 16, 2 * HUGE_PAGE + 8),
            Some((2 * HUGE_PAGE, HUGE_PAGE))
        );
        assert_eq!(advised_range(usize::MAX - 8, MIN_BYTES), None);
    }

    #[test]
    fn reserving_keeps_the_values_and_grows_as_vec_does() {
        let mut short = vec![1.0, 2.0, 3.0];
        reserve(&mut short, 10);
        assert_eq!(
            (short.as_slice(), short.capacity()),
            (&[1.0, 2.0, 3.0][..], 13)
        );
        let cap = short.capacity();
        reserve(&mut short, 10);
        assert_eq!(short.capacity(), cap, "room enough: nothing reallocates");
        let n = MIN_BYTES / 8 + 5;
        let mut long: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let old = long.capacity();
        reserve(&mut long, 1);
        assert_eq!(long.capacity(), 2 * old);
        assert!(long.iter().enumerate().all(|(i, &x)| x == i as f64));
        assert_eq!(long.len(), n);
    }

    /// The flags of the mapping holding `address`, from `/proc/self/smaps`.
    #[cfg(target_os = "linux")]
    fn mapping_flags(address: usize) -> Option<String> {
        let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
        let mut inside = false;
        for line in smaps.lines() {
            let range = line
                .split_whitespace()
                .next()
                .and_then(|r| r.split_once('-'));
            let bounds = range.and_then(|(a, b)| {
                Some((
                    usize::from_str_radix(a, 16).ok()?,
                    usize::from_str_radix(b, 16).ok()?,
                ))
            });
            if let Some((a, b)) = bounds {
                inside = (a..b).contains(&address);
            } else if let (true, Some(flags)) = (inside, line.strip_prefix("VmFlags:")) {
                return Some(flags.to_string());
            }
        }
        None
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_long_reservation_is_marked_for_huge_pages() {
        // larger than glibc ever serves from its heap: mappings of their own
        let values = 24 * HUGE_PAGE / 8;
        let control: Vec<f64> = Vec::with_capacity(values);
        let at = |v: &Vec<f64>| advised_range(v.as_ptr() as usize, values * 8).map(|r| r.0);
        let Some(flags) = at(&control).and_then(mapping_flags) else {
            return; // no /proc/self/smaps to read the flags from
        };
        let marked = |flags: &str| flags.split_whitespace().any(|f| f == "hg");
        if marked(&flags) {
            return; // the allocator advises every mapping itself: nothing to tell apart
        }
        let mut reserved = Vec::new();
        reserve(&mut reserved, values);
        if !advise(&control) {
            return; // the kernel refuses the advice (no transparent huge pages)
        }
        let flags = at(&reserved).and_then(mapping_flags).expect("mapped");
        assert!(marked(&flags), "{flags}");
    }
}
