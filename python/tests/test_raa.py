"""afe.raa, the AFE's Room Acoustic Analyzer, against afeRAA run under GNU Octave on
data/raa_speech_16k.wav (data/oracle_raa/README.md): every par field within 1e-6
relative, every array within 1e-6 of its largest magnitude, the masks and integers
exactly; the CLI's --json equal to it; the errors of inputs afeRAA cannot take."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import afe
from conftest import under_address_limit

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
WAV = os.path.join(ROOT, "data", "raa_speech_16k.wav")
REF = np.load(os.path.join(ROOT, "data", "oracle_raa", "raa_speech_16k.npz"))
PAR = ["BL", "sREV", "FL", "pClar", "sClar", "Llow", "ITDf", "pASW", "sASW", "ITDb", "pLEV", "sLEV"]


@pytest.fixture(scope="module")
def result():
    x, fs = afe.read_wav(WAV)
    return afe.raa(x, fs)


def field_error(out, ref):
    """max|out - ref| / max|ref| over a whole field."""
    return np.max(np.abs(out - ref)) / np.max(np.abs(ref))


def test_every_predictor_matches_afe_raa(result):
    par, _ = result
    assert list(par) == PAR
    for name in PAR:
        want = float(REF[f"par_{name}"])
        assert isinstance(par[name], float)
        assert abs(par[name] - want) <= 1e-6 * abs(want), (name, par[name], want)


def test_psi_matches_afe_raa(result):
    _, psi = result
    assert psi["fs"] == REF["psi_fs"] == 16000
    for name in ("numSamples", "numBands", "itdNumFrames"):
        assert isinstance(psi[name], int)
        assert psi[name] == REF[f"psi_{name}"], name
    for ear in "LR":
        mask = REF[f"dirmask_{ear}"] == 1
        np.testing.assert_array_equal(psi[f"Psi{ear}dir"] != 0, mask)
        base = REF[f"Psi{ear}"].astype(np.float64)
        for stream, ref in ((f"Psi{ear}dir", base * mask), (f"Psi{ear}rev", base * ~mask)):
            assert psi[stream].shape == ref.shape
            assert field_error(psi[stream], ref) <= 1e-6, stream
    for name in ("PsiL", "PsiR", "ITD", "ITDdir", "ITDrev", "f", "t_psi", "t_itd"):
        ref = REF[name].astype(np.float64)
        assert psi[name].shape == ref.shape, name
        assert psi[name].dtype == np.float64
        assert field_error(psi[name], ref) <= 1e-6, (name, field_error(psi[name], ref))


def test_a_path_and_the_afe_constants_give_the_same(result):
    par, _ = result
    defaults = {k[len("parConf_"):]: float(REF[k]) for k in REF.files if k.startswith("parConf_")}
    assert len(defaults) == 15
    par_path, _ = afe.raa(WAV, None, **defaults)
    assert par_path == par


def test_constants_change_the_predictors(result):
    par, _ = result
    # a longer T_min leaves fewer direct segments: less foreground, more background
    longer, _ = afe.raa(WAV, 16000, T_min=0.2)
    assert longer["FL"] < par["FL"] and longer["BL"] > par["BL"]
    # b_P_REV only moves the reverberance sigmoid
    shifted, _ = afe.raa(WAV, 16000, b_P_REV=par["BL"])
    assert shifted["sREV"] == 0.5 and shifted["BL"] == par["BL"]


def test_cli_json_equals_afe_raa(cli, result):
    par, psi = result
    out = subprocess.run([cli, "raa", WAV, "--json"], capture_output=True, text=True, check=True)
    printed = json.loads(out.stdout)
    assert printed["par"] == par
    assert printed["psi"] == {k: psi[k] for k in ("fs", "numSamples", "numBands", "itdNumFrames")}


def test_bad_input_is_refused_naming_what_is_wrong():
    x, fs = afe.read_wav(WAV)
    short = x[:4000]
    cases = [
        (lambda: afe.raa(x[:, 0], fs), "two channels (left, right): got 1"),
        (lambda: afe.raa(x.T, fs), "pass x.T"),
        (lambda: afe.raa(np.zeros((0, 2)), fs), "the input signal is empty"),
        (lambda: afe.raa(np.where(np.arange(4000)[:, None] == 9, np.nan, short), fs),
         "sample 9 of the left ear is NaN"),
        (lambda: afe.raa(short, 8000), "more than 8000 Hz"),
        (lambda: afe.raa(short[:1000], fs), "at least 1200"),
        (lambda: afe.raa(short, fs, mu_psi=1e6), "give mu_psi a lower value"),
        (lambda: afe.raa(short, fs, mu_psi_dip=-1e6), "give mu_psi_dip a higher value"),
        (lambda: afe.raa(short, fs, Tmin=0.1), "unknown RAA constant 'Tmin' (did you mean 'T_min'?)"),
        (lambda: afe.raa(short, fs, T_min="long"), "'T_min': expected a number"),
        (lambda: afe.raa(short, fs, T_min=float("nan")), "constant 'T_min' is nan"),
        (lambda: afe.raa(short, None), "fs is required"),
        (lambda: afe.raa(WAV, 44100), "sampled at 16000"),
    ]
    for call, needle in cases:
        with pytest.raises(ValueError) as e:
            call()
        assert needle in str(e.value), (needle, str(e.value))


def test_constants_outside_their_range_are_refused_naming_them():
    """Issue 57, finding 6: nu_ASW=-1 and 12 other values gave NaN or inf predictors."""
    x, fs = afe.read_wav(WAV)
    short = x[:16000]
    for name in ("mu_psi", "mu_psi_dip", "T_min", "a_P_REV", "b_P_REV", "a_P_CLA", "b_P_CLA",
                 "mu_ASW", "nu_ASW", "a_P_ASW", "b_P_ASW", "mu_LEV", "nu_LEV", "a_P_LEV",
                 "b_P_LEV"):
        for value in (-1.0, 0.0, 1e308, -1e308):
            try:
                par, _ = afe.raa(short, fs, **{name: value})
            except ValueError as e:
                text = str(e)
                assert f"RAA constant {name} = " in text or "no sample of Psi" in text, text
                continue
            assert all(np.isfinite(v) for v in par.values()), (name, value, par)
    with pytest.raises(ValueError, match="nu_ASW = -1: the predictors are finite for values"):
        afe.raa(short, fs, nu_ASW=-1)


def test_a_signal_too_long_for_the_memory_is_a_memory_error(monkeypatch):
    """Issue 57, finding 3: afe.raa under 3 GB killed Python; now refused before it runs."""
    x, fs = afe.read_wav(WAV)
    monkeypatch.setenv("AFE_MEMORY_AVAILABLE_GB", "0.05")
    with pytest.raises(MemoryError, match="more than the 50.0 MB available: analyse an excerpt"):
        afe.raa(x, fs)
    monkeypatch.setenv("AFE_MEMORY_AVAILABLE_GB", "abc")
    with pytest.raises(ValueError, match='AFE_MEMORY_AVAILABLE_GB is "abc"'):
        afe.raa(x, fs)


def test_raa_under_an_address_space_limit_raises_and_the_interpreter_lives():
    """60 s at 16 kHz under RLIMIT_AS of what the interpreter holds plus 300 MB."""
    # the signal made under the limit, as the RAA's own input
    out = under_address_limit(
        "", "afe.raa(0.1 * np.sin(0.05 * np.arange(60 * 16000))[:, None] * np.ones(2), 16000)",
        300_000_000, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "refused: the RAA of 60.0 s of signal would take about" in out.stdout, out.stdout
