"""The gammatone filterbank: its channels, their frequency responses, and their sum.

Ports the AFE's ``DEMO_Gammatone`` (request ``filterbank``: 16 channels, 80 Hz – 8 kHz,
on speech, drawn as stacked waveforms) and the idea of ``DEMO_Gammatone_Reconstruction``:
filter a unit impulse with 64 channels from 50 Hz to half the sampling rate, compensate
each channel's envelope delay (``fb_delaySec`` of ``Manager.request_parameters``) and sum
the channels. Without phase alignment the channels' carriers interfere in the sum; with
``fb_bAlign = True`` each channel's carrier peaks with its envelope and the sum is close
to a delayed impulse, with a nearly flat magnitude response.

Key numbers (channels from 200 Hz up): each channel's magnitude response peaks at its
centre frequency (truth: relative error 0) and its equivalent rectangular bandwidth is
1.018 × 0.982 = 1.000 ERB (a 4th-order gammatone with ``fb_bwERBs = 1.018``); the ripple
of the summed response between 200 Hz and 16 kHz, with and without phase alignment.

usage: python demo_gammatone.py [outdir]
"""

from __future__ import annotations

from typing import Dict, Tuple

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import erb_axis, erb_hz, read_example, run, save_figure, waveplot

SPEECH_PARAMS = {"fb_type": "gammatone", "fb_lowFreqHz": 80, "fb_highFreqHz": 8000,
                 "fb_nChannels": 16}
IMPULSE_LENGTH = 8192  # samples
IMPULSE_AT = 1024  # sample index of the unit impulse
FLAT_BAND_HZ = (200.0, 16000.0)  # band where the summed response's ripple is measured
NFFT = 1 << 16  # FFT length of the frequency responses (0.67-Hz bins at 44.1 kHz)


def impulse_responses(fs: float, align: bool) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Impulse responses ``[sample, channel]`` of a 64-channel filterbank, its centre
    frequencies (Hz) and envelope delays (s)."""
    m = afe.Manager(fs, channels=1)
    h = m.add_request("filterbank", {"fb_lowFreqHz": 50, "fb_highFreqHz": fs / 2,
                                     "fb_nChannels": 64, "fb_bAlign": align})
    impulse = np.zeros(IMPULSE_LENGTH)
    impulse[IMPULSE_AT] = 1.0
    out = m.process_signal(impulse)["filterbank_mono"]
    chain = m.request_parameters(h)
    return out, np.array(chain["fb_cfHz"]), np.array(chain["fb_delaySec"])


def delay_compensated_sum(responses: np.ndarray, delay_s: np.ndarray, fs: float) -> np.ndarray:
    """Sum over channels after delaying each so that all envelopes peak together."""
    delay = np.round(delay_s * fs).astype(int)
    shifted = [np.roll(responses[:, c], delay.max() - delay[c]) for c in range(len(delay))]
    return np.sum(shifted, axis=0)


def main(outdir: str) -> Dict[str, float]:
    """Filters speech and an impulse, saves ``demo_gammatone.png``, returns the response checks."""
    x, fs = read_example()
    m = afe.Manager(fs, channels=1)
    m.add_request("filterbank", SPEECH_PARAMS)
    speech_bands = m.process_signal(x[:, 0])["filterbank_mono"]
    speech_cf = m.info()["filterbank_mono"]["cf_hz"]

    freqs = np.fft.rfftfreq(NFFT, 1 / fs)
    flat = (freqs >= FLAT_BAND_HZ[0]) & (freqs <= FLAT_BAND_HZ[1])
    sums, ripple = {}, {}
    for align in (False, True):
        responses, cf, delay_s = impulse_responses(fs, align)
        sums[align] = delay_compensated_sum(responses, delay_s, fs)
        sum_db = 20 * np.log10(np.abs(np.fft.rfft(sums[align], NFFT)))
        ripple[align] = float(np.ptp(sum_db[flat]))
    gains = np.abs(np.fft.rfft(responses, NFFT, axis=0))  # aligned bank, [frequency, channel]
    peak_hz = freqs[np.argmax(gains, axis=0)]
    erb_measured = np.sum(gains**2, axis=0) * (freqs[1] - freqs[0]) / np.max(gains, axis=0) ** 2
    upper = cf >= FLAT_BAND_HZ[0]

    fig, axes = plt.subplots(3, 1, figsize=(9, 12), constrained_layout=True)
    waveplot(axes[0], speech_bands, fs, speech_cf, zoom=3)
    axes[0].set_title("Gammatone filterbank output, left ear of the example WAV (16 channels)")
    for c in range(0, len(cf), 3):
        axes[1].plot(freqs[1:], 20 * np.log10(gains[1:, c]), color="0.6", linewidth=0.7)
    for align, style in ((False, "C0"), (True, "C3")):
        axes[1].plot(freqs[1:], 20 * np.log10(np.abs(np.fft.rfft(sums[align], NFFT)))[1:], style,
                     label=f"sum of all 64, {'with' if align else 'without'} phase alignment")
    erb_axis(axes[1], "x", label="frequency (Hz)")
    axes[1].set(ylabel="magnitude (dB)", ylim=(-40, 15), xlim=(30, fs / 2),
                title="Impulse responses: every third channel (grey) and the delay-compensated sums")
    axes[1].legend(loc="lower center")
    t_ms = 1e3 * (np.arange(IMPULSE_LENGTH) - IMPULSE_AT) / fs
    centre = IMPULSE_AT + int(round(delay_s.max() * fs))
    view = slice(centre - 40, centre + 40)
    for align, style in ((False, "C0"), (True, "C3")):
        axes[2].plot(t_ms[view], sums[align][view], style,
                     label=f"sum, {'with' if align else 'without'} phase alignment")
    axes[2].axvline(t_ms[centre], color="gray", linestyle="--", label="delayed input impulse")
    axes[2].set(xlabel="time after the impulse (ms)", ylabel="amplitude",
                title="Reconstructed impulse (the channels' sum)")
    axes[2].legend()
    save_figure(fig, outdir, "demo_gammatone")
    return {
        "max_peak_error_rel": float(np.max(np.abs(peak_hz[upper] / cf[upper] - 1))),
        "median_erb_ratio": float(np.median(erb_measured[upper] / erb_hz(cf[upper]))),
        "ripple_db_aligned": ripple[True],
        "ripple_db_unaligned": ripple[False],
    }


if __name__ == "__main__":
    run(main)
