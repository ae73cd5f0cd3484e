//! Helpers shared by the command-line tests: run the `afe` binary, make inputs, read its
//! `.npz` outputs, check error lines.
// Each test binary uses its own subset of these helpers.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use afe::npy::{decode, decode_text, METADATA_ENTRY};
use afe::{Manager, ParamMap, Recorder};

/// Runs `afe` with `args`.
pub fn afe(args: &[&str]) -> Output {
    afe_env(args, &[])
}

/// Runs `afe` with `args` and extra environment variables.
pub fn afe_env(args: &[&str], env: &[(&str, &Path)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_afe"));
    cmd.args(args);
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("run afe")
}

/// A path in this test process's own temporary folder, under Cargo's `target/tmp`. The
/// folders of test processes that have ended go as the next process makes its own, so
/// that runs do not pile up their inputs (a run writes hundreds of megabytes).
pub fn tmp(name: &str) -> PathBuf {
    static OWN: std::sync::Once = std::sync::Once::new();
    let root = Path::new(env!("CARGO_TARGET_TMPDIR"));
    OWN.call_once(|| remove_ended(root, "afe-tests-"));
    let dir = root.join(format!("afe-tests-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir.join(name)
}

/// Removes the folders `<prefix><pid>` in `root` of processes that no longer run (where
/// `/proc` tells).
pub fn remove_ended(root: &Path, prefix: &str) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(root) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let pid = name
            .to_str()
            .and_then(|n| n.strip_prefix(prefix)?.parse::<u32>().ok());
        if let Some(pid) = pid {
            if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
                // another process may be removing it too
                let _ = std::fs::remove_dir_all(entry.path());
            }
        }
    }
}

/// Writes a 32-bit float WAV whose interleaved sample `i` is `value(i)`.
pub fn write_wav(path: &Path, channels: u16, fs: u32, frames: usize, value: impl Fn(usize) -> f32) {
    let spec = hound::WavSpec {
        channels,
        sample_rate: fs,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(path, spec).expect("create wav");
    for i in 0..frames * usize::from(channels) {
        w.write_sample(value(i)).expect("write");
    }
    w.finalize().expect("finalize");
}

/// A slow sinusoid of interleaved sample index `i`, peak 0.3.
pub fn tone(i: usize) -> f32 {
    (0.05 * i as f32).sin() * 0.3
}

/// The entries of an `.npz`: (name without `.npy`, bytes), in archive order.
fn npz_entries(path: &Path) -> Vec<(String, Vec<u8>)> {
    let file = std::fs::File::open(path).expect("npz");
    let mut zip = zip::ZipArchive::new(file).expect("zip");
    (0..zip.len())
        .map(|i| {
            let mut entry = zip.by_index(i).expect("entry");
            let name = entry.name().trim_end_matches(".npy").to_string();
            let mut bytes = Vec::new();
            std::io::Read::read_to_end(&mut entry, &mut bytes).expect("read");
            (name, bytes)
        })
        .collect()
}

/// The arrays of an `.npz` written by afe: (name, shape, values), in archive order
/// (its metadata entry left out: see [`npz_metadata`]).
pub fn npz_arrays(path: &Path) -> Vec<(String, Vec<usize>, Vec<f64>)> {
    npz_entries(path)
        .into_iter()
        .filter(|(name, _)| name != METADATA_ENTRY)
        .map(|(name, bytes)| {
            let a = decode(&bytes).expect("npy");
            (name, a.shape, a.data)
        })
        .collect()
}

/// The descriptions in an afe `.npz`'s metadata entry, keyed by array name.
pub fn npz_metadata(path: &Path) -> serde_json::Value {
    let (_, bytes) = npz_entries(path)
        .into_iter()
        .find(|(name, _)| name == METADATA_ENTRY)
        .expect("afe_metadata entry");
    serde_json::from_str(&decode_text(&bytes).expect("text")).expect("json")
}

/// What the library computes on the WAV at `path` for `requests` with `params` (AFE name
/// → JSON value), in one `process_signal`: (name, shape, values) of every requested
/// output, or of every signal with `all`, sorted by name.
pub fn library_arrays(
    path: &Path,
    requests: &[&str],
    params: &[(&str, serde_json::Value)],
    all: bool,
) -> Vec<(String, Vec<usize>, Vec<f64>)> {
    let audio = afe::wav::read_wav(path).expect("wav");
    let mut mgr = Manager::new(audio.fs, audio.channels.len()).expect("manager");
    let params: ParamMap = params
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect();
    for r in requests {
        mgr.add_request(r, &params).expect("request");
    }
    let ears: Vec<&[f64]> = audio.channels.iter().map(Vec::as_slice).collect();
    mgr.set_keep_all(all);
    mgr.process_signal(&ears).expect("process");
    let mut rec = Recorder::new(all);
    rec.record(&mgr);
    sorted(
        rec.signals()
            .iter()
            .map(|s| (s.key.clone(), s.shape(), s.data.as_slice().to_vec()))
            .collect(),
    )
}

/// `arrays` sorted by name.
pub fn sorted(
    mut arrays: Vec<(String, Vec<usize>, Vec<f64>)>,
) -> Vec<(String, Vec<usize>, Vec<f64>)> {
    arrays.sort_by(|a, b| a.0.cmp(&b.0));
    arrays
}

/// `out` failed with one `error:` line containing `needle`, no panic, and no output file.
pub fn assert_clear_error(out: &Output, needle: &str, output_file: &Path) {
    assert!(!out.status.success(), "should fail: {needle}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        err.trim().lines().count(),
        1,
        "one line expected, got: {err}"
    );
    assert!(err.starts_with("error: "), "{err}");
    assert!(err.contains(needle), "'{needle}' not in: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!output_file.exists(), "no output file on error");
}

/// Runs `afe args...` under `ulimit -v` of `limit_kb` (none: unlimited) with `env`, the
/// memory setting removed unless given.
pub fn afe_under_ulimit(
    limit_kb: Option<u64>,
    args: &[&str],
    env: &[(&str, &str)],
) -> std::process::Output {
    let quoted: Vec<String> = args.iter().map(|a| format!("'{a}'")).collect();
    let limit = limit_kb.map_or(String::new(), |kb| format!("ulimit -v {kb} && "));
    let script = format!(
        "{limit}exec '{}' {}",
        env!("CARGO_BIN_EXE_afe"),
        quoted.join(" ")
    );
    let mut cmd = std::process::Command::new("sh");
    cmd.args(["-c", &script])
        .env_remove("AFE_MEMORY_AVAILABLE_GB")
        .env_remove("AFE_WHOLE_SIGNAL_LIMIT_MB")
        .env("RUST_BACKTRACE", "0");
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("run sh")
}
