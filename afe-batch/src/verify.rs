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

use std::path::Path;

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

/// The JSON of the file at `path`, if it can be read and parsed.
fn json(path: &Path) -> Option<Value> {
    serde_json::from_str(&afe::bounded_read::read_text(path, crate::store::META_MAX_BYTES).ok()?)
        .ok()
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
    let numbers =
        |v: &Value| -> Option<Vec<u64>> { v.as_array()?.iter().map(Value::as_u64).collect() };
    let shape = numbers(&meta["shape"]).ok_or("its metadata has no shape")?;
    let chunk = numbers(&meta["chunk_grid"]["configuration"]["chunk_shape"])
        .filter(|c| c.len() == shape.len() && c.iter().all(|&n| n > 0))
        .ok_or("its metadata has no chunk shape")?;
    let size: u64 = match meta["data_type"].as_str() {
        Some("float32") => 4,
        Some("float64" | "complex64") => 8,
        Some("complex128") => 16,
        _ => return Err("its metadata names no type afe writes".into()),
    };
    let bytes = chunk.iter().product::<u64>() * size;
    // chunk counts per axis (the grid), then every chunk of it, as `c/i/j/...`
    let grid: Vec<u64> = shape
        .iter()
        .zip(&chunk)
        .map(|(&n, &c)| n.div_ceil(c))
        .collect();
    let count: u64 = grid.iter().product();
    for k in 0..count {
        let mut path = dir.join("c");
        let mut rest = k;
        let mut indices = vec![0; grid.len()];
        for (axis, &n) in grid.iter().enumerate().rev() {
            indices[axis] = rest % n;
            rest /= n;
        }
        for i in &indices {
            path.push(i.to_string());
        }
        match std::fs::metadata(&path) {
            Ok(m) if m.len() == bytes => {}
            Ok(m) => {
                return Err(format!(
                    "chunk {indices:?} holds {} bytes, not {bytes}",
                    m.len()
                ))
            }
            Err(_) if every_chunk => return Err(format!("chunk {indices:?} is missing")),
            Err(_) => {}
        }
    }
    Ok(())
}

fn verify_npz(path: &Path) -> Result<(), String> {
    use std::io::{Read, Seek, SeekFrom};
    let mut file = std::fs::File::open(path).map_err(|_| "its .npz is missing".to_string())?;
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
        std::fs::remove_file(root.join("d/zarr.json")).expect("rm");
        assert!(store
            .verify("d/x.wav")
            .is_err_and(|e| e.contains("its folder")));
        let _ = std::fs::remove_dir_all(&root);
    }
}
