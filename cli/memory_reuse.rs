//! Reuse of freed memory by a process that runs whole signals one after another, as a
//! benchmark's repeats do. Each run keeps its outputs in fresh blocks, hundreds of MB for
//! ten seconds of autocorrelation, and glibc maps blocks that large for each allocation
//! and unmaps them when freed: every run then pays the kernel for zeroing that memory
//! again on first touch (a fifth of a whole-signal run's time on the development VMs).
//! Kept in the heap instead, the next run's blocks reuse it.

/// Free memory at the heap's top (bytes) above which glibc hands that memory back to the
/// kernel: as much as its `int` parameter allows (2 GiB).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const TRIM_ABOVE: libc::c_int = libc::c_int::MAX;

/// Makes the C allocator serve allocations from its main heap, never from a mapping of
/// their own, and keep the memory freed there for the next allocations: the heap's top is
/// handed back to the kernel only once more than 2 GiB of it is free. Call it before the
/// process starts any thread: a thread that has allocated already keeps its own heap
/// (which maps the blocks it cannot hold). A process-wide choice for programs that repeat
/// large runs (`afe bench`); `extract`, `stream` and `serve` keep glibc's defaults, and a
/// library should not make it for its caller. True where every option took effect (glibc
/// on Linux); elsewhere nothing changes.
pub fn keep_freed_memory() -> bool {
    set_allocator_options()
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn set_allocator_options() -> bool {
    [
        (libc::M_ARENA_MAX, 1),
        (libc::M_MMAP_MAX, 0),
        (libc::M_TRIM_THRESHOLD, TRIM_ABOVE),
    ]
    .map(|(parameter, value)| {
        // SAFETY: `mallopt` only sets an allocator parameter, under the allocator's own
        // lock; every live allocation stays as it is.
        #[allow(unsafe_code)]
        let status = unsafe { libc::mallopt(parameter, value) };
        status == 1
    })
    .into_iter()
    .all(|set| set)
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn set_allocator_options() -> bool {
    false
}
