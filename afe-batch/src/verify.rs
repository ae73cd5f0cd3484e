//! Whether a file's output is whole in the store, checked cheaply from the file system:
//! the metadata read and every chunk's size compared with what the metadata implies, no
//! value decoded. A file recorded as done that fails the check is reported by `status`
//! and computed again by the next run.
//!
//! A zarr file group's own `zarr.json` is written last, naming its arrays (`afe.arrays`):
//! a group without it was left by a run that did not finish. Each array's `zarr.json`
//! gives its shape, chunk shape and type: every chunk of the shape must exist (chunks of
//! zeros are stored too) with the size of an uncompressed chunk. The folder groups above
//! it must be readable group metadata. An npz file must end with its zip directory (it is
//! written whole and renamed into place, so only a later cut or deletion breaks it).

use std::io;
use std::path::{Path, PathBuf};

use serde_json::Value;

use super::store::{Format, Store};

impl Store {
    /// `Ok` if file `id`'s output is whole on disk, else what is missing or cut short.
    pub fn verify(&self, id: &str) -> Result<(), String> {
        match self.spec().format {
            Format::Npz => verify_npz(&self.file_path(id)),
            Format::Zarr => {
                let mut folder = self.root().to_path_buf();
                let parts: Vec<&str> = id.split('/').collect();
                for part in &parts[..parts.len() - 1] {
                    folder.push(part);
                    json(&folder.join("zarr.json"))
                        .filter(|v| v["node_type"] == "group")
                        .ok_or_else(|| {
                            format!(
                                "the metadata of its folder '{}' is missing",
                                folder.display()
                            )
                        })?;
                }
                verify_group(&self.file_path(id))
            }
        }
    }
}

/// The JSON of the file at `path`, if it can be read (a regular file, within the bound)
/// and parsed.
fn json(path: &Path) -> Option<Value> {
    read_json(path).ok()
}

/// Opens `path` to read it if it is a regular file: a FIFO or a device is refused without
/// blocking on it (it is looked at first, then opened non-blocking and looked at again).
pub(crate) fn open_regular(path: &Path) -> io::Result<std::fs::File> {
    let not_regular = || {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a regular file (a FIFO or a device)",
        )
    };
    if !std::fs::metadata(path)?.is_file() {
        return Err(not_regular());
    }
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path)?;
    if !file.metadata()?.is_file() {
        return Err(not_regular());
    }
    Ok(file)
}

/// The JSON metadata file at `path`: a regular file of at most
/// [`META_MAX_BYTES`](crate::store::META_MAX_BYTES), parsed.
pub(crate) fn read_json(path: &Path) -> Result<Value, String> {
    use std::io::Read;
    let max = crate::store::META_MAX_BYTES;
    let mut text = Vec::new();
    open_regular(path)
        .and_then(|f| f.take(max + 1).read_to_end(&mut text))
        .map_err(|e| e.to_string())?;
    if text.len() as u64 > max {
        return Err(format!("larger than {} KiB", max >> 10));
    }
    serde_json::from_slice(&text).map_err(|e| e.to_string())
}

/// An array's layout as its metadata declares it, in the form afe writes: uncompressed
/// chunks (the `bytes` codec alone) split along the first axis only, named `c/<k>/0...`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Layout {
    /// The array's shape.
    pub shape: Vec<u64>,
    /// Rows (first-axis entries) per chunk.
    pub rows_per_chunk: u64,
    /// Bytes per element.
    pub element: u64,
    /// Whether the elements are complex (two floats each).
    pub complex: bool,
    /// Bytes of one chunk on disk.
    pub chunk_bytes: u64,
    /// Chunks the shape implies.
    pub chunks: u64,
    /// Floats the array holds (two per complex element).
    pub values: u64,
}

impl Layout {
    /// The layout `meta` (an array's `zarr.json`) declares, or what afe cannot read in it;
    /// sizes that overflow are refused.
    pub(crate) fn of(meta: &Value) -> Result<Layout, String> {
        if meta["node_type"] != "array" {
            return Err("its metadata is not an array's".into());
        }
        let numbers =
            |v: &Value| -> Option<Vec<u64>> { v.as_array()?.iter().map(Value::as_u64).collect() };
        let shape = numbers(&meta["shape"])
            .filter(|s| !s.is_empty())
            .ok_or("its metadata has no shape")?;
        let chunk = numbers(&meta["chunk_grid"]["configuration"]["chunk_shape"])
            .filter(|c| c.len() == shape.len() && c.iter().all(|&n| n > 0))
            .ok_or("its metadata has no chunk shape")?;
        if chunk[1..]
            .iter()
            .zip(&shape[1..])
            .any(|(&c, &n)| c != n.max(1))
        {
            return Err(format!(
                "its shape {shape:?} does not match its chunks {chunk:?} (afe splits arrays along the first axis only)"
            ));
        }
        let (element, complex): (u64, bool) = match meta["data_type"].as_str() {
            Some("float32") => (4, false),
            Some("float64") => (8, false),
            Some("complex64") => (8, true),
            Some("complex128") => (16, true),
            _ => return Err("its metadata names no type afe writes".into()),
        };
        let codecs = meta["codecs"].as_array().map(Vec::as_slice);
        let uncompressed = matches!(codecs, Some([c]) if c["name"] == "bytes");
        let plain_keys = meta["chunk_key_encoding"]["name"] == "default"
            && matches!(
                meta["chunk_key_encoding"]["configuration"]["separator"].as_str(),
                None | Some("/")
            );
        let transformed = meta["storage_transformers"]
            .as_array()
            .is_some_and(|t| !t.is_empty());
        if !uncompressed || !plain_keys || transformed {
            return Err(
                "its metadata declares codecs, chunk names or storage afe does not write".into(),
            );
        }
        let product = |v: &[u64]| v.iter().try_fold(1u64, |p, &n| p.checked_mul(n));
        let too_large = || format!("its shape {shape:?} overflows a 64-bit size");
        let elements = product(&shape).ok_or_else(too_large)?;
        let values = elements
            .checked_mul(if complex { 2 } else { 1 })
            .ok_or_else(too_large)?;
        element.checked_mul(elements).ok_or_else(too_large)?;
        let chunk_bytes = product(&chunk)
            .and_then(|n| n.checked_mul(element))
            .ok_or_else(too_large)?;
        let chunks = if elements == 0 {
            0
        } else {
            shape[0].div_ceil(chunk[0])
        };
        Ok(Layout {
            rows_per_chunk: chunk[0],
            shape,
            element,
            complex,
            chunk_bytes,
            chunks,
            values,
        })
    }

    /// The indices of chunk `k` (`[k, 0, ...]`).
    pub(crate) fn indices(&self, k: u64) -> Vec<u64> {
        let mut indices = vec![0; self.shape.len()];
        indices[0] = k;
        indices
    }

    /// The file of chunk `k` of the array in `dir`.
    fn chunk_path(&self, dir: &Path, k: u64) -> PathBuf {
        let mut path = dir.join("c");
        for i in self.indices(k) {
            path.push(i.to_string());
        }
        path
    }

    /// Checks the chunk files of the array in `dir` against the layout: each one found a
    /// regular file of a chunk's size; `every_chunk`: each chunk of the shape on disk
    /// (else one absent is left to the fill value).
    pub(crate) fn check_chunks(&self, dir: &Path, every_chunk: bool) -> Result<(), String> {
        for k in 0..self.chunks {
            let indices = self.indices(k);
            match std::fs::metadata(self.chunk_path(dir, k)) {
                Ok(m) if !m.is_file() => {
                    return Err(format!(
                        "chunk {indices:?} is not a regular file (a FIFO or a device)"
                    ))
                }
                Ok(m) if m.len() == self.chunk_bytes => {}
                Ok(m) => {
                    return Err(format!(
                        "chunk {indices:?} holds {} bytes, not {}",
                        m.len(),
                        self.chunk_bytes
                    ))
                }
                Err(_) if every_chunk => return Err(format!("chunk {indices:?} is missing")),
                Err(_) => {}
            }
        }
        Ok(())
    }
}

fn verify_group(dir: &Path) -> Result<(), String> {
    let meta = json(&dir.join("zarr.json"))
        .ok_or_else(|| "its group metadata is missing (a run did not finish it)".to_string())?;
    let Some(arrays) = meta["attributes"]["afe"]["arrays"].as_array() else {
        return verify_earlier_group(dir);
    };
    for name in arrays {
        let name = name
            .as_str()
            .ok_or_else(|| "its group metadata lists an array without a name".to_string())?;
        verify_array(&dir.join(name), true).map_err(|e| format!("array '{name}': {e}"))?;
    }
    Ok(())
}

/// A group written before groups listed their arrays (and before chunks of zeros were
/// stored): the arrays found must have readable metadata, and the chunks found the size
/// of a chunk; a deleted array or chunk cannot be told from one never written.
fn verify_earlier_group(dir: &Path) -> Result<(), String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("its group cannot be read: {e}"))?;
    let mut arrays = 0;
    for entry in entries.filter_map(Result::ok) {
        let path = entry.path();
        if json(&path.join("zarr.json")).is_some_and(|m| m["node_type"] == "array") {
            let name = entry.file_name().to_string_lossy().into_owned();
            verify_array(&path, false).map_err(|e| format!("array '{name}': {e}"))?;
            arrays += 1;
        }
    }
    if arrays == 0 {
        return Err("its group holds no array".into());
    }
    Ok(())
}

/// Checks the array in `dir`; `every_chunk`: each chunk of its shape must be on disk
/// (else only those found are checked).
fn verify_array(dir: &Path, every_chunk: bool) -> Result<(), String> {
    let meta = json(&dir.join("zarr.json")).ok_or("its metadata is missing")?;
    Layout::of(&meta)?.check_chunks(dir, every_chunk)
}

fn verify_npz(path: &Path) -> Result<(), String> {
    use std::io::{Read, Seek, SeekFrom};
    let mut file = open_regular(path).map_err(|e| match e.kind() {
        io::ErrorKind::NotFound => "its .npz is missing".to_string(),
        _ => format!("its .npz cannot be read: {e}"),
    })?;
    let len = file.metadata().map_err(|e| e.to_string())?.len();
    // the zip's end record: 22 bytes at the very end (afe writes no zip comment)
    let mut end = [0u8; 22];
    let whole = len >= 22
        && file.seek(SeekFrom::Start(len - 22)).is_ok()
        && file.read_exact(&mut end).is_ok()
        && end[..4] == *b"PK\x05\x06";
    if whole {
        Ok(())
    } else {
        Err("its .npz is cut short (no zip directory at its end)".into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::StoreSpec;
    use serde_json::json;

    fn write(path: &Path, bytes: &[u8]) {
        std::fs::create_dir_all(path.parent().expect("parent")).expect("dir");
        std::fs::write(path, bytes).expect("write");
    }

    #[test]
    fn every_chunk_of_a_listed_array_is_checked_and_earlier_groups_by_what_they_hold() {
        let root = std::env::temp_dir().join(format!("afe-verify-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let spec = StoreSpec {
            requests: vec!["ratemap".into()],
            params: afe::ParamMap::new(),
            format: Format::Zarr,
            dtype: afe::npy::Dtype::Float64,
        };
        let store = Store::create(&root, &spec, false).expect("store");
        // 5 rows of 3 in chunks of 2 rows: chunks 0, 1 and 2 of 48 bytes each
        let array = json!({
            "zarr_format": 3, "node_type": "array", "shape": [5, 3], "data_type": "float64",
            "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": [2, 3]}},
            "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
            "codecs": [{"name": "bytes", "configuration": {"endian": "little"}}],
        });
        let group = |arrays: Option<&[&str]>| {
            let mut afe = json!({ "path": "x.wav" });
            if let Some(a) = arrays {
                afe["arrays"] = json!(a);
            }
            json!({ "zarr_format": 3, "node_type": "group", "attributes": { "afe": afe } })
        };
        let dir = root.join("d/x.wav");
        write(
            &root.join("d/zarr.json"),
            br#"{"zarr_format":3,"node_type":"group"}"#,
        );
        write(&dir.join("a/zarr.json"), array.to_string().as_bytes());
        for k in 0..3 {
            write(&dir.join(format!("a/c/{k}/0")), &[0; 48]);
        }
        assert_eq!(
            store.verify("d/x.wav"),
            Err("its group metadata is missing (a run did not finish it)".into())
        );
        write(
            &dir.join("zarr.json"),
            group(Some(&["a"])).to_string().as_bytes(),
        );
        assert_eq!(store.verify("d/x.wav"), Ok(()));
        std::fs::remove_file(dir.join("a/c/1/0")).expect("rm");
        assert_eq!(
            store.verify("d/x.wav"),
            Err("array 'a': chunk [1, 0] is missing".into())
        );
        // a group of an earlier version: a chunk may be absent (zeros were not stored),
        // one of the wrong size may not
        write(&dir.join("zarr.json"), group(None).to_string().as_bytes());
        assert_eq!(store.verify("d/x.wav"), Ok(()));
        write(&dir.join("a/c/2/0"), &[0; 40]);
        assert_eq!(
            store.verify("d/x.wav"),
            Err("array 'a': chunk [2, 0] holds 40 bytes, not 48".into())
        );
        // a FIFO in place of a chunk is refused without opening it
        std::fs::remove_file(dir.join("a/c/2/0")).expect("rm");
        let made = std::process::Command::new("mkfifo")
            .arg(dir.join("a/c/2/0"))
            .status();
        assert!(made.is_ok_and(|s| s.success()), "mkfifo");
        assert_eq!(
            store.verify("d/x.wav"),
            Err("array 'a': chunk [2, 0] is not a regular file (a FIFO or a device)".into())
        );
        std::fs::remove_file(root.join("d/zarr.json")).expect("rm");
        assert!(store
            .verify("d/x.wav")
            .is_err_and(|e| e.contains("its folder")));
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn layouts_afe_does_not_write_or_sizes_that_overflow_are_refused() {
        let array = |shape: Value, chunk: Value, codecs: Value| {
            json!({
                "node_type": "array", "shape": shape, "data_type": "float64",
                "chunk_grid": {"configuration": {"chunk_shape": chunk}},
                "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
                "codecs": codecs,
            })
        };
        let bytes = json!([{"name": "bytes"}]);
        let ok = Layout::of(&array(json!([5, 3]), json!([2, 3]), bytes.clone())).expect("ok");
        assert_eq!((ok.chunks, ok.chunk_bytes, ok.values), (3, 48, 15));
        let refused = |meta: Value| Layout::of(&meta).expect_err("refused");
        assert!(
            refused(array(json!([5, 3]), json!([2, 1]), bytes.clone())).contains("does not match")
        );
        let gzip = json!([{"name": "bytes"}, {"name": "gzip"}]);
        assert!(refused(array(json!([5, 3]), json!([2, 3]), gzip)).contains("codecs"));
        let huge = json!([u64::MAX / 2, 4]);
        assert!(refused(array(huge, json!([1, 4]), bytes)).contains("overflows"));
    }
}
