"""The MATLAB AFE oracle cases from Python: equal to the CLI bit for bit, and within the
oracle's tolerance (trimmed golden arrays always; the full oracle via AFE_ORACLE_DIR)."""
import json
import os
import subprocess

import numpy as np
import pytest

import afe

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
GOLDEN = os.path.join(ROOT, "data", "golden")
CASES = json.load(open(os.path.join(GOLDEN, "cases.json")))
# The bounds of each comparison and their reasons, shared with the Rust suite.
TOLERANCES = json.load(open(os.path.join(ROOT, "tests", "oracle_tolerances.json")))


def rel_error(out, ref):
    """compare.py's metric: per channel, max |out − ref| / max |ref|; NaN = NaN."""
    both_nan = np.isnan(out) & np.isnan(ref)
    diff = np.where(both_nan, 0.0, np.abs(out - ref))
    diff = np.where(np.isnan(diff), np.inf, diff)
    mag = np.where(np.isnan(ref), 0.0, np.abs(ref))
    if ref.ndim == 1:
        return diff / max(mag.max(initial=0.0), 1e-300)
    axes = tuple(a for a in range(ref.ndim) if a != 1)
    scale = mag.max(axis=axes, keepdims=True)
    return diff / np.where(scale > 0, scale, 1e-300)


def run_case(case, wav):
    """Runs a case as the oracle did; an ITD request also records its cross-correlation
    (the same shared node), to tell genuine peak ties from errors."""
    x, fs = afe.read_wav(wav)
    m = afe.Manager(fs, x.shape[1] if x.ndim == 2 else 1)
    requests = list(case["requests"])
    if "itd" in requests and "crosscorrelation" not in requests:
        requests.append("crosscorrelation")
    for r in requests:
        m.add_request(r, case["nondefault_params"])
    if case["mode"] == "chunks":
        start = 0
        for n in case["chunk_sizes_used"]:
            m.process_chunk(x[start : start + n])
            start += n
        return m.outputs(), fs
    return m.process_signal(x), fs


def rule(case_name, signal, float32):
    """The table's entry for a signal: the case's own, the float32 storage bound, the
    signal's, or the float64 default (the order of tests/oracle.rs)."""
    t = TOLERANCES
    if case_name in t["float64_by_case"]:
        return t["float64_by_case"][case_name]
    if float32:
        return t["float32_reference"]
    return t["float64_by_signal"].get(signal, t["float64_default"])


def check(out, key, ref, case_name, fs):
    got = out[key][: ref.shape[0]]
    signal = key.rsplit("_", 1)[0]
    r = rule(case_name, signal, ref.dtype == np.float32)
    err = rel_error(got, ref.astype(np.float64))
    over = err > r["rel"]
    if not over.any():
        return
    o = r.get("outliers")
    assert o, f"{key}: rel {err.max():.3e} over {r['rel']:.1e}"
    assert over.mean() <= o["max_fraction"], f"{key}: {over.mean():.4%} of cells over {r['rel']}"
    ccf = out[key.replace("itd", "crosscorrelation", 1)][: ref.shape[0]]
    max_lag = ccf.shape[2] // 2
    for t, c in zip(*np.nonzero(over)):
        ours, theirs = got[t, c], ref[t, c]
        steps = abs(ours - theirs) * fs
        row = ccf[t, c]
        lag = lambda itd: int(np.clip(round(itd * fs + max_lag), 0, 2 * max_lag))
        gap = abs(row[lag(ours)] - row[lag(theirs)])
        assert steps <= o["max_lag_steps"], f"{key}[{t}, {c}]: {steps:.2f} lag steps off"
        assert gap <= o["tie_rel"] * np.abs(row).max(), f"{key}[{t}, {c}]: not a tie"


@pytest.mark.parametrize("case", CASES, ids=[c["case"] for c in CASES])
def test_golden_case(case):
    out, fs = run_case(case, os.path.join(GOLDEN, case["input"]))
    for sig in case["signals"]:
        if sig["key"].split("_")[0] not in case["requests"]:
            continue  # intermediate signals are checked by the Rust suite
        assert list(out[sig["key"]].shape) == sig["shape"]
        ref = np.load(os.path.join(GOLDEN, sig["file"]))
        check(out, sig["key"], ref, case["case"], fs)


@pytest.mark.parametrize("name", ["default_ratemap", "itd_ic_w40_h20_hamming", "chunks_irregular", "ihc_hilbert_fb16"])
def test_python_equals_cli_bit_for_bit(name, cli, tmp_path):
    case = next(c for c in CASES if c["case"] == name)
    wav = os.path.join(GOLDEN, case["input"])
    params = tmp_path / "params.json"
    params.write_text(json.dumps(case["nondefault_params"]))
    npz = tmp_path / "out.npz"
    cmd = [cli, "extract", wav, "-r", ",".join(case["requests"]), "--params", str(params), "-o", str(npz)]
    subprocess.run(cmd, check=True, capture_output=True)
    ref = np.load(npz)
    out = afe.process(wav, None, case["requests"], case["nondefault_params"])
    assert sorted(ref.files) == sorted([*out, "afe_metadata"])
    for k in out:
        np.testing.assert_array_equal(out[k], ref[k], err_msg=k)


def oracle_cases():
    base = os.environ.get("AFE_ORACLE_DIR")
    if not base:
        return []
    out = []
    ref = os.path.join(base, "ref")
    for inp in sorted(os.listdir(ref)):
        for name in sorted(os.listdir(os.path.join(ref, inp))):
            meta_path = os.path.join(ref, inp, name, "meta.json")
            if not os.path.isfile(meta_path):
                continue
            meta = json.load(open(meta_path))
            if name in {c["case"] for c in CASES}:
                out.append((os.path.join(base, "inputs", inp + ".wav"), os.path.join(ref, inp), meta))
    return out


def test_full_oracle_is_present_in_ci():
    """Under CI=true the full-oracle cases must run, not be skipped."""
    if os.environ.get("CI") == "true":
        assert os.environ.get("AFE_ORACLE_DIR"), "CI=true but AFE_ORACLE_DIR is not set"
        assert oracle_cases(), "AFE_ORACLE_DIR holds no case afe implements"


@pytest.mark.skipif(not os.environ.get("AFE_ORACLE_DIR"), reason="AFE_ORACLE_DIR not set")
@pytest.mark.parametrize("wav,base,meta", oracle_cases(), ids=[m["case"] for _, _, m in oracle_cases()])
def test_full_oracle_case(wav, base, meta):
    out, fs = run_case(meta, wav)
    for sig in meta["signals"]:
        if sig["name"] not in meta["requests"] or not sig.get("file"):
            continue
        key = f"{sig['name']}_{sig['channel']}"
        check(out, key, np.load(os.path.join(base, sig["file"])), meta["case"], fs)
