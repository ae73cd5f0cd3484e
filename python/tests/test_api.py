"""The Python API: catalogue, WAV reading, streaming, run-time edits, errors."""
import json
import os
import pickle
import subprocess
import sys
import threading
import time
import warnings
import wave

import numpy as np
import pytest

import afe
from conftest import under_address_limit


def signal(n=8000, fs=16000):
    rng = np.random.default_rng(1)
    t = np.arange(n) / fs
    left = 0.3 * np.sin(2 * np.pi * 440 * t) + 0.05 * rng.standard_normal(n)
    right = np.concatenate([np.zeros(6), left[:-6]]) * 0.5
    return np.column_stack([left, right])


def test_catalogue_matches_the_afe_names():
    afe_names = {"time", "filterbank", "innerhaircell", "adaptation", "amsFeatures", "ratemap",
                 "ild", "crosscorrelation", "itd", "ic", "autocorrelation", "pitch",
                 "onsetStrength", "offsetStrength", "onsetMap", "offsetMap",
                 "spectralFeatures", "gabor", "stft", "moc", "precedence", "duet"}
    assert afe_names <= set(afe.requests())
    assert afe.requests()[:3] == ["time", "butterworth", "filterbank"]  # dependencies first
    names = {p["name"]: p for p in afe.parameters("ratemap")}
    assert names["rm_wSizeSec"]["default"] == 0.02 and names["rm_wSizeSec"]["unit"] == "s"
    assert names["ihc_method"]["default"] == "dau"
    assert names["fb_nChannels"]["processor"] == "filterbank"
    assert "ild_wSizeSec" not in names
    assert len(afe.parameters()) > len(afe.parameters("ratemap"))
    with pytest.raises(ValueError, match="'nope' is neither a request nor a parameter"):
        afe.parameters("nope")
    # one parameter by its name, with a hint for a typo
    (one,) = afe.parameters("fb_nChannels")
    assert one["processor"] == "filterbank" and one["type"] == "integer" and "channels" in one["description"]
    with pytest.raises(ValueError, match="did you mean 'fb_nChannels'"):
        afe.parameters("fb_nchannels")


def test_dir_shows_the_public_api_only():
    assert dir(afe) == sorted(
        ["Audio", "AudioBlock", "Frames", "Manager", "Remote", "RemoteError", "Signal", "Store", "Subscription", "batch", "connect",
         "heads", "host", "load", "locate", "open_store", "parameters", "plot", "process", "raa", "read_wav", "render", "requests",
         "save", "stream", "summary", "transfer", "__version__"]
    )


def test_the_package_type_checks_and_the_extension_matches_its_stub(tmp_path):
    # the package's annotations (py.typed) and afe/_afe.pyi, which types the extension:
    # mypy reads both, stubtest holds the stub to the compiled module's own signatures.
    # The optional dependencies whose types the package uses must be there to be read.
    pytest.importorskip("mypy")
    pytest.importorskip("matplotlib")
    pytest.importorskip("zenoh")
    # from a folder of their own, so that the installed package is the one checked, and
    # with a fresh cache (a cache from before a new module of the package can hide it)
    commands = [
        [sys.executable, "-m", "mypy", "--cache-dir", str(tmp_path / "cache"), "-p", "afe"],
        [sys.executable, "-m", "mypy.stubtest", "afe._afe"],
    ]
    failed = []
    for command in commands:
        run = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, timeout=600)
        if run.returncode != 0:
            failed.append(f"python {' '.join(command[1:])}:\n{run.stdout}{run.stderr}")
    assert not failed, "\n".join(failed)


def test_host_names_the_machine_a_timing_comes_from():
    h = afe.host()
    assert set(h) == {"cpu", "cores", "simd", "avx512_available", "version", "core_to_core_ns"}
    assert h["cpu"] and h["cores"] >= 1 and h["version"] == afe.__version__
    assert h["simd"] in ("avx512", "avx2", "baseline")
    if h["simd"] == "avx512":
        assert h["avx512_available"]
    assert h["core_to_core_ns"] is None or h["core_to_core_ns"] > 0


def test_a_top_channel_at_nyquist_is_accepted_as_in_the_afe():
    """AFE scripts write fb_highFreqHz = fs/2; the ERB round trip puts the top channel at
    22050.000000000004 Hz, which is accepted; beyond Nyquist is refused in the user's numbers."""
    x = signal(4410, 44100)
    out = afe.process(x, 44100, "filterbank", {"fb_highFreqHz": 22050, "fb_nChannels": 16})
    assert np.isfinite(out["filterbank_left"]).all()
    with pytest.raises(ValueError, match="fb_highFreqHz"):
        afe.process(x, 44100, "filterbank", {"fb_highFreqHz": 22100, "fb_nChannels": 16})


def test_matlab_shaped_parameters_are_scalars_and_vectors():
    """scipy.io.loadmat gives 1×N, N×1 and 1×1 matrices: taken as the AFE takes them."""
    x = signal(1600)
    flat = afe.process(x, 16000, "ratemap", {"fb_cfHz": [200, 1000, 4000], "rm_wSizeSec": 0.02})
    for cf in (np.array([[200, 1000, 4000]]), np.array([[200], [1000], [4000]])):
        out = afe.process(x, 16000, "ratemap", {"fb_cfHz": cf, "rm_wSizeSec": np.array([[0.02]])})
        np.testing.assert_array_equal(out["ratemap_left"], flat["ratemap_left"])
    with pytest.raises(ValueError, match="fb_cfHz"):
        afe.process(x, 16000, "ratemap", {"fb_cfHz": np.ones((2, 2)) * 500})


def test_read_wav_mono_and_stereo(tmp_path, example_wav):
    x, fs = afe.read_wav(example_wav)
    assert x.shape == (44100, 2) and fs == 44100.0 and x.dtype == np.float64
    mono = tmp_path / "mono.wav"
    with wave.open(str(mono), "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(8000)
        w.writeframes(np.array([0, 16384, -32768], dtype="<i2").tobytes())
    y, fs = afe.read_wav(mono)
    assert fs == 8000.0 and y.tolist() == [0.0, 0.5, -1.0]


def test_a_file_is_processed_as_its_samples_are(tmp_path, example_wav):
    """A path is decoded block by block in Rust; the arrays equal those of the decoded
    samples, for a chunk-invariant graph, one that runs past the AGC's seed, one that
    needs a whole call, and in chunks; a file's own errors name it."""
    x, fs = afe.read_wav(example_wav)
    for requests, params, chunk in [
        (["ratemap", "ild"], None, None),
        (["ratemap"], {"pp_bNormalizeRMS": True, "pp_intTimeSecRMS": 0.2}, None),
        (["pitch", "onsetMap"], None, None),
        (["itd"], None, 1000),
    ]:
        from_file = afe.process(example_wav, None, requests, params, chunk=chunk)
        from_array = afe.process(x, fs, requests, params, chunk=chunk)
        assert from_file.keys() == from_array.keys()
        for k in from_file:
            np.testing.assert_array_equal(from_file[k], from_array[k], err_msg=k)
            assert from_file[k].meta == from_array[k].meta
    with pytest.raises(ValueError, match="is sampled at 44100 Hz"):
        afe.process(example_wav, 16000, ["ratemap"])
    three = tmp_path / "three.wav"
    with wave.open(str(three), "wb") as w:
        w.setnchannels(3)
        w.setsampwidth(2)
        w.setframerate(8000)
        w.writeframes(np.zeros(30, dtype="<i2").tobytes())
    with pytest.raises(ValueError, match="3 channels"):
        afe.process(three, None, ["ratemap"])
    bad = tmp_path / "bad.wav"
    bad.write_bytes(b"RIFF not really")
    with pytest.raises(ValueError, match="as WAV"):
        afe.process(bad, None, ["ratemap"])


def test_a_whole_call_too_large_is_a_memory_error_naming_the_way_out():
    """The Hilbert IHC transforms the whole signal at once (as in the AFE): past the
    limit (here 4 MB: the joined filterbank and IHC output, 2 × 2 × 32 channels of
    float64, take 1 kB per sample, so 0.25 s at 16 kHz) the call is refused before
    anything is computed; a shorter signal runs."""
    script = (
        "import numpy as np, afe\n"
        "x = np.zeros((16000 * 3, 2))\n"
        "try:\n"
        "    afe.process(x, 16000, ['ratemap'], {'ihc_method': 'hilbert'})\n"
        "except MemoryError as e:\n"
        "    print(e)\n"
        "print(afe.process(x[:2000], 16000, ['ratemap'], {'ihc_method': 'hilbert'})['ratemap_left'].shape[0])\n"
    )
    env = dict(os.environ, AFE_WHOLE_SIGNAL_LIMIT_MB="4")
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
    message, frames = out.stdout.strip().splitlines()
    assert "innerhaircell" in message and "limit of 4 MB" in message and "chunk" in message
    assert int(frames) == 11  # floor((2000 - 320) / 160) + 1: 20-ms windows every 10 ms


def test_a_prepared_manager_gives_the_same_numbers_and_prepares_only_before_the_stream():
    x = signal(3200)
    plain = afe.Manager(16000, 2)
    prepared = afe.Manager(16000, 2, threads=2)
    for m in (plain, prepared):
        m.add_request("ild")
    prepared.prepare(160)
    for start in range(0, 3200, 160):
        a = plain.process_chunk(x[start : start + 160])
        b = prepared.process_chunk(x[start : start + 160])
        np.testing.assert_array_equal(a["ild_mono"], b["ild_mono"])
    with pytest.raises(ValueError, match="before the first chunk"):
        prepared.prepare(160)
    prepared.reset()
    prepared.prepare(160)
    with pytest.raises(ValueError, match="largest chunk"):
        prepared.prepare(0)


def test_chunked_stream_equals_whole_signal():
    x = signal()
    whole = afe.process(x, 16000, ["ratemap", "ild", "itd", "ic"])
    for threads in (None, 2):
        m = afe.Manager(16000, 2, threads=threads)
        for r in ["ratemap", "ild", "itd", "ic"]:
            m.add_request(r)
        parts = {}
        start = 0
        for n in [1, 100, 17, 441, 3000, 999, 160] * 3:
            out = m.process_chunk(x[start : start + n])
            for k, v in out.items():
                parts.setdefault(k, []).append(v)
            start += n
        out = m.process_chunk(x[start:])
        for k, v in out.items():
            parts[k].append(v)
        for k in whole:
            np.testing.assert_array_equal(np.concatenate(parts[k]), whole[k], err_msg=k)
            np.testing.assert_array_equal(m.outputs()[k], whole[k], err_msg=k)
    assert afe.process(x, 16000, "ild", chunk=333)["ild_mono"].tolist() == whole["ild_mono"].tolist()


def test_silence_leaves_no_subnormal_and_numpy_keeps_its_arithmetic():
    """A tone, then digital silence: afe flushes the filters' decay to zero below
    2.2e-308 while it computes (so a silent stretch costs no more than sound), on the
    caller's thread and the workers, and gives the thread back its IEEE arithmetic."""
    if os.environ.get("AFE_KEEP_SUBNORMALS", "0") not in ("", "0"):
        pytest.skip("AFE_KEEP_SUBNORMALS is set: subnormals are kept on purpose")
    x = signal()
    x[1600:] = 0.0
    tiny = np.float64(np.finfo(np.float64).tiny)
    for threads in (None, 2):
        out = afe.process(x, 16000, ["filterbank", "ratemap"], threads=threads)
        for k, v in out.items():
            assert not np.any((v != 0) & (np.abs(v) < tiny)), k
        m = afe.Manager(16000, 2, threads=threads)
        m.add_request("filterbank")
        m.process_chunk(x)
        assert tiny / 2 > 0, "numpy's subnormal results after a call (FTZ restored)"
        assert np.float64(5e-324) * 2 > 0, "numpy's subnormal inputs after a call (DAZ restored)"


def test_metadata_and_layouts():
    m = afe.Manager(16000, 2)
    m.add_request("crosscorrelation", {"fb_nChannels": 8})
    out = m.process_signal(signal(3200))
    assert out["crosscorrelation_mono"].shape == (19, 8, 37)
    info = m.info()["crosscorrelation_mono"]
    assert info["fs_hz"] == 100.0 and len(info["cf_hz"]) == 8 and len(info["lags_s"]) == 37
    assert info["lags_s"][0] == pytest.approx(-18 / 16000)


def test_every_signal_class_reaches_numpy_with_its_description(cli, tmp_path):
    """Spectra are complex128, features carry their names, modulation spectra their
    modulation frequencies, maps are 0/1; the CLI's .npz holds the same arrays."""
    reqs = ["stft", "pitch", "amsFeatures", "spectralFeatures", "onsetMap", "adaptation"]
    m = afe.Manager(16000, 2)
    for r in reqs:
        m.add_request(r)
    x = signal(8000)
    out = m.process_signal(x)
    info = m.info()
    stft = out["stft_left"]
    assert stft.dtype == np.complex128 and stft.shape[1] == len(info["stft_left"]["cf_hz"])
    assert info["stft_left"]["dtype"] == "complex128" and info["stft_left"]["kind"] == "spectrum"
    assert np.abs(stft.imag).max() > 0
    assert info["pitch_left"]["features"] == ["pitch", "rawPitch", "confidence"]
    assert out["pitch_left"].shape[1] == 3
    sf = info["spectralFeatures_left"]["features"]
    assert sf[0] == "centroid" and len(sf) == 14 == out["spectralFeatures_left"].shape[1]
    ams = out["amsFeatures_left"]
    assert ams.ndim == 3 and ams.shape[2] == len(info["amsFeatures_left"]["mod_cf_hz"])
    assert set(np.unique(out["onsetMap_left"])) <= {0.0, 1.0}
    assert info["onsetMap_left"]["afe_class"] == "BinaryMask"
    assert out["adaptation_left"].shape == (8000, 31)

    wav = tmp_path / "x.wav"
    with wave.open(str(wav), "wb") as w:
        w.setnchannels(2)
        w.setsampwidth(2)
        w.setframerate(16000)
        w.writeframes((np.clip(x, -1, 1) * 32767).astype("<i2").tobytes())
    npz = tmp_path / "out.npz"
    subprocess.run([cli, "extract", str(wav), "-r", ",".join(reqs), "-o", str(npz)], check=True)
    saved = np.load(npz)
    expected = afe.process(str(wav), None, reqs)
    assert sorted(saved.files) == sorted([*expected, "afe_metadata"])
    assert saved["stft_right"].dtype == np.complex128
    described = json.loads(str(saved["afe_metadata"]))
    for k, sig in expected.items():
        np.testing.assert_array_equal(saved[k], sig, err_msg=k)
        # the .npz carries the description the Python signal carries
        assert described[k] == sig.meta, k


def test_drnl_moc_precedence_and_duet_from_python():
    """The part-2 representations: precedence's three outputs under the oracle's names, the
    DUET histogram with its bins, a DRNL filterbank, and the MOC fed back in 10-ms chunks
    (equal on both executors; without the MOC the DRNL output stays as it was)."""
    x = signal(16000)  # one second: four DUET histograms of 0.5 s every 1/6 s
    out = afe.process(x, 16000, ["precedence", "duet"], {"fb_nChannels": 8})
    itd, ild, cc = (out["precedence_" + k + "_mono"] for k in ("itd", "ild", "cc"))
    assert itd.shape == ild.shape and itd.shape[1] == 8 and cc.shape[:2] == itd.shape
    assert np.all(np.abs(itd) <= 0.001 + 1e-12)
    duet = out["duet_mono"]
    assert duet.shape[0] == 4 and np.nanmax(duet, axis=(1, 2)).tolist() == [1.0] * 4
    m = afe.Manager(16000, 2)
    m.add_request("duet")
    m.process_signal(x)
    assert duet.shape[1:] == (len(m.info()["duet_mono"]["alpha"]), len(m.info()["duet_mono"]["delta_samples"]))

    quiet = x * 1e-3  # the MOC's fit attenuates from about -170 to -50 dB ratemap level

    def stream(requests, threads):
        m = afe.Manager(16000, 2, threads=threads)
        for r in requests:
            m.add_request(r, {"fb_type": "drnl"})
        chunks = [m.process_chunk(quiet[s : s + 160]) for s in range(0, len(x), 160)]
        return {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}, m.info()

    moc, info = stream(["moc", "filterbank"], None)
    assert info["moc_left"]["fs_hz"] == 100.0 and moc["moc_left"].shape[1] == 31
    assert moc["moc_left"].min() >= 0 and 0 < moc["moc_left"].max() <= 40
    plain, _ = stream(["filterbank"], None)
    assert not np.array_equal(moc["filterbank_left"], plain["filterbank_left"])
    np.testing.assert_array_equal(moc["filterbank_left"][:160], plain["filterbank_left"][:160])
    for k, v in stream(["moc", "filterbank"], 2)[0].items():
        np.testing.assert_array_equal(v, moc[k], err_msg=k)
    with pytest.raises(ValueError, match="fb_mocIpsi"):
        afe.process(x, 16000, "filterbank", {"fb_type": "drnl", "fb_mocIpsi": [1, 2]})


def test_run_time_edits():
    x = signal()
    m = afe.Manager(16000, 2, threads=2)
    rm = m.add_request("ratemap")
    ild = m.add_request("ild")
    m.process_chunk(x[:3200])
    m.modify_parameter("rm_scaling", "magnitude")
    m.remove_request(ild)
    out = m.process_chunk(x[3200:])
    assert set(out) == {"ratemap_left", "ratemap_right"}
    # the history keeps what came before the edits: ratemap in two segments, the removed
    # ild's rows under its name and the time they end
    hist = m.outputs()
    assert set(hist) == {"ratemap_left", "ratemap_right", "ild_mono@0.190"}
    np.testing.assert_array_equal(hist["ratemap_left"][-len(out["ratemap_left"]):], out["ratemap_left"])
    segments = hist["ratemap_left"].meta["segments"]
    assert [s["first_row"] for s in segments] == [0, len(hist["ratemap_left"]) - len(out["ratemap_left"])]
    assert [s["parameters"]["rm_scaling"] for s in segments] == ["power", "magnitude"]
    assert set(m.outputs(rm)) == {"ratemap_left", "ratemap_right"}
    with pytest.raises(KeyError):
        m.remove_request(ild)
    with pytest.raises(ValueError, match="cannot be changed at run time"):
        m.modify_parameter("fb_lowFreqHz", 100, handle=rm)
    with pytest.raises(ValueError, match="no request in place uses parameter"):
        m.modify_parameter("ild_wSizeSec", 0.04)
    with pytest.raises(ValueError, match="rm_scaling"):
        m.modify_parameter("rm_scaling", "loudness")


def test_editing_one_request_keeps_every_other_requests_history():
    """Removing a request and modifying another mid-stream (as the AFE's feedback demo
    does) leaves every untouched request's history equal to its uninterrupted run, and
    the edited ones' rows before the edit equal to theirs."""
    x = signal(16000)
    chunks = [x[s : s + 441] for s in range(0, len(x), 441)]

    def run(edit):
        m = afe.Manager(16000, 2, threads=2)
        handles = {r: m.add_request(r) for r in ["ratemap", "ild", "itd", "ic"]}
        for k, c in enumerate(chunks):
            if k == 20 and edit:
                m.remove_request(handles["itd"])
                m.modify_parameter("ild_wSizeSec", 0.04, handle=handles["ild"])
            m.process_chunk(c)
        return m.outputs()

    edited, plain = run(True), run(False)
    for key in ["ratemap_left", "ratemap_right", "ic_mono"]:
        np.testing.assert_array_equal(edited[key], plain[key], err_msg=key)
        assert "segments" not in edited[key].meta
    itd = [k for k in edited if k.startswith("itd_mono@")]
    assert len(itd) == 1
    np.testing.assert_array_equal(edited[itd[0]], plain["itd_mono"][: len(edited[itd[0]])])
    assert 0 < len(edited[itd[0]]) < len(plain["itd_mono"])
    ild = edited["ild_mono"]
    split = ild.meta["segments"][1]["first_row"]
    np.testing.assert_array_equal(ild[:split], plain["ild_mono"][:split])
    assert ild.meta["segments"][1]["parameters"]["ild_wSizeSec"] == 0.04


def test_a_bounded_history_keeps_the_last_seconds_of_each_output():
    """history_seconds keeps the newest rows (equal to the full history's last rows),
    with first_time_s moved on to the first row kept; the default keeps everything."""
    x = signal(16000)
    full = afe.Manager(16000, 2)
    short = afe.Manager(16000, 2, history_seconds=0.25)
    for m in (full, short):
        m.add_request("ratemap")
        for s in range(0, len(x), 160):
            m.process_chunk(x[s : s + 160])
    a, b = full.outputs()["ratemap_left"], short.outputs()["ratemap_left"]
    assert len(a) == 99 and 25 <= len(b) <= 50
    np.testing.assert_array_equal(b, a[-len(b):])
    assert b.first_time_s == pytest.approx(a.first_time_s + (len(a) - len(b)) / 100.0)
    np.testing.assert_allclose(b.t_s, a.t_s[-len(b):])
    with pytest.raises(ValueError, match="history_seconds = 0: expected a positive number"):
        afe.Manager(16000, 2, history_seconds=0)


def test_float32_outputs_are_the_float64_values_rounded():
    x = signal(8000)
    wide = afe.process(x, 16000, ["ratemap", "ild", "stft"], threads=0)
    narrow = afe.process(x, 16000, ["ratemap", "ild", "stft"], threads=0, dtype="float32")
    assert set(wide) == set(narrow)
    for k in wide:
        want = np.complex64 if np.iscomplexobj(wide[k]) else np.float32
        assert narrow[k].dtype == want, k
        np.testing.assert_array_equal(narrow[k], wide[k].astype(want), err_msg=k)
        assert narrow[k].meta["dtype"] == np.dtype(want).name
        assert narrow[k].nbytes * 2 == wide[k].nbytes
    with pytest.raises(ValueError) as e:
        afe.process(x, 16000, ["ild"], dtype="f16")
    assert str(e.value) == 'dtype = "f16": expected "float64" (as computed) or "float32" (rounded, half the memory)'


_WAYS_OUT = (
    'store them as float32 (`dtype="float32"`, `--dtype f32`), ask for fewer requests, write '
    "them to a store file by file (`afe.batch`, `afe batch`), or stream them (`afe.stream`, "
    "`afe stream`)"
)


def test_outputs_too_large_for_the_memory_are_announced_before_the_work(monkeypatch):
    """Half of the memory available: a ResourceWarning; all of it: a MemoryError; both
    name the size and the ways out. The estimate: 2 ears x 100 frames x 31 channels."""
    x = signal(16000)
    monkeypatch.setenv("AFE_MEMORY_AVAILABLE_GB", "0.00008")
    with pytest.warns(ResourceWarning) as w:
        out = afe.process(x, 16000, ["ratemap"])
    assert str(w[0].message) == (
        "the outputs will take 49.6 kB, more than half of the 80.0 kB of memory available: " + _WAYS_OUT
    )
    assert out["ratemap_left"].shape == (99, 31)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        afe.process(x, 16000, ["ratemap"], dtype="float32")  # 24.8 kB: no warning
    monkeypatch.setenv("AFE_MEMORY_AVAILABLE_GB", "0.00004")
    with pytest.raises(MemoryError) as e:
        afe.process(x, 16000, ["ratemap"])
    assert str(e.value) == (
        "keeping the outputs would take 49.6 kB, more than the 40.0 kB of memory available: " + _WAYS_OUT
    )



def test_parameters_beyond_the_work_limit_are_a_value_error_not_an_abort():
    """Issue 44, item 4: a 0.1-ms autocorrelation hop over 256 channels asked for 180 GB
    and killed the interpreter; it is refused when placed, in a child interpreter that
    must survive to print the message, and the manager goes on without it."""
    script = (
        "import numpy as np, afe\n"
        "m = afe.Manager(44100, 2)\n"
        "m.add_request('ild')\n"
        "try:\n"
        "    m.add_request('autocorrelation', {'ac_wSizeSec': 0.2, 'ac_hSizeSec': 0.0001, 'fb_nChannels': 256})\n"
        "except ValueError as e:\n"
        "    print(e)\n"
        "print(sorted(m.process_chunk(np.zeros((4410, 2)))))\n"
    )
    env = dict(os.environ)
    env.pop("AFE_WORK_LIMIT", None)
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    message, outputs = out.stdout.strip().splitlines()
    assert message.startswith("request 'autocorrelation' would make the graph compute about ")
    assert message.endswith(
        "over the limit of 2.0e9; parameters set: ac_hSizeSec=0.0001, ac_wSizeSec=0.2, fb_nChannels=256: "
        "a longer hop, a shorter window, fewer channels, lags or bins lower it, or raise the limit "
        "with the environment variable AFE_WORK_LIMIT (values per second)"
    )
    assert outputs == "['ild_mono']"

def test_errors_are_python_exceptions_with_clear_messages(tmp_path):
    x = signal(1600)
    cases = [
        (lambda: afe.process(x, 16000, ["ratemapp"]), ValueError, "unknown request 'ratemapp'"),
        (lambda: afe.process(x, 16000, ["ratemap"], {"rm_wSizeSecs": 1}), ValueError, "did you mean 'rm_wSizeSec'"),
        (lambda: afe.process(x, 16000, ["ratemap"], {"ihc_method": "daux"}), ValueError, "'dau'"),
        (lambda: afe.process(x, 16000, ["ratemap"], {"fb_nChannels": "many"}), ValueError, "fb_nChannels"),
        (lambda: afe.process(np.zeros((10, 3)), 16000, ["ratemap"]), ValueError, r"\[samples, 2\]"),
        (lambda: afe.process(np.zeros((0, 2)), 16000, ["ratemap"]), ValueError, "empty"),
        (lambda: afe.process(np.full((10, 2), np.nan), 16000, ["ratemap"]), ValueError, "NaN"),
        (lambda: afe.process(x * 1e200, 16000, ["ratemap"]), ValueError, "scale the input"),
        (lambda: afe.process((x * 1000).astype(np.int16), 16000, ["ratemap"]), ValueError, "x / 32768 for int16"),
        (lambda: afe.process(x, 16000, ["ratemap"], {"rm_wSizeSec": float("nan")}), ValueError, "'rm_wSizeSec' is nan"),
        (lambda: afe.process(x, 16000, ["ratemap"], {"pp_bLevelScaling": True, "pp_refSPLdB": -1e6}), ValueError, "pp_refSPLdB"),
        (lambda: afe.process(x[:, 0], 16000, ["itd"]), ValueError, "binaural"),
        (lambda: afe.process(x, -5, ["ratemap"]), ValueError, "sampling rate"),
        (lambda: afe.process(x, None, ["ratemap"]), ValueError, "fs is required"),
        (lambda: afe.process(x, 16000, ["ratemap"], chunk=0), ValueError, "chunk"),
        (lambda: afe.process("/nonexistent.wav", None, ["ratemap"]), FileNotFoundError, "nonexistent"),
        (lambda: afe.Manager(16000, 2).process_chunk(x[:, 0]), ValueError, "channels=2"),
        (lambda: afe.Manager(16000, 3), ValueError, "3 input channels"),
        (lambda: afe.Manager(16000, 2, threads=100), ValueError, "worker threads"),
    ]
    bad = tmp_path / "bad.wav"
    bad.write_bytes(b"RIFF not really")
    cases.append((lambda: afe.read_wav(bad), ValueError, "as WAV"))
    for call, exc, msg in cases:
        with pytest.raises(exc, match=msg):
            call()


def test_processing_releases_the_gil():
    """While a long `afe.process` runs in one thread, Python code in another makes
    progress (no timing ratio: if the call held the GIL, the main thread could not run a
    single bytecode in the middle half of the call), and two managers in two threads give
    the numbers each gives alone."""
    x = np.tile(signal(16000), (8, 1))
    reqs = ["ratemap", "ild", "itd", "ic"]
    span = {}
    results = {}

    def work(i):
        span.setdefault(i, [time.perf_counter()])
        results[i] = afe.process(x, 16000, reqs)
        span[i].append(time.perf_counter())

    worker = threading.Thread(target=work, args=(0,))
    stamps = []
    worker.start()
    while worker.is_alive():
        for _ in range(1000):
            pass
        stamps.append(time.perf_counter())
    worker.join()
    enter, leave = span[0]
    quarter = (leave - enter) / 4
    inside = [t for t in stamps if enter + quarter < t < leave - quarter]
    assert len(inside) >= 10, f"{len(inside)} progress marks in the middle of a {leave - enter:.3f} s call"

    threads = [threading.Thread(target=work, args=(i,)) for i in (1, 2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for i in (1, 2):
        assert sorted(results[i]) == sorted(results[0])
        for k in results[0]:
            np.testing.assert_array_equal(results[i][k], results[0][k])


def test_example_script_writes_its_figure(root, tmp_path):
    import subprocess
    import sys

    png = tmp_path / "cues.png"
    script = os.path.join(root, "examples", "plot_cues.py")
    subprocess.run([sys.executable, script, os.path.join(root, "data", "example_binaural.wav"), str(png)], check=True)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10000


_CTRL_C_SCRIPT = r"""
import signal, sys, time
import numpy as np
import afe
# Python's own Ctrl-C handler, even where the test runs in a background job (whose
# children a non-interactive shell starts with SIGINT ignored)
signal.signal(signal.SIGINT, signal.default_int_handler)
x = 0.1 * np.random.default_rng(0).standard_normal((44100 * 120, 2))
print("ready", flush=True)
t = time.monotonic()
try:
    afe.process(x, 44100, sys.argv[1].split(","))
    print("finished", time.monotonic() - t, flush=True)
except KeyboardInterrupt:
    print("interrupted", time.monotonic() - t, flush=True)
print("again", afe.process(x[:4410], 44100, ["ild"])["ild_mono"].shape, flush=True)
"""


@pytest.mark.parametrize("requests", ["ratemap,ild,itd,ic", "pitch"])
def test_ctrl_c_interrupts_a_long_process_call_at_once(requests):
    """Blocks read in turn (the cues) and a whole signal whose pitch absorbs its
    autocorrelation block by block (issue 44, item 9) both stop at the next block."""
    import signal
    import sys
    import time

    proc = subprocess.Popen(
        [sys.executable, "-c", _CTRL_C_SCRIPT, requests], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout.readline().strip() == "ready"
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    lines = out.split("\n")
    assert lines[0].startswith("interrupted"), (out, err)
    # within a fraction of a second of the signal, not when the 120-s signal is done
    assert float(lines[0].split()[1]) < 2.5, out
    # the next call runs normally
    assert lines[1] == "again (9, 31)", (out, err)


def test_cancelling_one_manager_leaves_another_in_another_thread_running():
    """Two managers, each computing a whole signal in a thread of its own: cancelling the
    first stops it within a fraction of a second, while the second, still running then,
    finishes with the output of an undisturbed run; the first then runs again (issue 58)."""
    rng = np.random.default_rng(5)
    slow = 0.1 * rng.standard_normal((44100 * 120, 2))
    other = 0.1 * rng.standard_normal((44100 * 60, 2))
    first, second = afe.Manager(44100, keep_history=False), afe.Manager(44100, keep_history=False)
    first.add_request("pitch")
    # the whole cue chain, so that it is still computing when the first is cancelled
    for r in ("ratemap", "ild", "itd", "ic"):
        second.add_request(r)
    got: dict = {}

    def run(name, mgr, x):
        t = time.monotonic()
        try:
            got[name] = mgr.process_signal(x)
        except KeyboardInterrupt:
            got[name] = "interrupted"
        got[name + "_end"] = time.monotonic() - t

    threads = [threading.Thread(target=run, args=a) for a in (("first", first, slow), ("second", second, other))]
    start = time.monotonic()
    for t in threads:
        t.start()
    time.sleep(0.3)
    first.cancel()
    cancelled = time.monotonic() - start
    threads[0].join(timeout=60)
    threads[1].join(timeout=120)
    assert got["first"] == "interrupted", got
    assert got["first_end"] < cancelled + 2.5, (got["first_end"], cancelled)
    # the second was still computing when the first was cancelled, and was not stopped
    assert got["second_end"] > cancelled, (got["second_end"], cancelled)
    alone = afe.Manager(44100, keep_history=False)
    for r in ("ratemap", "ild", "itd", "ic"):
        alone.add_request(r)
    want = alone.process_signal(other)
    assert set(got["second"]) == set(want)
    for k in want:
        assert np.array_equal(got["second"][k], want[k]), k
    # a cancel withdrawn: the next call of the cancelled manager runs to its end
    assert first.process_signal(slow[:4410])["pitch_left"].shape[0] > 0


def test_keep_all_returns_the_intermediate_signals_as_extract_all(example_wav, cli, tmp_path):
    out = afe.process(example_wav, None, ["ild"], keep="all")
    for name in ("time_left", "time_right", "filterbank_left", "innerhaircell_right", "ild_mono"):
        assert name in out, sorted(out)
    assert out["filterbank_left"].shape[1] == out["ild_mono"].shape[1]
    assert set(afe.process(example_wav, None, ["ild"])) == {"ild_mono"}
    npz = tmp_path / "all.npz"
    subprocess.run([cli, "extract", example_wav, "-r", "ild", "--all", "-o", str(npz)], check=True, capture_output=True)
    with np.load(npz) as z:
        assert sorted(z.files) == sorted([*out, "afe_metadata"])
        assert json.loads(str(z["afe_metadata"]))["innerhaircell_left"] == out["innerhaircell_left"].meta
        for k in out:
            assert np.array_equal(z[k], out[k]), k
    with pytest.raises(ValueError, match="keep"):
        afe.process(example_wav, None, ["ild"], keep="everything")


def test_two_instances_of_a_request_have_their_own_outputs_and_parameters():
    x = signal(16000)
    m = afe.Manager(16000, channels=2)
    wide = m.add_request("ratemap", {"fb_nChannels": 32})
    narrow = m.add_request("ratemap", {"fb_nChannels": 16, "rm_wSizeSec": 0.05})
    out = m.process_chunk(x)
    names = {h: m.request_outputs(h) for h in (wide, narrow)}
    assert names[wide] == ["ratemap_left", "ratemap_right"]
    assert names[narrow] == ["ratemap_2_left", "ratemap_2_right"]
    assert out[names[wide][0]].shape[1] == 32 and out[names[narrow][0]].shape[1] == 16
    used = {h: m.request_parameters(h) for h in (wide, narrow)}
    assert (used[wide]["fb_nChannels"], used[wide]["rm_wSizeSec"]) == (32, 0.02)
    assert (used[narrow]["fb_nChannels"], used[narrow]["rm_wSizeSec"]) == (16, 0.05)
    # defaults of the whole chain are there too
    assert used[narrow]["ihc_method"] == "dau" and "pp_bRemoveDC" in used[narrow]
    with pytest.raises(KeyError):
        m.request_outputs(99)


def test_streamed_frames_carry_their_index_and_time_across_modify_parameter():
    """The AFE's Feedback demo changes a parameter mid-stream: the time axis must follow
    the input, not compress."""
    fs = 16000
    x = signal(fs * 2)
    m = afe.Manager(fs, channels=2)
    h = m.add_request("ratemap", {"fb_nChannels": 8})
    times, index = [], 0
    for k, start in enumerate(range(0, len(x), 160)):
        if k == 100:
            m.modify_parameter("rm_hSizeSec", 0.02, handle=h)
        new = m.process_chunk(x[start:start + 160])["ratemap_left"]
        info = m.frames()["ratemap_left"]
        assert info["first_frame"] == index and info["frames"] == len(new)
        # the chunk's signal carries the same clock, and the hop of its framing
        assert new.first_frame == index and new.first_time_s == info["first_time_s"]
        assert new.hop_s == pytest.approx(0.01 if k < 100 else 0.02)
        index += len(new)
        times.extend(info["first_time_s"] + np.arange(len(new)) / info["fs_hz"])
    times = np.array(times)
    assert np.all(np.diff(times) > 0)
    assert times[0] == 0.0 and abs(times[-1] - 1.98) < 1e-9  # 2 s: last 20-ms frame
    hops = np.diff(times)
    assert np.allclose(hops[times[1:] < 1.0], 0.01) and np.allclose(hops[times[:-1] >= 1.0], 0.02)


def test_outputs_are_signals_that_carry_their_description():
    fs = 16000
    x = signal(fs)
    out = afe.process(x, fs, ["ild", "itd", "filterbank"], {"fb_nChannels": 8, "ild_wSizeSec": 0.04})
    ild, fb, itd = out["ild_mono"], out["filterbank_left"], out["itd_mono"]
    assert isinstance(ild, afe.Signal) and isinstance(ild, np.ndarray)
    assert (ild.key, ild.name, ild.ear, ild.kind) == ("ild_mono", "ild", "mono", "time-frequency")
    assert (ild.unit, itd.unit) == ("dB", "s")
    assert (ild.window_s, ild.hop_s, ild.fs_hz, ild.audio_fs_hz) == (0.04, 0.01, 100.0, fs)
    # frames of 40 ms every 10 ms over 1 s: row k starts at k·10 ms
    assert len(ild) == (fs - 640) // 160 + 1
    np.testing.assert_allclose(ild.t_s, np.arange(len(ild)) * 0.01, rtol=0, atol=1e-12)
    assert ild.n_channels == 8 and len(ild.cf_hz) == 8 and ild.cf_hz[0] == pytest.approx(80)
    assert ild.parameters["ild_wSizeSec"] == 0.04 and ild.parameters["ihc_method"] == "dau"
    assert ild.processors[0] == "ild" and "filterbank" in ild.processors
    assert itd.window_s == 0.02 and len(itd.lags_s) == 0  # the cross-correlation's framing
    # the gammatone's per-channel envelope delay, the AFE's delaySec: 3/(2π·1.019·ERB)
    erb = 24.7 + fb.cf_hz / 9.265
    np.testing.assert_allclose(fb.delay_s, 3 / (2 * np.pi * 1.019 * erb), rtol=1e-3)
    assert (fb.window_s, fb.hop_s, len(fb)) == (None, None, fs)
    assert ild.delay_s is not None and out["ild_mono"].meta["first_frame"] == 0
    # numpy keeps working; derived arrays are plain ones (the description would not fit)
    assert type(ild[:, 0]) is np.ndarray and type(ild * 2) is np.ndarray
    assert type(np.asarray(ild)) is np.ndarray and float(ild.mean()) == float(np.asarray(ild).mean())
    again = pickle.loads(pickle.dumps(ild))
    assert isinstance(again, afe.Signal) and again.meta == ild.meta and np.array_equal(again, ild)
    assert "ild_mono" in repr(ild) and "100 Hz" in repr(ild)


def test_a_handle_fetches_its_own_outputs():
    fs = 16000
    m = afe.Manager(fs, channels=2)
    wide = m.add_request("ratemap", {"fb_nChannels": 16})
    narrow = m.add_request("ratemap", {"fb_nChannels": 8, "rm_wSizeSec": 0.05})
    m.process_chunk(signal(fs))
    mine = m.outputs(narrow)
    assert sorted(mine) == ["ratemap_2_left", "ratemap_2_right"]
    assert mine["ratemap_2_left"].shape[1] == 8 and mine["ratemap_2_left"].window_s == 0.05
    assert m.outputs(wide)["ratemap_left"].parameters["fb_nChannels"] == 16
    with pytest.raises(KeyError):
        m.outputs(7)


def test_a_hop_longer_than_the_window_leaves_gaps_as_in_the_afe():
    """The AFE accepts hSizeSec > wSizeSec: frames of 20 ms every 50 ms are every fifth
    frame of the 10-ms framing, exactly, in one call and in chunks."""
    fs = 16000
    x = signal(fs)
    dense = afe.process(x, fs, "ratemap", {"fb_nChannels": 8})["ratemap_left"]
    for chunk in (None, 100, 1234):
        sparse = afe.process(x, fs, "ratemap", {"fb_nChannels": 8, "rm_hSizeSec": 0.05}, chunk=chunk)["ratemap_left"]
        assert len(sparse) == (fs - 320) // 800 + 1 and sparse.hop_s == 0.05
        np.testing.assert_array_equal(sparse, dense[::5][: len(sparse)])
    with pytest.raises(ValueError, match="rm_hSizeSec"):
        afe.process(x, fs, "ratemap", {"rm_hSizeSec": 0})


# issue 46: per-request parameters in afe.process, messages, summaries, save and load


def _raises(call, exc=ValueError):
    with pytest.raises(exc) as e:
        call()
    return str(e.value)


def test_process_takes_requests_with_their_own_parameters():
    fs = 16000
    x = signal(fs)
    out = afe.process(x, fs, [("ratemap", {"fb_nChannels": 16}), ("ratemap", {"fb_nChannels": 8}), "ild"],
                      {"ihc_method": "halfwave"})
    assert list(out) == ["ratemap_left", "ratemap_right", "ratemap_2_left", "ratemap_2_right", "ild_mono"]
    assert out["ratemap_left"].shape[1] == 16 and out["ratemap_2_left"].shape[1] == 8
    assert out["ild_mono"].shape[1] == 31 and out["ild_mono"].parameters["ihc_method"] == "halfwave"
    # each equals the request computed on its own, bit for bit
    alone = lambda n: afe.process(x, fs, ["ratemap"], {"ihc_method": "halfwave", "fb_nChannels": n})["ratemap_left"]
    np.testing.assert_array_equal(out["ratemap_left"], alone(16))
    np.testing.assert_array_equal(out["ratemap_2_left"], alone(8))
    assert out["ratemap_2_left"].meta["instance"] == 2
    # a pair's own parameters go over the shared ones; a WAV path takes the same list
    own = afe.process(x, fs, [("ratemap", {"fb_nChannels": 8, "ihc_method": "dau"})], {"ihc_method": "halfwave"})
    assert own["ratemap_left"].parameters["ihc_method"] == "dau"
    # one pair on its own is a list of one
    assert list(afe.process(x, fs, ("ild", {"fb_nChannels": 8}))) == ["ild_mono"]


def test_process_names_the_request_that_is_wrong(tmp_path):
    fs = 16000
    x = signal(1600)
    assert _raises(lambda: afe.process(x, fs, ["ratemap", 5])) == (
        "requests[1] = 5: give a request name or a (name, params) pair, e.g. 'ratemap' or "
        "('ratemap', {'fb_nChannels': 16})"
    )
    assert _raises(lambda: afe.process(x, fs, [("ratemap", 16)])) == (
        "requests[0] ('ratemap'): its parameters must be a dict, got 16"
    )
    assert _raises(lambda: afe.process(x, fs, ["ild", ("ratemap", {"rm_wSizeSec": float("nan")})])) == (
        "requests[1] ('ratemap'): parameter 'rm_wSizeSec' is nan: AFE parameters take finite numbers"
    )
    assert _raises(lambda: afe.process(x, fs, ["ratemap", ("ild", {"fb_nChannels": 0})])) == (
        "requests[1]: invalid value 0 for parameter 'fb_nChannels': expected a positive integer"
    )
    assert _raises(lambda: afe.process(x[:, 0], fs, ["ratemap", "itd"])) == (
        "requests[1]: request 'itd' needs a binaural (two-channel) input, but the signal has shape "
        "(1600,): give [samples, 2] (left, right), e.g. np.column_stack([left, right]) (shape (1600, 2))"
    )
    # an unknown request, in any case, is named with the one meant
    assert _raises(lambda: afe.process(x, fs, ["ratemap", "ITD"])).startswith(
        "requests[1]: unknown request 'ITD' (did you mean 'itd'?) (known requests: time, "
    )
    # a shared parameter is named by itself, not by the first request that read it
    assert _raises(lambda: afe.process(x, fs, ["ratemap", "ild"], {"rm_wSizeSecs": 1})) == (
        "unknown parameter 'rm_wSizeSecs' (did you mean 'rm_wSizeSec'?)"
    )
    # the same from a WAV file
    path = tmp_path / "x.wav"
    with wave.open(str(path), "wb") as w:
        w.setnchannels(2)
        w.setsampwidth(2)
        w.setframerate(fs)
        w.writeframes((x * 32767).astype("<i2").tobytes())
    assert _raises(lambda: afe.process(path, None, ["ild", "ratemapp"])).startswith(
        "requests[1]: unknown request 'ratemapp' (did you mean 'ratemap'?) (known requests: "
    )
    two = afe.process(path, None, [("ratemap", {"fb_nChannels": 16}), ("ratemap", {"fb_nChannels": 8})])
    assert two["ratemap_left"].shape[1] == 16 and two["ratemap_2_left"].shape[1] == 8


def test_messages_guess_the_value_meant_and_say_the_default_only_when_it_is():
    x = signal(1600)
    msg = _raises(lambda: afe.process(x, 16000, ["ratemap"], {"ihc_method": "Dau"}))
    assert msg.startswith("invalid value \"Dau\" for parameter 'ihc_method': expected one of ")
    assert msg.endswith(" (did you mean 'dau'?)")
    msg = _raises(lambda: afe.Manager(16000).add_request("ITD"))
    assert msg.startswith("unknown request 'ITD' (did you mean 'itd'?) (known requests: ")
    # MATLAB v7.3 files come out of h5py as [channels, samples]
    assert _raises(lambda: afe.process(x.T, 16000, ["ild"])) == (
        "signal of shape (2, 1600): expected [samples] (mono) or [samples, 2] (left, right): "
        "it looks like [channels, samples]; pass x.T (shape (1600, 2))"
    )
    # [N] or [N, 1] to a binaural manager, [N, 2] to a mono one: the shape got and the one expected
    binaural, mono = afe.Manager(16000, 2), afe.Manager(16000, 1)
    assert _raises(lambda: binaural.process_chunk(x[:, 0])) == (
        "signal of shape (1600,): this manager (channels=2) expects [samples, 2] (left, right); "
        "give np.column_stack([left, right]) (shape (1600, 2))"
    )
    assert _raises(lambda: binaural.process_signal(x[:, :1])) == (
        "signal of shape (1600, 1): this manager (channels=2) expects [samples, 2] (left, right); "
        "give np.column_stack([left, right]) (shape (1600, 2))"
    )
    assert _raises(lambda: mono.process_chunk(x)) == (
        "signal of shape (1600, 2): this manager (channels=1) expects [samples]; "
        "pass one ear, x[:, 0] (shape (1600,)), or make the manager with channels=2"
    )
    # fb_highFreqHz = 8000 set at 11025 Hz is the user's value, not "the default"
    y = signal(1103, 11025)
    msg = _raises(lambda: afe.process(y, 11025, ["ratemap"], {"fb_highFreqHz": 8000}))
    assert msg.startswith("invalid value 8000.0 for parameter 'fb_highFreqHz': 8000 puts ") and "default" not in msg
    msg = _raises(lambda: afe.process(y, 11025, ["ratemap"]))
    assert msg.startswith("invalid value 8000.0 for parameter 'fb_highFreqHz': 8000 (the default) puts ")


def test_summary_shows_each_processor_with_its_changed_parameters():
    fs = 16000
    x = signal(1600)
    out = afe.process(x, fs, [("ratemap", {"fb_nChannels": 16}), ("ratemap", {"fb_nChannels": 8}), "ild"])
    text = afe.summary(out)
    assert text == SUMMARY_TEXT, text
    # the same from a manager, in print(m) and repr(m)
    m = afe.Manager(fs, 2)
    for name, p in [("ratemap", {"fb_nChannels": 16}), ("ratemap", {"fb_nChannels": 8}), ("ild", None)]:
        m.add_request(name, p)
    assert afe.summary(m) == text
    assert repr(m) == str(m) == "afe.Manager(fs=16000, channels=2, threads=0): 3 requests\n" + text
    assert repr(afe.Manager(fs, 2)) == "afe.Manager(fs=16000, channels=2, threads=0): 0 requests"
    # intermediate signals (keep="all") are the chains' tails: not listed again
    assert afe.summary(afe.process(x, fs, [("ratemap", {"fb_nChannels": 16})], keep="all")) == text.split("\nratemap_2")[0]
    with pytest.raises(ValueError, match="give an afe.Manager or signals"):
        afe.summary(42)


def test_summary_abbreviates_vectors():
    from afe.summary import value_text

    assert value_text(list(np.linspace(80, 8000, 32))) == "[80, 335.484, 590.968, ..., 8000] (32 values)"
    assert value_text([1, 2.5, 3]) == "[1, 2.5, 3]"
    assert value_text("dau") == "'dau'" and value_text(True) == "true" and value_text(0.02) == "0.02"


def test_save_and_load_round_trip_signals_with_their_metadata(tmp_path, cli):
    fs = 16000
    x = signal(4000)
    out = afe.process(x, fs, [("ratemap", {"fb_nChannels": 8}), "ild", "stft"])
    path = tmp_path / "cues"  # no suffix added: the file is written where asked
    afe.save(path, out)
    back = afe.load(path)
    assert list(back) == list(out)
    for k, s in out.items():
        assert isinstance(back[k], afe.Signal) and back[k].dtype == s.dtype
        assert np.array_equal(np.asarray(back[k]).view(np.uint8), np.asarray(s).view(np.uint8)), k
        assert back[k].meta == s.meta, k
    # one Signal saves under its key
    afe.save(tmp_path / "one.npz", out["ild_mono"])
    assert list(afe.load(tmp_path / "one.npz")) == ["ild_mono"]
    # the CLI's npz loads into Signals, the same as afe.process gives them
    wav = tmp_path / "x.wav"
    with wave.open(str(wav), "wb") as w:
        w.setnchannels(2)
        w.setsampwidth(2)
        w.setframerate(fs)
        w.writeframes((x * 32767).astype("<i2").tobytes())
    subprocess.run([cli, "extract", str(wav), "-r", "ratemap,ild", "-o", str(tmp_path / "cli.npz")],
                   check=True, capture_output=True)
    from_cli = afe.load(tmp_path / "cli.npz")
    mine = afe.process(wav, None, ["ratemap", "ild"])
    assert list(from_cli) == list(mine)
    for k, s in mine.items():
        np.testing.assert_array_equal(from_cli[k], s)
        assert from_cli[k].meta == s.meta, k
    # afe.open_store reads one npz as a store of one file
    store = afe.open_store(tmp_path / "cli.npz")
    assert store.ids() == ["cli"] and store.format == "npz-file" and store.requests == ["ratemap", "ild"]
    assert store["cli"]["ild_mono"].meta == from_cli["ild_mono"].meta
    afe.save(tmp_path / "mine.npz", out)
    assert afe.open_store(tmp_path / "mine.npz").requests == ["ratemap", "ild", "stft"]
    # errors
    assert _raises(lambda: afe.save(tmp_path / "p.npz", {"a": np.zeros(3)})) == (
        "signals['a'] is a ndarray, not an afe.Signal: it has no description to save (np.savez saves plain arrays)"
    )
    np.savez(tmp_path / "plain.npz", a=np.zeros(3))
    assert _raises(lambda: afe.load(tmp_path / "plain.npz")) == (
        f"'{tmp_path / 'plain.npz'}' has no 'afe_metadata' entry: not written by afe (np.load reads its arrays)"
    )
    with pytest.raises(FileNotFoundError):
        afe.load(tmp_path / "missing.npz")



def test_save_and_load_round_trip_through_a_zarr_group(tmp_path):
    fs = 16000
    x = signal(4000)
    out = afe.process(x, fs, [("ratemap", {"fb_nChannels": 8}), "ild", "stft"])
    narrow = afe.process(x, fs, ["ild", "stft"], dtype="float32")
    for name, signals in (("cues.zarr", out), ("narrow.zarr", narrow)):
        afe.save(tmp_path / name, signals)
        back = afe.load(tmp_path / name)
        assert list(back) == list(signals)
        for k, s in signals.items():
            assert isinstance(back[k], afe.Signal) and back[k].dtype == s.dtype, k
            assert np.array_equal(np.asarray(back[k]).view(np.uint8), np.asarray(s).view(np.uint8)), k
            assert back[k].meta == s.meta, k
    # saved again: replaced, not merged
    afe.save(tmp_path / "cues.zarr", out["ild_mono"])
    assert list(afe.load(tmp_path / "cues.zarr")) == ["ild_mono"]
    # any Zarr v3 reader opens it, with the description in each array's attributes
    zarr = pytest.importorskip("zarr")
    group = zarr.open_group(str(tmp_path / "narrow.zarr"), mode="r")
    np.testing.assert_array_equal(group["ild_mono"][:], narrow["ild_mono"])
    assert group["ild_mono"].attrs["afe"] == narrow["ild_mono"].meta
    # afe.open_store reads it as a store of one file
    store = afe.open_store(tmp_path / "narrow.zarr")
    assert store.ids() == ["narrow"] and store.format == "zarr-group" and store.dtype == "float32"
    assert store.requests == ["ild", "stft"]
    np.testing.assert_array_equal(store["narrow"]["stft_left"], narrow["stft_left"])
    # errors
    (tmp_path / "folder").mkdir()
    (tmp_path / "folder" / "notes.txt").write_text("mine")
    (tmp_path / "folder").rename(tmp_path / "folder.zarr")
    assert _raises(lambda: afe.save(tmp_path / "folder.zarr", out)) == (
        f"'{tmp_path / 'folder.zarr'}' exists and is not a group written by afe.save: give a new path ending in .zarr"
    )
    assert (tmp_path / "folder.zarr" / "notes.txt").read_text() == "mine"
    assert _raises(lambda: afe.load(tmp_path / "folder.zarr")) == (
        f"'{tmp_path / 'folder.zarr'}' is not an afe store: it is not a group written by afe.save "
        "(a batch store opens with afe.open_store)"
    )
    assert _raises(lambda: afe.save(tmp_path / "k.zarr", {"..": out["ild_mono"]})).startswith(
        "'..' cannot name an array of a Zarr group"
    )
    assert not (tmp_path / "k.zarr").exists() and not (tmp_path / "zarr.json").exists()
    # another byte order is stored as this machine's, the values unchanged
    swapped = afe.Signal(np.asarray(out["ild_mono"]).astype(">f8"), out["ild_mono"].meta)
    afe.save(tmp_path / "be.zarr", swapped)
    np.testing.assert_array_equal(afe.load(tmp_path / "be.zarr")["ild_mono"], out["ild_mono"])
    with pytest.raises(FileNotFoundError):
        afe.load(tmp_path / "missing.zarr")

SUMMARY_TEXT = """\
ratemap -> ratemap_left, ratemap_right
    ratemap
    innerhaircell
    filterbank
        fb_nERBs                 1.90081 ERB
        fb_nChannels             16
        fb_cfHz                  [80, 155.553, 249.587, ..., 8000] (16 values) Hz
    time
ratemap_2 -> ratemap_2_left, ratemap_2_right
    ratemap
    innerhaircell
    filterbank
        fb_nERBs                 3.80161 ERB
        fb_nChannels             8
        fb_cfHz                  [80, 264.781, 560.114, ..., 8000] (8 values) Hz
    time                         (shared with ratemap)
ild -> ild_mono
    ild
    innerhaircell
    filterbank
    time                         (shared with ratemap)"""


def test_the_examples_of_summary_and_saving_run():
    import doctest

    for name in ("afe.summary", "afe.saving"):
        failed, tried = doctest.testmod(sys.modules[name], optionflags=doctest.NORMALIZE_WHITESPACE)
        assert tried > 0 and failed == 0, name


def test_nan_where_names_every_representation_that_is_nan_on_silence():
    """Issue 44, item 10: digital silence makes some representations NaN, as the AFE's;
    each says so in its description, and the others stay finite."""
    out = afe.process(np.zeros((16000, 2)), 16000, afe.requests())
    nan = {s.name for s in out.values() if np.isnan(np.asarray(s).real).any()}
    # (tracking: no source in silence, every slot empty)
    assert nan == {"autocorrelation", "pitch", "precedence_ild", "gabor", "duet", "tracking"}
    for s in out.values():
        assert (s.nan_where is not None) == (s.name in nan | {"spectralFeatures"}), s.key
        assert not np.isinf(np.asarray(s).real).any(), s.key
    assert "unvoiced" in out["pitch_left"].nan_where
    assert out["ratemap_left"].nan_where is None


def test_the_loudest_accepted_input_gives_finite_output_and_louder_is_refused():
    """Issues 44 (item 10) and 57 (item 5): the largest amplitude accepted, 1e15 after the
    pre-processing's gain, gives finite output in every request (NaN only where nan_where
    says, here the unvoiced pitch and tracking's empty slots), with the square-law hair cell whose spectral features
    take the input's 16th power too; beyond it the input is refused, and so is float32
    noise at 1e18 through a level-scaling gain of 1e20 (it gave 61,000 Inf STFT values),
    and a float32 result that float32 cannot hold (a square-law ratemap at 1e15, 1e60)."""
    x = np.random.default_rng(0).uniform(-1, 1, (16000, 2))
    for params in [{}, {"ihc_method": "square"}]:
        out = afe.process(x * 1e15, 16000, afe.requests(), params)
        for s in out.values():
            values = np.asarray(s)
            assert not np.isinf(values.real).any() and not np.isinf(values.imag).any(), s.key
            # (the unvoiced pitch, and tracking's empty slots)
            assert s.name in {"pitch", "tracking"} or not np.isnan(values.real).any(), s.key
    for amp in [3e58, 1e30, 1e22, 1.1e15]:
        message = _raises(lambda: afe.process(x * amp, 16000, ["spectralFeatures"]))
        assert message.startswith("invalid input: sample ") and "beyond ±1e15" in message, amp
    gain = {"pp_bLevelScaling": True, "pp_refSPLdB": -300}
    message = _raises(lambda: afe.process(x.astype(np.float32) * 1e18, 16000, ["stft"], gain))
    assert "raises it by up to 1e20" in message and "pp_refSPLdB" in message, message
    out = afe.process(x * 1e-6, 16000, ["stft"], gain)
    assert np.isfinite(np.asarray(out["stft_left"])).all()
    message = _raises(
        lambda: afe.process(x * 1e15, 16000, ["ratemap"], {"ihc_method": "square"}, dtype="float32")
    )
    assert "beyond what float32 can hold" in message and "float64" in message, message


def _saved_group(tmp_path, name="g.zarr"):
    """A Zarr group of afe.save holding a 2-s ratemap (several chunks) and an ILD."""
    out = afe.process(signal(32000), 16000, [("ratemap", {"fb_nChannels": 8}), "ild"])
    path = tmp_path / name
    afe.save(path, out)
    return path, out


def _set_shape(path, array, shape):
    meta_path = path / array / "zarr.json"
    meta = json.loads(meta_path.read_text())
    meta["shape"] = shape
    meta_path.write_text(json.dumps(meta))


def test_a_hostile_shape_in_a_saved_group_is_an_error_not_an_abort(tmp_path):
    """Issue 57, finding 4: a shape of [1e12, 1e6] or [4e7, 32] in an array's zarr.json
    aborted afe.load and open_store(...)[id] (an allocation of 8e18 bytes); the shape is
    now checked against the chunk files and the memory available before anything is
    allocated. Run under a 2-GB address-space limit in a child, so that an abort could
    not take the test run with it."""
    import textwrap

    path, _ = _saved_group(tmp_path)
    code = textwrap.dedent(
        f"""
        import json, resource, sys
        resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))
        import afe
        path = {str(path)!r}
        meta_path = path + "/ratemap_left/zarr.json"
        meta = json.load(open(meta_path))
        width = meta["shape"][1]
        for shape in ([10**12, 10**6], [4 * 10**7, 32], [4 * 10**7, width]):
            meta["shape"] = shape
            json.dump(meta, open(meta_path, "w"))
            try:
                afe.load(path)
            except ValueError as e:
                print("load:", e)
            store = afe.open_store(path)
            print("store:", repr(store))
            try:
                store["g"]
            except KeyError as e:
                print("item:", e)
        """
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    loads = [l for l in lines if l.startswith("load:")]
    assert len(loads) == 3 and all("is damaged: array 'ratemap_left': " in l for l in loads), lines
    assert "shape [1000000000000, 1000000] does not match its chunks" in loads[0]
    assert "shape [40000000, 32] does not match its chunks" in loads[1]
    assert "chunk [" in loads[2] and "] is missing" in loads[2]
    assert sum("0 done, 0 failed, 1 missing" in l for l in lines if l.startswith("store:")) == 3
    assert sum("is damaged" in l for l in lines if l.startswith("item:")) == 3


def test_a_saved_group_larger_than_the_memory_available_is_a_memory_error(tmp_path):
    """Issue 57, finding 4: a shape whose chunks are on disk (here as they were saved)
    but whose values exceed the memory available raises MemoryError before reading."""
    path, _ = _saved_group(tmp_path)
    env = dict(os.environ, AFE_MEMORY_AVAILABLE_GB="0.00001")
    code = f"import afe\ntry:\n    afe.load({str(path)!r})\nexcept MemoryError as e:\n    print(e)\n"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "GB of memory, more than the 0.00 GB available" in done.stdout, done.stdout


def test_a_missing_chunk_of_a_saved_group_is_an_error_naming_the_array_and_chunk(tmp_path):
    """Issue 57, finding 7: removing one chunk file made afe.load return zeros and
    open_store say '1 done, 0 missing'."""
    path, out = _saved_group(tmp_path)
    chunks = sorted((path / "ratemap_left" / "c").iterdir())
    assert len(chunks) >= 1
    (chunks[0] / "0").unlink()
    message = _raises(lambda: afe.load(path))
    assert message.startswith(f"'{path}' is damaged: array 'ratemap_left': chunk [0, 0] is missing"), message
    store = afe.open_store(path)
    assert repr(store).endswith("0 done, 0 failed, 1 missing)") and store.ids() == []
    assert "chunk [0, 0] is missing" in store.missing["g"]
    assert "chunk [0, 0] is missing" in _raises(lambda: store["g"], KeyError)
    # saved whole again, a group of zeros loads (its chunks of zeros are stored too)
    zeros = {k: afe.Signal(np.zeros_like(np.asarray(s)), s.meta) for k, s in out.items()}
    afe.save(path, zeros)
    assert all(not np.asarray(s).any() for s in afe.load(path).values())


def test_a_fifo_chunk_of_a_saved_group_is_refused_without_blocking(tmp_path):
    """Issue 57, minor: a FIFO in place of a chunk hung afe.load (and Ctrl-C did not end
    it); it is refused as not a regular file. In a child with a timeout, so that a hang
    fails the test instead of stalling the run."""
    path, _ = _saved_group(tmp_path)
    chunk = path / "ild_mono" / "c" / "0" / "0"
    chunk.unlink()
    os.mkfifo(chunk)
    code = f"import afe\ntry:\n    afe.load({str(path)!r})\nexcept ValueError as e:\n    print(e)\n"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "array 'ild_mono': chunk [0, 0] is not a regular file (a FIFO or a device)" in done.stdout, (
        done.stdout + done.stderr
    )
    # a FIFO in place of the group's metadata: not a saved group, without blocking
    (path / "zarr.json").unlink()
    os.mkfifo(path / "zarr.json")
    code = f"import afe\ntry:\n    afe.open_store({str(path)!r})\nexcept (ValueError, OSError) as e:\n    print(e)\n"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and done.stdout.strip(), done.stderr


def test_summary_of_plain_arrays_says_what_it_accepts():
    """Issue 57, minor: afe.summary({"a": np.zeros(3)}) raised a bare TypeError."""
    message = _raises(lambda: afe.summary({"a": np.zeros(3)}))
    assert message.startswith("summary of signals: ['a'] is a ndarray, not an afe.Signal"), message
    assert "afe.Manager" in message


def test_a_whole_signal_beyond_the_memory_raises_and_the_interpreter_lives():
    """Issue 57, item 2: afe.process of 20 s of moc at 44.1 kHz under an address-space
    limit of what the interpreter holds plus 700 MB killed the interpreter ("memory
    allocation ... failed"); it raises MemoryError naming what it would take."""
    out = under_address_limit(
        "x = 0.1 * np.sin(0.05 * np.arange(20 * 44100))[:, None] * np.ones(2)",
        "afe.process(x, 44100, ['moc'])", 700_000_000, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("refused: "), out.stdout
