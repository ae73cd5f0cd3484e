//! `afe batch` end to end, through the binary: a generated corpus (nested folders, mixed
//! rates, lengths, channel counts and sample formats, corrupt files) into a store that
//! must hold exactly what `afe extract` computes for each file; resume after a SIGKILL;
//! shards; a store made with other parameters; npz stores; `--on-error stop`; manifests.
//!
//! The corpus, the runs of the binary and the readers of a store are here; the tests, one
//! module per concern: what a store holds, resuming, runs that share a store, failures.

mod failures;
mod resume;
mod shared_store;
mod stores;

use crate::common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Output;

use afe_batch::Store;
use common::{afe, npz_arrays};
use serde_json::Value;

/// An array as (name, shape, values).
type Arrays = Vec<(String, Vec<usize>, Vec<f64>)>;

/// A folder of this test process, removed when dropped (also when a test fails).
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("afe-batch-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("temp dir");
        TempDir(dir)
    }

    fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Runs `afe` with `args` and checks it succeeded.
fn afe_ok(args: &[&str]) -> Output {
    let out = afe(args);
    assert!(
        out.status.success(),
        "afe {} failed: {}",
        args.join(" "),
        stderr(&out)
    );
    out
}

/// Runs `afe` with `args` and checks it failed with one clear `error:` line holding every
/// one of `needles`.
fn afe_err(args: &[&str], needles: &[&str]) -> String {
    let out = afe(args);
    let err = stderr(&out);
    assert!(!out.status.success(), "afe {} should fail", args.join(" "));
    assert!(!err.contains("panicked"), "{err}");
    let line = err
        .lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or_else(|| panic!("no error line in: {err}"));
    for n in needles {
        assert!(line.contains(n), "'{n}' not in: {line}");
    }
    line.to_string()
}

/// A tiny deterministic generator (Knuth's MMIX LCG): no rand crate needed.
struct Lcg(u64);

impl Lcg {
    /// Uniform in [-1, 1).
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// How a generated WAV file is stored.
#[derive(Debug, Clone, Copy)]
struct Kind {
    fs: u32,
    channels: u16,
    /// 32-bit float, else 16-bit integer.
    float: bool,
    seconds: f64,
}

/// Writes a WAV of `kind` holding a tone, a second tone and seeded noise that differ per
/// `seed`; a second channel is the first delayed and softer (an ITD and an ILD).
fn write_signal(path: &Path, kind: Kind, seed: u64) {
    std::fs::create_dir_all(path.parent().expect("parent")).expect("dir");
    let spec = hound::WavSpec {
        channels: kind.channels,
        sample_rate: kind.fs,
        bits_per_sample: if kind.float { 32 } else { 16 },
        sample_format: if kind.float {
            hound::SampleFormat::Float
        } else {
            hound::SampleFormat::Int
        },
    };
    let fs = f64::from(kind.fs);
    let frames = ((kind.seconds * fs).round() as usize).max(1);
    let mut rng = Lcg(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0x2545_f491);
    let f1 = 150.0 + 97.0 * (seed % 23) as f64;
    let f2 = 1200.0 + 311.0 * (seed % 11) as f64;
    let noise = 0.02 + 0.1 * (seed % 5) as f64;
    let mono: Vec<f64> = (0..frames)
        .map(|t| {
            let x = t as f64 / fs;
            0.3 * (2.0 * std::f64::consts::PI * f1 * x).sin()
                + 0.1 * (2.0 * std::f64::consts::PI * f2 * x).sin()
                + noise * rng.next()
        })
        .collect();
    let delay = 1 + (seed % 17) as usize;
    let gain = 0.4 + 0.05 * (seed % 10) as f64;
    let mut w = hound::WavWriter::create(path, spec).expect("create wav");
    for t in 0..frames {
        let mut frame = vec![mono[t]];
        if kind.channels >= 2 {
            frame.push(gain * if t >= delay { mono[t - delay] } else { 0.0 });
        }
        for c in 2..usize::from(kind.channels) {
            frame.push(0.1 * c as f64 * mono[t]);
        }
        for v in frame {
            if kind.float {
                w.write_sample(v as f32).expect("write");
            } else {
                w.write_sample((v * 32767.0).round() as i16).expect("write");
            }
        }
    }
    w.finalize().expect("finalize");
}

/// Writes `n` good WAV files under `root` in nested folders: lengths 0.05 s to 1.5 s,
/// 16, 22.05 and 44.1 kHz, mono and stereo, 16-bit integer and 32-bit float, every
/// combination present once `n` >= 12. Returns their ids.
fn good_corpus(root: &Path, n: usize) -> Vec<String> {
    let rates = [16000, 22050, 44100];
    (0..n)
        .map(|k| {
            let id = match k % 5 {
                0 => format!("top{k:02}.wav"),
                1 | 2 => format!("spk{}/utt{k:02}.wav", k % 3),
                _ => format!("spk{}/session {}/utt{k:02}.wav", k % 3, k % 2),
            };
            let kind = Kind {
                fs: rates[k % 3],
                channels: if k % 4 == 0 { 1 } else { 2 },
                float: k % 2 == 0,
                seconds: 0.05 + 1.45 * ((k * 7) % n) as f64 / (n.max(2) - 1) as f64,
            };
            write_signal(&root.join(&id), kind, k as u64);
            id
        })
        .collect()
}

/// `afe batch status STORE --json`.
fn status(store: &Path) -> Value {
    let out = afe_ok(&["batch", "status", s(store), "--json"]);
    serde_json::from_slice(&out.stdout).expect("status json")
}

/// The records of one kind (`failed`, `missing`) in a `status --json` report, each
/// checked to carry that status: their ids with their errors.
fn errors_of(status: &Value, kind: &str) -> BTreeMap<String, String> {
    status[kind]
        .as_array()
        .unwrap_or_else(|| panic!("no '{kind}' list in {status}"))
        .iter()
        .map(|r| {
            assert_eq!(r["status"], kind);
            (
                r["id"].as_str().expect("id").to_string(),
                r["error"].as_str().expect("error").to_string(),
            )
        })
        .collect()
}

/// The ids of the files a zarr store holds: the groups with file attributes.
fn stored_ids(root: &Path) -> BTreeSet<String> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeSet<String>) {
        for entry in std::fs::read_dir(dir).expect("read dir") {
            let path = entry.expect("entry").path();
            if !path.is_dir() || path.ends_with(".afe-batch") {
                continue;
            }
            let meta: Value = std::fs::read(path.join("zarr.json"))
                .map(|b| {
                    serde_json::from_slice(&b).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
                })
                .unwrap_or(Value::Null);
            if meta["node_type"] == "group" && meta["attributes"]["afe"]["path"].is_string() {
                let id = path.strip_prefix(root).expect("inside");
                out.insert(s(id).to_string());
            } else {
                walk(root, &path, out);
            }
        }
    }
    let mut ids = BTreeSet::new();
    walk(root, root, &mut ids);
    ids
}

/// File `id`'s arrays in the zarr store at `root`, sorted by name.
fn stored(root: &Path, id: &str) -> Arrays {
    Store::open(root)
        .expect("store")
        .read(id)
        .unwrap_or_else(|e| panic!("{id}: {e}"))
        .into_iter()
        .map(|a| (a.key, a.shape, a.data))
        .collect()
}

/// `afe extract` of `wav` with `args` (requests and parameters): its arrays in archive
/// order.
fn extracted(wav: &Path, args: &[&str], out: &Path) -> Arrays {
    let mut all = vec!["extract", s(wav), "-o", s(out)];
    all.extend(args);
    afe_ok(&all);
    let arrays = npz_arrays(out);
    std::fs::remove_file(out).expect("remove npz");
    arrays
}

fn sorted(mut a: Arrays) -> Arrays {
    a.sort_by(|x, y| x.0.cmp(&y.0));
    a
}

/// `a` and `b` hold the same names, shapes and values, bit for bit (NaN, ±0 included);
/// the first difference is reported, not megabytes of values.
fn assert_same(a: &Arrays, b: &Arrays, what: &str) {
    let names = |x: &Arrays| x.iter().map(|e| e.0.clone()).collect::<Vec<_>>();
    assert_eq!(names(a), names(b), "{what}: array names");
    for ((name, sa, da), (_, sb, db)) in a.iter().zip(b) {
        assert_eq!(sa, sb, "{what}: shape of {name}");
        assert_eq!(da.len(), db.len(), "{what}: values of {name}");
        if let Some(i) = (0..da.len()).find(|&i| da[i].to_bits() != db[i].to_bits()) {
            panic!("{what}: {name}[{i}] = {} vs {}", da[i], db[i]);
        }
    }
}

/// Two zarr stores hold the same files with the same arrays.
fn assert_same_stores(a: &Path, b: &Path) {
    let ids = stored_ids(a);
    assert_eq!(ids, stored_ids(b), "the stores hold other files");
    for id in &ids {
        assert_same(&stored(a, id), &stored(b, id), id);
    }
}

/// The records of a store's logs (complete lines only: a killed writer may have left a
/// torn one).
fn ledger_records(store: &Path) -> Vec<Value> {
    let Ok(entries) = std::fs::read_dir(store.join(".afe-batch")) else {
        return Vec::new();
    };
    let mut records = Vec::new();
    for entry in entries {
        let text = std::fs::read_to_string(entry.expect("entry").path()).unwrap_or_default();
        records.extend(
            text.split_inclusive('\n')
                .filter(|l| l.ends_with('\n'))
                .filter_map(|l| serde_json::from_str::<Value>(l).ok()),
        );
    }
    records
}

/// The JSON lines of `--progress jsonl`.
fn events(out: &Output) -> Vec<Value> {
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect()
}

const REQUESTS: &str = "ratemap,filterbank";
