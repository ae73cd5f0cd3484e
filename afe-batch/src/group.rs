//! One Zarr v3 group of named arrays with their afe descriptions: what `afe.save` writes
//! to a `.zarr` path and `afe.load` reads back, in the layout of one file of a zarr batch
//! store (each array's description in its `afe` attribute), with the arrays' order kept
//! in the group's `afe_saved` attribute.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use afe_core::CancelToken;
use serde_json::{json, Value};
use zarrs::array::codec::CodecOptions;
use zarrs::array::{Array, ArrayBuilder, ArrayMetadata, DataType, FillValue};
use zarrs::array_subset::ArraySubset;
use zarrs::filesystem::FilesystemStore;
use zarrs::group::GroupBuilder;

use super::store::{StoredArray, CHUNK_BYTES};
use super::verify::{read_json, Layout};
use super::BatchError;

/// The root attribute that marks a saved group and keeps its arrays' order.
const SAVED: &str = "afe_saved";

/// The version of the saved groups written now: 2 stores every chunk, zeros too (a
/// missing chunk is damage); groups of version 1 left chunks of zeros out.
const SAVED_VERSION: u64 = 2;

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
    read_json(&root.join("zarr.json")).is_ok_and(|v| v["attributes"][SAVED].is_object())
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
    if !is_array_name(&a.key) {
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

/// Whether `key` can name an array of a group: a folder name of its own, not a reserved one.
fn is_array_name(key: &str) -> bool {
    let reserved = ["", ".", "..", "zarr.json"];
    !(reserved.contains(&key)
        || key.contains(['/', '\\'])
        || key.chars().any(char::is_control)
        || key.starts_with("__"))
}

fn write_into(root: &Path, arrays: &[SavedArray]) -> Result<(), BatchError> {
    std::fs::create_dir_all(root).map_err(|e| BatchError::store(root, &e))?;
    let store = Arc::new(FilesystemStore::new(root).map_err(|e| BatchError::store(root, &e))?);
    let order: Vec<&str> = arrays.iter().map(|a| a.key.as_str()).collect();
    let mut attrs = serde_json::Map::new();
    attrs.insert(
        SAVED.into(),
        json!({ "version": SAVED_VERSION, "order": order }),
    );
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
        // chunks of zeros are stored too (zarr would leave them out): a chunk missing on
        // disk is then damage, which reading reports
        let mut options = CodecOptions::default();
        options.set_store_empty_chunks(true);
        array
            .store_array_subset_opt(
                &ArraySubset::new_with_shape(shape),
                a.bytes.as_slice(),
                &options,
            )
            .map_err(|e| BatchError::store(root, &e))?;
    }
    Ok(())
}

/// The arrays of the group `root` written by [`write_group`], in their saved order.
///
/// Each is read within the bounds its metadata declares, checked against the files first:
/// every chunk the shape implies must be on disk (version 1 groups: those found), a regular
/// file of an uncompressed chunk's size ([`BatchError::Damaged`] naming the array and
/// chunk otherwise), and all the values must fit the memory available
/// ([`BatchError::TooLarge`]). A signal to the process ([`afe::interrupt`]) stops the
/// read between chunks.
pub fn read_group(root: &Path) -> Result<Vec<StoredArray>, BatchError> {
    read_group_until(root, &CancelToken::new())
}

/// As [`read_group`], stopped between chunks also by `cancel`.
pub fn read_group_until(root: &Path, cancel: &CancelToken) -> Result<Vec<StoredArray>, BatchError> {
    let arrays = check_group(root)?;
    read_planned(root, &arrays, cancel)
}

/// Checks the group `root` written by [`write_group`] as [`read_group`] does, without
/// reading a value: what it would read, or what is wrong.
pub fn check_group(root: &Path) -> Result<Vec<ArrayOnDisk>, BatchError> {
    let not_saved = || BatchError::NotAStore {
        path: root.to_path_buf(),
        reason: "it is not a group written by afe.save (a batch store opens with afe.open_store)"
            .into(),
    };
    let meta = read_json(&root.join("zarr.json")).map_err(|_| not_saved())?;
    let saved = &meta["attributes"][SAVED];
    if !saved.is_object() {
        return Err(not_saved());
    }
    let order = names(&saved["order"]).ok_or_else(|| BatchError::Damaged {
        path: root.to_path_buf(),
        reason: format!("its '{SAVED}' attribute has no list of array names"),
    })?;
    let every_chunk = saved["version"].as_u64().unwrap_or(1) >= SAVED_VERSION;
    plan_arrays(root, "", &order, every_chunk)
}

/// The names in the JSON list `v`, if it is a list of names of arrays.
fn names(v: &Value) -> Option<Vec<String>> {
    v.as_array()?
        .iter()
        .map(|k| k.as_str().filter(|k| is_array_name(k)).map(str::to_string))
        .collect()
}

/// One array found whole on disk by [`check_group`], to be read.
#[derive(Debug, Clone)]
pub struct ArrayOnDisk {
    key: String,
    /// Its path in the Zarr hierarchy (`/<group>/<key>`).
    node: String,
    meta: Value,
    layout: Layout,
}

/// The arrays `keys` of the group at `node` (`""`: the root) of the hierarchy `root`,
/// each checked against its files (see [`read_group`]).
fn plan_arrays(
    root: &Path,
    node: &str,
    keys: &[String],
    every_chunk: bool,
) -> Result<Vec<ArrayOnDisk>, BatchError> {
    let group = if node.is_empty() {
        root.to_path_buf()
    } else {
        root.join(node)
    };
    let damaged = |key: &str, why: String| BatchError::Damaged {
        path: group.clone(),
        reason: format!("array '{key}': {why}"),
    };
    keys.iter()
        .map(|key| {
            let dir = group.join(key);
            let meta = read_json(&dir.join("zarr.json"))
                .map_err(|e| damaged(key, format!("its metadata cannot be read: {e}")))?;
            let layout = Layout::of(&meta).map_err(|e| damaged(key, e))?;
            layout
                .check_chunks(&dir, every_chunk)
                .map_err(|e| damaged(key, e))?;
            Ok(ArrayOnDisk {
                key: key.clone(),
                node: if node.is_empty() {
                    format!("/{key}")
                } else {
                    format!("/{node}/{key}")
                },
                meta,
                layout,
            })
        })
        .collect()
}

/// Reads the arrays checked by [`plan_arrays`] from the hierarchy `root`, once their
/// values (as f64, and their copy handed on) are known to fit the memory available.
pub(crate) fn read_planned(
    root: &Path,
    arrays: &[ArrayOnDisk],
    cancel: &CancelToken,
) -> Result<Vec<StoredArray>, BatchError> {
    // the values widened to f64, and the copy a caller (numpy) makes of them
    let needed: f64 = arrays.iter().map(|a| a.layout.values as f64 * 16.0).sum();
    if let Some(available) = afe::memory::available_bytes() {
        if needed > available {
            return Err(BatchError::TooLarge {
                path: root.to_path_buf(),
                needed_bytes: needed,
                available_bytes: Some(available),
            });
        }
    }
    let store = Arc::new(FilesystemStore::new(root).map_err(|e| BatchError::store(root, &e))?);
    arrays
        .iter()
        .map(|a| read_array(&store, root, a, cancel))
        .collect()
}

fn read_array(
    store: &Arc<FilesystemStore>,
    root: &Path,
    a: &ArrayOnDisk,
    cancel: &CancelToken,
) -> Result<StoredArray, BatchError> {
    let damaged = |why: &dyn std::fmt::Display| BatchError::Damaged {
        path: root.join(a.node.trim_start_matches('/')),
        reason: why.to_string(),
    };
    let metadata: ArrayMetadata =
        serde_json::from_value(a.meta.clone()).map_err(|e| damaged(&e))?;
    let array =
        Array::new_with_metadata(store.clone(), &a.node, metadata).map_err(|e| damaged(&e))?;
    let layout = &a.layout;
    let too_large = || BatchError::TooLarge {
        path: root.to_path_buf(),
        needed_bytes: layout.values as f64 * 8.0,
        available_bytes: None,
    };
    let mut data: Vec<f64> = Vec::new();
    data.try_reserve_exact(usize::try_from(layout.values).map_err(|_| too_large())?)
        .map_err(|_| too_large())?;
    let row_bytes = layout.chunk_bytes / layout.rows_per_chunk;
    let float = if layout.complex {
        layout.element / 2
    } else {
        layout.element
    };
    for k in 0..layout.chunks {
        if cancel.is_cancelled() {
            return Err(BatchError::Afe(afe_core::Error::Interrupted));
        }
        let bytes = array
            .retrieve_chunk(&layout.indices(k))
            .map_err(|e| damaged(&e))?
            .into_fixed()
            .map_err(|e| damaged(&e))?;
        let rows = layout
            .rows_per_chunk
            .min(layout.shape[0] - k * layout.rows_per_chunk);
        let part = usize::try_from(rows * row_bytes)
            .ok()
            .and_then(|n| bytes.get(..n))
            .ok_or_else(|| damaged(&format!("chunk {k} decodes short")))?;
        if float == 4 {
            data.extend(
                part.chunks_exact(4)
                    .map(|b| f64::from(f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))),
            );
        } else {
            data.extend(
                part.chunks_exact(8)
                    .map(|b| f64::from_ne_bytes(b.try_into().unwrap_or([0; 8]))),
            );
        }
    }
    Ok(StoredArray {
        key: a.key.clone(),
        shape: layout
            .shape
            .iter()
            .map(|&n| usize::try_from(n).map_err(|_| too_large()))
            .collect::<Result<_, _>>()?,
        data,
        info: a.meta["attributes"]
            .get("afe")
            .cloned()
            .unwrap_or(Value::Null),
    })
}

/// The arrays of the file group `id` of a batch store at `root`, each checked against
/// its files and read as [`read_group`] does: those its metadata lists (`afe.arrays`),
/// every chunk of which must be on disk, or for a group of an earlier version the arrays
/// and chunks found; sorted by name. `None`: the store holds no such group.
pub(crate) fn read_file_group(
    root: &Path,
    id: &str,
    cancel: &CancelToken,
) -> Result<Option<Vec<StoredArray>>, BatchError> {
    let dir = root.join(id);
    let Ok(meta) = read_json(&dir.join("zarr.json")) else {
        return Ok(None);
    };
    if meta["node_type"] != "group" {
        return Ok(None);
    }
    let (mut keys, every_chunk) = match meta["attributes"]["afe"].get("arrays") {
        Some(listed) => (
            names(listed).ok_or_else(|| BatchError::Damaged {
                path: dir.clone(),
                reason: "its metadata lists an array without a usable name".into(),
            })?,
            true,
        ),
        None => (arrays_found(&dir), false),
    };
    keys.sort();
    let arrays = plan_arrays(root, id, &keys, every_chunk)?;
    read_planned(root, &arrays, cancel).map(Some)
}

/// The names of the folders of `dir` holding an array's metadata.
fn arrays_found(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(Result::ok)
                .filter_map(|e| e.file_name().into_string().ok())
                .filter(|name| {
                    is_array_name(name)
                        && read_json(&dir.join(name).join("zarr.json"))
                            .is_ok_and(|m| m["node_type"] == "array")
                })
                .collect()
        })
        .unwrap_or_default()
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

    /// A saved group of one 3000 x 100 float64 array (three chunks: 1 MiB holds 1310 rows)
    /// in a fresh folder; its path and the array's folder.
    fn saved(name: &str) -> (PathBuf, PathBuf) {
        let dir = std::env::temp_dir().join(format!("afe-group-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("temp dir");
        let root = dir.join("g.zarr");
        let values = vec![0.0; 3000 * 100];
        write_group(&root, &[floats("x", vec![3000, 100], &values)]).expect("written");
        let array = root.join("x");
        (root, array)
    }

    fn edit_meta(array: &Path, edit: impl FnOnce(&mut Value)) {
        let path = array.join("zarr.json");
        let mut meta: Value =
            serde_json::from_str(&std::fs::read_to_string(&path).expect("read")).expect("json");
        edit(&mut meta);
        std::fs::write(&path, meta.to_string()).expect("write");
    }

    #[test]
    fn a_hostile_shape_is_refused_before_anything_is_allocated() {
        let (root, array) = saved("shape");
        // the chunks of zeros are on disk: 3 of them
        assert_eq!(read_group(&root).expect("read")[0].data.len(), 300_000);
        // the probe's shapes (their trailing axis no longer the chunks'), then one whose
        // chunks the files do not hold
        for (shape, why) in [
            (
                json!([1_000_000_000_000u64, 1_000_000]),
                "does not match its chunks [1310, 100]",
            ),
            (
                json!([40_000_000, 32]),
                "does not match its chunks [1310, 100]",
            ),
            (json!([40_000_000, 100]), "chunk [3, 0] is missing"),
        ] {
            edit_meta(&array, |m| m["shape"] = shape.clone());
            let e = read_group(&root).expect_err("refused").to_string();
            assert!(
                e.contains("is damaged: array 'x': ") && e.contains(why),
                "{e}"
            );
        }
        // chunks of the right size (sparse files) for a shape the memory does not hold
        for k in 3..8 {
            std::fs::create_dir_all(array.join(format!("c/{k}"))).expect("dir");
            std::fs::File::create(array.join(format!("c/{k}/0")))
                .and_then(|f| f.set_len(1310 * 100 * 8))
                .expect("sparse chunk");
        }
        edit_meta(&array, |m| m["shape"] = json!([8 * 1310, 100]));
        // 10,480 x 100 values: 16.8 MB once read, against 1 MB available
        std::env::set_var("AFE_MEMORY_AVAILABLE_GB", "0.001");
        let e = read_group(&root).expect_err("refused");
        std::env::remove_var("AFE_MEMORY_AVAILABLE_GB");
        assert!(matches!(e, BatchError::TooLarge { .. }), "{e}");
        assert!(
            e.to_string().contains("more than the 0.00 GB available"),
            "{e}"
        );
        assert_eq!(read_group(&root).expect("read")[0].shape, [8 * 1310, 100]);
        let _ = std::fs::remove_dir_all(root.parent().expect("dir"));
    }

    #[test]
    fn a_missing_or_fifo_chunk_is_damage_naming_the_array_and_chunk() {
        let (root, array) = saved("chunk");
        std::fs::remove_file(array.join("c/1/0")).expect("rm");
        let e = read_group(&root).expect_err("refused");
        assert!(matches!(e, BatchError::Damaged { .. }), "{e}");
        assert!(
            e.to_string().contains("array 'x': chunk [1, 0] is missing"),
            "{e}"
        );
        assert!(check_group(&root).is_err());
        let made = std::process::Command::new("mkfifo")
            .arg(array.join("c/1/0"))
            .status();
        assert!(made.is_ok_and(|s| s.success()), "mkfifo");
        let e = read_group(&root).expect_err("refused").to_string();
        assert!(
            e.contains("chunk [1, 0] is not a regular file (a FIFO or a device)"),
            "{e}"
        );
        // a FIFO in place of the group's metadata: not a saved group, and nothing blocks
        std::fs::remove_file(root.join("zarr.json")).expect("rm");
        let made = std::process::Command::new("mkfifo")
            .arg(root.join("zarr.json"))
            .status();
        assert!(made.is_ok_and(|s| s.success()), "mkfifo");
        assert!(!is_saved_group(&root));
        let _ = std::fs::remove_dir_all(root.parent().expect("dir"));
    }

    #[test]
    fn a_version_1_group_reads_a_missing_chunk_as_zeros_and_a_listed_array_must_exist() {
        let (root, array) = saved("v1");
        std::fs::remove_file(array.join("c/1/0")).expect("rm");
        let meta_path = root.join("zarr.json");
        let mut meta: Value =
            serde_json::from_str(&std::fs::read_to_string(&meta_path).expect("read"))
                .expect("json");
        meta["attributes"][SAVED]["version"] = json!(1);
        std::fs::write(&meta_path, meta.to_string()).expect("write");
        assert_eq!(read_group(&root).expect("read")[0].data.len(), 300_000);
        meta["attributes"][SAVED]["order"] = json!(["x", "y"]);
        std::fs::write(&meta_path, meta.to_string()).expect("write");
        let e = read_group(&root).expect_err("refused").to_string();
        assert!(e.contains("array 'y': its metadata cannot be read"), "{e}");
        meta["attributes"][SAVED]["order"] = json!(["../x"]);
        std::fs::write(&meta_path, meta.to_string()).expect("write");
        let e = read_group(&root).expect_err("refused").to_string();
        assert!(e.contains("no list of array names"), "{e}");
        let _ = std::fs::remove_dir_all(root.parent().expect("dir"));
    }
}
