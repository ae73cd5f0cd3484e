//! The frame clocks: where each output of the graph stands in the input stream, so
//! that each chunk's first frame has an index and a time across edits and resets.

use super::*;

/// The frame count of one output, for the index and time of each chunk's first frame.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct FrameClock {
    /// Input sample (stream clock) at which the output's framing (re)started.
    pub(super) start: u64,
    /// Frames since then.
    pub(super) since: u64,
    /// Frames given in all.
    pub(super) given: u64,
    /// `since` and `given` before the last chunk: its first frame.
    pub(super) first_since: u64,
    pub(super) first_given: u64,
}

impl FrameClock {
    /// A clock (re)started at input sample `start`, after `given` frames in all.
    pub(super) fn started_at(start: u64, given: u64) -> Self {
        FrameClock {
            start,
            given,
            first_given: given,
            ..FrameClock::default()
        }
    }

    /// Counts the `frames` of a chunk, the first of which the clock then stands at.
    pub(super) fn advance(&mut self, frames: u64) {
        self.first_since = self.since;
        self.first_given = self.given;
        self.since += frames;
        self.given += frames;
    }
}

impl Manager {
    /// Gives every output of the graph a frame clock: outputs new since the last edit
    /// start at the current input sample.
    pub(super) fn sync_clocks(&mut self) {
        let now = self.stream_pos;
        self.clocks.resize_with(self.graph.nodes.len(), Vec::new);
        for (clocks, node) in self.clocks.iter_mut().zip(&self.graph.nodes) {
            clocks.resize(node.outputs.len(), FrameClock::started_at(now, 0));
        }
    }

    /// Restarts the framing of `node`'s outputs at the current input sample.
    pub(super) fn restart_clocks(&mut self, node: usize) {
        let now = self.stream_pos;
        for c in self.clocks.get_mut(node).into_iter().flatten() {
            *c = FrameClock::started_at(now, c.given);
        }
    }

    /// Counts the frames of the chunk just collected (node 0, the input, is no signal).
    pub(super) fn tick(&mut self) {
        for (n, clocks) in self.clocks.iter_mut().enumerate().skip(1) {
            for (o, c) in clocks.iter_mut().enumerate() {
                let r = OutputRef { node: n, output: o };
                let frames = match &self.engine {
                    Some(e) => e.frames(r),
                    None => self.graph.nodes[n].outputs[o].frames(),
                };
                c.advance(frames as u64);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// Chunks of 10 ms with a window change after 0.5 s and a reset after 1 s: the frame
    /// times stay monotonic, the index keeps counting, and each restart's first frame
    /// stands at the input sample where it restarted.
    #[test]
    fn frame_times_follow_the_input_across_edits_and_resets() {
        for threads in [0, 2] {
            let fs = 16000.0;
            let mut m = Manager::with_threads(fs, 2, threads).expect("manager");
            let h = m
                .add_request("ratemap", &params(&[("fb_nChannels", json!(4))]))
                .expect("ratemap");
            let x: Vec<f64> = (0..160).map(|t| (t as f64 * 0.3).sin() * 0.1).collect();
            let mut times: Vec<f64> = Vec::new();
            let mut index = 0;
            let mut restarted: Option<f64> = None;
            for k in 0..150 {
                if k == 50 {
                    m.modify_parameter(h, "rm_hSizeSec", json!(0.02))
                        .expect("modify");
                }
                if k == 100 {
                    m.reset().expect("reset");
                }
                m.submit_chunk(&[&x, &x]).expect("submit");
                m.collect_chunk().expect("collect");
                let s = &m.request_signals(h).expect("signals")[0];
                assert_eq!(s.first_frame, index, "threads {threads}, chunk {k}");
                if s.new.frames() == 0 {
                    continue;
                }
                index += s.new.frames() as u64;
                let hop = 1.0 / s.info.fs_hz;
                for f in 0..s.new.frames() {
                    times.push(s.first_time_s + f as f64 * hop);
                }
                if let Some(t) = restarted.take() {
                    // the first frame after a restart stands where the restart was
                    assert!(
                        (s.first_time_s - t).abs() < 1e-12,
                        "{} vs {t}",
                        s.first_time_s
                    );
                }
            }
            assert!(
                times.windows(2).all(|w| w[1] > w[0]),
                "threads {threads}: not monotonic"
            );
            assert_eq!(times[0], 0.0);
            // 10-ms hops before the change, 20-ms hops after it
            let hops = |t0: f64, t1: f64| -> Vec<f64> {
                times
                    .windows(2)
                    .filter(|w| w[0] >= t0 && w[1] < t1)
                    .map(|w| w[1] - w[0])
                    .collect()
            };
            assert!(hops(0.0, 0.5).iter().all(|h| (h - 0.01).abs() < 1e-12));
            assert!(hops(0.5, 1.0).iter().all(|h| (h - 0.02).abs() < 1e-12));
            assert!(hops(1.0, 1.5).iter().all(|h| (h - 0.02).abs() < 1e-12));
        }
    }
}
