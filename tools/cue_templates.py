"""A localiser on the AFE's own cues, the second estimator issue 59 asks to compare with
afe's projection: per gammatone channel, templates of the normalised interaural
cross-correlation (lags within ±1.1 ms) and of the ILD for every azimuth, learnt from the
head model in diffuse noise; a frame's score for an azimuth is the Gaussian log-likelihood
of its cues summed over channels (each channel's cue spread learnt beside its template);
the frames' posteriors, each normalised, are averaged over the active frames, and the
largest is the estimate (the scheme of Two!Ears' GmmLocationKS, with one Gaussian per
channel and azimuth).

Used by tools/eval_localisation.py; needs only afe and numpy.
"""

from __future__ import annotations

from typing import Callable, Dict, List, Tuple

import numpy as np

import afe

#: The AFE's defaults for the cues, with 32 channels over 80-8000 Hz (as GmmLocationKS).
PARAMS = {"fb_nChannels": 32, "fb_lowFreqHz": 80.0, "fb_highFreqHz": 8000.0}
#: Azimuths rendered to learn from (deg), and the grid the templates are read on.
LEARNT = np.arange(0.0, 360.0, 5.0)
GRID = np.arange(0.0, 360.0, 1.0)
#: Frames within this many dB of the loudest one are located.
ACTIVE_DB = 30.0

_cache: Dict[Tuple[str, float], "Templates"] = {}


def cues(ears: np.ndarray, fs: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cross-correlation `[frame, channel, lag]`, the ILD `[frame, channel]` (dB) and
    each frame's level (dB) of binaural `ears` `[samples, 2]`."""
    out = afe.process(ears, fs, ["crosscorrelation", "ild"], PARAMS)
    cc = np.nan_to_num(np.asarray(out["crosscorrelation_mono"]))
    ild = np.nan_to_num(np.asarray(out["ild_mono"]))
    hop = int(round(0.01 * fs))
    frames = len(cc)
    energy = np.array([np.sum(ears[k * hop:k * hop + 2 * hop] ** 2) for k in range(frames)])
    level = 10.0 * np.log10(energy + 1e-20)
    return cc, ild, level


class Templates:
    """Per channel and azimuth of `GRID`, the mean cues in each training condition (a
    signal-to-noise ratio of the diffuse noise) and their spread in it: a mixture of one
    Gaussian per condition."""

    def __init__(self, head: str, fs: float, seconds: float = 0.5,
                 snrs_db: Tuple[float, ...] = (30.0, 10.0, 0.0)):
        rng = np.random.default_rng(59)
        n = int(seconds * fs)
        # diffuse noise from 18 directions, independent in each, a stretch per azimuth
        # (a render reads the head: one per direction)
        diffuse = sum(afe.render(rng.standard_normal(n * len(LEARNT)), fs, float(d), head=head)
                      for d in np.arange(0.0, 360.0, 20.0))
        stats = {snr: ([], [], [], []) for snr in snrs_db}
        for k, az in enumerate(LEARNT):
            ears = afe.render(rng.standard_normal(n), fs, float(az), head=head)
            noise = diffuse[k * n:(k + 1) * n]
            for snr in snrs_db:
                gain = np.sqrt(np.sum(ears ** 2) / np.sum(noise ** 2)) * 10 ** (-snr / 20.0)
                cc, ild, _ = cues(ears + gain * noise, fs)
                cc, ild = cc[2:], ild[2:]  # the first frames see the filters' onsets
                m_cc, m_ild, v_cc, v_ild = stats[snr]
                m_cc.append(cc.mean(axis=0))
                m_ild.append(ild.mean(axis=0))
                v_cc.append(((cc - cc.mean(axis=0)) ** 2).mean(axis=0).sum(axis=-1))
                v_ild.append(((ild - ild.mean(axis=0)) ** 2).mean(axis=0))

        # read on the 1-degree grid between the learnt azimuths, round the circle
        def on_grid(m: np.ndarray) -> np.ndarray:
            ext = np.concatenate([m, m[:1]])
            at = np.concatenate([LEARNT, [360.0]])
            flat = ext.reshape(len(ext), -1)
            cols = [np.interp(GRID, at, flat[:, j]) for j in range(flat.shape[1])]
            return np.stack(cols, axis=-1).reshape((len(GRID),) + m.shape[1:])

        # [condition, azimuth, channel(, lag)] and [condition, channel]
        self.cc = np.stack([on_grid(np.array(stats[s][0])) for s in snrs_db])
        self.ild = np.stack([on_grid(np.array(stats[s][1])) for s in snrs_db])
        self.var_cc = np.stack([np.mean(stats[s][2], axis=0) for s in snrs_db]) + 1e-6
        self.var_ild = np.stack([np.mean(stats[s][3], axis=0) for s in snrs_db]) + 1e-3

    def frame_scores(self, cc: np.ndarray, ild: np.ndarray) -> np.ndarray:
        """One frame's log-likelihood of every azimuth: per channel, the mixture over the
        conditions, summed over channels."""
        lags = cc.shape[-1]
        d_cc = ((cc[None, None] - self.cc) ** 2).sum(axis=-1) / self.var_cc[:, None]
        d_ild = (ild[None, None] - self.ild) ** 2 / self.var_ild[:, None]
        norm = 0.5 * (lags * np.log(self.var_cc / lags) + np.log(self.var_ild))[:, None]
        ll = -0.5 * (d_cc + d_ild) - norm  # [condition, azimuth, channel]
        top = ll.max(axis=0)
        per_channel = top + np.log(np.exp(ll - top).sum(axis=0))
        return per_channel.sum(axis=1)

    def posterior(self, ears: np.ndarray, fs: float) -> np.ndarray:
        """The frames' normalised posteriors over `GRID`, averaged over the active frames."""
        cc, ild, level = cues(ears, fs)
        active = level >= level.max() - ACTIVE_DB
        total = np.zeros(len(GRID))
        for t in np.flatnonzero(active):
            score = self.frame_scores(cc[t], ild[t])
            p = np.exp(score - score.max())
            total += p / p.sum()
        return total / max(1, active.sum())


def estimate(head: str, fs: float) -> Callable[[np.ndarray, float], List[float]]:
    """A localiser of single talkers by the cue templates of `head` at `fs` (learnt once)."""
    key = (head, fs)
    if key not in _cache:
        _cache[key] = Templates(head, fs)
    templates = _cache[key]

    def run(ears: np.ndarray, rate: float) -> List[float]:
        return [float(GRID[int(np.argmax(templates.posterior(ears, rate)))])]

    return run
