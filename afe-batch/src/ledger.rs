//! The record of which files a store holds: one append-only log per process, a line of
//! JSON per finished or failed file. A file counts as done only once its line is written,
//! after all its arrays; a run killed part-way leaves at most a torn last line, which is
//! ignored, so the next run redoes exactly the files not recorded. A line that is not a
//! record (a torn one, bytes written over the log) is skipped and counted, never fatal.

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
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
    /// Recorded as done, but its output in the store is missing or incomplete (a group,
    /// array or chunk deleted or cut short): the next run computes it again. Never
    /// written to a log: [`crate::status`] finds it on disk.
    Missing,
}

impl Status {
    /// The name in a log line and in JSON.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Done => "done",
            Status::Failed => "failed",
            Status::Missing => "missing",
        }
    }
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
            "status": self.status.as_str(),
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
    /// A log left by an earlier process of the same pid is appended to, after a line break
    /// if it ends in a torn line (which would otherwise swallow the first new record).
    pub fn open(store: &Path) -> std::io::Result<Ledger> {
        let dir = store.join(LOG_DIR);
        std::fs::create_dir_all(&dir)?;
        let path = dir.join(format!("log-{}-{}.jsonl", host_name(), std::process::id()));
        let mut file = OpenOptions::new()
            .create(true)
            .read(true)
            .append(true)
            .open(&path)?;
        let len = file.metadata()?.len();
        if len > 0 {
            let mut last = [0u8];
            file.seek(SeekFrom::Start(len - 1))?;
            file.read_exact(&mut last)?;
            if last[0] != b'\n' {
                file.write_all(b"\n")?;
            }
        }
        Ok(Ledger {
            path,
            file: Mutex::new(file),
        })
    }

    /// Appends `record` as one line, in one write. Not synced to the disk: a killed process loses
    /// nothing the kernel has; a power cut may lose the last lines, whose files are then
    /// computed again.
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

/// This host's name as it appears in log and run file names (letters, digits, `-`).
pub(crate) fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| {
            h.trim()
                .replace(|c: char| !c.is_ascii_alphanumeric() && c != '-', "_")
        })
        .unwrap_or_else(|_| "host".into())
}

/// The latest record of every file in a store's logs, read incrementally: each
/// [`LedgerView::refresh`] reads only what the logs gained since the last one, so a run
/// can look again cheaply when another run may have finished a file meanwhile.
#[derive(Debug, Default)]
pub struct LedgerView {
    /// Bytes of each log read so far (up to its last whole line).
    read: HashMap<PathBuf, u64>,
    latest: HashMap<String, Record>,
    /// Whole lines that were not records, per log.
    skipped: HashMap<PathBuf, usize>,
}

impl LedgerView {
    /// Reads what `store`'s logs gained since the last call (all of them the first time;
    /// nothing if the store has no logs yet).
    pub fn refresh(&mut self, store: &Path) -> std::io::Result<()> {
        let dir = store.join(LOG_DIR);
        let entries = match std::fs::read_dir(&dir) {
            Ok(e) => e,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
            Err(e) => return Err(e),
        };
        for entry in entries {
            let path = entry?.path();
            if path.extension().is_none_or(|e| e != "jsonl") {
                continue;
            }
            let from = self.read.get(&path).copied().unwrap_or(0);
            let mut file = File::open(&path)?;
            if file.metadata()?.len() <= from {
                continue;
            }
            file.seek(SeekFrom::Start(from))?;
            let mut bytes = Vec::new();
            file.read_to_end(&mut bytes)?;
            // a last line without its line break is being written, or torn by a kill:
            // it is read (or skipped) once it is whole
            let whole = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
            for line in bytes[..whole].split(|&b| b == b'\n') {
                if line.iter().all(u8::is_ascii_whitespace) {
                    continue;
                }
                match serde_json::from_slice::<Value>(line)
                    .ok()
                    .and_then(|v| Record::from_json(&v))
                {
                    Some(rec) => self.insert(rec),
                    None => *self.skipped.entry(path.clone()).or_default() += 1,
                }
            }
            self.read.insert(path, from + whole as u64);
        }
        Ok(())
    }

    fn insert(&mut self, rec: Record) {
        match self.latest.get(&rec.id) {
            Some(old) if old.time > rec.time => {}
            _ => {
                self.latest.insert(rec.id.clone(), rec);
            }
        }
    }

    /// The latest record of file `id`.
    pub fn get(&self, id: &str) -> Option<&Record> {
        self.latest.get(id)
    }

    /// The latest record of every file.
    pub fn records(&self) -> &HashMap<String, Record> {
        &self.latest
    }

    /// What was skipped, for people: one line per log holding lines that are not records.
    pub fn warnings(&self) -> Vec<String> {
        let mut w: Vec<String> = self
            .skipped
            .iter()
            .map(|(path, n)| {
                format!(
                    "skipped {n} line(s) of '{}' that are not records (torn by a kill, or overwritten): a file recorded only there counts as not done and is computed again",
                    path.display()
                )
            })
            .collect();
        w.sort();
        w
    }
}

/// The latest record of every file in `store`'s logs (none if it has no logs yet), and
/// the warnings of [`LedgerView::warnings`].
pub fn read(store: &Path) -> std::io::Result<(HashMap<String, Record>, Vec<String>)> {
    let mut view = LedgerView::default();
    view.refresh(store)?;
    let warnings = view.warnings();
    Ok((view.latest, warnings))
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
        let (got, warnings) = read(&dir).expect("read");
        assert_eq!(got.len(), 2);
        assert_eq!(got["a.wav"], done);
        assert_eq!(got["b.wav"].status, Status::Done);
        assert_eq!(got["b.wav"].audio_s, 2.0);
        // a torn last line is not counted: it may be a line being written
        assert!(warnings.is_empty(), "{warnings:?}");

        // a process reusing the pid goes on after a line break; binary bytes in another
        // log are skipped with a warning, the records around them kept
        let again = Ledger::open(&dir).expect("reopen");
        again
            .append(&Record::now(
                "c.wav",
                Path::new("/x/c.wav"),
                Ok(()),
                3.0,
                0.1,
            ))
            .expect("append");
        let other = dir.join(LOG_DIR).join("log-other-1.jsonl");
        let mut bytes = Record::now("d.wav", Path::new("/x/d.wav"), Ok(()), 4.0, 0.1)
            .to_json()
            .to_string()
            .into_bytes();
        bytes.extend(b"\n\xff\xfe\x00garbage\x80\n\n");
        bytes.extend(
            Record::now("e.wav", Path::new("/x/e.wav"), Ok(()), 5.0, 0.1)
                .to_json()
                .to_string()
                .into_bytes(),
        );
        bytes.push(b'\n');
        std::fs::write(&other, bytes).expect("write");
        let (got, warnings) = read(&dir).expect("read");
        let mut ids: Vec<&str> = got.keys().map(String::as_str).collect();
        ids.sort_unstable();
        assert_eq!(ids, ["a.wav", "b.wav", "c.wav", "d.wav", "e.wav"]);
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(
            warnings
                .iter()
                .any(|w| w.contains("skipped 1 line(s)") && w.contains("log-other-1.jsonl")),
            "{warnings:?}"
        );
        std::fs::remove_dir_all(&dir).expect("clean");
    }
}
