//! `keep_freed_memory` in a process of its own, on its main thread: it changes the
//! allocator for the whole process, and keeps the memory of the main thread's heap (the
//! test harness would run the test on a thread of its own, with a heap of its own). The
//! CLI's own module, compiled here through `#[path]`.

#[path = "../cli/memory_reuse.rs"]
#[allow(dead_code)]
mod memory_reuse;

/// Answers a test runner's listing (`--list --format terse`, as cargo-nextest asks every
/// test binary) with the one test this binary is; true when it was such a listing.
fn listed() -> bool {
    let args: Vec<String> = std::env::args().collect();
    if !args.iter().any(|a| a == "--list") {
        return false;
    }
    if !args.iter().any(|a| a == "--ignored") {
        println!("memory_reuse: test");
    }
    true
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn main() {
    if listed() {
        return;
    }
    assert!(memory_reuse::keep_freed_memory());
    let values = (64 << 20) / std::mem::size_of::<f64>();
    drop(std::hint::black_box(vec![1.0_f64; values]));
    let before = minor_faults();
    let again = std::hint::black_box(vec![2.0_f64; values]);
    let faults = minor_faults() - before;
    assert_eq!(again[values - 1], 2.0);
    // unmapped and mapped afresh, its 64 MiB would take 16384 faults (32 on huge pages)
    assert!(faults < 8, "{faults} page faults writing a reused block");
    println!("a freed block was reused: {faults} page faults writing it again");
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn main() {
    if listed() {
        return;
    }
    assert!(!memory_reuse::keep_freed_memory());
}

/// Page faults of this process that the kernel served without I/O.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn minor_faults() -> u64 {
    let stat = std::fs::read_to_string("/proc/self/stat").expect("/proc/self/stat");
    // after the command name (in parentheses, which may hold spaces) minflt is the eighth
    // field (the tenth of the whole line)
    let rest = &stat[stat.rfind(')').expect("command name") + 2..];
    rest.split(' ')
        .nth(7)
        .expect("minflt")
        .parse()
        .expect("a count")
}
