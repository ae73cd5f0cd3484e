//! What a store holds: exactly what `afe extract` computes for each file of the corpus
//! (its failures recorded), in zarr and npz, float32 rounded, and the files a manifest names.

use crate::common;

use std::collections::BTreeSet;
use std::path::Path;

use common::{afe, npz_arrays};
use serde_json::Value;

use super::{
    afe_err, afe_ok, assert_same, errors_of, extracted, good_corpus, s, sorted, status, stderr,
    stored, stored_ids, write_signal, Arrays, Kind, TempDir, REQUESTS,
};

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
