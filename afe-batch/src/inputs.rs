//! Which files a batch computes, under which ids: directories (searched recursively for
//! `.wav` files), glob patterns, single WAV files and manifests (`id<TAB>path` lines).

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use super::BatchError;
use afe::wav::WavBlocks;

/// One input file of a batch.
#[derive(Debug, Clone, PartialEq)]
pub struct InputFile {
    /// Its id in the store: the path relative to its input's root, or the manifest's id.
    pub id: String,
    /// Where it is read from.
    pub path: PathBuf,
    /// Duration of its audio in seconds from its header (0 when the header is unreadable:
    /// the file then fails when computed, with the reader's message).
    pub audio_s: f64,
}

/// Why a FIFO or a device is not an input.
const NOT_REGULAR: &str = "not a regular file (a FIFO or a device): afe batch takes WAV files \
                           it can measure, read again and resume (afe extract reads one from \
                           a device)";

/// Longest part of an id, bytes: file systems hold names of 255 bytes, and the store names
/// a file's `.npz` and its temporary files after the id's last part (`.<part>.npz.<pid>.<n>.partial`).
const ID_PART_MAX_BYTES: usize = 200;

/// Finds the files named by `inputs`, with their ids, in a stable order; refuses inputs
/// that do not exist, manifest lines without an id, ids that are not usable as store
/// paths, and two files under one id.
pub fn discover(inputs: &[PathBuf]) -> Result<Vec<InputFile>, BatchError> {
    let mut found: Vec<(String, PathBuf)> = Vec::new();
    for input in inputs {
        let text = input.to_string_lossy();
        if input.is_dir() {
            let mut files = Vec::new();
            walk(input, &mut files).map_err(|e| BatchError::input(input, &e.to_string()))?;
            files.sort();
            found.extend(files.into_iter().map(|f| (relative_id(&f, input), f)));
        } else if input.is_file() {
            if is_wav(input) {
                let root = input.parent().unwrap_or(Path::new(""));
                found.push((relative_id(input, root), input.clone()));
            } else {
                found.extend(manifest(input)?);
            }
        } else if text.contains(['*', '?', '[']) {
            found.extend(glob_files(&text)?);
        } else if input.exists() {
            return Err(BatchError::input(input, NOT_REGULAR));
        } else {
            return Err(BatchError::input(input, "no such file or directory"));
        }
    }
    let mut by_id: HashMap<&str, &Path> = HashMap::new();
    for (id, path) in &found {
        check_id(id)?;
        if let Some(first) = by_id.insert(id, path) {
            return Err(BatchError::DuplicateId {
                id: id.clone(),
                first: first.to_path_buf(),
                second: path.clone(),
            });
        }
    }
    // an id cannot also be a folder of others ("a" and "a/b.wav")
    if let Some((id, child)) = nesting(by_id.keys().copied(), |id| by_id.contains_key(id)) {
        return Err(BatchError::IdIsFolder { id, child });
    }
    // a FIFO or device blocks the planning that measures it, and cannot be read again
    if let Some((_, path)) = found
        .iter()
        .find(|(_, p)| std::fs::metadata(p).is_ok_and(|m| !m.is_file()))
    {
        return Err(BatchError::input(path, NOT_REGULAR));
    }
    Ok(found
        .into_iter()
        .map(|(id, path)| {
            let audio_s = WavBlocks::open(&path).map_or(0.0, |w| w.frames() as f64 / w.fs());
            InputFile { id, path, audio_s }
        })
        .collect())
}

/// The first id of `ids` that has an ancestor folder `holds` (`(ancestor, id)`), as in
/// `a` and `a/b.wav`.
pub(crate) fn nesting<'a>(
    ids: impl IntoIterator<Item = &'a str>,
    holds: impl Fn(&str) -> bool,
) -> Option<(String, String)> {
    ids.into_iter().find_map(|id| {
        let mut prefix = id;
        while let Some((parent, _)) = prefix.rsplit_once('/') {
            if holds(parent) {
                return Some((parent.to_string(), id.to_string()));
            }
            prefix = parent;
        }
        None
    })
}

/// Refuses files whose ids nest with an id `known` holds (the ids a store holds already):
/// one would be a folder of the other's group, which redoing the outer one deletes.
pub(crate) fn check_nesting(
    files: &[InputFile],
    known: &HashMap<String, impl Sized>,
    store: &Path,
) -> Result<(), BatchError> {
    let refuse = |(outer, inner): (String, String), new: &str| {
        let stored = if outer == new {
            inner.clone()
        } else {
            outer.clone()
        };
        Err(BatchError::NestsInStore {
            id: new.to_string(),
            stored,
            outer,
            inner,
            store: store.to_path_buf(),
        })
    };
    // a new id under one the store holds
    let new = files.iter().map(|f| f.id.as_str());
    if let Some((outer, inner)) = nesting(new, |p| known.contains_key(p)) {
        let id = inner.clone();
        return refuse((outer, inner), &id);
    }
    // a new id that is a folder of one the store holds
    let new: HashSet<&str> = files.iter().map(|f| f.id.as_str()).collect();
    if let Some((outer, inner)) = nesting(known.keys().map(String::as_str), |p| new.contains(p)) {
        let id = outer.clone();
        return refuse((outer, inner), &id);
    }
    Ok(())
}

/// Keeps the files of shard `index` of `count` (0-based), chosen by a stable hash of
/// their ids, so that independent jobs split one input list without talking.
pub fn shard(files: Vec<InputFile>, index: u64, count: u64) -> Vec<InputFile> {
    files
        .into_iter()
        .filter(|f| fnv1a(f.id.as_bytes()) % count == index)
        .collect()
}

/// FNV-1a, 64 bits: a hash that is the same on every machine and in every version.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(*b)).wrapping_mul(0x0100_0000_01b3)
    })
}

fn is_wav(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("wav"))
}

/// The WAV files under `dir`; symlinked folders are not followed (no cycles).
fn walk(dir: &Path, out: &mut Vec<PathBuf>) -> std::io::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let path = entry.path();
        if entry.file_type()?.is_dir() {
            walk(&path, out)?;
        } else if is_wav(&path) && path.is_file() {
            out.push(path);
        }
    }
    Ok(())
}

/// `path` relative to `root`, with `/` separators.
fn relative_id(path: &Path, root: &Path) -> String {
    let rel = path.strip_prefix(root).unwrap_or(path);
    rel.components()
        .map(|c| c.as_os_str().to_string_lossy())
        .collect::<Vec<_>>()
        .join("/")
}

/// The files matching a glob pattern, with ids relative to the pattern's folder part.
fn glob_files(pattern: &str) -> Result<Vec<(String, PathBuf)>, BatchError> {
    let paths = glob::glob(pattern)
        .map_err(|e| BatchError::input(Path::new(pattern), &format!("bad pattern: {e}")))?;
    let root: PathBuf = Path::new(pattern)
        .components()
        .take_while(|c| !c.as_os_str().to_string_lossy().contains(['*', '?', '[']))
        .collect();
    let mut files = Vec::new();
    for p in paths {
        let p = p.map_err(|e| BatchError::input(Path::new(pattern), &e.to_string()))?;
        if p.is_file() {
            files.push((relative_id(&p, &root), p));
        }
    }
    if files.is_empty() {
        return Err(BatchError::input(
            Path::new(pattern),
            "the pattern matches no file",
        ));
    }
    Ok(files)
}

/// Largest manifest read, bytes: a million lines of 256 bytes (a large file given by
/// mistake is refused after that much, not read whole).
const MANIFEST_MAX_BYTES: u64 = 256 << 20;

/// A manifest: one `id<TAB>path` per line; blank lines and `#` comments are skipped;
/// relative paths are taken from the manifest's folder.
fn manifest(path: &Path) -> Result<Vec<(String, PathBuf)>, BatchError> {
    let text = afe::bounded_read::read_text(path, MANIFEST_MAX_BYTES).map_err(|e| {
        BatchError::input(
            path,
            &format!("cannot read it as a manifest (id<TAB>path lines): {e}"),
        )
    })?;
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut files = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim_end_matches('\r');
        if line.trim().is_empty() || line.starts_with('#') {
            continue;
        }
        let Some((id, file)) = line.split_once('\t') else {
            return Err(BatchError::input(
                path,
                &format!("line {}: expected 'id<TAB>path', got '{line}'", n + 1),
            ));
        };
        files.push((id.trim().to_string(), dir.join(file.trim())));
    }
    Ok(files)
}

/// Refuses ids that cannot name a group of the store (zarr node names).
pub(crate) fn check_id(id: &str) -> Result<(), BatchError> {
    let bad = |why: &str| {
        Err(BatchError::BadId {
            id: id.to_string(),
            reason: why.to_string(),
        })
    };
    if id.is_empty() {
        return bad("it is empty");
    }
    if id.starts_with('/') || id.ends_with('/') {
        return bad("it starts or ends with '/'");
    }
    for part in id.split('/') {
        if part.is_empty() || part == "." || part == ".." {
            return bad("it has an empty, '.' or '..' part");
        }
        if part.starts_with("__") || part.starts_with(".afe") {
            return bad("a part starts with '__' or '.afe' (reserved names)");
        }
        if part == "zarr.json" || part.chars().any(char::is_control) {
            return bad("a part is 'zarr.json' or holds a control character");
        }
        if part.len() > ID_PART_MAX_BYTES {
            return bad(&format!(
                "a part is {} bytes long, more than the {ID_PART_MAX_BYTES} a store's file \
                 names leave for it (file systems hold names of 255 bytes): give a shorter id \
                 (a manifest: id<TAB>path)",
                part.len()
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_relative_paths_and_checked() {
        assert_eq!(
            relative_id(Path::new("/c/a/b.wav"), Path::new("/c")),
            "a/b.wav"
        );
        assert!(check_id("spk1/utt 2.wav").is_ok());
        assert!(check_id(&format!("a/{}", "x".repeat(ID_PART_MAX_BYTES))).is_ok());
        for bad in [
            "",
            "/a",
            "a//b",
            "a/../b",
            "__x",
            "a/zarr.json",
            "a\tb",
            ".afe-batch",
            &"x".repeat(ID_PART_MAX_BYTES + 1),
        ] {
            assert!(check_id(bad).is_err(), "{bad:?} accepted");
        }
    }

    #[test]
    fn a_manifest_naming_a_fifo_is_refused_before_anything_blocks_on_it() {
        let dir = std::env::temp_dir().join(format!("afe-inputs-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("dir");
        let fifo = dir.join("live.wav");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        assert!(made.is_ok_and(|s| s.success()), "mkfifo");
        let list = dir.join("list.tsv");
        std::fs::write(&list, "a\tlive.wav\n").expect("manifest");
        let e = discover(&[list]).expect_err("refused").to_string();
        assert!(
            e.contains("live.wav") && e.contains("not a regular file"),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn shards_partition_the_files() {
        let files: Vec<InputFile> = (0..100)
            .map(|k| InputFile {
                id: format!("f{k}.wav"),
                path: PathBuf::new(),
                audio_s: 1.0,
            })
            .collect();
        let parts: Vec<Vec<InputFile>> = (0..3).map(|i| shard(files.clone(), i, 3)).collect();
        assert_eq!(parts.iter().map(Vec::len).sum::<usize>(), 100);
        assert!(
            parts.iter().all(|p| p.len() > 20),
            "unbalanced: {:?}",
            parts.iter().map(Vec::len).collect::<Vec<_>>()
        );
        for f in &files {
            assert_eq!(parts.iter().filter(|p| p.contains(f)).count(), 1);
        }
        // the hash is fixed: the same split on every machine and version
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
    }
}
