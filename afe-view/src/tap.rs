//! The audio side of the live view: after each block it copies the new frames into a
//! pooled batch and hands full batches to the server's thread without blocking; when
//! no batch is free (a slow page) the frames are dropped and counted, never queued.
//! Edits asked for by pages are applied here, between blocks, within the view's
//! [`Limits`]: requests per page and in all, edits per block, the stream's load.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError};
use std::sync::Arc;

use afe_graph::{Manager, OutputRef};
use serde_json::{json, Value};

use afe::metadata::describe;
use afe::stream::{Observer, Timing};

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

/// The live view's end of a stream (an [`Observer`]).
pub struct Tap {
    pub(crate) to_server: SyncSender<ToServer>,
    pub(crate) pool: Receiver<Batch>,
    pub(crate) edits: Receiver<Edit>,
    pub(crate) listeners: Arc<AtomicUsize>,
    /// Blocks per batch.
    pub(crate) batch_blocks: u32,
    limits: Limits,
    batch: Option<Batch>,
    /// The signals of the current layout.
    sources: Vec<OutputRef>,
    version: u64,
    dropped_frames: u64,
    /// Requests placed by pages and still in place: (handle, page).
    placed: Vec<(usize, u64)>,
    /// Compute time of a block over its duration, averaged over about a second.
    load: f64,
}

impl Tap {
    pub(crate) fn new(
        to_server: SyncSender<ToServer>,
        pool: Receiver<Batch>,
        edits: Receiver<Edit>,
        listeners: Arc<AtomicUsize>,
        batch_blocks: u32,
        limits: Limits,
    ) -> Self {
        Tap {
            to_server,
            pool,
            edits,
            listeners,
            batch_blocks,
            limits,
            batch: None,
            sources: Vec::new(),
            version: 0,
            dropped_frames: 0,
            placed: Vec::new(),
            load: 0.0,
        }
    }

    /// Applies up to `edits_per_block` of the edits pages asked for, replying to each
    /// page.
    fn apply_edits(&mut self, mgr: &mut Manager) {
        for _ in 0..self.limits.edits_per_block {
            let Ok(edit) = self.edits.try_recv() else {
                break;
            };
            let (page, op, outcome) = match edit {
                Edit::Add { page, name, params } => {
                    (page, "add", self.add(mgr, page, &name, &params))
                }
                Edit::Remove { page, handle } => (
                    page,
                    "remove",
                    mgr.remove_request(afe_graph::RequestHandle::from_index(handle))
                        .map(|()| {
                            self.placed.retain(|&(h, _)| h != handle);
                            format!("removed request {handle}")
                        })
                        .map_err(|e| e.to_string()),
                ),
                Edit::Set { page, name, value } => (
                    page,
                    "set",
                    set_everywhere(mgr, &name, value).map_err(|e| e.to_string()),
                ),
            };
            let reply = match outcome {
                Ok(message) => json!({ "type": "reply", "op": op, "ok": true, "message": message }),
                Err(message) => {
                    json!({ "type": "reply", "op": op, "ok": false, "message": message })
                }
            };
            // control messages wait for room: they are few (bounded per block), and a
            // page must see them
            let _ = self.to_server.send(ToServer::Reply {
                page,
                text: reply.to_string(),
            });
        }
    }

    /// Places a request for `page` if the limits allow it.
    fn add(
        &mut self,
        mgr: &mut Manager,
        page: u64,
        name: &str,
        params: &afe_core::ParamMap,
    ) -> Result<String, String> {
        let limits = &self.limits;
        let mine = self.placed.iter().filter(|&&(_, p)| p == page).count();
        if mine >= limits.requests_per_page {
            return Err(format!(
                "this page has {mine} requests in place, the most one page may add: \
                 remove one first"
            ));
        }
        if self.placed.len() >= limits.requests {
            return Err(format!(
                "pages have {} requests in place, the most this server takes from pages: \
                 remove one first",
                self.placed.len()
            ));
        }
        if self.load > limits.max_load {
            return Err(format!(
                "the stream uses {:.0} % of its real-time budget (above {:.0} %): remove a \
                 request before adding one",
                100.0 * self.load,
                100.0 * limits.max_load
            ));
        }
        let h = mgr.add_request(name, params).map_err(|e| e.to_string())?;
        self.placed.push((h.index(), page));
        Ok(format!("placed {name} (request {})", h.index()))
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
        let catalogue: Vec<&str> = afe::requests().iter().map(|r| r.name).collect();
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

/// Sets parameter `name` in every request that uses it (the AFE's `modifyParameter`
/// applied to the whole graph); an error if none does or the value is invalid.
fn set_everywhere(mgr: &mut Manager, name: &str, value: Value) -> afe_core::Result<String> {
    let handles: Vec<_> = mgr.handles().collect();
    let mut changed = 0;
    for h in handles {
        match mgr.modify_parameter(h, name, value.clone()) {
            Ok(()) => changed += 1,
            Err(e) if e.to_string().contains("uses this parameter") => {}
            Err(e) => return Err(e),
        }
    }
    if changed == 0 {
        return Err(afe_core::Error::InvalidInput(format!(
            "no request in place uses parameter '{name}'"
        )));
    }
    Ok(format!("{name} = {value} in {changed} request(s)"))
}

impl Observer for Tap {
    fn block(&mut self, timing: &Timing, mgr: &mut Manager, input: &[Vec<f64>]) {
        let (ms, budget) = timing.last_block_ms();
        if budget > 0.0 {
            // a first-order average with a time constant of about a second
            let alpha = (budget / 1000.0).min(1.0);
            self.load += alpha * (ms / budget - self.load);
        }
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
