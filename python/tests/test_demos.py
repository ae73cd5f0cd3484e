"""The demos of examples/afe_demos: each runs, draws a non-blank figure, and its key
numbers match the known cues of its inputs (ILD, ITD, F0, formants, filter shapes, ...)."""

import importlib.util
import os
import subprocess
import sys
from types import ModuleType
from typing import Callable, Dict

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
from matplotlib import image  # noqa: E402

DEMOS_DIR = os.path.abspath(
    os.path.join(os.path.dirname(__file__), "..", "..", "examples", "afe_demos")
)
DEMOS = sorted(f[:-3] for f in os.listdir(DEMOS_DIR) if f.startswith("demo_") and f.endswith(".py"))
FS = 44100.0  # rate of the example WAV, Hz


def _load(name: str) -> ModuleType:
    """Imports examples/afe_demos/<name>.py (its directory on sys.path, for _common)."""
    if DEMOS_DIR not in sys.path:
        sys.path.insert(0, DEMOS_DIR)
    spec = importlib.util.spec_from_file_location(name, os.path.join(DEMOS_DIR, f"{name}.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def outdir(tmp_path_factory):
    """One figure directory for the whole module."""
    return tmp_path_factory.mktemp("demo_figures")


@pytest.fixture(scope="module")
def run(outdir) -> Callable[[str], Dict[str, object]]:
    """Runs a demo once per test session and returns its key numbers."""
    cache: Dict[str, Dict[str, object]] = {}

    def _run(name: str) -> Dict[str, object]:
        """The key numbers of demo ``name`` (run on first use)."""
        if name not in cache:
            cache[name] = _load(name).main(str(outdir))
        return cache[name]

    return _run


def test_the_demos_are_there():
    assert len(DEMOS) >= 9, DEMOS
    for required in ("ild", "itd", "ic", "ratemap", "crosscorrelation", "chunkbased",
                     "gammatone", "feedback", "preprocessing"):
        assert f"demo_{required}" in DEMOS


@pytest.mark.parametrize("name", DEMOS)
def test_demo_draws_a_figure(run, outdir, name):
    numbers = run(name)
    assert numbers and all(isinstance(k, str) for k in numbers)
    png = outdir / f"{name}.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert png.stat().st_size > 20000
    pixels = image.imread(str(png))[..., :3]
    assert pixels.std() > 0.05  # not blank
    assert np.mean(pixels.min(axis=2) < 0.9) > 0.02  # something is drawn, not just a frame


@pytest.mark.parametrize("name", DEMOS)
def test_demo_has_checks_and_is_documented(name):
    """Every demo has a key-number test below and a line in the README."""
    assert f"test_{name}" in globals(), f"add a test of {name}'s key numbers"
    with open(os.path.join(DEMOS_DIR, "README.md"), encoding="utf-8") as f:
        assert f"{name}.py" in f.read()
    assert _load(name).__doc__.strip()


def test_demo_ild(run):
    n = run("demo_ild")
    assert n["median_ild_example_db"] == pytest.approx(-6.0, abs=0.5)  # right ear 6 dB weaker
    assert n["median_ild_noise_db"] == pytest.approx(6.0, abs=0.5)  # right ear 6 dB louder


def test_demo_itd(run):
    n = run("demo_itd")
    assert n["itd_example_ms"] == pytest.approx(-0.5, abs=1e3 / FS)  # right ear lags 0.5 ms
    assert n["itd_noise_samples"] == pytest.approx(10.0, abs=1.0)  # left ear lags 10 samples


def test_demo_ic(run):
    n = run("demo_ic")
    assert n["ic_anechoic"] > 0.98
    assert n["ic_reverberant"] < n["ic_anechoic"] - 0.05
    noise = [n[f"ic_noise_rho_{rho:.2f}"] for rho in (0.0, 0.25, 0.5, 0.75, 1.0)]
    assert noise[-1] > 0.999  # identical ears
    assert all(a < b for a, b in zip(noise, noise[1:]))  # IC grows with the correlation


def test_demo_ratemap(run):
    n = run("demo_ratemap")
    for formant in (500, 1500, 2500):
        erb = 24.7 + 0.108 * formant
        assert abs(n[f"formant_peak_{formant}_hz"] - formant) < erb


def test_demo_crosscorrelation(run):
    n = run("demo_crosscorrelation")
    for key in ("peak_lag_frame_ms", "peak_lag_median_ms"):
        assert n[key] == pytest.approx(-0.5, abs=1e3 / FS)


def test_demo_chunkbased(run):
    n = run("demo_chunkbased")
    assert n["chunks"] > 5
    diffs = {k: v for k, v in n.items() if k.startswith("max_abs_diff_")}
    assert len(diffs) == 6 and all(v == 0.0 for v in diffs.values()), diffs  # bit for bit


def test_demo_gammatone(run):
    n = run("demo_gammatone")
    assert n["max_peak_error_rel"] < 0.01  # each channel peaks at its centre frequency
    assert n["median_erb_ratio"] == pytest.approx(1.018 * 0.9817, abs=0.01)
    assert n["ripple_db_aligned"] < 2.0
    assert n["ripple_db_unaligned"] > 2 * n["ripple_db_aligned"]


def test_demo_feedback(run):
    n = run("demo_feedback")
    assert n["frame_times_increasing"] is True
    assert n["frames_per_chunk"] == 9  # 0.1-s chunks, framing restarted by each change
    for which in ("first", "last"):
        assert n[f"width_{which}_hz"] == pytest.approx(n[f"width_{which}_predicted_hz"], rel=0.1)
    assert n["width_last_hz"] > 3 * n["width_first_hz"]


def test_demo_preprocessing(run):
    n = run("demo_preprocessing")
    assert n["dc_residue_db"] < -60  # the 0.5-Hz sinusoid is gone
    assert n["level_step_db"] == pytest.approx(20 * np.log10(5), abs=0.01)
    assert abs(n["level_step_mono_agc_db"]) < 3  # AGC equalises the halves
    assert abs(n["ild_mono_agc_db"]) < 0.5  # monaural AGC erases the ILD
    assert n["ild_binaural_agc_db"] == pytest.approx(-6.0, abs=0.5)  # binaural AGC keeps it
    assert n["level_scaling_gain_db"] == pytest.approx(100 - 94, abs=1e-9)
    assert abs(n["middle_ear_peak_hz"] - 800) < 100  # stapes velocity maximum of the data
    assert n["middle_ear_peak_db"] == pytest.approx(0.0, abs=0.1)  # unity compensation
    assert n["middle_ear_delay_samples"] == 256  # linear phase, 513 taps


def test_demo_autocorrelation(run):
    n = run("demo_autocorrelation")
    assert n["f0_frame_hz"] == pytest.approx(n["f0_frame_truth_hz"], rel=0.02)
    assert n["f0_median_rel_error"] < 0.02


def test_demo_pitch(run):
    n = run("demo_pitch")
    assert n["complex_pitch_hz"] == pytest.approx(200.0, rel=0.02)
    assert n["speech_median_rel_error"] < 0.02
    assert n["speech_voiced_fraction"] > 0.6


def test_demo_onset_offset(run):
    n = run("demo_onset_offset")
    for f, on, off in ((1000, 0.2, 0.6), (4000, 0.4, 0.8)):
        assert n[f"onset_{f}hz_s"] == pytest.approx(on, abs=0.02)
        assert 0.0 <= n[f"offset_{f}hz_s"] - off <= 0.04
    assert n["offset_strength_in_silence_db"] == pytest.approx(n["decay_rate_db_per_frame"], abs=0.2)
    assert n["decay_rate_db_per_frame"] == pytest.approx(10.857, abs=1e-3)


def test_demo_spectral_features(run):
    n = run("demo_spectral_features")
    assert n["centroid_500hz_tone_hz"] == pytest.approx(500, rel=0.05)
    assert n["centroid_2000hz_tone_hz"] == pytest.approx(2000, rel=0.05)
    assert n["brightness_500hz_tone"] < 0.01 and n["brightness_2000hz_tone"] > 0.99
    assert n["flatness_tone"] < 0.01 and n["flatness_noise"] > 0.3


def test_demo_gabor(run):
    n = run("demo_gabor")
    assert n["n_features"] == 311  # the GBFB dimension for 23 channels
    assert n["max_abs_feature_mean"] < 1e-9
    assert n["median_feature_std"] == pytest.approx(1.0, abs=1e-6)


def test_demo_stft(run):
    n = run("demo_stft")
    assert n["peak_bin_hz"] == pytest.approx(n["tone_hz"], abs=1e-9)
    assert n["peak_magnitude_ratio"] == pytest.approx(1.0, abs=0.01)


def test_demo_drnl(run):
    n = run("demo_drnl")
    assert n["gammatone_slope"] == pytest.approx(1.0, abs=0.01)  # linear
    assert n["drnl_low_slope"] == pytest.approx(1.0, abs=0.1)  # linear below ~30 dB SPL
    assert 0.15 < n["drnl_mid_slope"] < 0.35  # compressive, CASP exponent 0.25
    assert n["speech_step_gammatone_db"] == pytest.approx(20 * np.log10(5), abs=0.1)
    assert n["speech_step_drnl_db"] < 0.7 * n["speech_step_gammatone_db"]


def test_demo_moc(run):
    n = run("demo_moc")
    for f in (520, 3980):
        att = [n[f"moc_{f}hz_{level}db_db"] for level in range(0, 91, 10)]
        assert att[0] == 0.0 and att[1] == 0.0  # faint tones: no attenuation
        assert all(b >= a for a, b in zip(att[:8], att[1:8]))  # grows with level up to 70 dB
        assert max(att) <= 40.0 and att[-1] > 20.0
        assert n[f"drnl_reduction_{f}hz_60db_db"] > 1.0


def test_demo_precedence(run):
    n = run("demo_precedence")
    assert n["itd_precedence_median_ms"] == pytest.approx(-0.5, abs=1e3 / FS)  # the lead's ITD
    assert n["frames_at_lead_precedence"] > 0.9
    assert n["frames_at_lead_precedence"] > n["frames_at_lead_plain"] + 0.2


def test_demo_adaptation(run):
    n = run("demo_adaptation")
    steady = [n[f"steady_{level}db_mu"] for level in (40, 60, 80)]
    assert steady[0] < steady[1] < steady[2]
    assert 0.8 < n["step_ratio"] < 1.25  # about logarithmic
    assert n["min_onset_ratio"] > 5
    assert n["offsets_undershoot"] is True


def test_demo_ams(run):
    n = run("demo_ams")
    for kind, fm in (("log", 32), ("log", 200), ("lin", 32), ("lin", 200)):
        assert n[f"{kind}_band_{fm}hz"] == n[f"{kind}_nearest_{fm}hz"]


def test_demo_duet(run):
    n = run("demo_duet")
    for source, (gain_db, delay) in (("voice", (-2.0, 2)), ("tones", (2.0, -2))):
        g = 10 ** (gain_db / 20)
        assert n[f"{source}_alpha"] == pytest.approx(g - 1 / g, abs=n["alpha_bin"])
        assert n[f"{source}_delta_samples"] == pytest.approx(delay, abs=n["delta_bin_samples"])


def test_demo_raa(run):
    n = run("demo_raa")
    assert n["max_par_rel_error_vs_afe"] < 1e-6  # the AFE's afeRAA on the same file
    for scaled in ("sREV", "sClar", "sASW", "sLEV"):
        assert 0.0 <= n[scaled] <= 1.0
    assert n["pClar"] == pytest.approx(n["FL"] / n["BL"], rel=1e-12)
    # a reverberant room: the direct streams hold a minority of the samples
    assert 0.0 < n["direct_fraction_left"] < 0.5 and 0.0 < n["direct_fraction_right"] < 0.5


def test_demo_runs_as_a_script(tmp_path):
    """``python demo_x.py OUTDIR`` writes the figure there and prints the key numbers."""
    script = os.path.join(DEMOS_DIR, "demo_ild.py")
    done = subprocess.run([sys.executable, script, str(tmp_path)], check=True,
                          capture_output=True, text=True, env=dict(os.environ, MPLBACKEND="Agg"))
    assert "median_ild_example_db: -6.0" in done.stdout
    assert (tmp_path / "demo_ild.png").stat().st_size > 20000
