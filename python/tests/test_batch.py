"""Corpus extraction from Python: afe.batch (Rust engine or any executor, Dask
included) and afe.open_store, checked against `afe extract` and zarr-python."""
import os
import subprocess
import wave
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import afe

REQUESTS = ["ratemap", "ild"]


def _write_wav(path, x, fs):
    """16-bit PCM WAV of x ([samples] or [samples, channels], full scale 1.0)."""
    x = np.atleast_2d(np.asarray(x).T).T
    pcm = np.clip(np.round(x * 32767), -32768, 32767).astype("<i2")
    with wave.open(str(path), "wb") as w:
        w.setnchannels(x.shape[1])
        w.setsampwidth(2)
        w.setframerate(fs)
        w.writeframes(pcm.tobytes())


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    """12 binaural files of mixed lengths and rates in two folders, one mono file and
    two corrupt ones."""
    root = tmp_path_factory.mktemp("corpus")
    rng = np.random.default_rng(7)
    good = []
    for k in range(12):
        fs = (16000, 22050, 44100)[k % 3]
        n = int(fs * (0.1 + 0.07 * k))
        t = np.arange(n) / fs
        left = 0.3 * np.sin(2 * np.pi * (300 + 50 * k) * t) + 0.05 * rng.standard_normal(n)
        right = 0.5 * np.roll(left, k + 1)
        folder = root / ("spk1" if k % 2 else "spk2")
        folder.mkdir(exist_ok=True)
        _write_wav(folder / f"utt{k:02d}.wav", np.column_stack([left, right]), fs)
        good.append(f"{folder.name}/utt{k:02d}.wav")
    _write_wav(root / "mono.wav", 0.1 * rng.standard_normal(8000), 16000)
    (root / "text.wav").write_text("not audio")
    with open(root / "spk2" / "utt00.wav", "rb") as f:
        head = f.read(30)
    (root / "cut.wav").write_bytes(head)
    return root, sorted(good)


def _extract(cli, wav, out):
    subprocess.run(
        [cli, "extract", str(wav), "-r", ",".join(REQUESTS), "-o", str(out)],
        check=True,
        capture_output=True,
    )
    with np.load(out) as z:
        return {k: z[k] for k in z.files if k != "afe_metadata"}


def _same_store(a, b):
    assert a.ids() == b.ids()
    for fid in a:
        x, y = a[fid], b[fid]
        assert sorted(x) == sorted(y), fid
        for k in x:
            assert np.array_equal(x[k], y[k]), (fid, k)


def test_store_equals_extract_and_opens_in_zarr_python(corpus, cli, tmp_path):
    root, good = corpus
    summary = afe.batch(root, REQUESTS, out=tmp_path / "s.zarr", jobs=2, progress="none")
    assert summary["done"] == len(good)
    failed = {f["id"]: f["error"] for f in summary["failed"]}
    assert set(failed) == {"mono.wav", "text.wav", "cut.wav"}
    assert "binaural" in failed["mono.wav"]
    assert "WAV" in failed["text.wav"]
    store = afe.open_store(tmp_path / "s.zarr")
    assert store.ids() == good
    assert store.failed.keys() == failed.keys()
    zarr = pytest.importorskip("zarr")
    group = zarr.open_group(str(tmp_path / "s.zarr"), mode="r")
    assert group.attrs["afe"]["param_hash"] == store.param_hash
    assert group.attrs["afe"]["requests"] == REQUESTS
    for k, fid in enumerate(good[:4]):
        ref = _extract(cli, root / fid, tmp_path / f"ref{k}.npz")
        mine = store[fid]
        assert sorted(mine) == sorted(ref) == ["ild_mono", "ratemap_left", "ratemap_right"]
        for name, value in ref.items():
            assert np.array_equal(mine[name], value), (fid, name)
            assert np.array_equal(group[fid][name][:], value), (fid, name)
    info = store.info(good[0])["ratemap_left"]
    assert info["kind"] == "time-frequency" and info["fs_hz"] == 100.0
    assert len(info["cf_hz"]) == store[good[0]]["ratemap_left"].shape[1]
    # the same call again resumes: nothing left to do but the files that failed
    again = afe.batch(root, REQUESTS, out=tmp_path / "s.zarr", progress="none")
    assert (again["already_done"], again["done"], len(again["failed"])) == (len(good), 0, 3)


def test_an_executor_fills_the_same_store(corpus, tmp_path):
    root, _ = corpus
    afe.batch(root, REQUESTS, out=tmp_path / "rust.zarr", progress="none")
    with ThreadPoolExecutor(2) as ex:
        summary = afe.batch([root], ",".join(REQUESTS), out=tmp_path / "ex.zarr", executor=ex, progress="none")
    assert len(summary["failed"]) == 3
    _same_store(afe.open_store(tmp_path / "rust.zarr"), afe.open_store(tmp_path / "ex.zarr"))


def test_two_executor_runs_at_once_share_the_store_and_a_deleted_chunk_is_redone(corpus, tmp_path):
    root, good = corpus
    afe.batch(root, REQUESTS, out=tmp_path / "rust.zarr", progress="none")
    out = tmp_path / "shared.zarr"

    def one_run():
        with ThreadPoolExecutor(2) as ex:
            return afe.batch(root, REQUESTS, out=out, executor=ex, progress="none")

    # two distributed runs over one store at once: each file claimed by one task at a
    # time, a file done by the other run is not computed again
    with ThreadPoolExecutor(2) as runs:
        summaries = [f.result() for f in [runs.submit(one_run) for _ in range(2)]]
    for s in summaries:
        assert s["done"] + s["done_elsewhere"] + s["already_done"] + len(s["failed"]) == len(good) + 3
    assert sum(s["done"] for s in summaries) == len(good)
    store = afe.open_store(out)
    assert store.ids() == good and store.missing == {}
    _same_store(afe.open_store(tmp_path / "rust.zarr"), store)

    # a chunk deleted behind the store's back: reported, refused on reading, redone
    os.remove(out / good[0] / "ratemap_left" / "c" / "0" / "0")
    store = afe.open_store(out)
    assert good[0] not in store
    assert "chunk [0, 0] is missing" in store.missing[good[0]]
    with pytest.raises(KeyError, match="recorded as done, but array 'ratemap_left'"):
        store[good[0]]
    with ThreadPoolExecutor(2) as ex:
        again = afe.batch(root, REQUESTS, out=out, executor=ex, progress="none")
    assert (again["already_done"], again["done"]) == (len(good) - 1, 1)
    _same_store(afe.open_store(tmp_path / "rust.zarr"), afe.open_store(out))


def test_dask_local_cluster_fills_the_same_store(corpus, tmp_path):
    distributed = pytest.importorskip("distributed", reason="install afe[dask] to run Dask batches")
    root, good = corpus
    afe.batch(root, REQUESTS, out=tmp_path / "rust.zarr", progress="none")
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
    ) as cluster, distributed.Client(cluster) as client:
        summary = afe.batch(root, REQUESTS, out=tmp_path / "dask.zarr", executor=client.get_executor(), progress="none")
    assert summary["done"] == len(good)
    _same_store(afe.open_store(tmp_path / "rust.zarr"), afe.open_store(tmp_path / "dask.zarr"))


def test_shards_together_equal_one_run(corpus, tmp_path):
    root, good = corpus
    afe.batch(root, REQUESTS, out=tmp_path / "one.zarr", progress="none")
    parts = [afe.batch(root, REQUESTS, out=tmp_path / "two.zarr", shard=(i, 2), progress="none") for i in range(2)]
    assert sum(p["done"] for p in parts) == len(good)
    assert all(p["done"] > 0 for p in parts)
    _same_store(afe.open_store(tmp_path / "one.zarr"), afe.open_store(tmp_path / "two.zarr"))
    with pytest.raises(ValueError, match="shard 2/2"):
        afe.batch(root, REQUESTS, out=tmp_path / "bad.zarr", shard=(2, 2))


def test_other_parameters_are_refused_unless_overwrite(corpus, tmp_path):
    root, good = corpus
    out = tmp_path / "s.zarr"
    afe.batch(root / "spk1", ["ratemap"], out=out, progress="none")
    with pytest.raises(ValueError, match="fb_nChannels"):
        afe.batch(root / "spk1", ["ratemap"], {"fb_nChannels": 16}, out=out, progress="none")
    afe.batch(root / "spk1", ["ratemap"], {"fb_nChannels": 16}, out=out, overwrite=True, progress="none")
    store = afe.open_store(out)
    assert store.params == {"fb_nChannels": 16}
    assert store[store.ids()[0]]["ratemap_left"].shape[1] == 16


def test_npz_store_and_errors(corpus, cli, tmp_path):
    root, good = corpus
    afe.batch(root / "spk2", REQUESTS, out=tmp_path / "n", format="npz", progress="none")
    store = afe.open_store(tmp_path / "n")
    fid = store.ids()[0]
    ref = _extract(cli, root / "spk2" / fid, tmp_path / "ref.npz")
    assert all(np.array_equal(store[fid][k], v) for k, v in ref.items())
    assert store[fid]["ild_mono"].parameters == store.info(fid)["ild_mono"]["parameters"]
    with pytest.raises(KeyError, match="no file"):
        store["missing.wav"]
    with pytest.raises(RuntimeError, match="stopped at"):
        afe.batch(root, REQUESTS, out=tmp_path / "stop.zarr", on_error="stop", jobs=1, progress="none")
    with pytest.raises(ValueError, match="unknown request"):
        afe.batch(root, ["ratemapp"], out=tmp_path / "x.zarr")
    with pytest.raises(ValueError, match="no such file"):
        afe.batch(tmp_path / "nowhere", REQUESTS, out=tmp_path / "y.zarr")
    with pytest.raises(ValueError, match="not an afe store"):
        afe.open_store(root)


def test_float32_stores_hold_the_float64_values_rounded(corpus, tmp_path):
    root, _ = corpus
    folder = root / "spk1"
    requests = ["ratemap", "stft"]  # the STFT is complex: complex64
    afe.batch(folder, requests, out=tmp_path / "wide.zarr", progress="none")
    wide = afe.open_store(tmp_path / "wide.zarr")
    for fmt, out in (("zarr", tmp_path / "narrow.zarr"), ("npz", tmp_path / "narrow-npz")):
        afe.batch(folder, requests, out=out, format=fmt, dtype="float32", progress="none")
        narrow = afe.open_store(out)
        assert narrow.dtype == "float32" and wide.dtype == "float64"
        assert narrow.ids() == wide.ids()
        for fid in narrow:
            a, b = narrow[fid], wide[fid]
            for k in b:
                want = np.complex64 if np.iscomplexobj(b[k]) else np.float32
                assert a[k].dtype == want, (fmt, fid, k)
                assert np.array_equal(a[k], b[k].astype(want)), (fmt, fid, k)
                assert a[k].meta["dtype"] == np.dtype(want).name
    # zarr-python reads the float32 arrays as they are stored
    zarr = pytest.importorskip("zarr")
    group = zarr.open_group(str(tmp_path / "narrow.zarr"), mode="r")
    fid = wide.ids()[0]
    assert group[fid]["ratemap_left"].dtype == np.float32
    assert group[fid]["stft_left"].dtype == np.complex64
    # a store keeps one type
    with pytest.raises(ValueError, match="as zarr of float32 with"):
        afe.batch(folder, requests, out=tmp_path / "narrow.zarr", progress="none")
    with pytest.raises(ValueError, match='dtype = "f32"'):
        afe.batch(folder, requests, out=tmp_path / "bad.zarr", dtype="f32")
