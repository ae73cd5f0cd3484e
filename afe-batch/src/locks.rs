//! Who writes what in a store when several runs share it (unsharded runs started twice,
//! shards, Dask tasks, on one machine or over a shared file system).
//!
//! - The store's lock (`.afe-batch/lock`): every run holds it shared while it writes; a
//!   run that creates the store or empties it for `--overwrite` holds it exclusively, so
//!   an overwrite is refused while another run writes, and a run waits while another
//!   creates or empties the store.
//! - A file's claim: one of [`CLAIM_STRIPES`] lock files chosen by a hash of the file id,
//!   held exclusively while the file is cleared, computed, written and recorded. Another
//!   run that wants the same file waits for the claim and then finds it done.
//!
//! The locks are advisory `flock` locks: the kernel drops them when their holder exits,
//! however it ends (a SIGKILL included), so a dead run never leaves a stale lock behind.
//! Each run also leaves its host and pid under `.afe-batch/runs/` while it holds the
//! store's lock, for the messages that name it.

use std::fs::{File, OpenOptions};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use fs4::{FileExt, TryLockError};

use super::inputs::fnv1a;
use super::ledger::{host_name, LOG_DIR};

/// The store's lock file, inside [`LOG_DIR`].
pub(crate) const LOCK_FILE: &str = "lock";

/// The folder of the file claims, inside [`LOG_DIR`].
const CLAIMS: &str = "claims";

/// The folder of the runs holding the store's lock, inside [`LOG_DIR`].
const RUNS: &str = "runs";

/// Files share this many claim locks (a hash of the id picks one): a store keeps a
/// bounded number of lock files whatever its size, and two runs rarely want one stripe at
/// once (16 files in flight collide with odds of about 1 in 9).
pub const CLAIM_STRIPES: u64 = 1024;

/// Numbers the run entries of one process (Dask tasks take the store's lock per file, on
/// several threads at once).
static ENTRY: AtomicU64 = AtomicU64::new(0);

/// The store's lock, held shared or exclusive until dropped.
#[derive(Debug)]
pub struct StoreLock {
    _file: File,
    /// This run's entry under `runs/`, removed with the lock.
    entry: Option<PathBuf>,
}

impl StoreLock {
    /// Waits for the store's lock, shared (it waits only while another run creates or
    /// empties the store), and leaves this run's entry under `runs/`.
    pub(crate) fn shared(root: &Path) -> io::Result<StoreLock> {
        let file = open_lock(root)?;
        FileExt::lock_shared(&file)?;
        let dir = root.join(LOG_DIR).join(RUNS);
        std::fs::create_dir_all(&dir)?;
        let entry = dir.join(format!(
            "{}-{}-{}",
            host_name(),
            std::process::id(),
            ENTRY.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::write(&entry, b"")?;
        Ok(StoreLock {
            _file: file,
            entry: Some(entry),
        })
    }

    /// The store's lock, exclusive, if no other run holds it (the entries left under
    /// `runs/` are then those of runs that were killed: they are removed).
    pub(crate) fn try_exclusive(root: &Path) -> io::Result<Option<StoreLock>> {
        let file = open_lock(root)?;
        match FileExt::try_lock(&file) {
            Ok(()) => {
                if let Ok(entries) = std::fs::read_dir(root.join(LOG_DIR).join(RUNS)) {
                    for entry in entries.filter_map(Result::ok) {
                        let _ = std::fs::remove_file(entry.path());
                    }
                }
                Ok(Some(StoreLock {
                    _file: file,
                    entry: None,
                }))
            }
            Err(TryLockError::WouldBlock) => Ok(None),
            Err(TryLockError::Error(e)) => Err(e),
        }
    }
}

impl Drop for StoreLock {
    fn drop(&mut self) {
        if let Some(entry) = &self.entry {
            let _ = std::fs::remove_file(entry);
        }
    }
}

fn open_lock(root: &Path) -> io::Result<File> {
    let dir = root.join(LOG_DIR);
    std::fs::create_dir_all(&dir)?;
    OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(dir.join(LOCK_FILE))
}

/// The runs that hold the store's lock, as `pid N on HOST`: those of this host whose
/// process is alive, and every one of other hosts (whose liveness cannot be seen here).
pub(crate) fn active_runs(root: &Path) -> Vec<String> {
    let host = host_name();
    let Ok(entries) = std::fs::read_dir(root.join(LOG_DIR).join(RUNS)) else {
        return Vec::new();
    };
    let mut runs: Vec<String> = entries
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter_map(|name| {
            let mut parts = name.rsplitn(3, '-');
            let (_, pid, on) = (parts.next()?, parts.next()?, parts.next()?);
            let alive = on != host || Path::new("/proc").join(pid).exists();
            alive.then(|| format!("pid {pid} on {on}"))
        })
        .collect();
    runs.sort();
    runs.dedup();
    runs
}

/// A file's claim, held until dropped.
#[derive(Debug)]
pub struct Claim {
    _file: File,
}

/// File `id`'s claim if no one holds it.
pub(crate) fn try_claim(root: &Path, id: &str) -> io::Result<Option<Claim>> {
    let dir = root.join(LOG_DIR).join(CLAIMS);
    let path = dir.join(format!("{:03x}", fnv1a(id.as_bytes()) % CLAIM_STRIPES));
    let open = || {
        OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
    };
    let file = match open() {
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            std::fs::create_dir_all(&dir)?;
            open()?
        }
        other => other?,
    };
    match FileExt::try_lock(&file) {
        Ok(()) => Ok(Some(Claim { _file: file })),
        Err(TryLockError::WouldBlock) => Ok(None),
        Err(TryLockError::Error(e)) => Err(e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_claim_excludes_others_until_dropped_and_the_store_lock_is_shared() {
        let dir = std::env::temp_dir().join(format!("afe-locks-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("dir");
        let first = try_claim(&dir, "a/b.wav").expect("claim");
        assert!(first.is_some());
        // another open of the same stripe (as another process would) is refused
        assert!(try_claim(&dir, "a/b.wav").expect("claim").is_none());
        drop(first);
        assert!(try_claim(&dir, "a/b.wav").expect("claim").is_some());

        let one = StoreLock::shared(&dir).expect("shared");
        let two = StoreLock::shared(&dir).expect("shared");
        assert!(StoreLock::try_exclusive(&dir).expect("try").is_none());
        let runs = active_runs(&dir);
        assert_eq!(
            runs,
            [format!("pid {} on {}", std::process::id(), host_name())]
        );
        drop((one, two));
        assert!(active_runs(&dir).is_empty());
        let ex = StoreLock::try_exclusive(&dir).expect("try");
        assert!(ex.is_some());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
