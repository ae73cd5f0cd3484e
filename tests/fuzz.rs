//! Fuzzing (issue 13): random and mutated WAV bytes into the WAV reader and the
//! `afe extract` path, random parameter JSON into the parameter parser and the request
//! resolver, and random chunkings with run-time edits into the manager, on the sequential
//! executor and the concurrent one in lockstep.
//!
//! Each target runs for a time budget, once with a fixed seed and once with a fresh one
//! (printed with the command that reproduces it). What a case must do: return a value or
//! a typed error, never panic; take under [`CASE_LIMIT`]; and never make the process hold
//! more than [`HEAP_LIMIT`] bytes of heap (the counting allocator below refuses beyond it,
//! which aborts the process: the seed line printed first says what to rerun).
//!
//! Environment: `AFE_FUZZ_SECONDS` (budget per target, default [`DEFAULT_SECONDS`]),
//! `AFE_FUZZ_SEED` (run only this seed, for the whole budget), `AFE_FUZZ_CASE` (run only
//! this case of that seed). A longer run: `AFE_FUZZ_SECONDS=600 cargo test --test integration fuzz::`.

use std::collections::VecDeque;
use std::io::Write;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use afe::bass_source::{WavReader, WavSamples};
use afe::extract::{run_source, Job};
use afe::{Error, Manager, ParamMap, RequestHandle};
use afe_core::ParamKind;
use serde_json::{json, Value};

/// Heap the test process may hold at once (2 GiB): far above what a case needs (inputs
/// are a few thousand frames; the peak is a few hundred MiB), below what a header or a
/// parameter that sizes a buffer from untrusted numbers asks for (a WAV header declares up
/// to 4 GiB of samples; 2^32 AMS filters asked for 34 GB). Valid windows are drawn short
/// (see [`LONGEST_DRAWN_S`]): the longest a processor accepts, 2^24 values over all
/// channels, makes the precedence processor alone hold 1.5 GiB.
const HEAP_LIMIT: usize = 2 << 30;

#[global_allocator]
static ALLOCATOR: cap::Cap<std::alloc::System> = cap::Cap::new(std::alloc::System, HEAP_LIMIT);

/// Longest a single case may take (they normally take milliseconds): beyond it the case
/// counts as a hang.
const CASE_LIMIT: Duration = Duration::from_secs(10);

/// A case still running after this long never returns: a watchdog thread names it and
/// ends the process.
const HANG_LIMIT: Duration = Duration::from_secs(60);

/// Default time budget per target in seconds, split between the fixed and a fresh seed.
const DEFAULT_SECONDS: f64 = 15.0;

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
    let dir = std::env::temp_dir()
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
            let t0 = Instant::now();
            *running() = Some((rerun.clone(), k, t0));
            let outcome = catch_unwind(AssertUnwindSafe(|| case(&mut rng, &dir)));
            *running() = None;
            let took = t0.elapsed();
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
                    "took {:.1} s (limit {} s): a hang?",
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
             process heap peak {peak} (limit {} MiB)",
            cases as f64 / secs.max(1e-9),
            HEAP_LIMIT >> 20
        ));
        let tally = TALLY.with(|t| std::mem::take(&mut *t.borrow_mut()));
        let tally: Vec<String> = tally.iter().map(|(k, n)| format!("{k} {n}")).collect();
        say(&format!(
            "fuzz {target}: {label} seed {seed}: {}",
            tally.join(", ")
        ));
        let _ = std::fs::remove_dir_all(&dir);
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

// ---------------------------------------------------------------------------------------
// Target 1: WAV bytes into the reader and the extract path.

/// A valid WAV file of random format and content, with random extra chunks (odd ones
/// padded), built in memory.
fn valid_wav(rng: &mut Rng) -> Vec<u8> {
    let channels: u16 = *rng.pick(&[1, 1, 2, 2, 2, 3]);
    let (bits, float): (u16, bool) = *rng.pick(&[
        (8, false),
        (16, false),
        (24, false),
        (32, false),
        (32, true),
    ]);
    let extensible = rng.one_in(3);
    let rate: u32 = if rng.one_in(8) {
        1 + rng.below(200_000) as u32
    } else {
        *rng.pick(&[8000, 16000, 22050, 44100, 48000, 96000])
    };
    let frames = match rng.below(4) {
        0 => rng.below(8),
        _ => rng.below(3000),
    };
    let width = usize::from(bits / 8);
    let block = usize::from(channels) * width;
    let mut fmt = Vec::new();
    fmt.extend_from_slice(
        &(if extensible {
            0xFFFEu16
        } else if float {
            3
        } else {
            1
        })
        .to_le_bytes(),
    );
    fmt.extend_from_slice(&channels.to_le_bytes());
    fmt.extend_from_slice(&rate.to_le_bytes());
    fmt.extend_from_slice(&(rate * block as u32).to_le_bytes());
    fmt.extend_from_slice(&(block as u16).to_le_bytes());
    fmt.extend_from_slice(&bits.to_le_bytes());
    if extensible {
        fmt.extend_from_slice(&22u16.to_le_bytes());
        fmt.extend_from_slice(&bits.to_le_bytes());
        fmt.extend_from_slice(&(if channels == 2 { 3u32 } else { 4 }).to_le_bytes());
        fmt.extend_from_slice(&(if float { 3u16 } else { 1 }).to_le_bytes());
        fmt.extend_from_slice(&[0, 0, 0, 0, 0x10, 0, 0x80, 0, 0, 0xaa, 0, 0x38, 0x9b, 0x71]);
    } else if rng.one_in(3) {
        fmt.extend_from_slice(&0u16.to_le_bytes()); // cbSize
    }
    let mut data = Vec::with_capacity(frames * block);
    for _ in 0..frames * usize::from(channels) {
        if float {
            let v = match rng.below(20) {
                0 => f32::from_bits(rng.next() as u32),
                1 => *rng.pick(&[f32::NAN, f32::INFINITY, f32::MAX, 1e30, -1.0, 0.0]),
                _ => (rng.unit() * 2.0 - 1.0) as f32,
            };
            data.extend_from_slice(&v.to_le_bytes());
        } else {
            for _ in 0..width {
                data.push(rng.byte());
            }
        }
    }
    let mut body = b"WAVE".to_vec();
    let extra = |rng: &mut Rng, body: &mut Vec<u8>| {
        for _ in 0..rng.below(3) {
            let id = *rng.pick(&[b"LIST", b"junk", b"fact", b"bext", b"PAD ", b"cue "]);
            let len = rng.below(70);
            let payload: Vec<u8> = (0..len).map(|_| rng.byte()).collect();
            chunk(body, id, &payload, !rng.one_in(20));
        }
    };
    extra(rng, &mut body);
    chunk(&mut body, b"fmt ", &fmt, true);
    extra(rng, &mut body);
    let data_at = body.len() + 4;
    chunk(&mut body, b"data", &data, true);
    match rng.below(12) {
        // the open sizes of streaming writers
        0 => body[data_at..data_at + 4].copy_from_slice(&0u32.to_le_bytes()),
        1 => body[data_at..data_at + 4].copy_from_slice(&u32::MAX.to_le_bytes()),
        _ => {}
    }
    if rng.one_in(3) {
        extra(rng, &mut body);
    }
    let mut out = b"RIFF".to_vec();
    out.extend_from_slice(&(body.len() as u32).to_le_bytes());
    out.extend(body);
    out
}

/// Appends a RIFF chunk, with its pad byte after an odd payload if `pad`.
fn chunk(body: &mut Vec<u8>, id: &[u8; 4], payload: &[u8], pad: bool) {
    body.extend_from_slice(id);
    body.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    body.extend_from_slice(payload);
    if pad && payload.len() % 2 == 1 {
        body.push(0);
    }
}

/// The chunks of a RIFF file as its sizes lay them out: (start of the chunk header, end
/// of the chunk with its pad byte), cut at the end of the bytes.
fn chunk_spans(b: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut at = 12;
    while at + 8 <= b.len() {
        let size = u32::from_le_bytes([b[at + 4], b[at + 5], b[at + 6], b[at + 7]]) as usize;
        let end = (at + 8).saturating_add(size + (size & 1)).min(b.len());
        spans.push((at, end));
        at = end;
    }
    spans
}

/// Sizes that break readers: none, one, odd, sign bit, all ones.
const SIZES: [u32; 8] = [
    0,
    1,
    3,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFF,
    0xFFFF_FFFE,
    40,
];

/// Applies 1 to 4 random mutations: bit flips (mostly in the header), bytes set to
/// extreme values, truncation, chunk-size and RIFF-size fields set to 0/huge/odd, format
/// fields overwritten, chunks duplicated, removed or swapped, bytes inserted.
fn mutate(rng: &mut Rng, b: &mut Vec<u8>) {
    for _ in 0..1 + rng.below(4) {
        let len = b.len();
        let spans = chunk_spans(b);
        match rng.below(10) {
            0 if len > 0 => {
                let at = if rng.one_in(2) {
                    rng.below(len.min(80))
                } else {
                    rng.below(len)
                };
                b[at] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                let at = rng.below(len.min(120));
                b[at] = *rng.pick(&[0, 1, 0x7F, 0x80, 0xFE, 0xFF]);
            }
            2 => b.truncate(rng.below(len + 1)),
            3 if !spans.is_empty() => {
                let (at, end) = *rng.pick(&spans);
                let old = (end - at - 8) as u32;
                let size = match rng.below(4) {
                    0 => old.wrapping_add(1),
                    1 => old.wrapping_sub(1),
                    2 => rng.next() as u32,
                    _ => *rng.pick(&SIZES),
                };
                b[at + 4..at + 8].copy_from_slice(&size.to_le_bytes());
            }
            4 if len >= 8 => {
                let size = if rng.one_in(2) {
                    *rng.pick(&SIZES)
                } else {
                    rng.next() as u32
                };
                b[4..8].copy_from_slice(&size.to_le_bytes());
            }
            5 => {
                // a field of the fmt chunk: tag, channels, rate, byte rate, block
                // align, bits, cbSize, valid bits, mask, sub-format tag
                if let Some(&(at, end)) = spans.iter().find(|(at, _)| &b[*at..*at + 4] == b"fmt ") {
                    let field = at + 8 + *rng.pick(&[0, 2, 4, 8, 12, 14, 16, 18, 20, 24]);
                    let value = *rng.pick(&[
                        0u32,
                        1,
                        2,
                        3,
                        0xFFFE,
                        0xFFFF,
                        7,
                        64,
                        65535,
                        u32::MAX,
                        0x8000_0000,
                    ]);
                    let bytes = value.to_le_bytes();
                    for (i, v) in bytes
                        .iter()
                        .enumerate()
                        .take(if rng.one_in(2) { 2 } else { 4 })
                    {
                        if field + i < end {
                            b[field + i] = *v;
                        }
                    }
                }
            }
            6 if !spans.is_empty() => {
                let (at, end) = *rng.pick(&spans);
                let copy = b[at..end].to_vec();
                let (to, _) = *rng.pick(&spans);
                b.splice(to..to, copy);
            }
            7 if !spans.is_empty() => {
                let (at, end) = *rng.pick(&spans);
                b.drain(at..end);
            }
            8 if spans.len() >= 2 => {
                let i = rng.below(spans.len() - 1);
                let (a0, a1) = spans[i];
                let (_, b1) = spans[i + 1];
                let first = b[a0..a1].to_vec();
                b.copy_within(a1..b1, a0);
                let at = a0 + (b1 - a1);
                b[at..b1].copy_from_slice(&first);
            }
            _ => {
                let at = rng.below(len + 1);
                let n = 1 + rng.below(16);
                let junk: Vec<u8> = (0..n).map(|_| rng.byte()).collect();
                b.splice(at..at, junk);
            }
        }
    }
}

/// Random bytes, often behind a RIFF/WAVE header (and a `fmt ` id) to get past the magic.
fn random_bytes(rng: &mut Rng) -> Vec<u8> {
    let mut b = Vec::new();
    if rng.one_in(2) {
        b.extend_from_slice(b"RIFF");
        b.extend_from_slice(&(rng.next() as u32).to_le_bytes());
        b.extend_from_slice(b"WAVE");
        if rng.one_in(2) {
            b.extend_from_slice(b"fmt ");
        }
    }
    let most = if rng.one_in(4) { 4000 } else { 120 };
    let n = rng.below(most);
    b.extend((0..n).map(|_| rng.byte()));
    b
}

/// The reader accepts or refuses the file; once it accepts, it reads exactly the frames it
/// declares, in any block sizes, and those fit in the file.
fn check_reader(rng: &mut Rng, path: &Path, file_len: u64) -> Result<(), String> {
    let Ok(mut reader) = WavReader::open(path) else {
        count("reader: refused");
        return Ok(());
    };
    count("reader: opened");
    let format = reader.format();
    let frame_bytes = u64::from(format.channels) * u64::from(format.bits / 8);
    if reader.frames().saturating_mul(frame_bytes) > file_len {
        return Err(format!(
            "the reader declares {} frames of {frame_bytes} bytes in a file of {file_len} bytes",
            reader.frames()
        ));
    }
    let mut out = if rng.one_in(2) {
        WavSamples::Int(Vec::new())
    } else {
        WavSamples::Float(Vec::new())
    };
    let mut total = 0u64;
    loop {
        let ask = if rng.one_in(8) {
            usize::MAX
        } else {
            1 + rng.below(900)
        };
        let got = reader
            .read(ask, &mut out)
            .map_err(|e| format!("a file the reader opened fails to read: {e}"))?;
        let (len, float) = match &out {
            WavSamples::Int(v) => (v.len(), false),
            WavSamples::Float(v) => (v.len(), true),
        };
        if got > ask || len != got * usize::from(format.channels) || float != format.float {
            return Err(format!(
                "read({ask}) gave {got} frames in {len} {} samples ({:?})",
                if float { "float" } else { "integer" },
                format
            ));
        }
        if got == 0 {
            break;
        }
        total += got as u64;
    }
    if total != reader.frames() {
        return Err(format!(
            "read {total} frames, the reader declared {}",
            reader.frames()
        ));
    }
    Ok(())
}

/// The library path of `afe extract`: open the input, build a manager, run a request (any,
/// on 4 channels) on at most [`MAX_FRAMES`] frames read block by block.
fn check_extract(rng: &mut Rng, path: &Path) -> Result<(), String> {
    let Ok(mut wav) = afe::wav::open_input(path) else {
        return Ok(());
    };
    count("extract: input taken");
    let ears = wav.channels();
    let threads = if rng.one_in(8) { 2 } else { 0 };
    let mut mgr = match Manager::with_threads(wav.fs(), ears, threads) {
        Ok(m) => m,
        Err(e) => return check_error(&e),
    };
    mgr.set_stall_timeout(CASE_LIMIT);
    let params: ParamMap = [("fb_nChannels".to_string(), json!(4))]
        .into_iter()
        .collect();
    let job = Job {
        // any request at the header's rate (binaural ones refuse mono files)
        requests: vec![if rng.one_in(2) {
            "ratemap".into()
        } else {
            rng.pick(afe::requests()).name.into()
        }],
        params,
        chunk: if rng.one_in(3) {
            None
        } else {
            Some(1 + rng.below(2000))
        },
        ..Job::default()
    };
    let mut left = MAX_FRAMES;
    let result = run_source(&mut mgr, &job, ears, |frames, out| {
        let got = wav
            .read(frames.min(left), out)
            .map_err(|e| Error::InvalidInput(e.to_string()))?;
        left -= got;
        Ok(got)
    });
    match result {
        Ok(rec) => {
            count("extract: computed");
            if rec.signals().is_empty() {
                return Err("extract succeeded and recorded nothing".into());
            }
            Ok(())
        }
        Err(e) => check_error(&e),
    }
}

/// The `afe extract` binary on the file, with the ratemap on 4 channels or a random
/// request with random `-p NAME=VALUE` parameters: any exit but a panic's (101) or a
/// signal's.
fn check_cli(rng: &mut Rng, path: &Path, dir: &Path) -> Result<(), String> {
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_afe"));
    cmd.arg("extract")
        .arg(path)
        .arg("-o")
        .arg(dir.join("out.npz"));
    if rng.one_in(2) {
        cmd.args(["-r", "ratemap", "-p", "fb_nChannels=4"]);
    } else {
        let name = rng.pick(afe::requests()).name;
        let entries = rng.below(4);
        cmd.args(["-r", name]);
        for (k, v) in random_params(rng, name, entries) {
            let arg = match v {
                Value::String(s) if rng.one_in(2) => format!("{k}={s}"),
                v => format!("{k}={v}"),
            };
            // a command line cannot carry a NUL byte
            if !arg.contains('\0') {
                cmd.arg("-p").arg(arg);
            }
        }
        if rng.one_in(3) {
            cmd.arg("--chunk").arg((1 + rng.below(3000)).to_string());
        }
    }
    note(|| format!("{cmd:?}"));
    let out = cmd.output().map_err(|e| format!("cannot run afe: {e}"))?;
    let stderr = String::from_utf8_lossy(&out.stderr);
    match out.status.code() {
        Some(101) | None => Err(format!("afe extract ended with {}: {stderr}", out.status)),
        _ if stderr.contains("panicked") => Err(format!("afe extract panicked: {stderr}")),
        _ => Ok(()),
    }
}

#[test]
fn wav_bytes() {
    fuzz("wav_bytes", |rng, dir| {
        let bytes = if rng.one_in(6) {
            random_bytes(rng)
        } else {
            let mut b = valid_wav(rng);
            if !rng.one_in(8) {
                mutate(rng, &mut b);
            }
            b
        };
        let path = dir.join("input.wav");
        std::fs::write(&path, &bytes)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        check_reader(rng, &path, bytes.len() as u64)?;
        check_extract(rng, &path)?;
        if rng.one_in(64) {
            count("afe extract runs");
            check_cli(rng, &path, dir)?;
        }
        Ok(())
    });
}

// ---------------------------------------------------------------------------------------
// Target 2: parameter JSON into the parameter parser and the request resolver.

/// Any JSON value, nested up to `depth`.
fn random_json(rng: &mut Rng, depth: usize) -> Value {
    match rng.below(if depth == 0 { 5 } else { 7 }) {
        0 => Value::Null,
        1 => Value::Bool(rng.one_in(2)),
        2 => random_number(rng),
        3 => json!(*rng.pick(&[
            "", "n-a", "NaN", "Infinity", "-inf", "1e999", "0x10", "hann", "dB", "none",
            "halfwave", "\u{0}", "ratemap", "🎧", "   ", "[]"
        ])),
        4 => json!((0..rng.below(12))
            .map(|_| char::from(32 + rng.below(95) as u8))
            .collect::<String>()),
        5 => Value::Array(
            (0..rng.below(6))
                .map(|_| random_json(rng, depth - 1))
                .collect(),
        ),
        _ => Value::Object(
            (0..rng.below(4))
                .map(|_| (format!("k{}", rng.below(4)), random_json(rng, depth - 1)))
                .collect(),
        ),
    }
}

/// A number that tests limits: zero, signs, huge, tiny, integers at type limits.
fn random_number(rng: &mut Rng) -> Value {
    match rng.below(6) {
        0 => json!(*rng.pick(&[
            0.0,
            -0.0,
            1e308,
            -1e308,
            5e-324,
            f64::MAX,
            f64::MIN_POSITIVE,
            1e-300
        ])),
        1 => json!(*rng.pick(&[
            i64::MIN,
            i64::MAX,
            -1,
            0,
            1,
            2,
            3,
            1023,
            1024,
            1025,
            65536,
            4_294_967_296
        ])),
        2 => json!(u64::MAX),
        3 => json!((rng.unit() - 0.5) * 10f64.powi(rng.below(40) as i32 - 12)),
        4 => json!(rng.below(100)),
        _ => json!(rng.unit()),
    }
}

/// The numbers of a parameter's default: a vector's, a scalar as one, none without one.
fn default_numbers(default: Option<&Value>) -> Vec<f64> {
    match default {
        Some(Value::Array(a)) => a.iter().filter_map(Value::as_f64).collect(),
        Some(v) => v.as_f64().into_iter().collect(),
        None => Vec::new(),
    }
}

/// A value aimed at a parameter of kind `kind` whose default is `default`: often valid or
/// near it, sometimes out of range, sometimes of another type.
fn value_for(rng: &mut Rng, kind: ParamKind, default: Option<&Value>) -> Value {
    if rng.one_in(5) {
        return random_json(rng, 2);
    }
    let scale = |rng: &mut Rng, x: f64| {
        x * *rng.pick(&[
            0.0, -1.0, 0.5, 0.9, 1.0, 1.1, 2.0, 10.0, 1e3, 1e6, 1e-6, 1e12,
        ])
    };
    match kind {
        ParamKind::Number => match default.and_then(Value::as_f64) {
            Some(x) if !rng.one_in(4) => json!(scale(rng, if x == 0.0 { 1.0 } else { x })),
            _ => random_number(rng),
        },
        ParamKind::Count | ParamKind::CountUpTo(_) => json!(*rng.pick(&[
            0.0,
            1.0,
            2.0,
            3.0,
            4.0,
            7.0,
            16.0,
            64.0,
            512.0,
            1024.0,
            1025.0,
            1e6,
            4294967295.0,
            -1.0,
            2.5
        ])),
        ParamKind::Flag => rng
            .pick(&[
                json!(true),
                json!(false),
                json!(0),
                json!(1),
                json!(2),
                json!("true"),
            ])
            .clone(),
        ParamKind::Choice(choices) => match rng.below(5) {
            0 => random_json(rng, 0),
            _ => json!(*rng.pick(choices)),
        },
        ParamKind::Choices(choices) => match rng.below(4) {
            0 => json!(*rng.pick(choices)),
            1 => random_json(rng, 1),
            _ => json!((0..rng.below(5))
                .map(|_| *rng.pick(choices))
                .collect::<Vec<_>>()),
        },
        ParamKind::Numbers => {
            let base = default_numbers(default);
            match rng.below(4) {
                0 if !base.is_empty() => {
                    json!(base.iter().map(|x| scale(rng, *x)).collect::<Vec<_>>())
                }
                1 => random_number(rng),
                _ => {
                    let n = *rng.pick(&[0, 1, 2, 3, 5, 8, 40, 2000]);
                    let mut v: Vec<f64> = (0..n).map(|_| rng.unit() * 8000.0).collect();
                    if rng.one_in(2) {
                        v.sort_by(f64::total_cmp);
                    }
                    json!(v)
                }
            }
        }
    }
}

/// A parameter name a user could type: a real one with a typo or another case, or junk.
fn junk_name(rng: &mut Rng, real: &str) -> String {
    let mut s: Vec<char> = real.chars().collect();
    match rng.below(4) {
        0 if !s.is_empty() => {
            s.remove(rng.below(s.len()));
        }
        1 => s = s.iter().flat_map(|c| c.to_uppercase()).collect(),
        2 => s.push(char::from(b'a' + rng.below(26) as u8)),
        _ => {
            return (0..rng.below(20))
                .map(|_| char::from(32 + rng.below(95) as u8))
                .collect()
        }
    }
    s.into_iter().collect()
}

/// Random request parameters for request `name`: mostly names of its own chain, some of
/// other processors, some junk; values from [`value_for`].
fn random_params(rng: &mut Rng, name: &str, entries: usize) -> ParamMap {
    let own: Vec<&'static afe::RequestDef> = afe::catalog::chain(name)
        .iter()
        .filter_map(|n| afe::find_request(n).ok())
        .collect();
    let all = afe::requests();
    let mut map = ParamMap::new();
    for _ in 0..entries {
        let def = if own.is_empty() || rng.one_in(4) {
            *rng.pick(all)
        } else {
            *rng.pick(&own)
        };
        if def.params.is_empty() {
            continue;
        }
        let spec = rng.pick(def.params);
        let defaults = (def.defaults)();
        let key = if rng.one_in(12) {
            junk_name(rng, spec.name)
        } else {
            spec.name.to_string()
        };
        let mut value = value_for(rng, spec.kind, defaults.get(spec.name));
        if spec.unit == "s" {
            value = shorter(value);
        }
        map.insert(key, value);
    }
    map
}

/// Longest duration drawn in the range the processors accept, in s. A window is valid up
/// to 2^24 values over all channels, and the processors hold several times that (per
/// window value: 8 bytes in the ratemap, 40 in the cross-correlation, 100 in the
/// precedence processor): what the user asked for, not a fault, so such windows are not
/// drawn; durations past the accepted range (≥ 1e4 s) are, to test their refusal.
const LONGEST_DRAWN_S: f64 = 0.05;

/// `value` with durations between [`LONGEST_DRAWN_S`] and 1e4 s folded below it.
fn shorter(value: Value) -> Value {
    match value {
        Value::Number(_) => match value.as_f64() {
            Some(x) if x.abs() > LONGEST_DRAWN_S && x.abs() < 1e4 => json!(x % LONGEST_DRAWN_S),
            _ => value,
        },
        Value::Array(items) => Value::Array(items.into_iter().map(shorter).collect()),
        _ => value,
    }
}

/// A random signal of `len` samples: noise, a tone, silence, clicks, or loud noise.
fn random_signal(rng: &mut Rng, len: usize) -> Vec<f64> {
    let kind = rng.below(6);
    let f = rng.unit() * 0.5;
    let gain = *rng.pick(&[1.0, 0.01, 1e-12, 1e6, 1e90]);
    (0..len)
        .map(|t| {
            gain * match kind {
                0 => 0.0,
                1 => (2.0 * std::f64::consts::PI * f * t as f64).sin(),
                2 => f64::from(u8::from(rng.one_in(200))),
                _ => rng.unit() * 2.0 - 1.0,
            }
        })
        .collect()
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

/// A sampling rate: mostly usual ones, some random, some invalid.
fn random_fs(rng: &mut Rng) -> f64 {
    match rng.below(10) {
        0 => *rng.pick(&[
            0.0,
            -44100.0,
            f64::NAN,
            f64::INFINITY,
            1e-3,
            1.0,
            2.0,
            7.0,
            50.0,
            100.0,
            300.0,
            1000.0,
            999_999.0,
            1e6,
            1e7,
        ]),
        1 => 1000.0 + rng.unit() * 200_000.0,
        _ => *rng.pick(&[8000.0, 16000.0, 22050.0, 44100.0, 48000.0, 96000.0]),
    }
}

#[test]
fn parameter_json() {
    let names: Vec<&str> = afe::requests().iter().map(|r| r.name).collect();
    fuzz("parameter_json", |rng, _| {
        let fs = random_fs(rng);
        let ears = if rng.one_in(20) {
            *rng.pick(&[0, 3])
        } else {
            1 + rng.below(2)
        };
        let threads = if rng.one_in(8) { 2 } else { 0 };
        let mut mgr = match Manager::with_threads(fs, ears, threads) {
            Ok(m) => m,
            Err(e) => return check_error(&e),
        };
        mgr.set_stall_timeout(CASE_LIMIT);
        mgr.set_keep_all(true);
        let mut accepted = false;
        for _ in 0..1 + rng.below(3) {
            let name = if rng.one_in(12) {
                {
                    let real = *rng.pick(&names);
                    junk_name(rng, real)
                }
            } else {
                rng.pick(&names).to_string()
            };
            let entries = rng.below(7);
            let params = random_params(rng, &name, entries);
            // the parser alone, for every processor (the resolver stops at the first error)
            for def in afe::requests() {
                if let Err(e) = (def.configure)(&params) {
                    check_error(&e)?;
                }
            }
            note(|| {
                format!(
                    "add_request({name:?}, {}) at {fs} Hz, {ears} ear(s)",
                    json!(params)
                )
            });
            match mgr.add_request(&name, &params) {
                Ok(_) => {
                    count("request accepted");
                    accepted = true;
                }
                Err(e) => {
                    count("request refused");
                    check_error(&e)?;
                }
            }
        }
        if accepted {
            let len = rng.below(2000);
            let x = random_signal(rng, len);
            let chunk: Vec<&[f64]> = vec![x.as_slice(); ears];
            // a chunk, or a whole signal (where a graph depends on chunk boundaries, its
            // own path through the graph)
            let whole = rng.one_in(3);
            note(|| {
                format!(
                    "{} of {len} samples",
                    if whole {
                        "process_signal"
                    } else {
                        "process_chunk"
                    }
                )
            });
            let result = if whole {
                mgr.process_signal(&chunk)
            } else {
                mgr.process_chunk(&chunk)
            };
            match result {
                Ok(()) if !whole => {
                    count("chunk processed");
                    check_outputs(&mgr, len)?;
                }
                Ok(()) => count("whole signal processed"),
                Err(e) => {
                    count("processing refused");
                    check_error(&e)?;
                }
            }
        }
        Ok(())
    });
}

// ---------------------------------------------------------------------------------------
// Target 3: random chunkings and run-time edits, sequential and concurrent in lockstep.

/// The requested outputs shown after a chunk: key and values.
type Snapshot = Vec<(String, usize, Vec<f64>)>;

fn snapshot(mgr: &Manager) -> Snapshot {
    mgr.signals(false)
        .iter()
        .map(|s| (s.key(), s.new.width(), s.new.as_slice().to_vec()))
        .collect()
}

/// Bit-for-bit equality of two snapshots (NaN equal to itself).
fn same(a: &Snapshot, b: &Snapshot) -> Result<(), String> {
    if a.len() != b.len() {
        return Err(format!(
            "{} signals sequentially, {} concurrently",
            a.len(),
            b.len()
        ));
    }
    for ((ka, wa, da), (kb, wb, db)) in a.iter().zip(b) {
        if ka != kb || wa != wb || da.len() != db.len() {
            return Err(format!(
                "{ka} ({wa} × {}) sequentially, {kb} ({wb} × {}) concurrently",
                da.len(),
                db.len()
            ));
        }
        if let Some(i) = da
            .iter()
            .zip(db)
            .position(|(x, y)| x.to_bits() != y.to_bits())
        {
            return Err(format!(
                "{ka}[{i}]: {} sequentially, {} concurrently",
                da[i], db[i]
            ));
        }
    }
    Ok(())
}

/// The same operation's outcome on both executors.
fn agree<T>(what: &str, a: &afe::Result<T>, b: &afe::Result<T>) -> Result<(), String> {
    count(&format!(
        "{what}: {}",
        if a.is_ok() { "done" } else { "refused" }
    ));
    match (a, b) {
        (Ok(_), Ok(_)) => Ok(()),
        (Err(x), Err(y)) if x == y => check_error(x),
        (Err(e), Ok(_)) => Err(format!(
            "{what}: sequential error '{e}', concurrent success"
        )),
        (Ok(_), Err(e)) => Err(format!(
            "{what}: sequential success, concurrent error '{e}'"
        )),
        (Err(x), Err(y)) => Err(format!(
            "{what}: sequential error '{x}', concurrent error '{y}'"
        )),
    }
}

/// `params` with at most 32 channels (the edit target is about edits, not sizes: two
/// managers with 1024 channels of autocorrelation hold hundreds of MB).
fn small(mut params: ParamMap) -> ParamMap {
    if let Some(v) = params.get_mut("fb_nChannels") {
        if v.as_f64().is_some_and(|n| n > 32.0) {
            *v = json!(32);
        }
    }
    if let Some(Value::Array(cf)) = params.get_mut("fb_cfHz") {
        cf.truncate(32);
    }
    params
}

/// The concurrent manager's outputs waiting to be compared: the sequential snapshots of
/// the chunks it has in flight, oldest first.
struct Lockstep {
    seq: Manager,
    con: Manager,
    queue: VecDeque<Snapshot>,
}

impl Lockstep {
    /// Collects every chunk the concurrent manager has in flight and compares each.
    fn drain(&mut self) -> Result<(), String> {
        while self.con.in_flight() > 0 {
            let r = self.con.collect_chunk();
            if let Err(e) = &r {
                check_error(e)?;
                return Err(format!("collecting a chunk failed: {e}"));
            }
            let want = self
                .queue
                .pop_front()
                .ok_or("a chunk in flight without its sequential twin")?;
            same(&want, &snapshot(&self.con))?;
        }
        Ok(())
    }

    /// A chunk into both: processed at once sequentially, pipelined concurrently.
    fn chunk(&mut self, x: &[f64]) -> Result<(), String> {
        let ears = self.seq.ears();
        let chunk: Vec<&[f64]> = vec![x; ears];
        let a = self.seq.process_chunk(&chunk);
        if self.con.in_flight() >= self.con.pipeline_depth() {
            let r = self.con.collect_chunk();
            if let Err(e) = &r {
                check_error(e)?;
                return Err(format!("collecting a chunk failed: {e}"));
            }
            let want = self
                .queue
                .pop_front()
                .ok_or("a chunk in flight without its sequential twin")?;
            same(&want, &snapshot(&self.con))?;
        }
        let b = self.con.submit_chunk(&chunk);
        agree("chunk", &a, &b)?;
        if a.is_ok() {
            check_outputs(&self.seq, x.len())?;
            self.queue.push_back(snapshot(&self.seq));
        }
        Ok(())
    }
}

#[test]
fn manager_edits() {
    fuzz("manager_edits", |rng, _| {
        let fs = *rng.pick(&[8000.0, 16000.0, 22050.0, 44100.0, 48000.0]);
        let ears = 1 + rng.below(2);
        let mut seq = Manager::new(fs, ears).map_err(|e| e.to_string())?;
        let mut con = Manager::with_threads(fs, ears, 2).map_err(|e| e.to_string())?;
        con.set_stall_timeout(CASE_LIMIT);
        // every signal, intermediate ones too, is compared between the executors
        seq.set_keep_all(true);
        con.set_keep_all(true);
        note(|| format!("{fs} Hz, {ears} ear(s)"));
        let mut m = Lockstep {
            seq,
            con,
            queue: VecDeque::new(),
        };
        let mut handles: Vec<(usize, &str)> = Vec::new();
        let mut fed = 0;
        for _ in 0..4 + rng.below(30) {
            if fed >= 4 * MAX_FRAMES {
                break;
            }
            match rng.below(12) {
                0..=2 => {
                    let name = rng.pick(afe::requests()).name;
                    let entries = rng.below(3);
                    let mut params = small(random_params(rng, name, entries));
                    if !params.contains_key("fb_nChannels") && !rng.one_in(4) {
                        params.insert("fb_nChannels".into(), json!(1 + rng.below(12)));
                    }
                    m.drain()?;
                    note(|| format!("add_request({name:?}, {})", json!(params)));
                    let a = m.seq.add_request(name, &params);
                    let b = m.con.add_request(name, &params);
                    agree("add_request", &a, &b)?;
                    if let (Ok(x), Ok(y)) = (&a, &b) {
                        if x != y {
                            return Err(format!("handles {x:?} and {y:?} for the same request"));
                        }
                        handles.push((x.index(), name));
                    }
                }
                3 => {
                    let h = RequestHandle::from_index(rng.below(handles.len() + 2));
                    note(|| format!("remove_request({})", h.index()));
                    m.drain()?;
                    agree(
                        "remove_request",
                        &m.seq.remove_request(h),
                        &m.con.remove_request(h),
                    )?;
                }
                4 | 5 => {
                    let (h, name) = match handles.is_empty() {
                        true => (rng.below(3), "ratemap"),
                        false => *rng.pick(&handles),
                    };
                    let params = small(random_params(rng, name, 1));
                    let Some((key, value)) = params.into_iter().next() else {
                        continue;
                    };
                    m.drain()?;
                    let h = RequestHandle::from_index(h);
                    note(|| format!("modify_parameter({}, {key:?}, {value})", h.index()));
                    let a = m.seq.modify_parameter(h, &key, value.clone());
                    let b = m.con.modify_parameter(h, &key, value);
                    agree("modify_parameter", &a, &b)?;
                }
                6 => {
                    m.drain()?;
                    note(|| "reset".into());
                    agree("reset", &m.seq.reset(), &m.con.reset())?;
                }
                7 => {
                    m.drain()?;
                    let len = rng.below(3000);
                    let x = random_signal(rng, len);
                    let chunk: Vec<&[f64]> = vec![x.as_slice(); ears];
                    note(|| format!("process_signal({len} samples)"));
                    let a = m.seq.process_signal(&chunk);
                    let b = m.con.process_signal(&chunk);
                    agree("process_signal", &a, &b)?;
                    if a.is_ok() {
                        same(&snapshot(&m.seq), &snapshot(&m.con))?;
                    }
                    fed += x.len();
                }
                _ => {
                    let len = match rng.below(6) {
                        0 => rng.below(3),
                        1 => 2000 + rng.below(1000),
                        _ => rng.below(700),
                    };
                    let mut x = random_signal(rng, len);
                    if len > 0 && rng.one_in(40) {
                        x[rng.below(len)] = *rng.pick(&[f64::NAN, f64::INFINITY, 1e200]);
                    }
                    note(|| format!("chunk of {len} samples"));
                    m.chunk(&x)?;
                    fed += len;
                }
            }
        }
        m.drain()
    });
}

// ---------------------------------------------------------------------------------------
// Target 4: every request with parameters drawn over the ranges its parser accepts, the
// extremes included (issue 44): refused when placed, or finite output within the case's
// time and the process's heap limit.

/// Whether the parser of `def` accepts `params` (with the value under test in it).
fn parses(def: &afe::RequestDef, params: &ParamMap) -> bool {
    (def.configure)(params).is_ok()
}

/// `x` moved by bisection in log space towards the farthest value on its side (`up`:
/// larger, else closer to zero) that the parser of `def` still accepts for `name`.
fn extreme(def: &afe::RequestDef, params: &ParamMap, name: &str, x: f64, up: bool) -> f64 {
    let with = |v: f64| {
        let mut p = params.clone();
        p.insert(name.to_string(), json!(v));
        parses(def, &p)
    };
    let far = if up { x * 1e12 } else { x * 1e-12 };
    if with(far) {
        return far;
    }
    let (mut good, mut bad) = (x, far);
    for _ in 0..40 {
        let mid = (good.abs().ln() * 0.5 + bad.abs().ln() * 0.5).exp() * x.signum();
        if with(mid) {
            good = mid;
        } else {
            bad = mid;
        }
    }
    good
}

/// A value of `spec` drawn over what its parser may accept: numbers across twelve orders
/// of magnitude around the default, counts up to the channel limit, every choice.
fn accepted_draw(rng: &mut Rng, spec: &afe_core::ParamSpec, default: Option<&Value>) -> Value {
    let magnitude = |rng: &mut Rng, x: f64| x * 10f64.powf(rng.unit() * 12.0 - 6.0);
    match spec.kind {
        ParamKind::Number => {
            let x = default
                .and_then(Value::as_f64)
                .filter(|x| *x != 0.0)
                .unwrap_or(1.0);
            json!(match rng.below(6) {
                0 => 0.0,
                1 => -magnitude(rng, x),
                _ => magnitude(rng, x),
            })
        }
        ParamKind::Count | ParamKind::CountUpTo(_) => json!(match rng.below(4) {
            0 => 1 + rng.below(4),
            1 => *rng.pick(&[256, 512, 1000, 1024, 4096, 65_536]),
            _ => 1 + rng.below(128),
        }),
        ParamKind::Flag => json!(rng.one_in(2)),
        ParamKind::Choice(choices) => json!(*rng.pick(choices)),
        ParamKind::Choices(choices) => json!((0..1 + rng.below(choices.len()))
            .map(|_| *rng.pick(choices))
            .collect::<Vec<_>>()),
        ParamKind::Numbers => {
            let base = default_numbers(default);
            if base.is_empty() || rng.one_in(3) {
                let n = 1 + rng.below(40);
                let mut v: Vec<f64> = (0..n).map(|_| rng.unit() * 8000.0).collect();
                v.sort_by(f64::total_cmp);
                json!(v)
            } else {
                let k = 10f64.powf(rng.unit() * 4.0 - 2.0);
                json!(base.iter().map(|x| x * k).collect::<Vec<_>>())
            }
        }
    }
}

/// Parameters for the chain of `request`: each parameter with probability 1/3, drawn by
/// [`accepted_draw`] until its processor's parser accepts it (else left out), and a
/// quarter of the numbers then pushed to the largest or smallest value accepted.
fn accepted_params(rng: &mut Rng, request: &str) -> ParamMap {
    let mut params = ParamMap::new();
    for def in afe::catalog::chain(request)
        .iter()
        .filter_map(|n| afe::find_request(n).ok())
    {
        let defaults = (def.defaults)();
        for spec in def.params {
            if !rng.one_in(3) {
                continue;
            }
            for _ in 0..8 {
                let mut trial = params.clone();
                let value = accepted_draw(rng, spec, defaults.get(spec.name));
                trial.insert(spec.name.to_string(), value.clone());
                if !parses(def, &trial) {
                    continue;
                }
                let pushed = match value.as_f64() {
                    Some(x) if x != 0.0 && spec.kind == ParamKind::Number && rng.one_in(4) => {
                        json!(extreme(def, &params, spec.name, x, rng.one_in(2)))
                    }
                    _ => value,
                };
                params.insert(spec.name.to_string(), pushed);
                break;
            }
        }
    }
    params
}

/// Checks that every requested output shown holds finite values, from an input that is
/// not silent: NaN only in the representations whose description says where the AFE
/// gives it (`nan_where`: an unvoiced pitch frame, an autocorrelation frame of zeros, the
/// logarithms of a signed ratemap, ...), and ±Inf only in the Gabor features of a chunk
/// whose features do not vary.
fn check_finite(mgr: &Manager) -> Result<(), String> {
    for s in mgr.signals(false) {
        let nan_allowed = s.info.nan_where.is_some();
        let inf_allowed = s.name == "gabor";
        let wrong = |v: &f64| {
            !(v.is_finite() || (nan_allowed && v.is_nan()) || (inf_allowed && v.is_infinite()))
        };
        if let Some(i) = s.new.as_slice().iter().position(wrong) {
            return Err(format!(
                "{}: value {i} is {} from a finite, audible input",
                s.key(),
                s.new.as_slice()[i]
            ));
        }
    }
    Ok(())
}

#[test]
fn accepted_ranges() {
    let names: Vec<&str> = afe::requests().iter().map(|r| r.name).collect();
    fuzz("accepted_ranges", |rng, _| {
        let name = *rng.pick(&names);
        let fs = *rng.pick(&[16000.0, 22050.0, 44100.0, 48000.0]);
        let binaural = afe::catalog::chain(name)
            .iter()
            .filter_map(|n| afe::find_request(n).ok())
            .any(|d| d.ears == afe_core::Ears::Binaural);
        let ears = if binaural { 2 } else { 1 + rng.below(2) };
        let params = accepted_params(rng, name);
        note(|| format!("add_request({name:?}, {}) at {fs} Hz", json!(params)));
        let mut mgr = Manager::with_threads(fs, ears, 0).map_err(|e| e.to_string())?;
        if let Err(e) = mgr.add_request(name, &params) {
            count("refused when placed");
            return check_error(&e);
        }
        // a quarter of a second at most (at the output limit, 0.5 GB of blocks in one
        // chunk): noise or a tone, at full scale or 40 dB below
        let len = 1 + rng.below(fs as usize / 4);
        let gain = *rng.pick(&[1.0, 0.01]);
        let f = 0.001 + rng.unit() * 0.2;
        let x: Vec<f64> = (0..len)
            .map(|t| {
                gain * if rng.one_in(2) {
                    rng.unit() * 2.0 - 1.0
                } else {
                    (2.0 * std::f64::consts::PI * f * t as f64).sin()
                }
            })
            .collect();
        let chunk = 1 + rng.below(len);
        note(|| format!("{len} samples in chunks of {chunk}"));
        for part in x.chunks(chunk) {
            let ears: Vec<&[f64]> = vec![part; ears];
            if let Err(e) = mgr.process_chunk(&ears) {
                count("refused when processing");
                return check_error(&e);
            }
            check_finite(&mgr)?;
        }
        count("computed, finite");
        Ok(())
    });
}
