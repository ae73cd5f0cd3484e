"""Interaural coherence (IC): the height of the normalised interaural cross-correlation
peak per frame and channel.

Ports the AFE's ``DEMO_IC``, which compares anechoic and reverberant speech. Here the
anechoic input is the example WAV (one talker, no room: IC close to 1) and the
reverberant one is the same signal convolved, per ear, with a direct path plus an
independent exponentially decaying noise tail (reverberation time 0.4 s, direct-to-reverberant
ratio 0 dB): the diffuse tail decorrelates the ears, so the IC drops. A third input
sweeps the coherence of binaural noise (left = n₁, right = ρ·n₁ + √(1−ρ²)·n₂): the IC
rises with ρ and is 1 for identical ears. (The IC is computed on the inner-hair-cell
envelopes, which are positive, so independent noises still give an IC well above 0.)

usage: python demo_ic.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import EXAMPLE_VOICED_S, frame_times, read_example, run, save_figure, tf_image

PARAMS = {"fb_lowFreqHz": 80, "fb_highFreqHz": 8000, "fb_nChannels": 32, "ihc_method": "dau",
          "cc_wSizeSec": 0.02, "cc_hSizeSec": 0.01, "cc_wname": "hann"}
RT60_S = 0.4  # reverberation time of the synthetic room
COHERENCES = (0.0, 0.25, 0.5, 0.75, 1.0)  # interaural correlation of the noise inputs


def fft_convolve(x: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Linear convolution of ``x`` with ``h``, truncated to ``len(x)`` samples."""
    n = len(x) + len(h) - 1
    nfft = 1 << (n - 1).bit_length()
    return np.fft.irfft(np.fft.rfft(x, nfft) * np.fft.rfft(h, nfft), nfft)[: len(x)]


def reverberate(x: np.ndarray, fs: float, rng: np.random.Generator) -> np.ndarray:
    """Adds a diffuse tail (independent per ear, equal in energy to the direct path)."""
    t = np.arange(int(RT60_S * fs)) / fs
    ears = []
    for ear in range(x.shape[1]):
        tail = rng.standard_normal(t.size) * 10 ** (-3 * t / RT60_S)  # −60 dB at RT60
        tail[0] = 0.0
        h = tail / np.sqrt(np.sum(tail**2))
        h[0] = 1.0  # direct path
        ears.append(fft_convolve(x[:, ear], h))
    return np.column_stack(ears)


def main(outdir: str) -> Dict[str, float]:
    """Computes the IC of every input, saves ``demo_ic.png``, returns the median ICs."""
    x, fs = read_example()
    rng = np.random.default_rng(3)
    rev = reverberate(x, fs, rng)

    m = afe.Manager(fs, channels=2)
    m.add_request("ic", PARAMS)
    ic_anechoic = m.process_signal(x)["ic_mono"]
    info = m.info()["ic_mono"]
    ic_reverberant = m.process_signal(rev)["ic_mono"]
    t = frame_times(ic_anechoic.shape[0], info["fs_hz"])
    voiced = (t >= EXAMPLE_VOICED_S[0]) & (t <= EXAMPLE_VOICED_S[1])

    n1, n2 = 0.1 * rng.standard_normal((2, int(fs)))
    ic_noise = []
    for rho in COHERENCES:
        right = rho * n1 + np.sqrt(1 - rho**2) * n2
        ic = m.process_signal(np.column_stack([n1, right]))["ic_mono"]
        ic_noise.append(float(np.median(ic[2:])))

    fig = plt.figure(figsize=(9, 10), constrained_layout=True)
    grid = fig.add_gridspec(3, 1)
    for row, (ic, title) in enumerate([(ic_anechoic, "anechoic (example WAV)"),
                                       (ic_reverberant, f"reverberant (RT60 {RT60_S} s)")]):
        ax = fig.add_subplot(grid[row])
        tf_image(fig, ax, ic, info["fs_hz"], info["cf_hz"], "IC", vmin=0.0, vmax=1.0)
        ax.set_title(f"Interaural coherence, {title}")
    ax = fig.add_subplot(grid[2])
    ax.plot(COHERENCES, ic_noise, "o-")
    ax.set(xlabel="interaural correlation ρ of the noise", ylabel="median IC",
           title="IC of partially coherent noise")
    ax.grid(True)
    save_figure(fig, outdir, "demo_ic")
    numbers = {"ic_anechoic": float(np.median(ic_anechoic[voiced])),
               "ic_reverberant": float(np.median(ic_reverberant[voiced]))}
    numbers.update({f"ic_noise_rho_{rho:.2f}": ic for rho, ic in zip(COHERENCES, ic_noise)})
    return numbers


if __name__ == "__main__":
    run(main)
