#!/usr/bin/env python3
"""Synthesise ``data/example_binaural.wav``, the binaural test signal of the examples and
benchmarks (Python standard library only; deterministic).

The signal
----------
1.0 s at 44100 Hz, 2 channels (left, right), 16-bit PCM, peak -3 dBFS.

* A speech-like voiced source: a harmonic complex of 20 harmonics whose fundamental glides
  linearly from 110 Hz to 180 Hz. Each harmonic is weighted by a formant-like spectral
  envelope (resonances near 500, 1500 and 2500 Hz on a -6 dB/octave tilt) evaluated at the
  harmonic's instantaneous frequency, so the formants stay put while f0 moves.
* Amplitude-modulated at a 4 Hz syllable rate (sin^2, depth 80 %) and gated: silence for
  the first 50 ms, a 20 ms raised-cosine onset, a 20 ms offset ending at 0.98 s.
* Plus a little white noise (seeded, about 35 dB below the voiced part's RMS) that is
  present throughout, including the leading 50 ms.

The source reaches the ears as from a talker on the left: the right ear gets the same
source delayed by 0.5 ms (22.05 samples) and attenuated by 6 dB. The voiced part of the
right ear is synthesised directly at t - 0.5 ms (exact for a synthesised signal); the
noise is delayed by linear interpolation.

Expected cues (once the voice is present, i.e. after about 60 ms)
-----------------------------------------------------------------
* ILD (right re left) about -6 dB in every channel with signal energy.
* ITD about -0.5 ms (the right ear lags; the AFE convention is positive = right leads),
  clearest in the low-frequency channels.
* IC close to 1.

Usage: ``python3 tools/make_example_wav.py [output.wav]`` (default: the path above,
relative to the repository root).
"""

import math
import os
import random
import struct
import sys
import wave

FS = 44100
DURATION_S = 1.0
F0_START_HZ = 110.0
F0_END_HZ = 180.0
HARMONICS = 20
SYLLABLE_RATE_HZ = 4.0
AM_DEPTH = 0.8
VOICE_START_S = 0.05
VOICE_END_S = 0.98
RAMP_S = 0.02
ITD_S = 0.5e-3  # right ear lags by this much
ILD_DB = -6.0  # right re left
PEAK_DBFS = -3.0
NOISE_RE_VOICE_DB = -35.0
SEED = 20240611

# (centre Hz, bandwidth Hz, gain) of the formant-like resonances
FORMANTS = ((500.0, 120.0, 1.0), (1500.0, 180.0, 0.5), (2500.0, 250.0, 0.3))


def f0_phase(t):
    """Phase (cycles) of the fundamental at time t: integral of the linear f0 glide."""
    slope = (F0_END_HZ - F0_START_HZ) / DURATION_S
    return F0_START_HZ * t + 0.5 * slope * t * t


def f0_at(t):
    """Instantaneous fundamental frequency in Hz."""
    return F0_START_HZ + (F0_END_HZ - F0_START_HZ) * t / DURATION_S


def spectral_envelope(f_hz):
    """Linear amplitude of a harmonic at f_hz: resonances on a -6 dB/octave tilt."""
    tilt = 100.0 / max(f_hz, 100.0)
    res = 0.05
    for centre, bw, gain in FORMANTS:
        res += gain / (1.0 + ((f_hz - centre) / bw) ** 2)
    return tilt * res


def gate(t):
    """Voice on/off gate with raised-cosine ramps."""
    if t <= VOICE_START_S or t >= VOICE_END_S:
        return 0.0
    if t < VOICE_START_S + RAMP_S:
        return 0.5 - 0.5 * math.cos(math.pi * (t - VOICE_START_S) / RAMP_S)
    if t > VOICE_END_S - RAMP_S:
        return 0.5 - 0.5 * math.cos(math.pi * (VOICE_END_S - t) / RAMP_S)
    return 1.0


def voice(t):
    """The voiced source at time t (any real t, so it can be evaluated at t - ITD)."""
    g = gate(t)
    if g == 0.0:
        return 0.0
    am = 1.0 - AM_DEPTH + AM_DEPTH * math.sin(math.pi * SYLLABLE_RATE_HZ * (t - VOICE_START_S)) ** 2
    phase = 2.0 * math.pi * f0_phase(t)
    f0 = f0_at(t)
    x = 0.0
    for k in range(1, HARMONICS + 1):
        x += spectral_envelope(k * f0) * math.sin(k * phase)
    return g * am * x


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(root, "data", "example_binaural.wav")
    n = int(round(FS * DURATION_S))
    rng = random.Random(SEED)

    left_voice = [voice(i / FS) for i in range(n)]
    right_voice = [voice(i / FS - ITD_S) for i in range(n)]

    voiced = [v for i, v in enumerate(left_voice) if gate(i / FS) == 1.0]
    voice_rms = math.sqrt(sum(v * v for v in voiced) / len(voiced))
    noise_rms = voice_rms * 10.0 ** (NOISE_RE_VOICE_DB / 20.0)
    # extra leading samples so the delayed right-ear noise is defined from t = 0
    lead = int(math.ceil(ITD_S * FS)) + 1
    noise = [rng.gauss(0.0, noise_rms) for _ in range(n + lead)]

    def noise_at(t):
        """The noise source at time t >= -lead/FS, by linear interpolation."""
        pos = t * FS + lead
        i = int(math.floor(pos))
        frac = pos - i
        return (1.0 - frac) * noise[i] + frac * noise[min(i + 1, len(noise) - 1)]

    gain_r = 10.0 ** (ILD_DB / 20.0)
    left = [left_voice[i] + noise[i + lead] for i in range(n)]
    right = [gain_r * (right_voice[i] + noise_at(i / FS - ITD_S)) for i in range(n)]

    peak = max(max(abs(v) for v in left), max(abs(v) for v in right))
    scale = 10.0 ** (PEAK_DBFS / 20.0) / peak
    frames = bytearray()
    for a, b in zip(left, right):
        qa = max(-32768, min(32767, int(round(a * scale * 32768.0))))
        qb = max(-32768, min(32767, int(round(b * scale * 32768.0))))
        frames += struct.pack("<hh", qa, qb)

    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    with wave.open(out, "wb") as w:
        w.setnchannels(2)
        w.setsampwidth(2)
        w.setframerate(FS)
        w.writeframes(bytes(frames))
    print(f"wrote {out}: {n} frames, {FS} Hz, 2 ch, 16-bit, peak {PEAK_DBFS:.1f} dBFS")


if __name__ == "__main__":
    main()
