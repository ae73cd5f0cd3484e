//! Output files that are checked before any computation, never left half-written, and
//! never replace what they should not: a symlink keeps pointing at its file, a device
//! stays a device.

use std::io::{BufWriter, Cursor, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Why an output file cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The file's directory does not exist (or is not a directory).
    #[error("cannot write '{path}': directory '{dir}' does not exist")]
    NoDirectory {
        /// The output as given.
        path: PathBuf,
        /// The directory it would go in.
        dir: PathBuf,
    },
    /// The output names a directory.
    #[error("cannot write '{0}': it is a directory, give a file name")]
    IsDirectory(PathBuf),
    /// The output names no file (empty, or ending in a separator).
    #[error("cannot write '{0}': give a file name")]
    NotAFile(PathBuf),
    /// Two outputs of one run name the same file.
    #[error("'{0}' is given as two outputs of one run: give each its own file")]
    SameFile(PathBuf),
    /// The input would be overwritten.
    #[error("'{0}' is the input file: give the output another name")]
    IsInput(PathBuf),
    /// A stop was asked for (SIGINT, Ctrl-C) before the file was in place; nothing was
    /// left behind.
    #[error("interrupted while writing '{0}': nothing was written")]
    Interrupted(PathBuf),
    /// Writing failed (disk full, permissions, ...); nothing was left behind.
    #[error("cannot write '{path}': {source}")]
    Write {
        /// The output as given.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
}

/// What an output is written to: a file, or a buffer for a device (both can seek, as
/// the zip writer needs).
pub trait WriteSeek: Write + Seek {}

impl<W: Write + Seek> WriteSeek for W {}

/// Distinguishes the temporary files of one process.
static TEMPORARIES: AtomicU64 = AtomicU64::new(0);

/// Most symlinks followed from an output name (as the kernel's limit, 40).
const MAX_LINKS: usize = 40;

/// An output file, checked when the run starts.
#[derive(Debug, Clone)]
pub struct OutputFile {
    /// The name as given, for messages.
    given: PathBuf,
    /// The file it names once symlinks are followed.
    target: PathBuf,
    /// Whether the target exists and is not a regular file (a device, a FIFO): it is
    /// written in place instead of being replaced.
    in_place: bool,
}

impl OutputFile {
    /// Checks `path` as an output: symlinks are followed to the file they name; a new
    /// file needs an existing directory; a directory is refused.
    pub fn check(path: &Path) -> Result<OutputFile, OutputError> {
        let given = path.to_path_buf();
        if path.as_os_str().is_empty() || path.file_name().is_none() || ends_in_separator(path) {
            return Err(OutputError::NotAFile(given));
        }
        // the kernel follows the links (also /dev/stdout's, into /proc): a device or
        // FIFO is written in place under the name given
        match std::fs::metadata(path) {
            Ok(m) if m.is_dir() => return Err(OutputError::IsDirectory(given)),
            Ok(m) if !m.is_file() => {
                return Ok(OutputFile {
                    target: given.clone(),
                    given,
                    in_place: true,
                })
            }
            _ => {}
        }
        let target = follow_links(path).map_err(|source| OutputError::Write {
            path: given.clone(),
            source,
        })?;
        if target.file_name().is_none() {
            return Err(OutputError::NotAFile(given));
        }
        if !target.exists() {
            let dir = directory_of(&target);
            if !dir.is_dir() {
                return Err(OutputError::NoDirectory { path: given, dir });
            }
        }
        Ok(OutputFile {
            given,
            target,
            in_place: false,
        })
    }

    /// Refuses an output that is the same file as `other` (another output or the input).
    pub fn check_distinct(&self, other: &OutputFile) -> Result<(), OutputError> {
        if self.same_file(&other.target) {
            return Err(OutputError::SameFile(self.given.clone()));
        }
        Ok(())
    }

    /// Refuses an output that would overwrite the input file `input`.
    pub fn check_not_input(&self, input: &Path) -> Result<(), OutputError> {
        // resolving an existing input follows its links already
        if self.same_file(input) {
            return Err(OutputError::IsInput(self.given.clone()));
        }
        Ok(())
    }

    fn same_file(&self, other: &Path) -> bool {
        resolved(&self.target) == resolved(other)
    }

    /// The name as given.
    pub fn path(&self) -> &Path {
        &self.given
    }

    /// Writes the file with `write`: a regular file through a temporary file of its own
    /// beside the target, renamed into place when complete (a failure or a concurrent
    /// run never leaves a partial or mixed file); a device or FIFO in place, through a
    /// buffer in memory (so that `write` may seek).
    pub fn write(
        &self,
        write: impl FnOnce(&mut dyn WriteSeek) -> std::io::Result<()>,
    ) -> Result<(), OutputError> {
        self.stage(write)?.commit()
    }

    /// Writes the file's contents with `write` without putting them in place: a regular
    /// file into its temporary file, a device or FIFO into memory. [`Staged::commit`]
    /// puts them in place; dropped uncommitted, they leave nothing. A run with several
    /// outputs stages them all, then commits them with [`commit_all`], so that a failure
    /// of one leaves none of them written.
    pub fn stage(
        &self,
        write: impl FnOnce(&mut dyn WriteSeek) -> std::io::Result<()>,
    ) -> Result<Staged<'_>, OutputError> {
        self.stage_as(write, false)
    }

    /// As [`OutputFile::stage`], for a run that a stop (SIGINT, Ctrl-C) abandons: asked
    /// for before or while the contents are written, or before they are put in place, it
    /// leaves nothing and gives [`OutputError::Interrupted`]. (A stream that saves what
    /// it computed when stopped uses [`OutputFile::stage`].)
    pub fn stage_unless_interrupted(
        &self,
        write: impl FnOnce(&mut dyn WriteSeek) -> std::io::Result<()>,
    ) -> Result<Staged<'_>, OutputError> {
        self.stage_as(write, true)
    }

    fn stage_as(
        &self,
        write: impl FnOnce(&mut dyn WriteSeek) -> std::io::Result<()>,
        interruptible: bool,
    ) -> Result<Staged<'_>, OutputError> {
        let stopped = || interruptible && crate::interrupt::requested();
        if stopped() {
            return Err(OutputError::Interrupted(self.given.clone()));
        }
        let failed = |e| {
            if stopped() {
                OutputError::Interrupted(self.given.clone())
            } else {
                self.failed(e)
            }
        };
        if self.in_place {
            let mut buf = Cursor::new(Vec::new());
            write(&mut Interruptible(&mut buf, interruptible)).map_err(failed)?;
            return Ok(Staged {
                out: self,
                content: Content::Memory(buf.into_inner()),
                interruptible,
            });
        }
        let tmp = self.temporary();
        let staged = Staged {
            out: self,
            content: Content::Temporary(tmp.clone()),
            interruptible,
        };
        std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .and_then(|f| {
                let mut w = BufWriter::new(f);
                write(&mut Interruptible(&mut w, interruptible))?;
                w.into_inner().map_err(|e| e.into_error())?.sync_all()
            })
            .map_err(failed)?;
        Ok(staged)
    }

    fn failed(&self, source: std::io::Error) -> OutputError {
        OutputError::Write {
            path: self.given.clone(),
            source,
        }
    }

    /// A name beside the target that no other run or output of this run uses.
    fn temporary(&self) -> PathBuf {
        let name = self
            .target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let n = TEMPORARIES.fetch_add(1, Ordering::Relaxed);
        let tmp =
            directory_of(&self.target).join(format!(".{name}.{}.{n}.partial", std::process::id()));
        partial_files().push(tmp.clone());
        tmp
    }
}

/// Bytes handed on per write by [`Interruptible`]: a stop is noticed within this much.
const INTERRUPT_GRAIN: usize = 1 << 20;

/// A writer that, where the run is interruptible (the flag), stops with an error once a
/// stop is asked for, so that a large output being written is abandoned (and its
/// temporary file removed) within [`INTERRUPT_GRAIN`] bytes.
struct Interruptible<'a, W: ?Sized>(&'a mut W, bool);

impl<W: Write + ?Sized> Write for Interruptible<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.1 && crate::interrupt::requested() {
            return Err(std::io::Error::other("interrupted"));
        }
        self.0.write(&buf[..buf.len().min(INTERRUPT_GRAIN)])
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()
    }
}

impl<W: Seek + ?Sized> Seek for Interruptible<'_, W> {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        self.0.seek(pos)
    }
}

/// An output's contents, complete, waiting to be put in place.
pub struct Staged<'a> {
    out: &'a OutputFile,
    content: Content,
    /// Whether a stop asked for before the commit abandons it.
    interruptible: bool,
}

/// Where staged contents wait.
enum Content {
    /// A temporary file beside the target, renamed onto it.
    Temporary(PathBuf),
    /// Bytes for a device or FIFO, written to it in place.
    Memory(Vec<u8>),
    /// Put in place already.
    Committed,
}

impl Staged<'_> {
    /// Puts the contents in place: renames the temporary file onto the target, or writes
    /// the bytes to the device.
    pub fn commit(mut self) -> Result<(), OutputError> {
        if self.interruptible && crate::interrupt::requested() {
            return Err(OutputError::Interrupted(self.out.given.clone()));
        }
        match std::mem::replace(&mut self.content, Content::Committed) {
            Content::Temporary(tmp) => {
                let renamed = std::fs::rename(&tmp, &self.out.target);
                forget_partial(&tmp);
                renamed.map_err(|e| {
                    let _ = std::fs::remove_file(&tmp);
                    self.out.failed(e)
                })
            }
            Content::Memory(bytes) => {
                let mut file = std::fs::OpenOptions::new()
                    .write(true)
                    .open(&self.out.target)
                    .map_err(|e| self.out.failed(e))?;
                file.write_all(&bytes)
                    .and_then(|()| file.flush())
                    .map_err(|e| self.out.failed(e))
            }
            Content::Committed => Ok(()),
        }
    }
}

impl Drop for Staged<'_> {
    fn drop(&mut self) {
        if let Content::Temporary(tmp) = &self.content {
            let _ = std::fs::remove_file(tmp);
            forget_partial(tmp);
        }
    }
}

/// Commits the outputs of one run: those written in place first (a device is the one
/// that can still fail: a full one refuses the bytes), then the regular files, whose
/// renames do not fail once their temporary files are written beside them. On the first
/// failure, the outputs not yet committed are dropped, leaving nothing.
pub fn commit_all(staged: Vec<Staged<'_>>) -> Result<(), OutputError> {
    let (devices, files): (Vec<_>, Vec<_>) = staged
        .into_iter()
        .partition(|s| matches!(s.content, Content::Memory(_)));
    for s in devices.into_iter().chain(files) {
        s.commit()?;
    }
    Ok(())
}

/// The temporary files of this process not yet renamed or removed.
fn partial_files() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    static PARTIAL: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    PARTIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn forget_partial(tmp: &Path) {
    partial_files().retain(|p| p != tmp);
}

/// Removes every temporary file this process is writing: for a process that quits at
/// once (a second Ctrl-C) in the middle of a write, so that no `.partial` file stays.
pub fn remove_partial_files() {
    for tmp in partial_files().drain(..) {
        let _ = std::fs::remove_file(tmp);
    }
}

/// The directory a file named `path` is in (`.` for a bare name).
fn directory_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// `path` with its directory canonical (`..` and symlinked directories resolved), so
/// that two names of one file, existing or not yet, compare equal.
fn resolved(path: &Path) -> PathBuf {
    if let Ok(p) = path.canonicalize() {
        return p;
    }
    let dir = directory_of(path);
    match (dir.canonicalize(), path.file_name()) {
        (Ok(d), Some(name)) => d.join(name),
        _ => std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()),
    }
}

/// Whether `path` is written with a trailing separator (`out/`), naming a directory.
fn ends_in_separator(path: &Path) -> bool {
    path.as_os_str()
        .to_string_lossy()
        .ends_with(std::path::MAIN_SEPARATOR)
}

/// Follows `path` through symlinks (also dangling ones) to the name of a file that is
/// not a symlink.
fn follow_links(path: &Path) -> std::io::Result<PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..MAX_LINKS {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let link = std::fs::read_link(&p)?;
                p = directory_of(&p).join(link);
            }
            _ => return Ok(p),
        }
    }
    Err(std::io::Error::other(format!(
        "more than {MAX_LINKS} symbolic links"
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("afe-output-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("temp dir");
        d
    }

    fn entries(d: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .expect("dir")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_symlink_keeps_pointing_at_the_file_it_names() {
        let d = dir("link");
        std::fs::write(d.join("real.npz"), b"old").expect("write");
        std::os::unix::fs::symlink("real.npz", d.join("link.npz")).expect("link");
        let out = OutputFile::check(&d.join("link.npz")).expect("ok");
        out.write(|w| w.write_all(b"new")).expect("write");
        assert!(std::fs::symlink_metadata(d.join("link.npz"))
            .expect("link")
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read(d.join("real.npz")).expect("read"), b"new");
        assert_eq!(entries(&d), ["link.npz", "real.npz"], "no temporary left");
    }

    #[test]
    fn a_device_is_written_in_place_and_its_errors_reported() {
        let null = OutputFile::check(Path::new("/dev/null")).expect("ok");
        null.write(|w| w.write_all(b"x")).expect("write");
        assert!(!std::fs::metadata("/dev/null").expect("dev").is_file());
        if Path::new("/dev/full").exists() {
            let full = OutputFile::check(Path::new("/dev/full")).expect("ok");
            let e = full.write(|w| w.write_all(&[0; 4096])).expect_err("full");
            assert!(e.to_string().contains("/dev/full"), "{e}");
            assert!(!std::fs::metadata("/dev/full").expect("dev").is_file());
        }
    }

    #[test]
    fn missing_directories_and_directories_are_refused_up_front() {
        let d = dir("missing");
        let e = OutputFile::check(&d.join("nope/out.npz")).expect_err("missing");
        assert!(matches!(e, OutputError::NoDirectory { .. }), "{e}");
        assert!(e.to_string().contains("nope"), "{e}");
        let e = OutputFile::check(&d).expect_err("directory");
        assert!(matches!(e, OutputError::IsDirectory(_)), "{e}");
        assert!(OutputFile::check(Path::new("bare-name.npz")).is_ok());
    }

    #[test]
    fn a_failed_write_leaves_nothing_and_keeps_the_old_file() {
        let d = dir("fail");
        std::fs::write(d.join("out.npz"), b"old").expect("write");
        let out = OutputFile::check(&d.join("out.npz")).expect("ok");
        out.write(|_| Err(std::io::Error::other("boom")))
            .expect_err("failed");
        assert_eq!(std::fs::read(d.join("out.npz")).expect("read"), b"old");
        assert_eq!(entries(&d), ["out.npz"]);
    }

    #[test]
    fn the_same_file_twice_or_the_input_is_refused() {
        let d = dir("same");
        std::fs::write(d.join("in.wav"), b"RIFF").expect("write");
        std::os::unix::fs::symlink("in.wav", d.join("alias.npz")).expect("link");
        let a = OutputFile::check(&d.join("out.npz")).expect("ok");
        let b = OutputFile::check(&d.join(".").join("out.npz")).expect("ok");
        assert!(matches!(
            a.check_distinct(&b),
            Err(OutputError::SameFile(_))
        ));
        let alias = OutputFile::check(&d.join("alias.npz")).expect("ok");
        assert!(matches!(
            alias.check_not_input(&d.join("in.wav")),
            Err(OutputError::IsInput(_))
        ));
        assert!(a.check_not_input(&d.join("in.wav")).is_ok());
    }

    #[test]
    fn two_names_of_one_new_file_are_the_same_output() {
        let d = dir("names");
        std::fs::create_dir_all(d.join("sub")).expect("sub");
        std::os::unix::fs::symlink(".", d.join("here")).expect("link");
        let a = OutputFile::check(&d.join("out.npz")).expect("ok");
        for other in ["sub/../out.npz", "here/out.npz"] {
            let b = OutputFile::check(&d.join(other)).expect("ok");
            assert!(a.check_distinct(&b).is_err(), "{other}");
        }
        let e = OutputFile::check(Path::new("out.npz/")).expect_err("trailing slash");
        assert!(matches!(e, OutputError::NotAFile(_)), "{e}");
        assert!(OutputFile::check(Path::new("")).is_err());
    }

    #[test]
    fn concurrent_writers_each_leave_a_whole_file() {
        let d = dir("race");
        let target = d.join("out.npz");
        std::thread::scope(|s| {
            for k in 0..8u8 {
                let target = &target;
                s.spawn(move || {
                    let out = OutputFile::check(target).expect("ok");
                    out.write(|w| w.write_all(&[k; 100_000])).expect("write");
                });
            }
        });
        let bytes = std::fs::read(&target).expect("read");
        assert_eq!(bytes.len(), 100_000);
        assert!(
            bytes.iter().all(|b| *b == bytes[0]),
            "one writer's file, whole"
        );
        assert_eq!(entries(&d), ["out.npz"]);
    }
}
