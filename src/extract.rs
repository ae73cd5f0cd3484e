//! Running a set of requests over a whole signal, whole or in chunks.

use afe_core::{ParamMap, Result};
use afe_graph::Manager;

use crate::recorder::Recorder;

/// What to compute and how to feed the input.
#[derive(Debug, Clone, Default)]
pub struct Job {
    /// AFE request names, all placed with the same parameters.
    pub requests: Vec<String>,
    /// AFE parameter name → value, shared by every request.
    pub params: ParamMap,
    /// Feed the input in chunks of this many samples (`None`: in one call).
    pub chunk: Option<usize>,
    /// Record every intermediate signal too.
    pub all: bool,
}

/// Computes `job` on `channels` (one slice per ear) at `fs` Hz.
pub fn run(job: &Job, fs: f64, channels: &[&[f64]]) -> Result<Recorder> {
    let mut mgr = Manager::new(fs, channels.len())?;
    for r in &job.requests {
        mgr.add_request(r, &job.params)?;
    }
    let mut rec = Recorder::new(job.all);
    let len = channels.first().map_or(0, |c| c.len());
    match job.chunk {
        None => {
            mgr.process_signal(channels)?;
            rec.record(&mgr);
        }
        Some(n) => {
            if len == 0 {
                return Err(afe_core::Error::InvalidInput("the signal is empty".into()));
            }
            let n = n.max(1);
            let mut start = 0;
            while start < len {
                let end = (start + n).min(len);
                let part: Vec<&[f64]> = channels.iter().map(|c| &c[start..end]).collect();
                mgr.process_chunk(&part)?;
                rec.record(&mgr);
                start = end;
            }
        }
    }
    Ok(rec)
}
