//! `afe batch` end to end, through the binary: a generated corpus (nested folders, mixed
//! rates, lengths, channel counts and sample formats, corrupt files) into a store that
//! must hold exactly what `afe extract` computes for each file; resume after a SIGKILL;
//! shards; a store made with other parameters; npz stores; `--on-error stop`; manifests.

use crate::common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant, SystemTime};

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

/// Writes corrupt files under `root/bad`: returns (id, words their error must hold).
fn corrupt_files(root: &Path) -> Vec<(String, &'static str)> {
    let dir = root.join("bad");
    std::fs::create_dir_all(&dir).expect("dir");
    let whole = dir.join("whole.tmp");
    let kind = Kind {
        fs: 16000,
        channels: 2,
        float: false,
        seconds: 0.2,
    };
    write_signal(&whole, kind, 99);
    let bytes = std::fs::read(&whole).expect("read");
    std::fs::remove_file(&whole).expect("remove");
    // the RIFF header and the start of the fmt chunk
    std::fs::write(dir.join("truncated_header.wav"), &bytes[..28]).expect("write");
    // the whole header and half of the samples
    std::fs::write(dir.join("truncated_data.wav"), &bytes[..bytes.len() / 2]).expect("write");
    std::fs::write(
        dir.join("not_audio.wav"),
        "this is a text file, not audio\n",
    )
    .expect("write");
    let three = Kind {
        channels: 3,
        ..kind
    };
    write_signal(&dir.join("three_channels.wav"), three, 5);
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: 16000,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    hound::WavWriter::create(dir.join("empty.wav"), spec)
        .expect("create")
        .finalize()
        .expect("finalize");
    vec![
        ("bad/empty.wav".into(), "holds no samples"),
        ("bad/not_audio.wav".into(), "not a WAV file"),
        ("bad/three_channels.wav".into(), "3 channels"),
        ("bad/truncated_data.wav".into(), "truncated"),
        ("bad/truncated_header.wav".into(), "ends inside its header"),
    ]
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

/// Copies a folder tree.
fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("dir");
    for entry in std::fs::read_dir(from).expect("read dir") {
        let path = entry.expect("entry").path();
        let dest = to.join(path.file_name().expect("name"));
        if path.is_dir() {
            copy_dir(&path, &dest);
        } else {
            std::fs::copy(&path, &dest).expect("copy");
        }
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

#[test]
fn corpus_store_holds_what_extract_computes_and_records_every_failure() {
    let tmp = TempDir::new("corpus");
    let corpus = tmp.join("corpus");
    let good = good_corpus(&corpus, 50);
    let bad = corrupt_files(&corpus);
    let store = tmp.join("store.zarr");
    // 8 channels: a filterbank of 1.5 s at 44.1 kHz then spans several 1 MiB chunks
    let params = ["-r", REQUESTS, "-p", "fb_nChannels=8"];
    let mut args = vec!["batch", s(&corpus), "-o", s(&store)];
    args.extend(params);
    args.extend(["-j", "2", "--progress", "none"]);
    let out = afe_ok(&args);
    let summary = stderr(&out);
    assert!(
        summary.contains("55 file(s): 50 done now, 0 done before, 5 failed"),
        "{summary}"
    );

    // every corrupt file is listed as failed, with its problem, and left nothing behind
    let st = status(&store);
    assert_eq!(st["done"], 50, "{st}");
    let failed = errors_of(&st, "failed");
    assert_eq!(
        failed.keys().cloned().collect::<Vec<_>>(),
        bad.iter().map(|b| b.0.clone()).collect::<Vec<_>>()
    );
    for (id, needle) in &bad {
        assert!(failed[id].contains(needle), "{id}: '{}'", failed[id]);
        let name = Path::new(id).file_name().expect("name");
        assert!(
            failed[id].contains(s(Path::new(name))),
            "{id}: '{}'",
            failed[id]
        );
        assert!(!store.join(id).exists(), "{id} left a group");
    }

    // the root records the requests, the parameters and their hash
    let root: Value =
        serde_json::from_slice(&std::fs::read(store.join("zarr.json")).expect("zarr.json"))
            .expect("json");
    let afe_meta = &root["attributes"]["afe"];
    let hash = afe_meta["param_hash"].as_str().expect("param_hash");
    assert_eq!(hash.len(), 16, "{hash}");
    assert!(hash.chars().all(|c| c.is_ascii_hexdigit()), "{hash}");
    assert_eq!(st["param_hash"], hash);
    assert_eq!(
        afe_meta["requests"],
        serde_json::json!(["ratemap", "filterbank"])
    );
    assert_eq!(afe_meta["params"]["fb_nChannels"], 8);

    // every good file's arrays are `afe extract`'s, bit for bit; the binary is run per
    // file (a few ms each) so that the claim is about the two commands, which also run
    // different executors (extract's concurrent scheduler, batch's sequential one)
    assert_eq!(
        stored_ids(&store),
        good.iter().cloned().collect::<BTreeSet<_>>()
    );
    let npz = tmp.join("x.npz");
    let mut multi_chunk = 0;
    for id in &good {
        let want = sorted(extracted(&corpus.join(id), &params, &npz));
        let got = stored(&store, id);
        assert_same(&got, &want, id);
        // the file's group records its facts; a mono file gives `_mono` outputs
        let wav = hound::WavReader::open(corpus.join(id)).expect("wav").spec();
        let group: Value =
            serde_json::from_slice(&std::fs::read(store.join(id).join("zarr.json")).expect("read"))
                .expect("json");
        let facts = &group["attributes"]["afe"];
        assert_eq!(facts["channels"], wav.channels, "{id}");
        assert_eq!(facts["fs_hz"], f64::from(wav.sample_rate), "{id}");
        let ears: &[&str] = if wav.channels == 1 {
            &["_mono"]
        } else {
            &["_left", "_right"]
        };
        assert_eq!(got.len(), 2 * ears.len(), "{id}");
        assert!(
            got.iter().all(|a| ears.iter().any(|e| a.0.ends_with(e))),
            "{id}"
        );
        let fb = store.join(id).join("filterbank_left/c");
        if std::fs::read_dir(&fb).map_or(0, Iterator::count) > 1 {
            multi_chunk += 1;
        }
    }
    assert!(
        multi_chunk >= 3,
        "only {multi_chunk} files span several chunks"
    );
}

/// Waits until `store` records a finished file (then kills `child`), or panics if the
/// child ends first.
fn kill_after_first_record(child: &mut std::process::Child, store: &Path) {
    let start = Instant::now();
    loop {
        if ledger_records(store).iter().any(|r| r["status"] == "done") {
            child.kill().expect("kill");
            child.wait().expect("wait");
            return;
        }
        if let Some(code) = child.try_wait().expect("try_wait") {
            panic!("the run ended ({code}) before any file was recorded");
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no file recorded in 60 s"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn a_killed_run_resumes_without_redoing_finished_files() {
    let tmp = TempDir::new("resume");
    let corpus = tmp.join("corpus");
    let rates = [44100, 22050];
    let ids: Vec<String> = (0..24)
        .map(|k| {
            let id = format!("d{}/f{k:02}.wav", k % 3);
            let kind = Kind {
                fs: rates[k % 2],
                channels: 2 - (k % 5 == 0) as u16,
                float: k % 3 == 0,
                seconds: 0.8 + 0.03 * k as f64,
            };
            write_signal(&corpus.join(&id), kind, 1000 + k as u64);
            id
        })
        .collect();
    let copy = tmp.join("copy");
    copy_dir(&corpus, &copy);

    let whole = tmp.join("whole.zarr");
    afe_ok(&[
        "batch",
        s(&corpus),
        "-r",
        "ratemap",
        "-o",
        s(&whole),
        "-j",
        "2",
        "--progress",
        "none",
    ]);

    let store = tmp.join("resumed.zarr");
    let args = [
        "batch",
        s(&copy),
        "-r",
        "ratemap",
        "-o",
        s(&store),
        "-j",
        "1",
        "--progress",
        "jsonl",
    ];
    let mut child = Command::new(env!("CARGO_BIN_EXE_afe"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn afe");
    kill_after_first_record(&mut child, &store);
    let before: BTreeSet<String> = ledger_records(&store)
        .iter()
        .filter(|r| r["status"] == "done")
        .map(|r| r["id"].as_str().expect("id").to_string())
        .collect();
    assert!(
        !before.is_empty() && before.len() < ids.len(),
        "killed after {} of {} files",
        before.len(),
        ids.len()
    );
    // the finished files' metadata files, with their modification times
    let mtimes = |id: &str| -> Vec<(PathBuf, SystemTime)> {
        let mut files = vec![store.join(id).join("zarr.json")];
        for a in ["ratemap_left", "ratemap_right", "ratemap_mono"] {
            let p = store.join(id).join(a).join("zarr.json");
            if p.exists() {
                files.push(p);
            }
        }
        files
            .into_iter()
            .map(|p| {
                let t = std::fs::metadata(&p)
                    .expect("meta")
                    .modified()
                    .expect("mtime");
                (p, t)
            })
            .collect()
    };
    let times_before: Vec<_> = before.iter().map(|id| mtimes(id)).collect();
    // the file in flight (one worker, longest first: f23, f22, ...) as a kill in its
    // first writes leaves it, whether or not this kill did: its folder's group metadata
    // truncated, its own group torn with a stray file in it
    let next = &ids[ids.len() - 1 - before.len()];
    let folder = store.join(next).parent().expect("folder").to_path_buf();
    std::fs::create_dir_all(store.join(next)).expect("dir");
    std::fs::write(folder.join("zarr.json"), "").expect("truncate");
    std::fs::write(store.join(next).join("zarr.json"), "{\"zarr_for").expect("torn");
    std::fs::write(store.join(next).join("stray"), "x").expect("stray");

    let out = afe_ok(&args);
    let ev = events(&out);
    assert_eq!(ev[0]["event"], "start");
    assert_eq!(ev[0]["already_done"], before.len());
    let redone: BTreeSet<String> = ev
        .iter()
        .filter(|e| e["event"] == "file")
        .map(|e| {
            assert_eq!(e["status"], "done", "{e}");
            e["id"].as_str().expect("id").to_string()
        })
        .collect();
    assert!(
        redone.is_disjoint(&before),
        "recomputed: {:?}",
        redone.intersection(&before).collect::<Vec<_>>()
    );
    let all: BTreeSet<String> = redone.union(&before).cloned().collect();
    assert_eq!(all, ids.iter().cloned().collect::<BTreeSet<_>>());
    let last = ev.last().expect("summary");
    assert_eq!(last["event"], "summary");
    assert_eq!(last["done"], ids.len() - before.len());
    for (id, times) in before.iter().zip(&times_before) {
        assert_eq!(&mtimes(id), times, "{id} was rewritten");
    }

    assert!(!store.join(next).join("stray").exists());
    let meta: Value =
        serde_json::from_slice(&std::fs::read(folder.join("zarr.json")).expect("read"))
            .expect("the folder's group is written again");
    assert_eq!(meta["node_type"], "group");
    assert_same_stores(&store, &whole);
    let st = status(&store);
    assert_eq!(st["done"], ids.len());
    assert_eq!(st["failed"], serde_json::json!([]));
    // a third run finds nothing to do
    let out = afe_ok(&args);
    let ev = events(&out);
    assert_eq!(ev[0]["already_done"], ids.len(), "{ev:?}");
    assert_eq!(ev.len(), 2, "{ev:?}");
}

#[test]
fn shards_fill_one_store_as_a_single_run_does() {
    let tmp = TempDir::new("shards");
    let corpus = tmp.join("corpus");
    let ids = good_corpus(&corpus, 16);
    let single = tmp.join("single.zarr");
    let sharded = tmp.join("sharded.zarr");
    let base = [
        "-r",
        "ratemap",
        "-p",
        "fb_nChannels=16",
        "--progress",
        "jsonl",
    ];
    let mut args = vec!["batch", s(&corpus), "-o", s(&single)];
    args.extend(base);
    afe_ok(&args);
    let mut counts = Vec::new();
    for shard in ["0/2", "1/2"] {
        let mut args = vec!["batch", s(&corpus), "-o", s(&sharded), "--shard", shard];
        args.extend(base);
        let ev = events(&afe_ok(&args));
        counts.push(ev[0]["files"].as_u64().expect("files"));
    }
    assert_eq!(counts.iter().sum::<u64>(), ids.len() as u64, "{counts:?}");
    assert!(counts.iter().all(|&n| n > 0), "{counts:?}");
    assert_eq!(status(&sharded)["done"], ids.len());
    assert_same_stores(&sharded, &single);

    let bad_store = tmp.join("bad.zarr");
    for (shard, needle) in [
        ("2/2", "shard 2/2"),
        ("1/0", "shard 1/0"),
        ("x", "--shard 'x'"),
        ("1-2", "--shard '1-2'"),
    ] {
        afe_err(
            &[
                "batch",
                s(&corpus),
                "-r",
                "ratemap",
                "-o",
                s(&bad_store),
                "--shard",
                shard,
            ],
            &[needle, "I/N"],
        );
        assert!(!bad_store.exists(), "{shard} created the store");
    }
}

#[test]
fn other_parameters_are_refused_unless_overwrite() {
    let tmp = TempDir::new("params");
    let corpus = tmp.join("corpus");
    good_corpus(&corpus, 4);
    let store = tmp.join("store.zarr");
    let run = |n: &str, extra: &[&str]| {
        let p = format!("fb_nChannels={n}");
        let mut args = vec![
            "batch",
            s(&corpus),
            "-r",
            "ratemap",
            "-p",
            &p,
            "-o",
            s(&store),
            "--progress",
            "none",
        ];
        args.extend(extra);
        afe(&args)
    };
    assert!(run("8", &[]).status.success());
    let hash8 = status(&store)["param_hash"].clone();
    let out = run("16", &[]);
    assert!(!out.status.success());
    let err = stderr(&out);
    for needle in [
        r#""fb_nChannels":8"#,
        r#""fb_nChannels":16"#,
        "--overwrite",
        s(&store),
    ] {
        assert!(err.contains(needle), "'{needle}' not in: {err}");
    }
    // refused before anything was touched
    assert_eq!(status(&store)["param_hash"], hash8);
    assert_eq!(stored(&store, "top00.wav")[0].1[1], 8);

    assert!(run("16", &["--overwrite"]).status.success());
    let st = status(&store);
    assert_ne!(st["param_hash"], hash8);
    assert_eq!(st["params"]["fb_nChannels"], 16);
    assert_eq!(st["done"], 4);
    assert_eq!(stored_ids(&store).len(), 4);
    assert_eq!(stored(&store, "top00.wav")[0].1[1], 16);
    // the same parameters again: accepted, nothing to redo
    let out = run("16", &[]);
    assert!(out.status.success());
    assert!(
        stderr(&out).contains("0 done now, 4 done before"),
        "{}",
        stderr(&out)
    );

    // a folder that is not a store is never touched
    let other = tmp.join("other");
    std::fs::create_dir_all(&other).expect("dir");
    std::fs::write(other.join("keep.txt"), "mine").expect("write");
    afe_err(
        &["batch", s(&corpus), "-r", "ratemap", "-o", s(&other)],
        &["not an afe store"],
    );
    assert_eq!(std::fs::read_dir(&other).expect("dir").count(), 1);
}

#[test]
fn npz_and_zarr_stores_of_a_whole_signal_graph_equal_extract() {
    let tmp = TempDir::new("npz");
    let corpus = tmp.join("corpus");
    let ids = good_corpus(&corpus, 6);
    // pitch is computed on the whole signal (not chunk-invariant); the STFT is complex
    let params = ["-r", "pitch,stft", "-p", "fb_nChannels=8"];
    let npz_store = tmp.join("store-npz");
    let zarr_store = tmp.join("store.zarr");
    for (store, format) in [(&npz_store, "npz"), (&zarr_store, "zarr")] {
        let mut args = vec!["batch", s(&corpus), "-o", s(store), "--format", format];
        args.extend(params);
        args.extend(["--progress", "none"]);
        afe_ok(&args);
    }
    let st = status(&npz_store);
    assert_eq!(
        (st["format"].as_str(), &st["done"]),
        (Some("npz"), &ids.len().into())
    );
    let npz = tmp.join("x.npz");
    for id in &ids {
        let want = extracted(&corpus.join(id), &params, &npz);
        // the same arrays in the same order as `afe extract` writes them
        assert_same(&npz_arrays(&npz_store.join(format!("{id}.npz"))), &want, id);
        assert_same(&stored(&zarr_store, id), &sorted(want), id);
    }
    // a whole signal's output is cut into chunks as a streamed one is (128 STFT frames of
    // 1 KiB pairs make a 1 MiB chunk: the 1.5 s files have 150)
    let spans = |id: &String| {
        std::fs::read_dir(zarr_store.join(id).join("stft_left/c")).map_or(0, Iterator::count)
    };
    assert!(
        ids.iter().any(|id| spans(id) > 1),
        "no STFT spans two chunks"
    );
    let complex = stored(&zarr_store, &ids[0])
        .into_iter()
        .find(|a| a.0.starts_with("stft"))
        .expect("stft");
    assert_eq!(
        complex.2.len(),
        2 * complex.1.iter().product::<usize>(),
        "complex values as pairs"
    );

    // an .npz cut short is reported missing and redone by the next run
    let cut = npz_store.join(format!("{}.npz", ids[0]));
    let len = std::fs::metadata(&cut).expect("npz").len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&cut)
        .expect("open")
        .set_len(len - 10)
        .expect("cut");
    let st = status(&npz_store);
    assert_eq!(st["done"], ids.len() - 1, "{st}");
    assert_eq!(st["missing"][0]["id"], ids[0].as_str(), "{st}");
    assert!(
        st["missing"][0]["error"]
            .as_str()
            .is_some_and(|e| e.contains("cut short")),
        "{st}"
    );
    let mut args = vec!["batch", s(&corpus), "-o", s(&npz_store), "--format", "npz"];
    args.extend(params);
    args.extend(["--progress", "none"]);
    let out = afe_ok(&args);
    assert!(stderr(&out).contains("1 done now"), "{}", stderr(&out));
    assert_same(
        &npz_arrays(&cut),
        &extracted(&corpus.join(&ids[0]), &params, &npz),
        &ids[0],
    );
}

#[test]
fn float32_stores_hold_the_extracted_values_rounded_and_keep_their_type() {
    let tmp = TempDir::new("f32");
    let corpus = tmp.join("corpus");
    let ids = good_corpus(&corpus, 3);
    // the STFT is complex: complex64 in a float32 store
    let params = ["-r", "ratemap,stft", "-p", "fb_nChannels=8"];
    let npz_store = tmp.join("store-npz");
    let zarr_store = tmp.join("store.zarr");
    let batch = |store: &Path, format: &str, dtype: &str| {
        let mut args = vec!["batch", s(&corpus), "-o", s(store), "--format", format];
        args.extend(params);
        args.extend(["--dtype", dtype, "--progress", "none"]);
        afe(&args)
    };
    for (store, format) in [(&npz_store, "npz"), (&zarr_store, "zarr")] {
        assert!(batch(store, format, "f32").status.success());
        assert_eq!(status(store)["dtype"], "float32");
    }
    let npz = tmp.join("x.npz");
    for id in &ids {
        let mut wide = params.to_vec();
        wide.extend(["--dtype", "f64"]);
        let want: Arrays = extracted(&corpus.join(id), &wide, &npz)
            .into_iter()
            .map(|(k, shape, v)| (k, shape, v.iter().map(|&x| f64::from(x as f32)).collect()))
            .collect();
        assert_same(&npz_arrays(&npz_store.join(format!("{id}.npz"))), &want, id);
        assert_same(&stored(&zarr_store, id), &sorted(want), id);
        // stored as float32 (complex64), half the bytes, the description saying so
        let meta = common::npz_metadata(&npz_store.join(format!("{id}.npz")));
        let ear = if meta.get("ratemap_left").is_some() {
            "left"
        } else {
            "mono"
        };
        assert_eq!(meta[format!("ratemap_{ear}")]["dtype"], "float32", "{id}");
        assert_eq!(meta[format!("stft_{ear}")]["dtype"], "complex64", "{id}");
        for (array, dtype) in [("ratemap", "float32"), ("stft", "complex64")] {
            let folder = zarr_store.join(id).join(format!("{array}_{ear}"));
            let text = std::fs::read(folder.join("zarr.json")).expect("array metadata");
            let zarr: Value = serde_json::from_slice(&text).expect("json");
            assert_eq!(zarr["data_type"], dtype, "{id} {array}");
            assert_eq!(zarr["attributes"]["afe"]["dtype"], dtype, "{id} {array}");
        }
    }
    // a store keeps one type: float64 into it is refused, naming both
    let out = batch(&zarr_store, "zarr", "f64");
    assert!(!out.status.success());
    let err = stderr(&out);
    for needle in ["of float32 with", "of float64 with", "--overwrite"] {
        assert!(err.contains(needle), "'{needle}' not in: {err}");
    }
}

#[test]
fn failures_are_recorded_or_stop_the_run() {
    let tmp = TempDir::new("stop");
    let corpus = tmp.join("corpus");
    good_corpus(&corpus, 6);
    // a mono file cannot give an ILD
    let store = tmp.join("skip.zarr");
    let out = afe_ok(&[
        "batch",
        s(&corpus),
        "-r",
        "ratemap,ild",
        "-o",
        s(&store),
        "--progress",
        "none",
    ]);
    assert!(stderr(&out).contains("2 failed"), "{}", stderr(&out));
    let st = status(&store);
    let failed: Vec<&Value> = st["failed"].as_array().expect("failed").iter().collect();
    let ids: Vec<&str> = failed
        .iter()
        .map(|r| r["id"].as_str().expect("id"))
        .collect();
    assert_eq!(ids, ["spk1/session 0/utt04.wav", "top00.wav"]);
    for r in &failed {
        let e = r["error"].as_str().expect("error");
        assert!(e.contains("ild"), "{e}");
        assert!(e.contains("two"), "{e}");
    }
    assert_eq!(st["done"], 4);

    // longest first on one worker: the 1.5 s stereo file, then the 1.21 s mono one fails
    let store = tmp.join("stop.zarr");
    afe_err(
        &[
            "batch",
            s(&corpus),
            "-r",
            "ratemap,ild",
            "-o",
            s(&store),
            "-j",
            "1",
            "--on-error",
            "stop",
            "--progress",
            "none",
        ],
        &["stopped at 'spk1/session 0/utt04.wav'", "ild"],
    );
    let st = status(&store);
    assert_eq!(st["failed"].as_array().expect("failed").len(), 1, "{st}");
    assert_eq!(st["done"], 1, "{st}");
    assert_eq!(
        stored_ids(&store),
        BTreeSet::from(["top05.wav".to_string()])
    );
}

#[test]
fn a_manifest_names_the_files() {
    let tmp = TempDir::new("manifest");
    let corpus = tmp.join("corpus");
    let files = good_corpus(&corpus, 5);
    let manifest = corpus.join("list.tsv");
    let mut text = String::from("# id<TAB>path, relative to this file\n\n");
    let ids = [
        "alice/take 1",
        "alice/take2",
        "bob",
        "carol/x/y",
        "dave.flac",
    ];
    for (id, f) in ids.iter().zip(&files) {
        text.push_str(&format!("{id}\t{f}\n"));
    }
    std::fs::write(&manifest, &text).expect("write");
    let store = tmp.join("store.zarr");
    let params = ["-r", "ratemap", "-p", "fb_nChannels=8"];
    let mut args = vec!["batch", s(&manifest), "-o", s(&store), "--progress", "none"];
    args.extend(params);
    afe_ok(&args);
    assert_eq!(
        stored_ids(&store),
        ids.iter().map(|i| i.to_string()).collect::<BTreeSet<_>>()
    );
    let npz = tmp.join("x.npz");
    for (id, f) in ids.iter().zip(&files) {
        let want = sorted(extracted(&corpus.join(f), &params, &npz));
        assert_same(&stored(&store, id), &want, id);
    }

    let dup = corpus.join("dup.tsv");
    std::fs::write(
        &dup,
        format!("a\t{}\nb\t{}\na\t{}\n", files[0], files[1], files[2]),
    )
    .expect("write");
    let dup_store = tmp.join("dup.zarr");
    afe_err(
        &["batch", s(&dup), "-r", "ratemap", "-o", s(&dup_store)],
        &["two inputs have the id 'a'", &files[0], &files[2]],
    );
    assert!(!dup_store.exists());
    let no_tab = corpus.join("notab.tsv");
    std::fs::write(&no_tab, format!("a {}\n", files[0])).expect("write");
    afe_err(
        &["batch", s(&no_tab), "-r", "ratemap", "-o", s(&dup_store)],
        &["line 1", "id<TAB>path"],
    );
}

/// Spawns `afe` with `args`, its stdout piped (the `--progress jsonl` events) and its
/// stderr kept.
fn spawn(args: &[&str]) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_afe"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn afe")
}

/// Waits until `store` records a finished file, or panics if `child` ends first.
fn wait_for_first_record(child: &mut std::process::Child, store: &Path) {
    let start = Instant::now();
    while !ledger_records(store).iter().any(|r| r["status"] == "done") {
        if let Some(code) = child.try_wait().expect("try_wait") {
            panic!("the run ended ({code}) before any file was recorded");
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no file recorded in 60 s"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// The summary event of a finished `--progress jsonl` run, which must have succeeded.
fn summary_of(child: std::process::Child) -> Value {
    let out = child.wait_with_output().expect("wait");
    assert!(out.status.success(), "afe batch failed: {}", stderr(&out));
    let ev = events(&out);
    let last = ev.last().expect("events").clone();
    assert_eq!(last["event"], "summary", "{ev:?}");
    last
}

#[test]
fn two_unsharded_runs_share_one_store_and_an_overwrite_meanwhile_is_refused() {
    let tmp = TempDir::new("concurrent");
    let corpus = tmp.join("corpus");
    let ids = good_corpus(&corpus, 24);
    let store = tmp.join("store.zarr");
    let params = ["-r", "ratemap,ild,itd,ic", "-p", "fb_nChannels=16"];
    let mut args = vec!["batch", s(&corpus), "-o", s(&store)];
    args.extend(params);
    args.extend(["-j", "1", "--progress", "jsonl"]);
    // the second run starts while the first one is writing (it has recorded one file)
    let mut first = spawn(&args);
    wait_for_first_record(&mut first, &store);
    let second = spawn(&args);
    // an overwrite with other parameters while they write: refused, naming a run
    let line = afe_err(
        &[
            "batch",
            s(&corpus),
            "-r",
            "ratemap",
            "-o",
            s(&store),
            "--overwrite",
            "--progress",
            "none",
        ],
        &["another run is writing the store", "--overwrite"],
    );
    assert!(
        line.contains(&format!("pid {} on ", first.id()))
            || line.contains(&format!("pid {} on ", second.id())),
        "{line}"
    );
    let (a, b) = (summary_of(first), summary_of(second));
    // mono files cannot give an ILD: they fail in whichever run takes them
    let count = |v: &Value, key: &str| v[key].as_u64().expect(key);
    let failed = |v: &Value| v["failed"].as_array().expect("failed").len() as u64;
    for run in [&a, &b] {
        assert_eq!(count(run, "files"), ids.len() as u64, "{run}");
        assert_eq!(
            count(run, "done")
                + count(run, "done_elsewhere")
                + count(run, "already_done")
                + failed(run),
            ids.len() as u64,
            "{run}"
        );
    }
    // each good file computed by exactly one of them; the second run did share the work
    let mono = ids.len() as u64 - ids.len() as u64 / 4 * 3;
    assert_eq!(
        count(&a, "done") + count(&b, "done"),
        ids.len() as u64 - mono
    );
    assert!(count(&b, "already_done") < ids.len() as u64 - mono, "{b}");

    let st = status(&store);
    assert_eq!(st["done"], ids.len() as u64 - mono, "{st}");
    assert_eq!(st["missing"], serde_json::json!([]), "{st}");
    assert_eq!(
        st["params"]["fb_nChannels"], 16,
        "the overwrite touched the store"
    );
    // every file of the corpus holds what `afe extract` computes, or failed for its ILD
    let npz = tmp.join("x.npz");
    let failed_ids: BTreeSet<&str> = st["failed"]
        .as_array()
        .expect("failed")
        .iter()
        .map(|r| r["id"].as_str().expect("id"))
        .collect();
    for id in &ids {
        let wav = hound::WavReader::open(corpus.join(id)).expect("wav").spec();
        if wav.channels == 1 {
            assert!(failed_ids.contains(id.as_str()), "{id}");
            continue;
        }
        let want = sorted(extracted(&corpus.join(id), &params, &npz));
        assert_same(&stored(&store, id), &want, id);
    }
}

#[test]
fn status_and_resume_find_deleted_groups_arrays_and_chunks_and_skip_garbage_in_the_log() {
    let tmp = TempDir::new("damaged");
    let corpus = tmp.join("corpus");
    let ids = good_corpus(&corpus, 8);
    let store = tmp.join("store.zarr");
    let params = ["-r", REQUESTS, "-p", "fb_nChannels=8"];
    let mut args = vec!["batch", s(&corpus), "-o", s(&store)];
    args.extend(params);
    args.extend(["--progress", "jsonl"]);
    afe_ok(&args);
    let reference = tmp.join("reference.zarr");
    copy_dir(&store, &reference);

    // a whole group, one array, one chunk, and a chunk cut short
    let stereo: Vec<&String> = ids
        .iter()
        .filter(|id| store.join(id).join("ratemap_left").exists())
        .collect();
    let (group, array, chunk, cut) = (stereo[0], stereo[1], stereo[2], stereo[3]);
    std::fs::remove_dir_all(store.join(group)).expect("rm group");
    std::fs::remove_dir_all(store.join(array).join("ratemap_right")).expect("rm array");
    std::fs::remove_file(store.join(chunk).join("filterbank_left/c/0/0")).expect("rm chunk");
    let cut_chunk = store.join(cut).join("ratemap_left/c/0/0");
    let len = std::fs::metadata(&cut_chunk).expect("chunk").len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&cut_chunk)
        .expect("open")
        .set_len(len / 2)
        .expect("cut");
    // binary bytes in a log, between whole lines
    let log = std::fs::read_dir(store.join(".afe-batch"))
        .expect("logs")
        .map(|e| e.expect("entry").path())
        .find(|p| p.extension().is_some_and(|e| e == "jsonl"))
        .expect("a log");
    let mut bytes = std::fs::read(&log).expect("log");
    bytes.extend(b"\x00\xff\xfe{\"id\":\x80garbage\n");
    std::fs::write(&log, bytes).expect("write log");

    let st = status(&store);
    assert_eq!(st["done"], ids.len() - 4, "{st}");
    let missing = errors_of(&st, "missing");
    assert_eq!(
        missing.keys().collect::<BTreeSet<_>>(),
        BTreeSet::from([group, array, chunk, cut])
    );
    assert!(
        missing[group].contains("group metadata is missing"),
        "{missing:?}"
    );
    assert!(missing[array].contains("'ratemap_right'"), "{missing:?}");
    assert!(
        missing[chunk].contains("chunk [0, 0] is missing"),
        "{missing:?}"
    );
    assert!(
        missing[cut].contains(&format!("holds {} bytes", len / 2)),
        "{missing:?}"
    );
    let warnings = st["warnings"].as_array().expect("warnings");
    assert_eq!(warnings.len(), 1, "{st}");
    assert!(warnings[0]
        .as_str()
        .expect("text")
        .contains("skipped 1 line(s)"));
    let text = afe_ok(&["batch", "status", s(&store)]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(text.contains(", 0 failed, 4 missing"), "{text}");

    // the resume computes exactly those again, and the store equals the one before
    let ev = events(&afe_ok(&args));
    assert_eq!(ev[0]["already_done"], ids.len() - 4);
    let redone: BTreeSet<&str> = ev
        .iter()
        .filter(|e| e["event"] == "file")
        .map(|e| e["id"].as_str().expect("id"))
        .collect();
    assert_eq!(
        redone,
        BTreeSet::from([group, array, chunk, cut].map(String::as_str))
    );
    let summary = ev.last().expect("summary");
    assert_eq!(
        summary["incomplete"].as_array().expect("incomplete").len(),
        4
    );
    assert_same_stores(&store, &reference);
    let st = status(&store);
    assert_eq!(st["done"], ids.len());
    assert_eq!(st["missing"], serde_json::json!([]));
}

#[test]
fn a_store_that_cannot_be_written_stops_the_run_and_leaves_the_files_to_resume() {
    let tmp = TempDir::new("full");
    let corpus = tmp.join("corpus");
    let ids = good_corpus(&corpus, 12);
    let store = tmp.join("store.zarr");
    let params = ["-r", REQUESTS, "-p", "fb_nChannels=8"];
    let mut args = vec!["batch", s(&corpus), "-o", s(&store)];
    args.extend(params);
    args.extend(["-j", "1", "--progress", "none"]);
    // a file size limit of 64 blocks (32 or 64 KiB): writing a longer chunk fails with
    // EFBIG (SIGXFSZ ignored), as a full disk fails with ENOSPC
    let out = Command::new("sh")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 64 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_afe"))
        .args(&args)
        .output()
        .expect("run sh");
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let line = err
        .lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or_else(|| panic!("no error line in: {err}"));
    for needle in [
        "cannot write the store",
        "File too large",
        "run the same command again",
    ] {
        assert!(line.contains(needle), "'{needle}' not in: {line}");
    }
    // no file is recorded as failed, and what is recorded is whole
    let st = status(&store);
    assert_eq!(st["failed"], serde_json::json!([]), "{st}");
    assert_eq!(st["missing"], serde_json::json!([]), "{st}");
    let before = st["done"].as_u64().expect("done");
    assert!(before < ids.len() as u64, "{st}");

    let ev = events(&afe_ok(&{
        let mut a = args.clone();
        a.pop();
        a.push("jsonl");
        a
    }));
    assert_eq!(ev[0]["already_done"], before);
    let st = status(&store);
    assert_eq!(st["done"], ids.len(), "{st}");
    let npz = tmp.join("x.npz");
    for id in &ids {
        let want = sorted(extracted(&corpus.join(id), &params, &npz));
        assert_same(&stored(&store, id), &want, id);
    }
}

/// Issue 57, finding 8: ids of two manifests that nest (`p` and `p/q`) never share one
/// store, whichever comes first; and a store where they nest already (the ledger of one
/// lost, as when two runs start at once) never has the inner file deleted by the outer
/// one's redo.
#[test]
fn ids_that_nest_with_the_stores_are_refused_and_never_delete_a_finished_file() {
    let tmp = TempDir::new("nest");
    let corpus = tmp.join("corpus");
    let files = good_corpus(&corpus, 2);
    let outer = corpus.join("a.tsv");
    std::fs::write(&outer, format!("p\t{}\n", files[0])).expect("write");
    let inner = corpus.join("b.tsv");
    std::fs::write(&inner, format!("p/q\t{}\n", files[1])).expect("write");
    let run = |manifest: &Path, store: &Path| {
        vec![
            "batch".to_string(),
            s(manifest).to_string(),
            "-r".into(),
            "ratemap".into(),
            "-p".into(),
            "fb_nChannels=4".into(),
            "-o".into(),
            s(store).to_string(),
            "--progress".into(),
            "none".into(),
        ]
    };
    fn args(v: &[String]) -> Vec<&str> {
        v.iter().map(String::as_str).collect()
    }
    for (first, second, id, stored) in [(&outer, &inner, "p/q", "p"), (&inner, &outer, "p", "p/q")]
    {
        let store = tmp.join(&format!("first-{}.zarr", stored.replace('/', "-")));
        afe_ok(&args(&run(first, &store)));
        let before = stored_ids(&store);
        afe_err(
            &args(&run(second, &store)),
            &[
                &format!("file id '{id}' nests with '{stored}', which the store"),
                "redoing 'p' would delete 'p/q'",
                "give",
            ],
        );
        assert_eq!(stored_ids(&store), before);
    }
    // a store holding both (the inner one's record lost): the outer one's redo fails
    // with the reason and leaves the inner one whole
    let store = tmp.join("both.zarr");
    afe_ok(&args(&run(&inner, &store)));
    std::fs::remove_dir_all(store.join(".afe-batch")).expect("rm logs");
    let out = afe_ok(&args(&run(&outer, &store)));
    let err = stderr(&out) + &String::from_utf8_lossy(&out.stdout);
    assert!(
        err.contains("file id 'p' is also the folder of 'p/q'"),
        "{err}"
    );
    assert!(stored_ids(&store).contains("p/q"));
    let q = store.join("p/q/ratemap_left");
    assert!(q.join("zarr.json").is_file() && q.join("c/0/0").is_file());
}

/// Issue 57, minor: a FIFO or a device as an input is "not a regular file", and an id
/// with a part too long for a file name is refused before anything is written.
#[test]
fn a_device_or_fifo_input_and_an_overlong_id_are_refused_clearly() {
    let tmp = TempDir::new("messages");
    let store = tmp.join("s.zarr");
    let fifo = tmp.join("live");
    let made = Command::new("mkfifo").arg(&fifo).status();
    assert!(made.is_ok_and(|s| s.success()), "mkfifo");
    for input in [Path::new("/dev/null"), fifo.as_path()] {
        afe_err(
            &["batch", s(input), "-r", "ratemap", "-o", s(&store)],
            &[s(input), "not a regular file (a FIFO or a device)"],
        );
    }
    let files = good_corpus(&tmp.join("corpus"), 1);
    let manifest = tmp.join("corpus/long.tsv");
    std::fs::write(&manifest, format!("{}\t{}\n", "x".repeat(300), files[0])).expect("write");
    afe_err(
        &["batch", s(&manifest), "-r", "ratemap", "-o", s(&store)],
        &[
            "a part is 300 bytes long, more than the 200",
            "give a shorter id",
        ],
    );
    assert!(!store.exists());
}
