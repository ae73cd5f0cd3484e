//! Fuzzing (issue 13): random and mutated WAV bytes into the WAV reader and the
//! `afe extract` path, random parameter JSON into the parameter parser and the request
//! resolver, and random chunkings with run-time edits into the manager, on the sequential
//! executor and the concurrent one in lockstep.
//!
//! Each target runs for a time budget, once with a fixed seed and once with a fresh one
//! (printed with the command that reproduces it). What a case must do: return a value or
//! a typed error, never panic; take under [`CASE_LIMIT`] of CPU time; and never make the
//! process hold more than [`HEAP_LIMIT`] bytes of heap (the counting allocator below
//! refuses beyond it, which aborts the process: the seed line printed first says what to
//! rerun).
//!
//! Environment: `AFE_FUZZ_SECONDS` (budget per target, default [`DEFAULT_SECONDS`]),
//! `AFE_FUZZ_SEED` (run only this seed, for the whole budget), `AFE_FUZZ_CASE` (run only
//! this case of that seed). A longer run: `AFE_FUZZ_SECONDS=600 cargo test --test integration fuzz::`.
//!
//! One module per target, named as the target is (`fuzz::wav_bytes` runs it); [`draws`]
//! holds the random values they share.

mod accepted_ranges;
mod draws;
mod manager_edits;
mod parameter_json;
mod wav_bytes;

use std::io::Write;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use afe::{Error, Manager};

/// Heap the test process may hold at once (2 GiB): far above what a case needs (inputs
/// are a few thousand frames; the peak is a few hundred MiB), below what a header or a
/// parameter that sizes a buffer from untrusted numbers asks for (a WAV header declares up
/// to 4 GiB of samples; 2^32 AMS filters asked for 34 GB). Valid windows are drawn short
/// (see [`draws::LONGEST_DRAWN_S`]): the longest a processor accepts, 2^24 values over all
/// channels, makes the precedence processor alone hold 1.5 GiB.
const HEAP_LIMIT: usize = 2 << 30;

#[global_allocator]
static ALLOCATOR: cap::Cap<std::alloc::System> = cap::Cap::new(std::alloc::System, HEAP_LIMIT);

/// Most CPU time a single case may take on its own thread (they normally take
/// milliseconds; the heaviest a few hundred): beyond it the case counts as a hang. CPU
/// time, not wall time, so that what else the host runs (the CI's Python tests beside
/// these, a vCPU taken away) does not count against the case.
const CASE_LIMIT: Duration = Duration::from_secs(10);

/// A case still running after this long never returns: a watchdog thread names it and
/// ends the process.
const HANG_LIMIT: Duration = Duration::from_secs(60);

/// Default time budget per target in seconds, split between the fixed and a fresh seed.
const DEFAULT_SECONDS: f64 = 15.0;

/// CPU time the calling thread has used: a case's cost, whatever the host's load (the
/// executor threads a case starts are not counted; the watchdog's wall-clock
/// [`HANG_LIMIT`] covers them).
#[cfg(target_os = "linux")]
fn thread_cpu_time() -> Duration {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `clock_gettime` writes one `timespec` through a pointer to a live local.
    #[allow(unsafe_code)]
    let status = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) };
    assert_eq!(status, 0, "the thread's CPU clock is not readable");
    Duration::new(t.tv_sec.unsigned_abs(), t.tv_nsec.unsigned_abs() as u32)
}

/// Elsewhere, the wall time since the process's first call (a loaded host counts).
#[cfg(not(target_os = "linux"))]
fn thread_cpu_time() -> Duration {
    static START: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
    START.get_or_init(Instant::now).elapsed()
}

/// The seed every run starts with, so that CI always covers the same cases first.
const FIXED_SEED: u64 = 0x00af_e13f_0220_5eed;

/// Most input frames a case feeds through a manager.
const MAX_FRAMES: usize = 4096;

/// A small seeded generator (SplitMix64): fast, and every case reproducible from its seed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (`n` > 0).
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    /// True once in `n` draws on average.
    fn one_in(&mut self, n: usize) -> bool {
        self.below(n) == 0
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }

    fn byte(&mut self) -> u8 {
        self.next() as u8
    }
}

/// The seed of case `case` of a run seeded `seed`: every case can be rerun alone.
fn case_seed(seed: u64, case: u64) -> u64 {
    Rng(seed ^ case.wrapping_mul(0xd1b5_4a32_d192_ed03)).next()
}

/// Prints past the test harness's capture, so that the seed lines reach the log even when
/// the test passes or the process aborts.
fn say(line: &str) {
    let _ = writeln!(std::io::stderr(), "{line}");
}

thread_local! {
    /// What the cases of the running target did, counted by outcome.
    static TALLY: std::cell::RefCell<std::collections::BTreeMap<String, u64>> =
        Default::default();
}

/// Counts one `outcome` of the running target.
fn count(outcome: &str) {
    TALLY.with(|t| *t.borrow_mut().entry(outcome.to_string()).or_default() += 1);
}

/// Set when one case runs alone (`AFE_FUZZ_CASE`): the case then prints what it does.
static SHOW: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Prints what a case does when it runs alone.
fn note(line: impl FnOnce() -> String) {
    if SHOW.load(std::sync::atomic::Ordering::Relaxed) {
        say(&line());
    }
}

fn env_number<T: std::str::FromStr>(name: &str) -> Option<T> {
    let v = std::env::var(name).ok()?;
    match v.trim().parse::<T>() {
        Ok(x) => Some(x),
        Err(_) => panic!("{name}={v}: expected a non-negative number"),
    }
}

/// A scratch folder of this process for `target` (inputs written there stay after a
/// failure, for reproduction).
fn scratch(target: &str, seed: u64) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("afe-fuzz-{}", std::process::id()))
        .join(format!("{target}-{seed}"));
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<String>()
        .cloned()
        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "(a panic without a message)".into())
}

/// The case running now, for the watchdog: its rerun command, number and start.
static RUNNING: std::sync::Mutex<Option<(String, u64, Instant)>> = std::sync::Mutex::new(None);

fn running() -> std::sync::MutexGuard<'static, Option<(String, u64, Instant)>> {
    RUNNING
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Starts (once) the thread that ends the process when a case hangs past [`HANG_LIMIT`].
fn watchdog() {
    static START: std::sync::Once = std::sync::Once::new();
    START.call_once(|| {
        std::thread::spawn(|| loop {
            std::thread::sleep(Duration::from_secs(1));
            if let Some((rerun, k, t0)) = running().as_ref() {
                if t0.elapsed() > HANG_LIMIT {
                    say(&format!(
                        "fuzz: case {k} has run for {} s, a hang: rerun it: AFE_FUZZ_CASE={k} {rerun}",
                        t0.elapsed().as_secs()
                    ));
                    std::process::exit(1);
                }
            }
        });
    });
}

/// One target at a time: the heap limit is the whole process's, so targets running in
/// parallel test threads would add their peaks up.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Runs cases of `target` for the time budget: the fixed seed and a fresh one, or only
/// `AFE_FUZZ_SEED` (and only `AFE_FUZZ_CASE` of it). `case` gets the case's generator
/// and a scratch folder; it returns an error for a broken invariant.
fn fuzz(target: &str, mut case: impl FnMut(&mut Rng, &Path) -> Result<(), String>) {
    let _turn = ONE_AT_A_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let budget = Duration::from_secs_f64(
        env_number::<f64>("AFE_FUZZ_SECONDS")
            .unwrap_or(DEFAULT_SECONDS)
            .max(0.0),
    );
    let only_case = env_number::<u64>("AFE_FUZZ_CASE");
    watchdog();
    SHOW.store(only_case.is_some(), std::sync::atomic::Ordering::Relaxed);
    let seeds: Vec<(u64, &str, Duration)> = match env_number::<u64>("AFE_FUZZ_SEED") {
        Some(s) => vec![(s, "given", budget)],
        None => {
            let now = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos() as u64);
            let fresh = Rng(now ^ u64::from(std::process::id()) << 32).next() >> 12;
            vec![
                (FIXED_SEED, "fixed", budget / 2),
                (fresh, "fresh", budget / 2),
            ]
        }
    };
    for (seed, label, part) in seeds {
        let rerun = format!("AFE_FUZZ_SEED={seed} cargo test --test integration fuzz::{target}");
        say(&format!(
            "fuzz {target}: {label} seed {seed} (reproduce: {rerun})"
        ));
        let dir = scratch(target, seed);
        let start = Instant::now();
        let mut cases = 0u64;
        // the case during which the process's heap peak last rose (with the peak)
        let mut peak_case = None;
        // the case that took the most CPU time, for the margin below CASE_LIMIT
        let mut slowest = (0, Duration::ZERO);
        let first_peak = ALLOCATOR.max_allocated();
        let range = match only_case {
            Some(c) => c..c + 1,
            None => 0..u64::MAX,
        };
        for k in range {
            if only_case.is_none() && k > 0 && start.elapsed() >= part {
                break;
            }
            // what an abort (the heap limit) leaves behind to name its case
            let _ = std::fs::write(
                dir.join("current-case"),
                format!("AFE_FUZZ_CASE={k} {rerun}\n"),
            );
            let mut rng = Rng(case_seed(seed, k));
            let cpu0 = thread_cpu_time();
            *running() = Some((rerun.clone(), k, Instant::now()));
            let outcome = catch_unwind(AssertUnwindSafe(|| case(&mut rng, &dir)));
            *running() = None;
            let took = thread_cpu_time().saturating_sub(cpu0);
            if took > slowest.1 {
                slowest = (k, took);
            }
            let fail = |why: String| -> ! {
                panic!(
                    "fuzz {target}: seed {seed}, case {k}: {why}\n  rerun it: \
                     AFE_FUZZ_CASE={k} {rerun}\n  its files: {}",
                    dir.display()
                )
            };
            match outcome {
                Err(p) => fail(format!("panicked: {}", panic_message(p.as_ref()))),
                Ok(Err(why)) => fail(why),
                Ok(Ok(())) if took > CASE_LIMIT => fail(format!(
                    "took {:.1} s of CPU time (limit {} s): a hang?",
                    took.as_secs_f64(),
                    CASE_LIMIT.as_secs()
                )),
                Ok(Ok(())) => {}
            }
            let peak = ALLOCATOR.max_allocated();
            if peak > peak_case.map_or(first_peak, |(_, p)| p) {
                peak_case = Some((k, peak));
            }
            cases += 1;
        }
        let secs = start.elapsed().as_secs_f64();
        let peak = match peak_case {
            Some((k, p)) => format!("{} MiB, last risen during case {k}", p >> 20),
            None => "unchanged".into(),
        };
        say(&format!(
            "fuzz {target}: {label} seed {seed}: {cases} cases in {secs:.1} s ({:.0}/s); \
             process heap peak {peak} (limit {} MiB); slowest case {} ({:.2} s of CPU \
             time, limit {} s)",
            cases as f64 / secs.max(1e-9),
            HEAP_LIMIT >> 20,
            slowest.0,
            slowest.1.as_secs_f64(),
            CASE_LIMIT.as_secs()
        ));
        let tally = TALLY.with(|t| std::mem::take(&mut *t.borrow_mut()));
        let tally: Vec<String> = tally.iter().map(|(k, n)| format!("{k} {n}")).collect();
        say(&format!(
            "fuzz {target}: {label} seed {seed}: {}",
            tally.join(", ")
        ));
        let _ = std::fs::remove_dir_all(&dir);
        // the process's folder too, once no failed case's files are in it
        if let Some(parent) = dir.parent() {
            let _ = std::fs::remove_dir(parent);
        }
    }
}

/// Errors that are bugs whatever the input: a panic caught on a worker, a stalled
/// scheduler.
fn check_error(e: &Error) -> Result<(), String> {
    match e {
        Error::WorkerPanicked | Error::Stalled(_) => {
            Err(format!("a bug surfaced as an error: {e}"))
        }
        _ => Ok(()),
    }
}

/// The signals computed sample by sample, at the input's rate.
const SAMPLE_BY_SAMPLE: [&str; 5] = [
    "time",
    "butterworth",
    "filterbank",
    "innerhaircell",
    "adaptation",
];

/// Checks the outputs shown after a chunk of `len` samples: each block as wide as its
/// signal says, and the sample-by-sample signals one value per input sample.
fn check_outputs(mgr: &Manager, len: usize) -> Result<(), String> {
    for s in mgr.signals(true) {
        if s.new.width() != s.info.width() {
            return Err(format!(
                "{}: blocks {} wide, the signal says {}",
                s.key(),
                s.new.width(),
                s.info.width()
            ));
        }
        if SAMPLE_BY_SAMPLE.contains(&s.name) && s.new.frames() != len {
            return Err(format!(
                "{}: {} frames out of a chunk of {len} samples",
                s.key(),
                s.new.frames()
            ));
        }
    }
    Ok(())
}
