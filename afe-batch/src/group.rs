//! One Zarr v3 group of named arrays with their afe descriptions: what `afe.save` writes
//! to a `.zarr` path and `afe.load` reads back, in the layout of one file of a zarr batch
//! store (each array's description in its `afe` attribute), with the arrays' order kept
//! in the group's `afe_saved` attribute.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use afe::bounded_read::read_text;

use serde_json::{json, Value};
use zarrs::array::{Array, ArrayBuilder, DataType, FillValue};
use zarrs::array_subset::ArraySubset;
use zarrs::filesystem::FilesystemStore;
use zarrs::group::{Group, GroupBuilder};

use super::store::{StoredArray, CHUNK_BYTES, META_MAX_BYTES};
use super::BatchError;

/// The root attribute that marks a saved group and keeps its arrays' order.
const SAVED: &str = "afe_saved";

/// How the values of a [`SavedArray`] are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ElementType {
    /// 8-byte floats.
    Float64,
    /// 4-byte floats.
    Float32,
    /// Pairs of 8-byte floats (re, im).
    Complex128,
    /// Pairs of 4-byte floats (re, im).
    Complex64,
}

impl ElementType {
    /// The type of a numpy dtype name (`float64`, `float32`, `complex128`, `complex64`).
    pub fn from_numpy(name: &str) -> Option<ElementType> {
        match name {
            "float64" => Some(ElementType::Float64),
            "float32" => Some(ElementType::Float32),
            "complex128" => Some(ElementType::Complex128),
            "complex64" => Some(ElementType::Complex64),
            _ => None,
        }
    }

    /// Bytes per element.
    fn size(self) -> usize {
        match self {
            ElementType::Float32 => 4,
            ElementType::Float64 | ElementType::Complex64 => 8,
            ElementType::Complex128 => 16,
        }
    }

    fn zarr(self) -> DataType {
        match self {
            ElementType::Float64 => DataType::Float64,
            ElementType::Float32 => DataType::Float32,
            ElementType::Complex128 => DataType::Complex128,
            ElementType::Complex64 => DataType::Complex64,
        }
    }
}

/// One array to save: its values as raw bytes in C order and native byte order.
#[derive(Debug, Clone)]
pub struct SavedArray {
    /// Its name in the group, e.g. `ratemap_left`.
    pub key: String,
    /// `[frames, ...]`.
    pub shape: Vec<usize>,
    /// Element type of `bytes`.
    pub element: ElementType,
    /// The values.
    pub bytes: Vec<u8>,
    /// Its description (`afe.Signal.meta`), stored as the array's `afe` attribute.
    pub info: Value,
}

/// Whether `root` is a group written by [`write_group`].
pub fn is_saved_group(root: &Path) -> bool {
    read_text(&root.join("zarr.json"), META_MAX_BYTES)
        .ok()
        .and_then(|t| serde_json::from_str::<Value>(&t).ok())
        .is_some_and(|v| v["attributes"][SAVED].is_object())
}

/// Writes `arrays` as the Zarr v3 group `root`, replacing a group this function wrote
/// before; any other existing path (a batch store, a folder of other files) is refused.
/// The group is written beside `root` and renamed into place, so a run killed midway
/// leaves the old group or none, never a torn one.
pub fn write_group(root: &Path, arrays: &[SavedArray]) -> Result<(), BatchError> {
    if root.exists() && !is_saved_group(root) {
        return Err(BatchError::Usage(format!(
            "'{}' exists and is not a group written by afe.save: give a new path ending in .zarr",
            root.display()
        )));
    }
    for (i, a) in arrays.iter().enumerate() {
        check(a)?;
        if arrays[..i].iter().any(|b| b.key == a.key) {
            return Err(BatchError::Usage(format!(
                "two arrays are named '{}'",
                a.key
            )));
        }
    }
    // names of this call alone: two threads saving to one path never share a folder
    static CALLS: AtomicU64 = AtomicU64::new(0);
    let tag = format!(
        "{}.{}",
        std::process::id(),
        CALLS.fetch_add(1, Ordering::Relaxed)
    );
    let staging = sibling(root, &format!("partial.{tag}"));
    let written = write_into(&staging, arrays).and_then(|()| replace(root, &staging, &tag));
    if written.is_err() {
        let _ = std::fs::remove_dir_all(&staging);
    }
    written
}

/// Puts the written group `staging` in place of `root`: the old group is moved aside
/// first, and back if the new one cannot take its place (a run killed between the two
/// renames leaves it at `<root>.old.<tag>`).
fn replace(root: &Path, staging: &Path, tag: &str) -> Result<(), BatchError> {
    let old = sibling(root, &format!("old.{tag}"));
    let had_old = root.exists();
    if had_old {
        std::fs::rename(root, &old).map_err(|e| BatchError::store(root, &e))?;
    }
    if let Err(e) = std::fs::rename(staging, root) {
        if had_old {
            let _ = std::fs::rename(&old, root);
        }
        return Err(BatchError::store(root, &e));
    }
    if had_old {
        // the new group is in place: an old one left behind only takes disk
        let _ = std::fs::remove_dir_all(&old);
    }
    Ok(())
}

/// `root` with `.<tag>` appended to its last component.
fn sibling(root: &Path, tag: &str) -> PathBuf {
    let mut name = root.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".{tag}"));
    root.with_file_name(name)
}

/// Refuses an array whose name cannot be a Zarr node or whose bytes do not fill its shape.
fn check(a: &SavedArray) -> Result<(), BatchError> {
    let reserved = ["", ".", "..", "zarr.json"];
    if reserved.contains(&a.key.as_str())
        || a.key.contains(['/', '\\'])
        || a.key.chars().any(char::is_control)
        || a.key.starts_with("__")
    {
        return Err(BatchError::Usage(format!(
            "'{}' cannot name an array of a Zarr group: give a name without '/', '\\' or control characters, not starting with '__', other than '.', '..' and 'zarr.json'",
            a.key
        )));
    }
    if a.shape.is_empty() {
        return Err(BatchError::Usage(format!(
            "'{}' has no dimension: save arrays of at least one axis",
            a.key
        )));
    }
    let elements: usize = a.shape.iter().product();
    if elements * a.element.size() != a.bytes.len() {
        return Err(BatchError::Usage(format!(
            "'{}': {} bytes do not fill the shape {:?} of {}-byte elements",
            a.key,
            a.bytes.len(),
            a.shape,
            a.element.size()
        )));
    }
    Ok(())
}

fn write_into(root: &Path, arrays: &[SavedArray]) -> Result<(), BatchError> {
    std::fs::create_dir_all(root).map_err(|e| BatchError::store(root, &e))?;
    let store = Arc::new(FilesystemStore::new(root).map_err(|e| BatchError::store(root, &e))?);
    let order: Vec<&str> = arrays.iter().map(|a| a.key.as_str()).collect();
    let mut attrs = serde_json::Map::new();
    attrs.insert(SAVED.into(), json!({ "version": 1, "order": order }));
    GroupBuilder::new()
        .attributes(attrs)
        .build(store.clone(), "/")
        .and_then(|g| g.store_metadata().map_err(Into::into))
        .map_err(|e| BatchError::store(root, &e))?;
    for a in arrays {
        let shape: Vec<u64> = a.shape.iter().map(|&n| n as u64).collect();
        let row: usize = a.shape[1..].iter().product::<usize>().max(1) * a.element.size();
        let rows = (CHUNK_BYTES / row).clamp(1, a.shape[0].max(1)) as u64;
        let mut chunk_shape = vec![rows];
        chunk_shape.extend(shape[1..].iter().map(|&n| n.max(1)));
        let mut attrs = serde_json::Map::new();
        attrs.insert("afe".into(), a.info.clone());
        let array = ArrayBuilder::new(
            shape.clone(),
            chunk_shape,
            a.element.zarr(),
            FillValue::new(vec![0; a.element.size()]),
        )
        .attributes(attrs)
        .build(store.clone(), &format!("/{}", a.key))
        .map_err(|e| BatchError::store(root, &e))?;
        array
            .store_metadata()
            .map_err(|e| BatchError::store(root, &e))?;
        if a.bytes.is_empty() {
            continue;
        }
        array
            .store_array_subset(&ArraySubset::new_with_shape(shape), a.bytes.as_slice())
            .map_err(|e| BatchError::store(root, &e))?;
    }
    Ok(())
}

/// The arrays of the group `root` written by [`write_group`], in their saved order.
pub fn read_group(root: &Path) -> Result<Vec<StoredArray>, BatchError> {
    if !is_saved_group(root) {
        return Err(BatchError::NotAStore {
            path: root.to_path_buf(),
            reason:
                "it is not a group written by afe.save (a batch store opens with afe.open_store)"
                    .into(),
        });
    }
    let store = Arc::new(FilesystemStore::new(root).map_err(|e| BatchError::store(root, &e))?);
    let group = Group::open(store.clone(), "/").map_err(|e| BatchError::store(root, &e))?;
    let order: Vec<String> = group.attributes()[SAVED]["order"]
        .as_array()
        .map(|o| {
            o.iter()
                .filter_map(|k| k.as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default();
    let mut arrays = read_arrays(&group, root)?;
    arrays.sort_by_key(|a| order.iter().position(|k| *k == a.key).unwrap_or(usize::MAX));
    Ok(arrays)
}

/// Every array of `group` with its `afe` attribute, float32 values widened to f64 (their
/// `info` says which they were), sorted by name.
pub(crate) fn read_arrays(
    group: &Group<FilesystemStore>,
    root: &Path,
) -> Result<Vec<StoredArray>, BatchError> {
    let mut out = Vec::new();
    for array in group
        .child_arrays()
        .map_err(|e| BatchError::store(root, &e))?
    {
        out.push(read_array(&array, root)?);
    }
    out.sort_by(|a, b| a.key.cmp(&b.key));
    Ok(out)
}

fn read_array(array: &Array<FilesystemStore>, root: &Path) -> Result<StoredArray, BatchError> {
    let shape: Vec<usize> = array.shape().iter().map(|&n| n as usize).collect();
    let bytes = array
        .retrieve_array_subset(&ArraySubset::new_with_shape(array.shape().to_vec()))
        .map_err(|e| BatchError::store(root, &e))?
        .into_fixed()
        .map_err(|e| BatchError::store(root, &e))?;
    let narrow = matches!(array.data_type(), DataType::Float32 | DataType::Complex64);
    let data = if narrow {
        bytes
            .chunks_exact(4)
            .map(|b| f64::from(f32::from_ne_bytes(b.try_into().unwrap_or([0; 4]))))
            .collect()
    } else {
        bytes
            .chunks_exact(8)
            .map(|b| f64::from_ne_bytes(b.try_into().unwrap_or([0; 8])))
            .collect()
    };
    Ok(StoredArray {
        key: array
            .path()
            .as_str()
            .rsplit('/')
            .next()
            .unwrap_or_default()
            .to_string(),
        shape,
        data,
        info: array
            .attributes()
            .get("afe")
            .cloned()
            .unwrap_or(Value::Null),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn floats(key: &str, shape: Vec<usize>, values: &[f64]) -> SavedArray {
        SavedArray {
            key: key.into(),
            shape,
            element: ElementType::Float64,
            bytes: values.iter().flat_map(|v| v.to_ne_bytes()).collect(),
            info: json!({ "name": key, "fs_hz": 100.0 }),
        }
    }

    #[test]
    fn a_group_round_trips_in_its_order_and_replaces_only_its_own_kind() {
        let dir = std::env::temp_dir().join(format!("afe-group-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("temp dir");
        let root = dir.join("x.zarr");
        let b = floats("b", vec![2, 3], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.5]);
        let a = SavedArray {
            key: "a".into(),
            shape: vec![2],
            element: ElementType::Complex64,
            bytes: [1.5f32, -2.0, 0.25, 8.0]
                .iter()
                .flat_map(|v| v.to_ne_bytes())
                .collect(),
            info: json!({ "name": "a", "dtype": "complex64" }),
        };
        write_group(&root, &[b.clone(), a]).expect("written");
        let back = read_group(&root).expect("read");
        assert_eq!(
            back.iter().map(|x| x.key.as_str()).collect::<Vec<_>>(),
            ["b", "a"]
        );
        assert_eq!(back[0].shape, [2, 3]);
        assert_eq!(back[0].data, [1.0, 2.0, 3.0, 4.0, 5.0, 6.5]);
        assert_eq!(back[0].info, b.info);
        assert_eq!(back[1].data, [1.5, -2.0, 0.25, 8.0]);
        // saved again over itself: replaced
        write_group(&root, &[floats("c", vec![0, 4], &[])]).expect("replaced");
        let back = read_group(&root).expect("read");
        assert_eq!(back.len(), 1);
        assert_eq!(back[0].shape, [0, 4]);
        // another folder is never replaced
        let other = dir.join("other");
        std::fs::create_dir_all(&other).expect("folder");
        let err = write_group(&other, std::slice::from_ref(&b)).expect_err("refused");
        assert!(
            err.to_string()
                .contains("is not a group written by afe.save"),
            "{err}"
        );
        let mut short = b;
        short.bytes.pop();
        let err = write_group(&dir.join("y.zarr"), &[short]).expect_err("refused");
        assert!(
            err.to_string().contains("do not fill the shape [2, 3]"),
            "{err}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
