//! What requests cost a live stream, measured before the stream takes them: a trial
//! places them in a graph of their own, on a thread of its own, and times its blocks on
//! noise; [`LoadCap`] refuses what would take the stream past its share of the block's
//! budget. The live view and the Zenoh server check every request this way before it
//! runs, so that one heavy request is refused instead of costing every client its
//! deadlines.
//!
//! The trial's cost is the least CPU time its thread spends on a block, over a few blocks
//! after the longest window has filled: the trial runs below the stream's priority, and
//! the time it waits for a core is not what the request costs (cache misses only ever
//! add time, hence the least). It is an upper bound of what placing
//! the request adds: in the stream's graph it shares the processors that equal ones
//! already there, which the trial computes again. Requests that add no processor at all
//! ([`shared_entirely`]) need no trial.

use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use afe_core::ParamMap;
use afe_graph::Manager;
use afe_processors::Registry;
use thiserror::Error;

use crate::stream::Timing;

/// Blocks timed once the longest window has filled; the cost is the least of them.
const TIMED_BLOCKS: usize = 3;
/// Longest warm-up, in seconds of signal: a longer window is costed before it fills.
const MAX_WARMUP_S: f64 = 2.0;
/// Longest a trial computes (CPU time of its thread); a slower one stops with the cost
/// measured so far.
const MAX_TRIAL: Duration = Duration::from_millis(1500);
/// Longest a trial waits and computes together (wall time): a trial starved of the cores
/// for this long stops too, rather than keep its client waiting.
const MAX_TRIAL_WALL: Duration = Duration::from_secs(10);
/// Peak amplitude of the trial's noise (a silent input would take the shortcuts of
/// silence and cost less than a signal).
const NOISE: f64 = 0.1;

/// Why a request was not taken, or could not be measured.
#[derive(Debug, Error)]
pub enum TrialError {
    /// The request cannot be placed at all (unknown, invalid parameters, too much work).
    #[error("request '{name}': {source}")]
    Request {
        /// The request's name.
        name: String,
        /// What the graph said.
        source: afe_core::Error,
    },
    /// The trial graph failed on its noise.
    #[error("the trial of {what} failed: {source}")]
    Run {
        /// The requests tried.
        what: String,
        /// What the graph said.
        source: afe_core::Error,
    },
    /// Every trial slot is taken.
    #[error("busy: {0} requests are being measured before they are placed; try again in a moment")]
    Busy(usize),
    /// The trial thread has gone (the server is stopping).
    #[error("the server is stopping: no request is measured any more")]
    Stopped,
    /// The stream is already above its load limit.
    #[error(
        "the stream uses {load_pct:.0} % of its real-time budget (above {max_pct:.0} %): \
         remove a request before adding one"
    )]
    Loaded {
        /// Its load now, percent.
        load_pct: f64,
        /// The limit, percent.
        max_pct: f64,
    },
    /// The requests would take the stream past its share of a block's budget.
    #[error(
        "{what} would cost {cost_ms:.2} ms{more} of each {budget_ms:.1}-ms block (measured \
         on a trial before placing it), and the stream already takes {used_ms:.2} ms of the \
         {cap_ms:.2} ms ({max_pct:.0} %) requests may use: ask for less (fewer channels, a \
         longer hop, a shorter window) or remove a request first"
    )]
    OverBudget {
        /// The requests tried.
        what: String,
        /// Their measured cost per block, ms.
        cost_ms: f64,
        /// `" or more"` when the trial stopped before the end.
        more: &'static str,
        /// A block's budget (its duration), ms.
        budget_ms: f64,
        /// What the stream takes now per block, ms.
        used_ms: f64,
        /// What all requests together may take per block, ms.
        cap_ms: f64,
        /// That share, percent of the budget.
        max_pct: f64,
    },
}

/// A trial's outcome: the requests' cost in ms per block of the stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cost {
    /// The least time of the blocks timed, ms.
    pub ms: f64,
    /// Whether the trial stopped early (too slow to finish): the cost is at least `ms`.
    pub partial: bool,
}

impl Cost {
    /// Nothing: what a stream without a deadline is charged.
    pub fn free() -> Cost {
        Cost {
            ms: 0.0,
            partial: false,
        }
    }

    /// This cost less what goes at the same time (requests it replaces).
    pub fn less(self, freed_ms: f64) -> Cost {
        Cost {
            ms: (self.ms - freed_ms).max(0.0),
            partial: self.partial,
        }
    }
}

/// The stream a trial imitates.
#[derive(Debug, Clone, Copy)]
pub struct Shape {
    /// Sampling rate, Hz.
    pub fs: f64,
    /// Ears (input channels).
    pub ears: usize,
    /// Frames of a block.
    pub block_frames: usize,
}

/// `requests` as a short phrase for messages: `'ratemap'`, `'ild' and 'itd'`.
pub fn describe(requests: &[(String, ParamMap)]) -> String {
    let names: Vec<String> = requests.iter().map(|(n, _)| format!("'{n}'")).collect();
    match names.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} and {last}", rest.join(", ")),
        None => "no request".into(),
    }
}

/// Places `requests` in a graph of their own shaped as the stream and times its blocks
/// on noise (CPU time of the calling thread): blocks until the longest window has
/// filled, then three more; the cost is the least of these. Stops early, with the cost
/// so far, once two timed blocks in a row took more than `enough_ms` (the answer is
/// known), after 1.5 s of computing or after 10 s in all.
pub fn measure(
    shape: Shape,
    registry: &Registry,
    requests: &[(String, ParamMap)],
    enough_ms: f64,
) -> Result<Cost, TrialError> {
    let run_error = |source| TrialError::Run {
        what: describe(requests),
        source,
    };
    let mut mgr = Manager::new(shape.fs, shape.ears).map_err(run_error)?;
    mgr.set_registry(registry.clone()).map_err(run_error)?;
    for (name, params) in requests {
        mgr.add_request(name, params)
            .map_err(|source| TrialError::Request {
                name: name.clone(),
                source,
            })?;
    }
    let block = shape.block_frames.max(1);
    let window_s = mgr
        .signals(true)
        .iter()
        .filter_map(|s| s.info.window_s)
        .fold(0.0, f64::max)
        .min(MAX_WARMUP_S);
    let warmup = (window_s * shape.fs / block as f64).ceil() as usize + 1;
    let mut noise = Noise(0x9E37_79B9_7F4A_7C15);
    let mut input = vec![vec![0.0; block]; shape.ears];
    let start = Instant::now();
    let started = thread_cpu();
    let out_of_time = || thread_cpu() - started > MAX_TRIAL || start.elapsed() > MAX_TRIAL_WALL;
    let mut least = f64::INFINITY;
    let mut over = 0;
    for k in 0..warmup + TIMED_BLOCKS {
        for ear in &mut input {
            ear.iter_mut().for_each(|v| *v = NOISE * noise.next());
        }
        let chunk: Vec<&[f64]> = input.iter().map(Vec::as_slice).collect();
        let t = thread_cpu();
        mgr.process_chunk(&chunk)
            .map_err(|source| TrialError::Run {
                what: describe(requests),
                source,
            })?;
        let ms = (thread_cpu() - t).as_secs_f64() * 1e3;
        if k + 1 < warmup {
            // the windows are filling: a block may cost less than it will
            if out_of_time() {
                return Ok(Cost { ms, partial: true });
            }
            continue;
        }
        least = least.min(ms);
        over = if ms > enough_ms { over + 1 } else { 0 };
        if over >= 2 || out_of_time() {
            return Ok(Cost {
                ms: least,
                partial: k + 1 < warmup + TIMED_BLOCKS,
            });
        }
    }
    Ok(Cost {
        ms: least,
        partial: false,
    })
}

/// Whether `requests` would add no processor to `mgr`'s graph: each of their outputs is
/// one of its requested signals already, computed through processors of the same
/// parameters (an equal request is in place). Then they cost the stream next to
/// nothing, and no trial is needed. Told from a graph of their own, built but not run;
/// `mgr` is not touched.
pub fn shared_entirely(mgr: &Manager, requests: &[(String, ParamMap)]) -> bool {
    let there = mgr.signals(false);
    // without a signal of the same name in place, no need to build anything
    let named = |name: &str| there.iter().any(|s| s.name.starts_with(name));
    if !requests.iter().all(|(name, _)| named(name)) {
        return false;
    }
    let Ok(mut alone) = Manager::new(mgr.fs(), mgr.ears()) else {
        return false;
    };
    if alone.set_registry(mgr.registry().clone()).is_err() {
        return false;
    }
    let mut outputs = Vec::new();
    for (name, params) in requests {
        match alone
            .add_request(name, params)
            .and_then(|h| alone.request_signals(h))
        {
            Ok(signals) => outputs.extend(signals.iter().map(|s| s.source)),
            Err(_) => return false,
        }
    }
    outputs.iter().all(|&r| {
        let chain = alone.signal_chain(r);
        there.iter().any(|s| mgr.signal_chain(s.source) == chain)
    })
}

/// The CPU time the calling thread has used: what a trial's blocks cost, whatever time
/// the thread spent waiting for a core.
fn thread_cpu() -> Duration {
    use nix::time::{clock_gettime, ClockId};
    clock_gettime(ClockId::CLOCK_THREAD_CPUTIME_ID)
        .map(Duration::from)
        .unwrap_or_default()
}

/// A small xorshift generator: uniform noise in [-1, 1), the same every trial.
struct Noise(u64);

impl Noise {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// A trial asked of [`Trials`]: its ticket, the stream's shape, the requests (from its
/// manager's registry) and the time above which the answer is known.
type Job = (u64, Shape, Registry, Vec<(String, ParamMap)>, f64);

/// A thread that runs trials one after another, off the audio path: the stream's
/// thread submits them and collects their outcomes between blocks, never waiting.
pub struct Trials {
    jobs: Option<SyncSender<Job>>,
    done: Receiver<(u64, Result<Cost, TrialError>)>,
    waiting: usize,
    thread: Option<JoinHandle<()>>,
}

/// Puts the calling thread (the trials') below the stream's threads, so that a trial
/// never takes their cores: the ordinary policy (not the SCHED_FIFO that threads started
/// after `--rt` inherit) at nice 10. Best effort: neither step needs a privilege, and a
/// trial that runs at the stream's own priority still measures the same cost.
fn below_the_stream() {
    use thread_priority::{
        set_thread_priority_and_policy, thread_native_id, NormalThreadSchedulePolicy,
        ThreadPriority, ThreadPriorityValue, ThreadSchedulePolicy,
    };
    let normal = ThreadSchedulePolicy::Normal(NormalThreadSchedulePolicy::Other);
    // 22 on the crate's 0-99 scale is nice 10 for the ordinary policy
    if let Ok(value) = ThreadPriorityValue::try_from(22u8) {
        let priority = ThreadPriority::Crossplatform(value);
        let _ = set_thread_priority_and_policy(thread_native_id(), priority, normal);
    }
}

impl Trials {
    /// Starts the thread; at most `slots` trials wait or run at once.
    pub fn start(slots: usize) -> std::io::Result<Trials> {
        let slots = slots.max(1);
        let (jobs, from) = mpsc::sync_channel::<Job>(slots);
        let (back, done) = mpsc::channel();
        let thread = std::thread::Builder::new()
            .name("afe-trials".into())
            .spawn(move || {
                below_the_stream();
                for (ticket, shape, registry, requests, enough_ms) in from {
                    if back
                        .send((ticket, measure(shape, &registry, &requests, enough_ms)))
                        .is_err()
                    {
                        break;
                    }
                }
            })?;
        Ok(Trials {
            jobs: Some(jobs),
            done,
            waiting: 0,
            thread: Some(thread),
        })
    }

    /// Asks for a trial of `requests` (of `registry`, the stream's manager's); refused
    /// when every slot is taken.
    pub fn submit(
        &mut self,
        ticket: u64,
        shape: Shape,
        registry: &Registry,
        requests: Vec<(String, ParamMap)>,
        enough_ms: f64,
    ) -> Result<(), TrialError> {
        let jobs = self.jobs.as_ref().ok_or(TrialError::Stopped)?;
        match jobs.try_send((ticket, shape, registry.clone(), requests, enough_ms)) {
            Ok(()) => {
                self.waiting += 1;
                Ok(())
            }
            Err(TrySendError::Full(_)) => Err(TrialError::Busy(self.waiting)),
            Err(TrySendError::Disconnected(_)) => Err(TrialError::Stopped),
        }
    }

    /// The outcomes of the trials finished since the last call.
    pub fn finished(&mut self) -> Vec<(u64, Result<Cost, TrialError>)> {
        let done: Vec<_> = self.done.try_iter().collect();
        self.waiting -= done.len().min(self.waiting);
        done
    }
}

impl Drop for Trials {
    fn drop(&mut self) {
        self.jobs = None;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// The stream's load (compute time of a block over its budget, averaged over about a
/// second) and the share of it requests may take.
#[derive(Debug, Clone)]
pub struct LoadCap {
    load: f64,
    max_load: f64,
    budget_ms: f64,
}

impl LoadCap {
    /// A cap at `max_load` (a share of the block's budget, e.g. 0.8).
    pub fn new(max_load: f64) -> Self {
        LoadCap {
            load: 0.0,
            max_load,
            budget_ms: 0.0,
        }
    }

    /// Follows the stream's last block.
    pub fn observe(&mut self, timing: &Timing) {
        let (ms, budget) = timing.last_block_ms();
        self.budget_ms = budget;
        if budget > 0.0 {
            // a first-order average with a time constant of about a second
            let alpha = (budget / 1000.0).min(1.0);
            self.load += alpha * (ms / budget - self.load);
        }
    }

    /// Whether the stream has a deadline (it runs at real time); without one, nothing
    /// needs measuring.
    pub fn has_deadline(&self) -> bool {
        self.budget_ms > 0.0
    }

    /// Refuses any addition while the stream is above its limit.
    pub fn check_load(&self) -> Result<(), TrialError> {
        if self.has_deadline() && self.load > self.max_load {
            return Err(TrialError::Loaded {
                load_pct: 100.0 * self.load,
                max_pct: 100.0 * self.max_load,
            });
        }
        Ok(())
    }

    /// What a block may still take, ms: the trial's answer is known beyond it.
    pub fn headroom_ms(&self) -> f64 {
        ((self.max_load - self.load) * self.budget_ms).max(0.0)
    }

    /// Takes requests of this cost, or refuses them; once taken, the load counts their
    /// cost at once (the average would take a second to see it), so that the next
    /// request is checked against it.
    pub fn admit(&mut self, what: &str, cost: Cost) -> Result<(), TrialError> {
        if !self.has_deadline() {
            return Ok(());
        }
        let cap_ms = self.max_load * self.budget_ms;
        let used_ms = self.load * self.budget_ms;
        if cost.partial || used_ms + cost.ms > cap_ms {
            return Err(TrialError::OverBudget {
                what: what.to_string(),
                cost_ms: cost.ms,
                more: if cost.partial { " or more" } else { "" },
                budget_ms: self.budget_ms,
                used_ms,
                cap_ms,
                max_pct: 100.0 * self.max_load,
            });
        }
        self.load += cost.ms / self.budget_ms;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape() -> Shape {
        Shape {
            fs: 16000.0,
            ears: 2,
            block_frames: 160,
        }
    }

    #[test]
    fn a_trial_costs_a_heavy_request_more_than_a_light_one() {
        let light = measure(
            shape(),
            &Registry::default(),
            &[("ild".into(), ParamMap::new())],
            f64::INFINITY,
        )
        .expect("ild");
        let heavy_params: ParamMap = [
            ("fb_nChannels".to_string(), serde_json::json!(64)),
            ("ac_wSizeSec".to_string(), serde_json::json!(0.05)),
            ("ac_hSizeSec".to_string(), serde_json::json!(0.002)),
        ]
        .into_iter()
        .collect();
        let heavy = measure(
            shape(),
            &Registry::default(),
            &[("autocorrelation".into(), heavy_params)],
            f64::INFINITY,
        )
        .expect("autocorrelation");
        assert!(!light.partial && !heavy.partial);
        assert!(heavy.ms > 5.0 * light.ms, "{heavy:?} vs {light:?}");
    }

    #[test]
    fn a_request_that_cannot_be_placed_is_named() {
        let bad: ParamMap = [("fb_nChannels".to_string(), serde_json::json!(-3))]
            .into_iter()
            .collect();
        let e = measure(
            shape(),
            &Registry::default(),
            &[("ratemap".into(), bad)],
            1.0,
        )
        .expect_err("refused");
        assert!(e.to_string().starts_with("request 'ratemap':"), "{e}");
    }

    #[test]
    fn requests_computed_already_are_told_and_the_graph_is_left_alone() {
        let mut mgr = Manager::new(16000.0, 2).expect("manager");
        let ild = vec![("ild".to_string(), ParamMap::new())];
        assert!(!shared_entirely(&mgr, &ild));
        assert_eq!(mgr.handles().count(), 0);
        mgr.add_request("ild", &ParamMap::new()).expect("ild");
        let count = mgr.processor_count();
        assert!(shared_entirely(&mgr, &ild));
        assert!(!shared_entirely(
            &mgr,
            &[("itd".to_string(), ParamMap::new())]
        ));
        assert_eq!((mgr.processor_count(), mgr.handles().count()), (count, 1));
    }

    #[test]
    fn requests_are_described_for_messages() {
        let r = |n: &str| (n.to_string(), ParamMap::new());
        assert_eq!(describe(&[r("ild")]), "'ild'");
        assert_eq!(
            describe(&[r("ild"), r("itd"), r("ic")]),
            "'ild', 'itd' and 'ic'"
        );
    }
}
