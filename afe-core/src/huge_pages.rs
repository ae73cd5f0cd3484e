//! Transparent huge pages for long blocks: a whole signal's output is written once to
//! fresh memory, and on Linux each first write to a 4-KiB page is a fault (about 2 µs on
//! a virtual machine, a third of the time of a whole-signal run that keeps its outputs).
//! Advised, the kernel backs the buffer with 2-MiB pages: one fault per 512 pages.

/// Allocations from this many bytes up are advised (smaller ones hold few whole 2-MiB
/// pages, and may share them with other allocations' pages).
const MIN_BYTES: usize = 4 << 20;

/// The size of a huge page on x86-64 and aarch64 (bytes).
const HUGE_PAGE: usize = 2 << 20;

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
/// or `madvise`). A hint: nothing changes where it is refused or unsupported.
pub(crate) fn advise(values: &Vec<f64>) {
    let bytes = values.capacity() * std::mem::size_of::<f64>();
    if let Some((first, len)) = advised_range(values.as_ptr() as usize, bytes) {
        hint(first, len);
    }
}

#[cfg(target_os = "linux")]
fn hint(first: usize, len: usize) {
    // SAFETY: `first..first + len` lies inside one live allocation of ours (see
    // `advised_range`), and MADV_HUGEPAGE changes neither the mapping nor its contents,
    // only how the kernel backs the pages. The result is ignored: the advice is a hint.
    #[allow(unsafe_code)]
    unsafe {
        libc::madvise(first as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
    }
}

#[cfg(not(target_os = "linux"))]
fn hint(_first: usize, _len: usize) {}

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
    fn advising_leaves_the_values_as_they_were() {
        let mut v: Vec<f64> = (0..(3 * HUGE_PAGE / 8)).map(|i| i as f64).collect();
        advise(&v);
        v.push(-1.0);
        assert!(v
            .iter()
            .take(v.len() - 1)
            .enumerate()
            .all(|(i, &x)| x == i as f64));
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
    fn a_long_buffer_is_marked_for_huge_pages() {
        if !std::path::Path::new("/sys/kernel/mm/transparent_hugepage").exists() {
            return; // a kernel without transparent huge pages refuses the advice
        }
        // larger than glibc ever serves from its heap: a mapping of its own, never advised
        let bytes = 24 * HUGE_PAGE;
        let v = vec![0.0; bytes / 8];
        let (first, _) = advised_range(v.as_ptr() as usize, bytes).expect("large");
        let before = mapping_flags(first).expect("the buffer is mapped");
        assert!(!before.split_whitespace().any(|f| f == "hg"), "{before}");
        advise(&v);
        let after = mapping_flags(first).expect("the buffer is mapped");
        assert!(after.split_whitespace().any(|f| f == "hg"), "{after}");
    }
}
