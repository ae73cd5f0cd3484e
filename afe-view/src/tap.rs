//! The audio side of the live view: after each block it copies the new frames into a
//! pooled batch and hands full batches to the server's thread without blocking; when
//! no batch is free (a slow page) the frames are dropped and counted, never queued.
//! Edits asked for by pages are applied here, between blocks, within the view's
//! [`Limits`]: requests per page and in all, edits per block, the stream's load. A page
//! edits only the requests it placed (never the stream's own, another page's or a Zenoh
//! client's), its requests go when it closes, and what it adds or changes is measured
//! first ([`afe::trial`]) and refused if it would take the stream past its deadline.

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError};
use std::sync::Arc;

use afe_graph::{Manager, OutputRef};
use serde_json::{json, Value};

use afe::metadata::describe;
use afe::stream::{Observer, Timing};
use afe::trial::{Cost, LoadCap, Shape, TrialError, Trials};

use super::Limits;

/// Values reserved per signal in a fresh batch, so that steady-state blocks append
/// without growing it.
const RESERVE: usize = 1 << 14;

/// One signal's frames in a batch.
pub(crate) struct Slot {
    /// Output name.
    pub key: String,
    /// Shape of one frame (complex values are sent as magnitudes).
    pub frame_shape: Vec<usize>,
    /// Whether the signal is complex (the values are `|z|`).
    complex: bool,
    /// Index of the first frame in the batch among the output's frames.
    pub first_frame: u64,
    /// Frames in the batch.
    pub rows: usize,
    /// The frames, time-major.
    pub data: Vec<f32>,
}

/// The frames of a few consecutive blocks, sent to pages as one message.
pub(crate) struct Batch {
    /// Layout version the slots follow.
    version: u64,
    /// One per signal, in the graph's order.
    pub slots: Vec<Slot>,
    /// Per block and ear: the block's minimum and maximum sample (the waveform).
    pub wave: Vec<f32>,
    /// The input samples, interleaved, while a page listens.
    pub audio: Vec<f32>,
    /// Blocks in the batch.
    pub blocks: u32,
    /// Frames the stream has processed up to the end of this batch.
    pub frames_total: u64,
    /// Frames the stream lost so far (its reader fell behind).
    pub lost_frames: u64,
    /// Frames dropped so far because no batch was free (slow pages).
    pub dropped_frames: u64,
    /// Largest compute time of a block in the batch, ms, and the block budget, ms.
    pub compute_ms_max: f64,
    /// Budget of one block (its duration), ms.
    pub budget_ms: f64,
}

impl Batch {
    /// An empty batch.
    pub fn new() -> Self {
        Batch {
            version: u64::MAX,
            slots: Vec::new(),
            wave: Vec::with_capacity(RESERVE),
            audio: Vec::with_capacity(RESERVE),
            blocks: 0,
            frames_total: 0,
            lost_frames: 0,
            dropped_frames: 0,
            compute_ms_max: 0.0,
            budget_ms: 0.0,
        }
    }

    /// Empties the batch, keeping its buffers.
    pub fn clear(&mut self) {
        for s in &mut self.slots {
            s.rows = 0;
            s.data.clear();
        }
        self.wave.clear();
        self.audio.clear();
        self.blocks = 0;
        self.compute_ms_max = 0.0;
    }
}

/// What the tap sends to the server's thread.
pub(crate) enum ToServer {
    /// Frames of a few blocks.
    Frames(Batch),
    /// A JSON text message for every page (the graph's new layout).
    Text(String),
    /// A JSON text message for one page (the outcome of its edit).
    Reply { page: u64, text: String },
}

/// An edit asked for by a page (`page` is its id).
pub(crate) enum Edit {
    /// Place request `name` with `params`.
    Add {
        page: u64,
        name: String,
        params: afe_core::ParamMap,
    },
    /// Remove the request with this handle.
    Remove { page: u64, handle: usize },
    /// Set parameter `name` to `value` in every request that uses it.
    Set {
        page: u64,
        name: String,
        value: Value,
    },
}

/// A request a page placed and that is still in place.
struct Placed {
    handle: usize,
    page: u64,
    name: String,
    /// The parameters it was placed with.
    params: afe_core::ParamMap,
    /// Its cost per block as measured before it was placed, ms.
    cost_ms: f64,
}

/// An edit waiting for the trial of what it would place.
enum Measured {
    /// A page's new request.
    Add {
        page: u64,
        name: String,
        params: afe_core::ParamMap,
    },
    /// A page's requests `old` (handles), to be placed again as `new` with `param` set.
    Set {
        page: u64,
        param: String,
        old: Vec<usize>,
        new: Vec<(String, afe_core::ParamMap)>,
    },
}

impl Measured {
    fn page(&self) -> u64 {
        match self {
            Measured::Add { page, .. } | Measured::Set { page, .. } => *page,
        }
    }
}

/// The live view's end of a stream (an [`Observer`]).
pub struct Tap {
    pub(crate) to_server: SyncSender<ToServer>,
    pub(crate) pool: Receiver<Batch>,
    pub(crate) edits: Receiver<Edit>,
    /// Pages that closed: their requests go.
    pub(crate) departed: Receiver<u64>,
    pub(crate) listeners: Arc<AtomicUsize>,
    /// Blocks per batch.
    pub(crate) batch_blocks: u32,
    limits: Limits,
    batch: Option<Batch>,
    /// The signals of the current layout.
    sources: Vec<OutputRef>,
    version: u64,
    dropped_frames: u64,
    /// Requests placed by pages and still in place.
    placed: Vec<Placed>,
    /// Edits whose cost is being measured, by ticket.
    measured: HashMap<u64, Measured>,
    next_ticket: u64,
    /// Measures requests before they are placed, off the audio path.
    trials: Trials,
    /// The stream's load and the share requests may take.
    cap: LoadCap,
    /// The stream's shape, for the trials.
    shape: Option<Shape>,
    /// The robot's platform descriptor, sent with each layout.
    platform: Option<Value>,
}

impl Tap {
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        to_server: SyncSender<ToServer>,
        pool: Receiver<Batch>,
        edits: Receiver<Edit>,
        departed: Receiver<u64>,
        listeners: Arc<AtomicUsize>,
        batch_blocks: u32,
        limits: Limits,
        trials: Trials,
        platform: Option<Value>,
    ) -> Self {
        Tap {
            to_server,
            pool,
            edits,
            departed,
            listeners,
            batch_blocks,
            cap: LoadCap::new(limits.max_load),
            limits,
            batch: None,
            sources: Vec::new(),
            version: 0,
            dropped_frames: 0,
            placed: Vec::new(),
            measured: HashMap::new(),
            next_ticket: 0,
            trials,
            shape: None,
            platform,
        }
    }

    /// Sends `page` the outcome of its edit `op`.
    fn reply(&self, page: u64, op: &str, outcome: Result<String, String>) {
        let reply = match outcome {
            Ok(message) => json!({ "type": "reply", "op": op, "ok": true, "message": message }),
            Err(message) => json!({ "type": "reply", "op": op, "ok": false, "message": message }),
        };
        // control messages wait for room: they are few (bounded per block), and a
        // page must see them
        let _ = self.to_server.send(ToServer::Reply {
            page,
            text: reply.to_string(),
        });
    }

    /// Removes the requests of the pages that closed, and forgets their edits.
    fn forget_departed(&mut self, mgr: &mut Manager) {
        while let Ok(page) = self.departed.try_recv() {
            for p in self.placed.iter().filter(|p| p.page == page) {
                let _ = mgr.remove_request(afe_graph::RequestHandle::from_index(p.handle));
            }
            self.placed.retain(|p| p.page != page);
            self.measured.retain(|_, m| m.page() != page);
        }
    }

    /// Places what was measured and fits, replying to each page.
    fn apply_measured(&mut self, mgr: &mut Manager) {
        for (ticket, cost) in self.trials.finished() {
            let Some(edit) = self.measured.remove(&ticket) else {
                continue; // its page has gone
            };
            match edit {
                Measured::Add { page, name, params } => {
                    let tried = [(name.clone(), params.clone())];
                    // computed already meanwhile (by an equal request placed since)
                    let cost = if afe::trial::shared_entirely(&*mgr, &tried) {
                        Ok(Cost::free())
                    } else {
                        cost
                    };
                    let outcome = cost
                        .and_then(|c| self.cap.admit(&format!("'{name}'"), c).map(|()| c))
                        .map_err(|e| e.to_string())
                        .and_then(|c| self.place(mgr, page, &name, &params, c.ms));
                    self.reply(page, "add", outcome);
                }
                Measured::Set {
                    page,
                    param,
                    old,
                    new,
                } => {
                    let outcome = self.replace(mgr, page, &param, &old, &new, cost);
                    self.reply(page, "set", outcome);
                }
            }
        }
    }

    /// Applies up to `edits_per_block` of the edits pages asked for, replying to each
    /// page (an add or a set once its trial has measured it).
    fn apply_edits(&mut self, mgr: &mut Manager) {
        self.forget_departed(mgr);
        self.apply_measured(mgr);
        for _ in 0..self.limits.edits_per_block {
            let Ok(edit) = self.edits.try_recv() else {
                break;
            };
            match edit {
                Edit::Add { page, name, params } => {
                    if let Err(why) = self.add(mgr, page, name, params) {
                        self.reply(page, "add", Err(why));
                    }
                }
                Edit::Remove { page, handle } => {
                    let outcome = self.remove(mgr, page, handle);
                    self.reply(page, "remove", outcome);
                }
                Edit::Set { page, name, value } => {
                    if let Err(why) = self.set(mgr, page, name, value) {
                        self.reply(page, "set", Err(why));
                    }
                }
            }
        }
    }

    /// Requests `page` has in place or being measured.
    fn count(&self, page: Option<u64>) -> usize {
        let mine = |p: u64| page.is_none_or(|q| q == p);
        self.placed.iter().filter(|p| mine(p.page)).count()
            + self
                .measured
                .values()
                .filter(|m| matches!(m, Measured::Add { page: p, .. } if mine(*p)))
                .count()
    }

    /// Asks for the trial of `page`'s new request if the limits allow it (or places it
    /// at once when the stream has no deadline); the reply comes when it is placed or
    /// refused.
    fn add(
        &mut self,
        mgr: &mut Manager,
        page: u64,
        name: String,
        params: afe_core::ParamMap,
    ) -> Result<(), String> {
        let limits = &self.limits;
        let mine = self.count(Some(page));
        if mine >= limits.requests_per_page {
            return Err(format!(
                "this page has {mine} requests in place, the most one page may add: \
                 remove one first"
            ));
        }
        let all = self.count(None);
        if all >= limits.requests {
            return Err(format!(
                "pages have {all} requests in place, the most this server takes from pages: \
                 remove one first"
            ));
        }
        self.cap.check_load().map_err(|e| e.to_string())?;
        let tried = vec![(name.clone(), params.clone())];
        match self.shape.filter(|_| self.cap.has_deadline()) {
            Some(shape) if !afe::trial::shared_entirely(&*mgr, &tried) => {
                let ticket = self.ticket();
                self.trials
                    .submit(ticket, shape, mgr.registry(), tried, self.cap.headroom_ms())
                    .map_err(|e| e.to_string())?;
                self.measured
                    .insert(ticket, Measured::Add { page, name, params });
            }
            // no deadline, or nothing new to compute: placed at once
            _ => {
                let outcome = self.place(mgr, page, &name, &params, 0.0);
                self.reply(page, "add", outcome);
            }
        }
        Ok(())
    }

    fn ticket(&mut self) -> u64 {
        self.next_ticket += 1;
        self.next_ticket
    }

    /// Places a request for `page`, measured at `cost_ms` per block.
    fn place(
        &mut self,
        mgr: &mut Manager,
        page: u64,
        name: &str,
        params: &afe_core::ParamMap,
        cost_ms: f64,
    ) -> Result<String, String> {
        let h = mgr.add_request(name, params).map_err(|e| e.to_string())?;
        self.placed.push(Placed {
            handle: h.index(),
            page,
            name: name.to_string(),
            params: params.clone(),
            cost_ms,
        });
        Ok(format!("placed {name} (request {})", h.index()))
    }

    /// Removes a request `page` placed; any other (the stream's own, another page's, a
    /// Zenoh client's) is refused.
    fn remove(&mut self, mgr: &mut Manager, page: u64, handle: usize) -> Result<String, String> {
        let h = afe_graph::RequestHandle::from_index(handle);
        if !self
            .placed
            .iter()
            .any(|p| p.handle == handle && p.page == page)
        {
            return Err(if mgr.request_signals(h).is_ok() {
                format!(
                    "request {handle} was not placed by this page: a page removes only the \
                     requests it added"
                )
            } else {
                format!("no request {handle} is in place")
            });
        }
        mgr.remove_request(h).map_err(|e| e.to_string())?;
        self.placed.retain(|p| p.handle != handle);
        Ok(format!("removed request {handle}"))
    }

    /// Sets parameter `name` in `page`'s requests that use it, by placing them again
    /// with the new value (their processors shared with other requests are left alone,
    /// so no one else's request changes): measured first when the stream has a deadline.
    fn set(
        &mut self,
        mgr: &mut Manager,
        page: u64,
        name: String,
        value: Value,
    ) -> Result<(), String> {
        let single: afe_core::ParamMap = [(name.clone(), value.clone())].into_iter().collect();
        mgr.registry()
            .check_parameter_names(single.keys())
            .map_err(|e| e.to_string())?;
        let mut old = Vec::new();
        let mut new = Vec::new();
        for p in self.placed.iter().filter(|p| p.page == page) {
            let h = afe_graph::RequestHandle::from_index(p.handle);
            let used = mgr
                .request_parameters(h)
                .is_ok_and(|used| used.contains_key(&name));
            if used {
                let mut params = p.params.clone();
                params.insert(name.clone(), value.clone());
                old.push(p.handle);
                new.push((p.name.clone(), params));
            }
        }
        if old.is_empty() {
            return Err(format!(
                "no request this page placed uses parameter '{name}' (a page changes only \
                 the requests it added)"
            ));
        }
        match self.shape.filter(|_| self.cap.has_deadline()) {
            None => {
                let outcome = self.replace(mgr, page, &name, &old, &new, Ok(Cost::free()));
                self.reply(page, "set", outcome);
            }
            Some(shape) => {
                let ticket = self.ticket();
                let freed: f64 = self.cost_of(&old);
                self.trials
                    .submit(
                        ticket,
                        shape,
                        mgr.registry(),
                        new.clone(),
                        self.cap.headroom_ms() + freed,
                    )
                    .map_err(|e| e.to_string())?;
                self.measured.insert(
                    ticket,
                    Measured::Set {
                        page,
                        param: name,
                        old,
                        new,
                    },
                );
            }
        }
        Ok(())
    }

    /// The measured cost of these placed requests, ms per block.
    fn cost_of(&self, handles: &[usize]) -> f64 {
        self.placed
            .iter()
            .filter(|p| handles.contains(&p.handle))
            .map(|p| p.cost_ms)
            .sum()
    }

    /// Places `new` in place of `page`'s requests `old` (those still there), if their
    /// measured cost fits once the old ones have gone; all or none.
    fn replace(
        &mut self,
        mgr: &mut Manager,
        page: u64,
        param: &str,
        old: &[usize],
        new: &[(String, afe_core::ParamMap)],
        cost: Result<Cost, TrialError>,
    ) -> Result<String, String> {
        let old: Vec<usize> = old
            .iter()
            .copied()
            .filter(|h| self.placed.iter().any(|p| p.handle == *h && p.page == page))
            .collect();
        if old.len() != new.len() {
            return Err(format!(
                "the requests using '{param}' changed meanwhile: set it again"
            ));
        }
        let cost = cost.map_err(|e| e.to_string())?;
        let freed = self.cost_of(&old);
        let what = afe::trial::describe(new);
        self.cap
            .admit(&what, cost.less(freed))
            .map_err(|e| e.to_string())?;
        let mut placed = Vec::new();
        for (name, params) in new {
            match mgr.add_request(name, params) {
                Ok(h) => placed.push(h),
                Err(e) => {
                    for h in placed {
                        let _ = mgr.remove_request(h);
                    }
                    return Err(format!("request '{name}': {e}"));
                }
            }
        }
        let each = cost.ms / new.len() as f64;
        for (h, (name, params)) in placed.iter().zip(new) {
            self.placed.push(Placed {
                handle: h.index(),
                page,
                name: name.clone(),
                params: params.clone(),
                cost_ms: each,
            });
        }
        for &h in &old {
            let _ = mgr.remove_request(afe_graph::RequestHandle::from_index(h));
        }
        self.placed.retain(|p| !old.contains(&p.handle));
        let now: Vec<String> = placed.iter().map(|h| h.index().to_string()).collect();
        Ok(format!(
            "{param} = {} in {} request(s) of this page, placed again as request(s) {}",
            new[0].1[param],
            new.len(),
            now.join(", ")
        ))
    }

    /// Sends the layout if the graph's signals changed (placed, removed, rebuilt), with
    /// what a page needs first: the input's rate and ears, the block length and the
    /// request catalogue. The first block always sends one, even with no request in
    /// place, so that a page knows the stream before anything is added.
    fn check_layout(&mut self, mgr: &Manager, timing: &Timing) {
        let signals = mgr.signals(false);
        if self.version > 0
            && signals.len() == self.sources.len()
            && signals
                .iter()
                .zip(&self.sources)
                .all(|(s, r)| s.source == *r)
        {
            return;
        }
        self.flush();
        self.sources = signals.iter().map(|s| s.source).collect();
        self.version += 1;
        let described: serde_json::Map<String, Value> = signals
            .iter()
            .map(|s| (s.key(), describe(mgr, s)))
            .collect();
        let requests: Vec<Value> = mgr
            .handles()
            .map(|h| {
                let outputs: Vec<String> = mgr
                    .request_signals(h)
                    .map(|v| v.iter().map(afe_graph::Signal::key).collect())
                    .unwrap_or_default();
                json!({ "handle": h.index(), "outputs": outputs })
            })
            .collect();
        let order: Vec<String> = signals.iter().map(afe_graph::Signal::key).collect();
        let catalogue: Vec<&str> = mgr.registry().requests().iter().map(|r| r.name).collect();
        let layout = json!({
            "type": "layout",
            "version": self.version,
            "fs_hz": mgr.fs(),
            "ears": mgr.ears(),
            "block_ms": timing.last_block_ms().1,
            "catalogue": catalogue,
            "order": order,
            "signals": described,
            "requests": requests,
            "platform": self.platform,
        });
        let _ = self.to_server.send(ToServer::Text(layout.to_string()));
    }

    /// Sends the batch being filled, if it holds anything; drops it (counted) when the
    /// server's thread has no room.
    fn flush(&mut self) {
        let Some(batch) = self.batch.take() else {
            return;
        };
        if batch.blocks == 0 {
            self.batch = Some(batch);
            return;
        }
        let frames = batch.slots.first().map_or(0, |s| s.rows as u64);
        match self.to_server.try_send(ToServer::Frames(batch)) {
            Ok(()) => {}
            Err(TrySendError::Full(ToServer::Frames(mut b))) => {
                self.dropped_frames += frames;
                b.clear();
                self.batch = Some(b);
            }
            Err(_) => {}
        }
    }
}

impl Observer for Tap {
    fn block(&mut self, timing: &Timing, mgr: &mut Manager, input: &[Vec<f64>]) {
        self.cap.observe(timing);
        self.shape = Some(Shape {
            fs: mgr.fs(),
            ears: mgr.ears(),
            block_frames: timing.block_frames(),
        });
        self.check_layout(mgr, timing);
        if self.batch.is_none() {
            self.batch = self.pool.try_recv().ok();
        }
        let signals = mgr.signals(false);
        let Some(batch) = self.batch.as_mut() else {
            // every batch is on its way to slow pages: these frames are dropped
            self.dropped_frames += signals.first().map_or(0, |s| s.new.frames() as u64);
            drop(signals);
            self.apply_edits(mgr);
            return;
        };
        if batch.version != self.version {
            batch.slots = signals
                .iter()
                .map(|s| Slot {
                    key: s.key(),
                    frame_shape: s.info.frame_shape(),
                    complex: s.info.is_complex(),
                    first_frame: 0,
                    rows: 0,
                    data: Vec::with_capacity(RESERVE),
                })
                .collect();
            batch.version = self.version;
        }
        for (slot, s) in batch.slots.iter_mut().zip(&signals) {
            if slot.rows == 0 {
                slot.first_frame = s.first_frame;
            }
            slot.rows += s.new.frames();
            let values = s.new.as_slice();
            if slot.complex {
                slot.data.extend(
                    values
                        .chunks_exact(2)
                        .map(|z| (z[0] * z[0] + z[1] * z[1]).sqrt() as f32),
                );
            } else {
                slot.data.extend(values.iter().map(|&v| v as f32));
            }
        }
        for ear in input {
            let (lo, hi) = ear
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                    (lo.min(v), hi.max(v))
                });
            batch.wave.extend([lo as f32, hi as f32]);
        }
        if self.listeners.load(Ordering::Relaxed) > 0 {
            let n = input.first().map_or(0, Vec::len);
            for t in 0..n {
                batch.audio.extend(input.iter().map(|ear| ear[t] as f32));
            }
        }
        let (ms, budget) = timing.last_block_ms();
        batch.blocks += 1;
        batch.compute_ms_max = batch.compute_ms_max.max(ms);
        batch.budget_ms = budget;
        batch.frames_total = timing.frames();
        batch.lost_frames = timing.lost_frames();
        batch.dropped_frames = self.dropped_frames;
        if batch.blocks >= self.batch_blocks {
            self.flush();
        }
        drop(signals);
        self.apply_edits(mgr);
    }
}
