//! Reuse of freed memory by a process that runs whole signals one after another, as a
//! benchmark's repeats do. Each run keeps its outputs in fresh
//! blocks, hundreds of MB for ten seconds of autocorrelation, and glibc maps blocks that
//! large for each allocation and unmaps them when freed: every run then pays the kernel
//! for zeroing that memory again on first touch (a fifth of a whole-signal run's time on
//! the development VMs). Kept in the heap instead, the next run's blocks reuse it.

/// The most memory (bytes) the heap keeps free at its top before handing it back: as
/// much as glibc's `int` parameter allows (2 GiB).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const KEEP_AT_TOP: libc::c_int = libc::c_int::MAX;

/// Makes the C allocator serve every allocation from its main heap, never from a mapping
/// of its own nor from a per-thread heap (which maps blocks it cannot hold), and keep up
/// to 2 GiB of freed memory there for the next allocations instead of returning it to the
/// kernel. A process-wide choice for programs that repeat large runs (`afe bench`): a
/// library should not make it for its caller. True where it took effect (glibc on Linux);
/// elsewhere nothing changes.
pub fn keep_freed_memory() -> bool {
    set_allocator_options()
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn set_allocator_options() -> bool {
    [
        (libc::M_ARENA_MAX, 1),
        (libc::M_MMAP_MAX, 0),
        (libc::M_TRIM_THRESHOLD, KEEP_AT_TOP),
    ]
    .into_iter()
    .all(|(parameter, value)| {
        // SAFETY: `mallopt` only sets an allocator parameter, under the allocator's own
        // lock; every live allocation stays as it is.
        #[allow(unsafe_code)]
        let status = unsafe { libc::mallopt(parameter, value) };
        status == 1
    })
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn set_allocator_options() -> bool {
    false
}
