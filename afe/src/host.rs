//! The machine a measurement ran on, for the reports of `afe bench` and `afe stream`:
//! speed figures are only comparable with the CPU and instruction set they came from,
//! and figures on several threads with how far apart their cores are.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use serde::Serialize;

/// The CPU, its logical cores and the instruction set the kernels take.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Host {
    /// The CPU's model name (Linux's `/proc/cpuinfo`), or the architecture where that
    /// is not known.
    pub cpu: String,
    /// Logical cores this process may use.
    pub cores: usize,
    /// The SIMD kernels' instruction set: `avx512`, `avx2` or `baseline`.
    pub simd: &'static str,
    /// Whether the CPU has AVX-512, so that `simd: avx2` with `avx512_available: true`
    /// is the forced AVX2 path of a `no-avx512` build.
    pub avx512_available: bool,
    /// The version of this crate.
    pub version: &'static str,
    /// How long one cache line takes to go from one thread's core to another's and
    /// back, in ns (see [`core_to_core_ns`]); `None` with one core, or on a machine too
    /// busy to run the two threads side by side.
    pub core_to_core_ns: Option<f64>,
}

impl Host {
    /// Describes the machine this runs on.
    pub fn detect() -> Self {
        Host {
            cpu: cpu_model().unwrap_or_else(|| std::env::consts::ARCH.to_string()),
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            simd: afe_core::cpu::simd_path(),
            avx512_available: afe_core::cpu::cpu_has_avx512(),
            version: env!("CARGO_PKG_VERSION"),
            core_to_core_ns: core_to_core_ns(),
        }
    }

    /// One line for a person: `AMD EPYC, 2 cores (80 ns apart), avx512`, with
    /// `(AVX-512 off)` on the forced AVX2 path.
    pub fn describe(&self) -> String {
        let forced = if self.avx512_available && self.simd != "avx512" {
            " (AVX-512 off)"
        } else {
            ""
        };
        let apart = self
            .core_to_core_ns
            .map_or(String::new(), |ns| format!(" ({ns:.0} ns apart)"));
        let cores = if self.cores == 1 { "core" } else { "cores" };
        format!(
            "{}, {} {cores}{apart}, {}{forced}",
            self.cpu, self.cores, self.simd
        )
    }
}

/// The round trip of one cache line between two threads, in ns: the fastest of up to
/// 50 batches of 100 hand-overs back and forth, within 50 ms. The two threads are pinned
/// to the first two logical CPUs this process may use, so that a busy machine cannot put
/// both on one core; a batch during which either thread lost its CPU only comes out
/// slower, so the fastest batch is the undisturbed round trip. Cores that share a
/// last-level cache take about 50–100 ns; cores apart (another chiplet or socket, or the
/// virtual CPUs of a VM placed so by its host) 300 ns and more, and the scheduler's
/// threads, which hand each block's signals from core to core, then gain less from the
/// second core. `None` with one CPU, when no second thread can be started, or when not
/// one batch ends within the 50 ms (a machine too busy to run the two side by side).
pub fn core_to_core_ns() -> Option<f64> {
    let [first, second] = two_cpus()?;
    /// The line handed over: the first thread writes odd values, the second even ones.
    #[repr(align(128))]
    struct Line(AtomicU64);
    /// Set by the first thread when it is done (on a line of its own).
    #[repr(align(128))]
    struct Stop(AtomicBool);
    const TRIPS: u64 = 100;
    const BATCHES: usize = 50;
    let (line, stop) = (Line(AtomicU64::new(0)), Stop(AtomicBool::new(false)));
    let deadline = Instant::now() + Duration::from_millis(50);
    let late = || Instant::now() > deadline;
    std::thread::scope(|s| {
        let answer = std::thread::Builder::new().spawn_scoped(s, || {
            pin_to(second);
            while !stop.0.load(Ordering::Acquire) {
                let v = line.0.load(Ordering::Acquire);
                if v % 2 == 1 {
                    // (only the value read: never over a newer one)
                    let _ = line
                        .0
                        .compare_exchange(v, v + 1, Ordering::Release, Ordering::Relaxed);
                } else {
                    std::hint::spin_loop();
                }
            }
        });
        if answer.is_err() {
            return None;
        }
        let ask = std::thread::Builder::new().spawn_scoped(s, || {
            pin_to(first);
            let mut fastest = None::<f64>;
            let mut next = 0;
            'batches: for _ in 0..BATCHES {
                let start = Instant::now();
                for _ in 0..TRIPS {
                    line.0.store(next + 1, Ordering::Release);
                    let mut spins = 0u32;
                    while line.0.load(Ordering::Acquire) != next + 2 {
                        spins = spins.wrapping_add(1);
                        if spins.is_multiple_of(1024) && late() {
                            break 'batches;
                        }
                        std::hint::spin_loop();
                    }
                    next += 2;
                }
                let ns = start.elapsed().as_secs_f64() * 1e9 / TRIPS as f64;
                fastest = Some(fastest.map_or(ns, |f| f.min(ns)));
                if late() {
                    break;
                }
            }
            fastest
        });
        let fastest = ask.ok().and_then(|ask| ask.join().ok().flatten());
        stop.0.store(true, Ordering::Release);
        fastest
    })
}

/// The first two logical CPUs this process may run on, or `None` with fewer.
fn two_cpus() -> Option<[usize; 2]> {
    let allowed = nix::sched::sched_getaffinity(nix::unistd::Pid::from_raw(0)).ok()?;
    let mut cpus = (0..nix::sched::CpuSet::count()).filter(|&c| allowed.is_set(c) == Ok(true));
    Some([cpus.next()?, cpus.next()?])
}

/// Keeps the calling thread on one logical CPU (best effort: unpinned, the measure is
/// only less sure to find the two threads on two cores).
fn pin_to(cpu: usize) {
    let mut set = nix::sched::CpuSet::new();
    if set.set(cpu).is_ok() {
        let _ = nix::sched::sched_setaffinity(nix::unistd::Pid::from_raw(0), &set);
    }
}

/// The first `model name` of `/proc/cpuinfo`.
fn cpu_model() -> Option<String> {
    let info = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    model_name(&info)
}

fn model_name(cpuinfo: &str) -> Option<String> {
    cpuinfo.lines().find_map(|line| {
        let (key, value) = line.split_once(':')?;
        let value = value.trim();
        (key.trim() == "model name" && !value.is_empty()).then(|| value.to_string())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_model_name_is_read_off_cpuinfo() {
        let info = "processor\t: 0\nvendor_id\t: GenuineIntel\nmodel name\t: Intel(R) Xeon(R) \
                    Platinum 8375C CPU @ 2.90GHz\nflags\t\t: fpu avx2\n\nprocessor\t: 1\n\
                    model name\t: other\n";
        assert_eq!(
            model_name(info).as_deref(),
            Some("Intel(R) Xeon(R) Platinum 8375C CPU @ 2.90GHz")
        );
        assert_eq!(model_name("processor\t: 0\nmodel name\t:\n"), None);
        assert_eq!(model_name(""), None);
    }

    #[test]
    fn the_description_names_a_forced_avx2_path() {
        let mut host = Host {
            cpu: "Xeon".into(),
            cores: 2,
            simd: "avx2",
            avx512_available: true,
            version: "0",
            core_to_core_ns: Some(81.6),
        };
        assert_eq!(
            host.describe(),
            "Xeon, 2 cores (82 ns apart), avx2 (AVX-512 off)"
        );
        host.avx512_available = false;
        host.core_to_core_ns = None;
        host.cores = 1;
        assert_eq!(host.describe(), "Xeon, 1 core, avx2");
    }

    #[test]
    fn the_round_trip_between_cores_is_measured_where_there_are_two() {
        if two_cpus().is_none() {
            assert_eq!(core_to_core_ns(), None);
            return;
        }
        // the two pinned threads need to run side by side for one batch (~10 µs) in
        // 50 ms; a machine busy with other tests may deny that now and then
        let Some(ns) = (0..20).find_map(|_| core_to_core_ns()) else {
            panic!("the two threads never ran side by side in 20 tries of 50 ms")
        };
        // a hand-over costs more than a cache hit; one batch ends within 50 ms
        assert!(ns > 10.0 && ns < 500_000.0, "{ns} ns");
    }
}
