//! The work budget: estimates of the values a graph computes and writes per second of
//! signal, checked when a request is placed, so that parameters asking for minutes of
//! computation and gigabytes of output per second of audio (a 0.1-ms hop over 256
//! channels, a second of lags) are refused up front with a message naming them, instead
//! of running for hours or exhausting the memory.
//!
//! A node writes each output's rate times its width in values per second. It computes
//! those, plus, for an output it frames, the input values its window spans once per
//! frame, plus what the processor reports of its hidden work
//! ([`afe_core::Processor::hidden_work_per_second`]). Every request of the AFE at its
//! defaults together compute about 6·10^7 values per second at 44.1 kHz; this machine's
//! kind computes about 10^9 values per second per core. The limits are for inputs up to
//! 44.1 kHz and grow in proportion beyond (every request at 1 MHz is accepted).
//!
//! The environment variables that move the limits ([`setting`]) and the memory available
//! to the process ([`memory_available`]), which bounds what a whole signal may hold, are
//! read here too.

use afe_core::error::WorkRefusal;
use afe_core::{Error, ParamMap, Result};

use crate::graph::Graph;

/// The default work limit, in values computed per second of signal: 2·10^9, some seconds
/// of one core's computation per second of audio.
pub const WORK_LIMIT: f64 = 2e9;

/// The default output limit, in values written per second of signal by all the nodes:
/// 2.5·10^8, 2 GB of float64 per second of signal in the blocks of one chunk (or of a
/// whole signal's outputs before they are kept).
pub const OUTPUT_LIMIT: f64 = 2.5e8;

/// The work limit in force: the environment variable `AFE_WORK_LIMIT` (values per second
/// of signal) where set, else [`WORK_LIMIT`]; a value that is not a positive number is an
/// [`Error::BadSetting`].
pub fn work_limit() -> Result<f64> {
    Ok(setting(&WORK_LIMIT_SETTING)?.unwrap_or(WORK_LIMIT))
}

/// The output limit in force: `AFE_OUTPUT_LIMIT` where set, else [`OUTPUT_LIMIT`]; a
/// value that is not a positive number is an [`Error::BadSetting`].
pub fn output_limit() -> Result<f64> {
    Ok(setting(&OUTPUT_LIMIT_SETTING)?.unwrap_or(OUTPUT_LIMIT))
}

/// An environment variable that moves a limit: its name, what it accepts (for the
/// message) and the test of a parsed value.
pub struct Setting {
    /// The variable's name.
    pub variable: &'static str,
    /// What it accepts, as the message says it.
    pub accepted: &'static str,
    /// Whether a parsed number is accepted.
    pub valid: fn(f64) -> bool,
}

fn positive(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

fn positive_integer(v: f64) -> bool {
    positive(v) && v.fract() == 0.0 && v < 2f64.powi(53)
}

/// `AFE_WORK_LIMIT`.
pub const WORK_LIMIT_SETTING: Setting = Setting {
    variable: "AFE_WORK_LIMIT",
    accepted: "a positive number of values per second of signal, e.g. 2e9 (the default)",
    valid: positive,
};

/// `AFE_OUTPUT_LIMIT`.
pub const OUTPUT_LIMIT_SETTING: Setting = Setting {
    variable: "AFE_OUTPUT_LIMIT",
    accepted: "a positive number of values per second of signal, e.g. 2.5e8 (the default)",
    valid: positive,
};

/// `AFE_WHOLE_SIGNAL_LIMIT_MB`.
pub const WHOLE_SIGNAL_LIMIT_SETTING: Setting = Setting {
    variable: "AFE_WHOLE_SIGNAL_LIMIT_MB",
    accepted: "a positive whole number of MB, e.g. 2048 (the default)",
    valid: positive_integer,
};

/// `AFE_MEMORY_AVAILABLE_GB`.
pub const MEMORY_AVAILABLE_SETTING: Setting = Setting {
    variable: "AFE_MEMORY_AVAILABLE_GB",
    accepted: "a positive number of GB, e.g. 4 or 0.5",
    valid: positive,
};

/// The value of `setting`'s variable: `None` where unset (or set to nothing), the number
/// where it parses and is accepted, an [`Error::BadSetting`] naming the variable, its
/// value and what it accepts otherwise (`abc`, `0`, `-1`, `nan`).
pub fn setting(setting: &Setting) -> Result<Option<f64>> {
    let Some(raw) = std::env::var_os(setting.variable) else {
        return Ok(None);
    };
    let text = raw.to_string_lossy();
    if text.trim().is_empty() {
        return Ok(None);
    }
    match text.trim().parse::<f64>() {
        Ok(v) if (setting.valid)(v) => Ok(Some(v)),
        _ => Err(Error::BadSetting {
            variable: setting.variable,
            value: text.into_owned(),
            accepted: setting.accepted,
        }),
    }
}

/// Memory available to this process in bytes, where known: `AFE_MEMORY_AVAILABLE_GB`
/// where set (a test's, or a share of your choosing), else the least of the kernel's
/// `MemAvailable`, the room left under the cgroup's `memory.max` (a container's share)
/// and the room left under the address-space limit (`ulimit -v`), beyond which an
/// allocation would fail and abort the process.
pub fn memory_available() -> Result<Option<f64>> {
    if let Some(gb) = setting(&MEMORY_AVAILABLE_SETTING)? {
        return Ok(Some(gb * 1e9));
    }
    Ok(memory_measured())
}

/// The memory available as the machine measures it (`AFE_MEMORY_AVAILABLE_GB` aside):
/// the least of `MemAvailable`, the cgroup's room and the address-space room, bytes.
pub fn memory_measured() -> Option<f64> {
    [mem_available(), cgroup_room(), address_space_room()]
        .into_iter()
        .flatten()
        .reduce(f64::min)
}

/// Checks every limit variable ([`WORK_LIMIT_SETTING`], [`OUTPUT_LIMIT_SETTING`],
/// [`WHOLE_SIGNAL_LIMIT_SETTING`], [`MEMORY_AVAILABLE_SETTING`]) at once: the first one
/// set to a value it does not accept is an [`Error::BadSetting`]. A program calls it at
/// its start (the CLI does), so that a mistyped limit is refused before any work rather
/// than where it is first read.
pub fn check_settings() -> Result<()> {
    for s in [
        &WORK_LIMIT_SETTING,
        &OUTPUT_LIMIT_SETTING,
        &WHOLE_SIGNAL_LIMIT_SETTING,
        &MEMORY_AVAILABLE_SETTING,
    ] {
        setting(s)?;
    }
    Ok(())
}

/// The kernel's `MemAvailable`, bytes.
fn mem_available() -> Option<f64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    kib_field(&info, "MemAvailable:")
}

/// A `name  N kB` line of a `/proc` file, in bytes.
fn kib_field(text: &str, name: &str) -> Option<f64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024.0)
}

/// `memory.max` minus what this process's cgroup (v2) holds beyond its page cache
/// (`memory.current` less `memory.stat`'s `file`, which the kernel reclaims), bytes;
/// `None` without a limit.
fn cgroup_room() -> Option<f64> {
    let group = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let path = group.lines().find_map(|l| l.strip_prefix("0::"))?;
    let dir = std::path::Path::new("/sys/fs/cgroup").join(path.trim_start_matches('/'));
    let read = |name: &str| std::fs::read_to_string(dir.join(name)).ok();
    let max: f64 = read("memory.max")?.trim().parse().ok()?;
    let current: f64 = read("memory.current")
        .and_then(|t| t.trim().parse().ok())
        .unwrap_or(0.0);
    let cache: f64 = read("memory.stat")
        .and_then(|t| {
            t.lines()
                .find_map(|l| l.strip_prefix("file "))
                .and_then(|v| v.trim().parse().ok())
        })
        .unwrap_or(0.0);
    Some((max - (current - cache).max(0.0)).max(0.0))
}

/// The soft address-space limit (`ulimit -v`, from `/proc/self/limits`) minus the
/// address space in use (`VmSize`), bytes; `None` without a limit.
fn address_space_room() -> Option<f64> {
    let limits = std::fs::read_to_string("/proc/self/limits").ok()?;
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    let soft: f64 = line
        .strip_prefix("Max address space")?
        .split_whitespace()
        .next()?
        .parse()
        .ok()?;
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let used = kib_field(&status, "VmSize:").unwrap_or(0.0);
    Some((soft - used).max(0.0))
}

/// A size in bytes as GB, MB or kB (decimal), to a tenth.
pub fn size(bytes: f64) -> String {
    match bytes {
        b if b >= 1e9 => format!("{:.1} GB", b / 1e9),
        b if b >= 1e6 => format!("{:.1} MB", b / 1e6),
        b => format!("{:.1} kB", b / 1e3),
    }
}

/// One limit to check: what it bounds (`compute`, `write`), the share of a node it sums,
/// the limit and the environment variable that moves it.
type Check = (&'static str, fn(&NodeWork) -> f64, f64, &'static str);

/// One node's estimates, values per second of signal.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct NodeWork {
    /// Values its outputs hold.
    pub written: f64,
    /// Values it computes, those written included.
    pub computed: f64,
}

impl Graph {
    /// The estimates of node `i` (zero for the input).
    pub(crate) fn node_work(&self, i: usize) -> NodeWork {
        let node = &self.nodes[i];
        if i == 0 {
            return NodeWork::default();
        }
        let inputs: Vec<_> = node
            .parents
            .iter()
            .map(|p| &self.nodes[p.node].infos[p.output])
            .collect();
        let input_width: f64 = inputs.iter().map(|info| info.width() as f64).sum();
        let input_fs = inputs.first().map_or(0.0, |info| info.fs_hz);
        let written: f64 = node
            .infos
            .iter()
            .map(|info| info.fs_hz * info.width() as f64)
            .sum();
        let windowed = node
            .infos
            .iter()
            // a window this node frames (an output at its input's rate passes one on)
            .filter(|info| info.fs_hz < input_fs)
            .filter_map(|info| info.window_s.map(|w| info.fs_hz * (w * input_fs).ceil()))
            .fold(0.0, f64::max)
            * input_width;
        let hidden = node
            .processor
            .as_ref()
            .map_or(0.0, |p| p.hidden_work_per_second());
        NodeWork {
            written,
            computed: written + windowed + hidden,
        }
    }

    /// The graph's estimate of the values it computes per second of signal.
    pub(crate) fn work_per_second(&self) -> f64 {
        (0..self.nodes.len())
            .map(|i| self.node_work(i).computed)
            .sum()
    }

    /// Refuses the graph as it stands, after placing `request` with `params`, if it
    /// computes more than [`work_limit`] or writes more than [`output_limit`].
    pub(crate) fn check_work(&self, request: &str, params: &ParamMap) -> Result<()> {
        let works: Vec<NodeWork> = (0..self.nodes.len()).map(|i| self.node_work(i)).collect();
        // the audio-rate signals grow with the rate: the limits hold up to 44.1 kHz and
        // grow with it beyond
        let rate = self.nodes[0]
            .infos
            .first()
            .map_or(1.0, |i| i.fs_hz / 44100.0)
            .max(1.0);
        let checks: [Check; 2] = [
            (
                "compute",
                |w| w.computed,
                work_limit()? * rate,
                "AFE_WORK_LIMIT",
            ),
            (
                "write",
                |w| w.written,
                output_limit()? * rate,
                "AFE_OUTPUT_LIMIT",
            ),
        ];
        for (what, share, limit, variable) in checks {
            let total: f64 = works.iter().map(share).sum();
            if total <= limit {
                continue;
            }
            let (heaviest, most) =
                works
                    .iter()
                    .map(share)
                    .enumerate()
                    .fold(
                        (0, 0.0),
                        |best, (i, w)| if w > best.1 { (i, w) } else { best },
                    );
            let mut names: Vec<_> = params.keys().cloned().collect();
            names.sort();
            let set = if names.is_empty() {
                String::new()
            } else {
                let listed: Vec<String> =
                    names.iter().map(|n| format!("{n}={}", params[n])).collect();
                format!("; parameters set: {}", listed.join(", "))
            };
            return Err(Error::TooMuchWork(Box::new(WorkRefusal {
                request: request.to_string(),
                what,
                per_second: total,
                heaviest: self.nodes[heaviest].name.to_string(),
                heaviest_per_second: most,
                limit,
                variable,
                set,
            })));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    #[test]
    fn sizes_read_in_the_unit_that_fits() {
        assert_eq!(super::size(7.2e9), "7.2 GB");
        assert_eq!(super::size(48_360.0), "48.4 kB");
        assert_eq!(super::size(3.25e6), "3.2 MB");
    }

    #[test]
    fn settings_accept_what_they_say() {
        assert!((super::WORK_LIMIT_SETTING.valid)(1e6));
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(!(super::MEMORY_AVAILABLE_SETTING.valid)(bad), "{bad}");
        }
        assert!((super::WHOLE_SIGNAL_LIMIT_SETTING.valid)(4.0));
        assert!(!(super::WHOLE_SIGNAL_LIMIT_SETTING.valid)(4.5));
    }

    use crate::Manager;

    fn params(pairs: &[(&str, serde_json::Value)]) -> afe_core::ParamMap {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone()))
            .collect()
    }

    #[test]
    fn every_request_at_its_defaults_is_far_below_the_limit() {
        let mut m = Manager::new(44100.0, 2).expect("manager");
        for r in afe_processors::requests() {
            m.add_request(r.name, &Default::default()).expect(r.name);
        }
        let total = m.work_per_second();
        assert!(total > 1e7 && total < super::WORK_LIMIT / 20.0, "{total:e}");
        let written: f64 = (m.signals(true).iter())
            .map(|s| s.info.fs_hz * s.info.width() as f64)
            .sum();
        assert!(
            written > 1e6 && written < super::OUTPUT_LIMIT / 10.0,
            "{written:e}"
        );
    }

    #[test]
    fn every_request_at_its_defaults_is_accepted_at_the_highest_rate() {
        let mut m = Manager::new(1e6, 2).expect("manager");
        for r in afe_processors::requests() {
            m.add_request(r.name, &Default::default()).expect(r.name);
        }
    }

    #[test]
    fn a_request_over_the_limit_is_refused_and_leaves_the_graph_as_it_was() {
        let mut m = Manager::new(44100.0, 2).expect("manager");
        m.add_request("ratemap", &Default::default())
            .expect("ratemap");
        let nodes = m.processor_count();
        let heavy = params(&[
            ("ac_wSizeSec", json!(0.2)),
            ("ac_hSizeSec", json!(0.0001)),
            ("fb_nChannels", json!(256)),
        ]);
        let e = m
            .add_request("autocorrelation", &heavy)
            .expect_err("refused");
        let text = e.to_string();
        assert!(
            text.starts_with("request 'autocorrelation' would make the graph compute about ")
                && text.contains("(its autocorrelation alone ")
                && text.contains("over the limit of 2.0e9; parameters set: ac_hSizeSec=0.0001, ac_wSizeSec=0.2, fb_nChannels=256: a longer hop"),
            "{text}"
        );
        assert_eq!(m.processor_count(), nodes);
        // AMS filters every channel by every modulation band before framing
        let ams = params(&[("ams_nFilters", json!(1000)), ("fb_nChannels", json!(1024))]);
        let e = m.add_request("amsFeatures", &ams).expect_err("refused");
        assert!(e.to_string().contains("(its amsFeatures alone "), "{e}");
        m.add_request("amsFeatures", &Default::default())
            .expect("defaults");
    }
}
