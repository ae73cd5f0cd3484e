//! Progress of a batch as people and wrappers want it: a bar with files done and failed,
//! hours of audio, throughput as x real time and an ETA; or one JSON line per file.

use std::io::Write;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde_json::json;

use super::ledger::{Record, Status};
use super::Summary;

/// How progress is shown.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProgressMode {
    /// A bar on stderr (drawn only on a terminal).
    Bar,
    /// One JSON object per line on stdout: `start`, one `file` per file, `summary`.
    Jsonl,
    /// Nothing.
    None,
}

impl std::str::FromStr for ProgressMode {
    type Err = super::BatchError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "bar" => Ok(ProgressMode::Bar),
            "jsonl" => Ok(ProgressMode::Jsonl),
            "none" => Ok(ProgressMode::None),
            _ => Err(super::BatchError::Usage(format!(
                "unknown progress '{s}': use bar, jsonl or none"
            ))),
        }
    }
}

/// The progress of one run, fed by the workers.
#[derive(Debug)]
pub struct Progress {
    mode: ProgressMode,
    bar: Option<ProgressBar>,
    start: Instant,
    files: usize,
    audio_total_s: f64,
    audio_done_s: f64,
    done: usize,
    failed: usize,
}

impl Progress {
    /// Starts showing a run over `files` files holding `audio_s` seconds of audio;
    /// `already` files were done by earlier runs and are skipped.
    pub fn start(mode: ProgressMode, files: usize, audio_s: f64, already: usize) -> Progress {
        let bar = (mode == ProgressMode::Bar).then(|| {
            let bar =
                ProgressBar::with_draw_target(Some(files as u64), ProgressDrawTarget::stderr());
            bar.set_style(
                ProgressStyle::with_template("{bar:30} {pos}/{len} files {msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            bar.enable_steady_tick(Duration::from_millis(500));
            bar
        });
        if mode == ProgressMode::Jsonl {
            emit(&json!({
                "event": "start", "files": files, "audio_s": audio_s, "already_done": already,
            }));
        }
        Progress {
            mode,
            bar,
            start: Instant::now(),
            files,
            audio_total_s: audio_s,
            audio_done_s: 0.0,
            done: 0,
            failed: 0,
        }
    }

    /// Counts a finished file; `elsewhere`: done by another run sharing the store (its
    /// `file` event says `"elsewhere": true`).
    pub fn file(&mut self, record: &Record, elsewhere: bool) {
        match record.status {
            Status::Done => self.done += 1,
            Status::Failed | Status::Missing => self.failed += 1,
        }
        self.audio_done_s += record.audio_s;
        let elapsed = self.start.elapsed().as_secs_f64();
        let speed = if elapsed > 0.0 {
            self.audio_done_s / elapsed
        } else {
            0.0
        };
        let eta_s = if speed > 0.0 {
            (self.audio_total_s - self.audio_done_s).max(0.0) / speed
        } else {
            f64::NAN
        };
        match self.mode {
            ProgressMode::Bar => {
                if let Some(bar) = &self.bar {
                    bar.set_position((self.done + self.failed) as u64);
                    bar.set_message(format!(
                        "({} failed) · {:.2} of {:.2} h audio · {:.0}x real time · ETA {}",
                        self.failed,
                        self.audio_done_s / 3600.0,
                        self.audio_total_s / 3600.0,
                        speed,
                        clock(eta_s)
                    ));
                }
            }
            ProgressMode::Jsonl => {
                let mut event = record.to_json();
                event["event"] = json!("file");
                if elsewhere {
                    event["elsewhere"] = json!(true);
                }
                event["done"] = json!(self.done);
                event["failed"] = json!(self.failed);
                event["files"] = json!(self.files);
                event["x_real_time"] = json!(speed);
                event["eta_s"] = json!(eta_s.is_finite().then_some(eta_s));
                emit(&event);
            }
            ProgressMode::None => {}
        }
    }

    /// Ends the display with the run's summary.
    pub fn finish(&self, summary: &Summary) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
        match self.mode {
            ProgressMode::Jsonl => {
                let mut event = summary.to_json();
                event["event"] = json!("summary");
                emit(&event);
            }
            ProgressMode::Bar => eprintln!("{}", summary.text()),
            ProgressMode::None => {}
        }
    }
}

/// `h:mm:ss`, or `?` before anything is measured.
fn clock(seconds: f64) -> String {
    if !seconds.is_finite() {
        return "?".into();
    }
    let s = seconds.round() as u64;
    format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
}

fn emit(event: &serde_json::Value) {
    let mut out = std::io::stdout().lock();
    // a closed stdout (a wrapper that went away) must not stop the extraction
    let _ = writeln!(out, "{event}");
    let _ = out.flush();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clock_reads_as_hours_minutes_seconds() {
        assert_eq!(clock(3725.4), "1:02:05");
        assert_eq!(clock(f64::NAN), "?");
    }
}
