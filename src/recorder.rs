//! Collecting the output of a run: every signal's values over all chunks.

use afe_core::{Block, SignalInfo};
use afe_graph::{Manager, OutputRef};

/// One signal's output over every chunk processed so far.
#[derive(Debug, Clone)]
pub struct Recorded {
    /// Output name, `<request>_<left|right|mono>` (see [`afe_graph::Signal::key`]).
    pub key: String,
    /// Rate, centre frequencies, lags.
    pub info: SignalInfo,
    /// All values, time-major.
    pub data: Block,
    source: OutputRef,
}

impl Recorded {
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
}

impl Recorder {
    /// A recorder of the requested signals, or (`all`) of every intermediate signal too.
    pub fn new(all: bool) -> Self {
        Recorder {
            all,
            signals: Vec::new(),
        }
    }

    /// Appends what `manager` computed in its last chunk.
    pub fn record(&mut self, manager: &Manager) {
        for s in manager.signals(self.all) {
            match self.signals.iter_mut().find(|r| r.source == s.source) {
                Some(r) => r.data.extend_from(s.new),
                None => self.signals.push(Recorded {
                    key: s.key(),
                    info: s.info.clone(),
                    data: s.new.clone(),
                    source: s.source,
                }),
            }
        }
    }

    /// Records the output of [`Manager::process_signal`], moving it out of `manager`
    /// (see [`Manager::take_whole`]) rather than copying it.
    pub fn record_whole(&mut self, manager: &mut Manager) {
        let found: Vec<(String, SignalInfo, OutputRef)> = manager
            .signals(self.all)
            .iter()
            .map(|s| (s.key(), s.info.clone(), s.source))
            .collect();
        for (key, info, source) in found {
            let Some(data) = manager.take_whole(source) else {
                continue;
            };
            match self.signals.iter_mut().find(|r| r.source == source) {
                Some(r) => r.data.extend_from(&data),
                None => self.signals.push(Recorded {
                    key,
                    info,
                    data,
                    source,
                }),
            }
        }
    }

    /// The recorded signals, in graph order.
    pub fn signals(&self) -> &[Recorded] {
        &self.signals
    }

    /// The signal named `key`, if recorded.
    pub fn get(&self, key: &str) -> Option<&Recorded> {
        self.signals.iter().find(|r| r.key == key)
    }
}
