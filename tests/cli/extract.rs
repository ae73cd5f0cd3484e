//! What `afe extract` writes: the oracle's layout (whatever the chunking), parameters from
//! a file, float32 outputs, the memory the outputs need, and silence flushed to zero.

use crate::common;

use common::{afe, library_arrays, npz_arrays, npz_metadata, sorted, tmp, tone, write_wav};
use serde_json::json;

#[test]
fn extract_writes_the_oracle_layout_and_chunking_does_not_change_it() {
    let wav = tmp("tone.wav");
    write_wav(&wav, 2, 16000, 4000, tone);
    let whole = tmp("whole.npz");
    let out = afe(&[
        "extract",
        wav.to_str().expect("path"),
        "-r",
        "ratemap,ild,crosscorrelation",
        "-p",
        "fb_nChannels=8",
        "-o",
        whole.to_str().expect("path"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let arrays = npz_arrays(&whole);
    let names: Vec<&str> = arrays.iter().map(|a| a.0.as_str()).collect();
    assert_eq!(
        names,
        [
            "ratemap_left",
            "ratemap_right",
            "ild_mono",
            "crosscorrelation_mono"
        ]
    );
    // 4000 samples, W = 320, H = 160: 24 frames; 8 channels; ceil(1.1e-3·16000) = 18 → 37 lags
    assert_eq!(arrays[0].1, vec![24, 8]);
    assert_eq!(arrays[3].1, vec![24, 8, 37]);
    // each array's description is in the metadata entry
    let meta = npz_metadata(&whole);
    assert_eq!(meta.as_object().map(|m| m.len()), Some(names.len()));
    let cc = &meta["crosscorrelation_mono"];
    assert_eq!(cc["lags_s"].as_array().map(Vec::len), Some(37));
    assert_eq!(
        (&cc["window_s"], &cc["hop_s"]),
        (&json!(0.02), &json!(0.01))
    );
    assert_eq!(cc["parameters"]["fb_nChannels"], 8);
    assert_eq!(meta["ratemap_left"]["ear"], "left");
    // the values are the library's, bit for bit
    let library = library_arrays(
        &wav,
        &["ratemap", "ild", "crosscorrelation"],
        &[("fb_nChannels", json!(8))],
        false,
    );
    assert_eq!(sorted(arrays.clone()), library);

    let chunked = tmp("chunked.npz");
    let out = afe(&[
        "extract",
        wav.to_str().expect("path"),
        "-r",
        "ratemap,ild,crosscorrelation",
        "-p",
        "fb_nChannels=8",
        "--chunk",
        "77",
        "-o",
        chunked.to_str().expect("path"),
    ]);
    assert!(out.status.success());
    assert_eq!(npz_arrays(&chunked), arrays);

    let all = tmp("all.npz");
    let out = afe(&[
        "extract",
        wav.to_str().expect("path"),
        "-r",
        "ild",
        "--all",
        "-o",
        all.to_str().expect("path"),
    ]);
    assert!(out.status.success());
    let every = sorted(npz_arrays(&all));
    assert_eq!(every, library_arrays(&wav, &["ild"], &[], true));
    let names: Vec<String> = every.into_iter().map(|a| a.0).collect();
    for n in [
        "time_left",
        "filterbank_right",
        "innerhaircell_left",
        "ild_mono",
    ] {
        assert!(names.iter().any(|k| k == n), "{n} missing from {names:?}");
    }
}

#[test]
fn params_file_takes_oracle_style_json() {
    let wav = tmp("p.wav");
    write_wav(&wav, 2, 16000, 3200, tone);
    let params = tmp("params.json");
    std::fs::write(&params, r#"{"fb_nChannels": 16, "fb_lowFreqHz": 100, "fb_highFreqHz": 6000, "ihc_method": "halfwave", "rm_scaling": "magnitude"}"#).expect("write");
    let out_file = tmp("p.npz");
    let out = afe(&[
        "extract",
        wav.to_str().expect("path"),
        "-r",
        "ratemap",
        "--params",
        params.to_str().expect("path"),
        "-o",
        out_file.to_str().expect("path"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let arrays = npz_arrays(&out_file);
    assert_eq!(arrays[0].1, vec![19, 16]);
    let params = [
        ("fb_nChannels", json!(16)),
        ("fb_lowFreqHz", json!(100)),
        ("fb_highFreqHz", json!(6000)),
        ("ihc_method", json!("halfwave")),
        ("rm_scaling", json!("magnitude")),
    ];
    assert_eq!(
        sorted(arrays),
        library_arrays(&wav, &["ratemap"], &params, false)
    );
}

/// `--dtype f32` stores every value rounded to float32 (complex64 for the STFT), the
/// float64 run's values exactly so rounded, and each description says so.
#[test]
fn extract_dtype_f32_stores_the_rounded_values() {
    let dir = tmp("dtype-f32");
    std::fs::create_dir_all(&dir).expect("dir");
    let wav = dir.join("in.wav");
    write_wav(&wav, 2, 16000, 8000, tone);
    let run = |dtype: &str| {
        let out = dir.join(format!("{dtype}.npz"));
        let res = afe(&[
            "extract",
            wav.to_str().expect("utf-8"),
            "-r",
            "ratemap,ild,stft",
            "--dtype",
            dtype,
            "-o",
            out.to_str().expect("utf-8"),
        ]);
        assert!(
            res.status.success(),
            "{}",
            String::from_utf8_lossy(&res.stderr)
        );
        out
    };
    let (wide, narrow) = (run("f64"), run("f32"));
    let bytes = |p: &std::path::Path| std::fs::metadata(p).expect("size").len();
    assert!(bytes(&narrow) < bytes(&wide) * 6 / 10);
    let (a, b) = (npz_arrays(&wide), npz_arrays(&narrow));
    assert_eq!(a.len(), b.len());
    for ((ka, sa, va), (kb, sb, vb)) in a.iter().zip(&b) {
        assert_eq!((ka, sa), (kb, sb));
        let rounded: Vec<f64> = va.iter().map(|&v| f64::from(v as f32)).collect();
        assert_eq!(&rounded, vb, "{ka}");
    }
    let meta = npz_metadata(&narrow);
    assert_eq!(meta["ild_mono"]["dtype"], "float32");
    assert_eq!(meta["stft_left"]["dtype"], "complex64");
    assert_eq!(npz_metadata(&wide)["stft_left"]["dtype"], "complex128");
    std::fs::remove_dir_all(&dir).expect("clean");
}

/// Outputs that would take more than half of the memory available get a warning before
/// the work; more than all of it, a clear error and nothing written.
#[test]
fn extract_announces_outputs_too_large_for_the_memory() {
    let dir = tmp("memory-check");
    std::fs::create_dir_all(&dir).expect("dir");
    let wav = dir.join("in.wav");
    write_wav(&wav, 2, 16000, 16000, tone);
    let out = dir.join("out.npz");
    let run = |available: &str| {
        common::afe_env(
            &[
                "extract",
                wav.to_str().expect("utf-8"),
                "-r",
                "ratemap",
                "-o",
                out.to_str().expect("utf-8"),
            ],
            &[("AFE_MEMORY_AVAILABLE_GB", std::path::Path::new(available))],
        )
    };
    let warned = run("0.00008");
    let stderr = String::from_utf8_lossy(&warned.stderr);
    assert!(warned.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning: the outputs will take 49.6 kB, more than half of the 80.0 kB of memory available: store them as float32"),
        "{stderr}"
    );
    std::fs::remove_file(&out).expect("written");
    let refused = run("0.00004");
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success());
    assert!(
        stderr.contains("keeping the outputs would take 49.6 kB, more than the 40.0 kB of memory available: store them as float32 (`dtype=\"float32\"`, `--dtype f32`), ask for fewer requests"),
        "{stderr}"
    );
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).expect("clean");
}

/// A tone, then 0.9 s of digital silence: the filterbank's decay stops at 0 instead of
/// running through the subnormals (see `afe_core::denormals`), unless
/// `AFE_KEEP_SUBNORMALS=1` asks for the IEEE arithmetic of the AFE; both on two threads.
#[test]
fn silence_is_flushed_to_zero_unless_subnormals_are_kept() {
    let dir = tmp("subnormals");
    std::fs::create_dir_all(&dir).expect("dir");
    let wav = dir.join("in.wav");
    write_wav(
        &wav,
        2,
        16000,
        16000,
        |i| if i < 3200 { tone(i) } else { 0.0 },
    );
    let subnormals = |keep: &str| {
        let out = dir.join(format!("keep-{keep}.npz"));
        let run = common::afe_env(
            &[
                "extract",
                wav.to_str().expect("utf-8"),
                "-r",
                "filterbank",
                "--threads",
                "2",
                "-o",
                out.to_str().expect("utf-8"),
            ],
            &[("AFE_KEEP_SUBNORMALS", std::path::Path::new(keep))],
        );
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        npz_arrays(&out)
            .iter()
            .map(|(_, _, data)| data.iter().filter(|v| v.is_subnormal()).count())
            .sum::<usize>()
    };
    assert_eq!(subnormals("0"), 0);
    assert!(subnormals("1") > 1000);
    std::fs::remove_dir_all(&dir).expect("clean");
}
