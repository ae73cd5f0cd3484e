//! Collecting the output of a run: every signal's values over all chunks.

use std::io::{Seek, Write};

use afe_core::{Block, SignalInfo};
use afe_graph::{Manager, OutputRef};
use serde_json::Value;

use crate::metadata::describe;
use crate::npy::Dtype;

/// One signal's output over every chunk processed so far.
#[derive(Debug, Clone)]
pub struct Recorded {
    /// Output name, `<request>_<left|right|mono>` (see [`afe_graph::Signal::key`]).
    pub key: String,
    /// Rate, centre frequencies, lags.
    pub info: SignalInfo,
    /// All values, time-major.
    pub data: Block,
    /// What the values are, as [`describe`] gives it when the recording starts (its
    /// `first_time_s` is the time of the first recorded row); after an edit of its
    /// request, `segments` lists where each parameter setting's rows start.
    pub description: Value,
    /// The output it records; `None` once its request is gone (the rows are kept).
    source: Option<OutputRef>,
}

impl Recorded {
    /// Drops the oldest `frames` rows, moving the description's first row on.
    fn drop_oldest(&mut self, frames: usize) {
        self.data.drop_front(frames);
        let d = &mut self.description;
        if let Some(t) = d["first_time_s"].as_f64() {
            d["first_time_s"] = serde_json::json!(t + frames as f64 / self.info.fs_hz);
        }
        if let Some(f) = d["first_frame"].as_u64() {
            d["first_frame"] = serde_json::json!(f + frames as u64);
        }
        if let Some(list) = d.get_mut("segments").and_then(Value::as_array_mut) {
            for seg in list.iter_mut() {
                let row = seg["first_row"].as_u64().unwrap_or(0) as usize;
                seg["first_row"] = serde_json::json!(row.saturating_sub(frames));
            }
            // segments whose rows are all gone: the last one starting at row 0 holds
            // the first row kept
            let first_kept = list.iter().rposition(|seg| seg["first_row"] == 0);
            list.drain(..first_kept.unwrap_or(0));
        }
    }

    /// The time (s) just after the last row.
    fn end_s(&self) -> f64 {
        let first = self.description["first_time_s"].as_f64().unwrap_or(0.0);
        first + self.data.frames() as f64 / self.info.fs_hz
    }

    /// Marks the next row as the start of a segment described by `now` (its output's
    /// description after the edit: parameters and first time), the first segment being
    /// the rows so far.
    fn start_segment(&mut self, now: Value) {
        let segment = |row: usize, d: &Value| {
            serde_json::json!({
                "first_row": row,
                "first_time_s": d["first_time_s"],
                "parameters": d["parameters"],
            })
        };
        let first = segment(0, &self.description);
        let next = segment(self.data.frames(), &now);
        if let Value::Object(d) = &mut self.description {
            let segments = d
                .entry("segments")
                .or_insert_with(|| Value::Array(vec![first]));
            if let Value::Array(list) = segments {
                list.push(next);
            }
        }
    }

    /// Array shape: `[frames]`, `[frames, channels]` or `[frames, channels, lags]`.
    pub fn shape(&self) -> Vec<usize> {
        let mut s = vec![self.data.frames()];
        s.extend(self.info.frame_shape());
        s
    }
}

/// Appends the new output of each chunk to a per-signal history.
#[derive(Debug, Clone, Default)]
pub struct Recorder {
    all: bool,
    signals: Vec<Recorded>,
    /// Input samples the run will have in all, where known (a file's length).
    expected: Option<u64>,
    /// Seconds of rows each history keeps (`None`: every row, as the AFE does).
    keep_s: Option<f64>,
}

impl Recorder {
    /// A recorder of the requested signals, or (`all`) of every intermediate signal too
    /// (those the manager keeps: see [`Manager::set_keep_all`]).
    pub fn new(all: bool) -> Self {
        Recorder {
            all,
            signals: Vec::new(),
            expected: None,
            keep_s: None,
        }
    }

    /// Keeps only the last `seconds` of each history (at least one row), for long live
    /// runs whose memory must stay bounded; `None` (the default) keeps every row, as the
    /// AFE's data object does. The rows dropped move each description's `first_time_s`
    /// and `first_frame` on (and its segments' first rows back).
    pub fn keep_last(&mut self, seconds: Option<f64>) {
        self.keep_s = seconds.filter(|s| s.is_finite() && *s > 0.0);
        self.trim();
    }

    /// Drops the rows older than the bound, once a history holds twice as many (so that
    /// each row is moved at most once on average). The bound counts back from the newest
    /// row of any history, so that the histories an edit closed (`key@time`) age too and
    /// go once all their rows are older than the bound: a live run that edits its
    /// requests keeps its memory bounded.
    fn trim(&mut self) {
        let Some(keep_s) = self.keep_s else { return };
        let now = (self.signals.iter())
            .filter(|r| r.source.is_some())
            .map(Recorded::end_s)
            .fold(f64::NEG_INFINITY, f64::max);
        self.signals.retain_mut(|r| {
            let keep = ((keep_s * r.info.fs_hz).ceil() as usize).max(1);
            if r.source.is_none() && now.is_finite() {
                // rows of a closed history still within the bound
                let late = ((now - r.end_s()) * r.info.fs_hz).max(0.0);
                let left = keep.saturating_sub(late.floor() as usize);
                if left == 0 {
                    return false;
                }
                if r.data.frames() > 2 * left {
                    r.drop_oldest(r.data.frames() - left);
                }
            } else if r.data.frames() > 2 * keep {
                r.drop_oldest(r.data.frames() - keep);
            }
            true
        });
    }

    /// Sizes each signal's history when it starts for a run of `samples` input samples in
    /// all (a file's length), so that its values are written once instead of growing.
    pub fn expect_input(&mut self, samples: u64) {
        self.expected = Some(samples);
    }

    /// Input samples per ear the run will have, as given to [`Recorder::expect_input`].
    pub fn expected_input(&self) -> Option<u64> {
        self.expected
    }

    /// Appends what `manager` computed in its last chunk.
    pub fn record(&mut self, manager: &Manager) {
        self.record_chunk(manager);
        self.trim();
    }

    fn record_chunk(&mut self, manager: &Manager) {
        for s in manager.signals(self.all) {
            match self.signals.iter_mut().find(|r| r.source == Some(s.source)) {
                Some(r) => r.data.extend_from(s.new),
                None => {
                    let mut data = Block::new(s.new.width());
                    if let Some(n) = self.expected {
                        // frames of the whole run at this signal's rate, and one for rounding
                        let frames = n as f64 * s.info.fs_hz / manager.fs();
                        data.reserve_frames(frames.ceil() as usize + 1);
                    }
                    data.extend_from(s.new);
                    self.signals.push(Recorded {
                        key: s.key(),
                        info: s.info.clone(),
                        data,
                        description: describe(manager, &s),
                        source: Some(s.source),
                    });
                }
            }
        }
    }

    /// Records the output of [`Manager::process_signal`], moving it out of `manager`
    /// (see [`Manager::take_whole`]) rather than copying it.
    pub fn record_whole(&mut self, manager: &mut Manager) {
        let found: Vec<(String, SignalInfo, Value, OutputRef)> = manager
            .signals(self.all)
            .iter()
            .map(|s| (s.key(), s.info.clone(), describe(manager, s), s.source))
            .collect();
        for (key, info, description, source) in found {
            let Some(data) = manager.take_whole(source) else {
                continue;
            };
            match self.signals.iter_mut().find(|r| r.source == Some(source)) {
                Some(r) => r.data.extend_from(&data),
                None => self.signals.push(Recorded {
                    key,
                    info,
                    data,
                    description,
                    source: Some(source),
                }),
            }
        }
    }

    /// Follows an edit of `manager`'s graph (a request added, removed or given a new
    /// parameter value), keeping every row recorded so far, as the AFE's data object
    /// does: each history goes on with the output of the same name, if it still has the
    /// same frame shape. The outputs named in `modified` (the edited request's) start a
    /// new segment, listed with its first row, time and parameters in the description's
    /// `segments`. A history whose output is gone, or now has another shape, keeps its
    /// rows under its name followed by `@` and the time (s, to the ms) where its next row
    /// would have started, and a reshaped output starts a history of its own.
    pub fn follow_edit(&mut self, manager: &Manager, modified: &[String]) {
        let now: Vec<_> = manager.signals(self.all);
        for r in &mut self.signals {
            if r.source.is_none() {
                continue;
            }
            let same = now
                .iter()
                .find(|s| s.key() == r.key && s.info.frame_shape() == r.info.frame_shape());
            match same {
                Some(s) => {
                    r.source = Some(s.source);
                    if modified.contains(&r.key) {
                        r.start_segment(describe(manager, s));
                    }
                }
                None => {
                    r.source = None;
                    let first = r.description["first_time_s"].as_f64().unwrap_or(0.0);
                    let end = first + r.data.frames() as f64 / r.info.fs_hz;
                    r.key = format!("{}@{end:.3}", r.key);
                }
            }
        }
    }

    /// The recorded signals, in graph order.
    pub fn signals(&self) -> &[Recorded] {
        &self.signals
    }

    /// The recorded signals, moved out (to hand their values on without a copy).
    pub fn into_signals(self) -> Vec<Recorded> {
        self.signals
    }

    /// Every recorded signal's description, as a JSON object keyed by output name.
    pub fn metadata(&self) -> Value {
        Value::Object(
            self.signals
                .iter()
                .map(|s| (s.key.clone(), s.description.clone()))
                .collect(),
        )
    }

    /// Writes the recorded signals as an `.npz`: one float64 (or complex128) array per
    /// output, named by its key, and their descriptions as JSON text in the entry
    /// [`crate::npy::METADATA_ENTRY`].
    pub fn write_npz<W: Write + Seek>(&self, out: W) -> std::io::Result<()> {
        self.write_npz_as(out, Dtype::Float64)
    }

    /// As [`Recorder::write_npz`], the values stored as `dtype` (each description's
    /// `dtype` says which).
    pub fn write_npz_as<W: Write + Seek>(&self, out: W, dtype: Dtype) -> std::io::Result<()> {
        let arrays: Vec<(String, Vec<usize>, &[f64])> = self
            .signals
            .iter()
            .map(|s| (s.key.clone(), s.shape(), s.data.as_slice()))
            .collect();
        let meta = self.metadata_as(dtype).to_string();
        crate::npy::write_npz_as(out, &arrays, Some(&meta), dtype)
    }

    /// Checks that every recorded value can be stored as `dtype` (float32 holds at most
    /// ±3.4e38): an error naming the first output that cannot.
    pub fn check_dtype(&self, dtype: Dtype) -> crate::Result<()> {
        (self.signals.iter()).try_for_each(|s| dtype.check(&s.key, s.data.as_slice()))
    }

    /// [`Recorder::metadata`], each description's `dtype` that of values stored as `dtype`.
    pub fn metadata_as(&self, dtype: Dtype) -> Value {
        let mut meta = self.metadata();
        for s in &self.signals {
            meta[&s.key]["dtype"] = Value::from(dtype.name(s.info.is_complex()));
        }
        meta
    }

    /// The signal named `key`, if recorded.
    pub fn get(&self, key: &str) -> Option<&Recorded> {
        self.signals.iter().find(|r| r.key == key)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bounded history stays bounded across edits (the probe: a request removed and
    /// added again every second, or a parameter changed every second, grew the history
    /// without bound: 3,600 closed histories and 3,602 segments in 30 min).
    #[test]
    fn a_bounded_history_stays_bounded_across_edits() {
        let fs = 16000.0;
        let chunk: Vec<f64> = (0..160).map(|t| (0.05 * t as f64).sin()).collect();
        let params = afe_core::ParamMap::new();
        let keep_s = 3.0;
        for modify in [false, true] {
            let mut mgr = Manager::new(fs, 1).expect("manager");
            let mut h = mgr.add_request("ratemap", &params).expect("request");
            let mut rec = Recorder::new(false);
            rec.keep_last(Some(keep_s));
            for second in 0..30 {
                for _ in 0..100 {
                    mgr.process_chunk(&[&chunk]).expect("chunk");
                    rec.record(&mgr);
                }
                if modify {
                    let value = serde_json::json!(0.5 + 0.01 * f64::from(second % 2));
                    mgr.modify_parameter(h, "rm_decaySec", value)
                        .expect("modify");
                    rec.follow_edit(&mgr, &["ratemap_mono".to_string()]);
                } else {
                    mgr.remove_request(h).expect("remove");
                    rec.follow_edit(&mgr, &[]);
                    h = mgr.add_request("ratemap", &params).expect("request");
                    rec.follow_edit(&mgr, &[]);
                }
            }
            let rows: usize = rec.signals().iter().map(|s| s.data.frames()).sum();
            // at most twice the bound's 300 rows, over at most bound + 1 histories
            assert!(rows <= 2 * 300 + 100, "modify {modify}: {rows} rows");
            assert!(
                rec.signals().len() <= keep_s as usize + 2,
                "modify {modify}: {} histories",
                rec.signals().len()
            );
            for s in rec.signals() {
                let segments = s.description["segments"].as_array().map_or(0, Vec::len);
                assert!(segments <= 2 * keep_s as usize + 2, "{}: {segments}", s.key);
            }
        }
    }

    /// With the input's length known, every history is sized when it starts: the chunks
    /// of a whole run are appended without moving it (written once, never copied), for
    /// full-rate and framed signals alike.
    #[test]
    fn histories_sized_up_front_are_never_moved() {
        let fs = 16000.0;
        let x: Vec<f64> = (0..16037).map(|t| (0.05 * t as f64).sin()).collect();
        let mut mgr = Manager::new(fs, 2).expect("manager");
        mgr.set_keep_all(true);
        for r in ["ratemap", "itd"] {
            mgr.add_request(r, &afe_core::ParamMap::new())
                .expect("request");
        }
        let mut rec = Recorder::new(true);
        rec.expect_input(x.len() as u64);
        let mut start = 0;
        let mut first: Vec<*const f64> = Vec::new();
        for size in [100, 4000, 1, 3000].iter().cycle() {
            let end = (start + size).min(x.len());
            mgr.process_chunk(&[&x[start..end], &x[start..end]])
                .expect("chunk");
            rec.record(&mgr);
            start = end;
            if first.is_empty() {
                first = rec
                    .signals()
                    .iter()
                    .map(|s| s.data.as_slice().as_ptr())
                    .collect();
            }
            if start == x.len() {
                break;
            }
        }
        assert!(
            rec.signals().len() >= 8,
            "time, filterbank, ... for both ears"
        );
        for (s, p) in rec.signals().iter().zip(first) {
            assert!(s.data.frames() > 0, "{}", s.key);
            assert_eq!(s.data.as_slice().as_ptr(), p, "{} was moved", s.key);
        }
    }
}
