//! What a remote subscriber received: counts, losses and the latency from the server's
//! port to this client, as `afe subscribe --json` reports them.

use std::time::{SystemTime, UNIX_EPOCH};

use serde_json::{json, Map, Value};

use super::{Frames, Subscription};
use afe::block_times::BlockTimes;

/// Running totals of a subscription's blocks.
#[derive(Debug, Clone, Default)]
pub struct Tally {
    messages: u64,
    input_frames: u64,
    rows: Vec<u64>,
    latency: BlockTimes,
}

impl Tally {
    /// Counts a block, with its latency: now minus the time its last frame was on the
    /// server's port (meaningful when both clocks are one, on the same host).
    pub fn add(&mut self, f: &Frames) {
        let now_ns = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        let latency_s = now_ns.saturating_sub(f.t_ns) as f64 * 1e-9;
        self.messages += 1;
        self.input_frames += f.input_frames as u64;
        self.rows.resize(f.signals.len(), 0);
        for (r, s) in self.rows.iter_mut().zip(&f.signals) {
            *r += s.rows as u64;
        }
        // a budget no block exceeds: only the quantiles are wanted
        self.latency.record(latency_s, f64::INFINITY);
    }

    /// Blocks received.
    pub fn messages(&self) -> u64 {
        self.messages
    }

    /// Input frames the received blocks cover.
    pub fn input_frames(&self) -> u64 {
        self.input_frames
    }

    /// The report: messages and frames received and lost per signal, and the latency's
    /// p50, p99 and maximum in ms.
    pub fn report(&self, sub: &Subscription) -> Value {
        let keys = sub.keys();
        let per_key = |v: &[u64]| -> Map<String, Value> {
            keys.iter()
                .zip(v.iter().chain(std::iter::repeat(&0)))
                .map(|(k, n)| (k.to_string(), json!(n)))
                .collect()
        };
        json!({
            "subscription": sub.id(),
            "keys": keys,
            "messages": self.messages,
            "lost_messages": sub.lost_messages(),
            "input_frames": self.input_frames,
            "frames": per_key(&self.rows),
            "lost_frames": per_key(sub.lost_frames()),
            "latency_ms_p50": self.latency.quantile_s(0.5) * 1e3,
            "latency_ms_p99": self.latency.quantile_s(0.99) * 1e3,
            "latency_ms_max": self.latency.max_s() * 1e3,
        })
    }
}
