//! The record of which files a store holds: one append-only log per process, a line of
//! JSON per finished or failed file. A file counts as done only once its line is written,
//! after all its arrays; a run killed part-way leaves at most a torn last line, which is
//! ignored, so the next run redoes exactly the files not recorded.

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{SystemTime, UNIX_EPOCH};

use serde_json::{json, Value};

/// The folder of the logs inside a store (hidden: zarr readers skip it).
pub const LOG_DIR: &str = ".afe-batch";

/// How a file ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// All its arrays are written.
    Done,
    /// It could not be computed (unreadable, corrupt, refused by a request).
    Failed,
}

/// One file's line in the log.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// The file's id in the store.
    pub id: String,
    /// The input file.
    pub path: PathBuf,
    /// How it ended.
    pub status: Status,
    /// Why it failed (`None` when done).
    pub error: Option<String>,
    /// Duration of its audio in seconds (0 when its header could not be read).
    pub audio_s: f64,
    /// Wall time spent on it in seconds.
    pub compute_s: f64,
    /// When it ended, in seconds since the Unix epoch.
    pub time: f64,
}

impl Record {
    /// A record ending now.
    pub fn now(
        id: &str,
        path: &Path,
        result: Result<(), String>,
        audio_s: f64,
        compute_s: f64,
    ) -> Self {
        let time = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        let (status, error) = match result {
            Ok(()) => (Status::Done, None),
            Err(e) => (Status::Failed, Some(e)),
        };
        Record {
            id: id.to_string(),
            path: path.to_path_buf(),
            status,
            error,
            audio_s,
            compute_s,
            time,
        }
    }

    /// The record as a JSON object (its log line, and the `--progress jsonl` event).
    pub fn to_json(&self) -> Value {
        json!({
            "id": self.id,
            "path": self.path.to_string_lossy(),
            "status": match self.status { Status::Done => "done", Status::Failed => "failed" },
            "error": self.error,
            "audio_s": self.audio_s,
            "compute_s": self.compute_s,
            "time": self.time,
        })
    }

    fn from_json(v: &Value) -> Option<Record> {
        let status = match v.get("status")?.as_str()? {
            "done" => Status::Done,
            "failed" => Status::Failed,
            _ => return None,
        };
        Some(Record {
            id: v.get("id")?.as_str()?.to_string(),
            path: PathBuf::from(v.get("path")?.as_str()?),
            status,
            error: v.get("error").and_then(Value::as_str).map(str::to_string),
            audio_s: v.get("audio_s")?.as_f64()?,
            compute_s: v.get("compute_s")?.as_f64()?,
            time: v.get("time")?.as_f64()?,
        })
    }
}

/// This process's log in a store; threads append to it in turn.
#[derive(Debug)]
pub struct Ledger {
    path: PathBuf,
    file: Mutex<File>,
}

impl Ledger {
    /// Opens (creating) this process's log in `store`: `log-<host>-<pid>.jsonl`, so that
    /// processes on several machines sharing one store never write the same file.
    pub fn open(store: &Path) -> std::io::Result<Ledger> {
        let dir = store.join(LOG_DIR);
        std::fs::create_dir_all(&dir)?;
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .map(|h| {
                h.trim()
                    .replace(|c: char| !c.is_ascii_alphanumeric() && c != '-', "_")
            })
            .unwrap_or_else(|_| "host".into());
        let path = dir.join(format!("log-{host}-{}.jsonl", std::process::id()));
        let file = OpenOptions::new().create(true).append(true).open(&path)?;
        Ok(Ledger {
            path,
            file: Mutex::new(file),
        })
    }

    /// Appends `record` as one line, in one write. Not synced to the disk: a killed
    /// process loses nothing the kernel has (the arrays are not synced either, so a sync
    /// here would not make a power cut safe, only every file slower).
    pub fn append(&self, record: &Record) -> std::io::Result<()> {
        let mut line = record.to_json().to_string();
        line.push('\n');
        // a poisoned lock only means another thread panicked between two whole lines
        let mut file = self
            .file
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        file.write_all(line.as_bytes())
    }

    /// The log file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// The latest record of every file in `store`'s logs (none if it has no logs yet).
pub fn read(store: &Path) -> std::io::Result<HashMap<String, Record>> {
    let mut latest: HashMap<String, Record> = HashMap::new();
    let dir = store.join(LOG_DIR);
    let entries = match std::fs::read_dir(&dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(latest),
        Err(e) => return Err(e),
    };
    for entry in entries {
        let path = entry?.path();
        if path.extension().is_none_or(|e| e != "jsonl") {
            continue;
        }
        let text = std::fs::read_to_string(&path)?;
        // a line torn by a kill fails to parse and is skipped
        for rec in text
            .lines()
            .filter_map(|l| serde_json::from_str::<Value>(l).ok())
            .filter_map(|v| Record::from_json(&v))
        {
            match latest.get(&rec.id) {
                Some(old) if old.time > rec.time => {}
                _ => {
                    latest.insert(rec.id.clone(), rec);
                }
            }
        }
    }
    Ok(latest)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latest_record_wins_and_torn_lines_are_skipped() {
        let dir = std::env::temp_dir().join(format!("afe-ledger-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("dir");
        let ledger = Ledger::open(&dir).expect("open");
        let mut failed = Record::now(
            "a.wav",
            Path::new("/x/a.wav"),
            Err("corrupt".into()),
            1.0,
            0.1,
        );
        failed.time = 10.0;
        let mut done = Record::now("a.wav", Path::new("/x/a.wav"), Ok(()), 1.0, 0.2);
        done.time = 20.0;
        ledger.append(&done).expect("append");
        ledger.append(&failed).expect("append");
        ledger
            .append(&Record::now(
                "b.wav",
                Path::new("/x/b.wav"),
                Ok(()),
                2.0,
                0.3,
            ))
            .expect("append");
        // a kill in the middle of a line
        let mut f = OpenOptions::new()
            .append(true)
            .open(ledger.path())
            .expect("reopen");
        f.write_all(b"{\"id\":\"c.wav\",\"sta").expect("torn");
        let got = read(&dir).expect("read");
        assert_eq!(got.len(), 2);
        assert_eq!(got["a.wav"], done);
        assert_eq!(got["b.wav"].status, Status::Done);
        assert_eq!(got["b.wav"].audio_s, 2.0);
        std::fs::remove_dir_all(&dir).expect("clean");
    }
}
