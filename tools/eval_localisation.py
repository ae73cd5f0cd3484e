"""Evaluation of afe's localisation against the baselines a user would pick instead
(issue 59): binaural renders made here, scored as % within 5 degrees, mean absolute error
and front-back confusions, with pyroomacoustics' SRP-PHAT and NormMUSIC on the two ear
positions beside afe, on the same renders, in one table.

Renders (the example file's left ear, 2 s of speech, as the source):
- KEMAR (Debian's libmysofa1 MIT set) at 16 and 44.1 kHz: anechoic (afe.render),
  cylindrically diffuse noise at 20, 10 and 0 dB (72 directions, independent noise each),
  and pyroomacoustics shoebox rooms at T60 0.3, 0.6 and 0.9 s with the SOFA file as the
  ears' directivity (image sources up to order 40);
- the rigid sphere (15 cm) at 24414 Hz: anechoic, the same noise, and the same rooms
  with each image source rendered through the sphere from its horizontal direction;
- two talkers 40 degrees or more apart, anechoic, both heads;
- with ``--turning`` (issue 60): a head turning 30 degrees to the left and back within
  2 s, KEMAR at 16 kHz and the sphere, anechoic and in the T60 0.6 s room, ten talkers
  each, located with and without the yaw track.

    pip install pyroomacoustics python-sofa
    python tools/eval_localisation.py [--quick] [--markdown] [--turning]

Errors are folded (a direction and its front-back image count alike) for the % and the
mean; a front-back confusion is an estimate nearer the truth's mirror image than the
truth. The baselines see the two ear signals as a free-field pair 2·radius apart
(0.18 m for KEMAR), so they are folded by nature.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Callable, Dict, List, Sequence, Tuple

import numpy as np

import afe

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cue_templates  # noqa: E402

if not hasattr(np, "in1d"):  # pyroomacoustics 0.10.1's peak finder calls it; numpy 2.4 removed it
    np.in1d = np.isin  # type: ignore[attr-defined]

HERE = os.path.dirname(os.path.abspath(__file__))
KEMAR_SOFA = os.environ.get("AFE_KEMAR_SOFA", "/usr/share/libmysofa/MIT_KEMAR_normal_pinna.sofa")
C = 343.0
AZIMUTHS = [0.0, 30.0, 60.0, 90.0, 120.0, 150.0, 180.0, 210.0, 240.0, 270.0, 300.0, 330.0,
            17.0, 112.5, 203.0, 287.0]
CHOSEN_PAIRS = [(20.0, 70.0), (330.0, 30.0), (60.0, 120.0), (250.0, 300.0), (0.0, 300.0),
                (45.0, 135.0), (200.0, 260.0), (90.0, 150.0)]
ROOM = [6.0, 4.5, 3.0]
HEAD_AT = np.array([2.6, 2.1, 1.5])
DISTANCE_M = 1.5


def folded(az: float) -> float:
    """Lateral angle in [-90, 90]: a direction and its front-back image agree."""
    a = (az + 180.0) % 360.0 - 180.0
    return 180.0 - a if a > 90 else (-180.0 - a if a < -90 else a)


def circular(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def two_talker_pairs(count: int = 32, seed: int = 5) -> List[Tuple[float, float]]:
    """The chosen pairs, then pairs drawn at random (to 0.1 degree) whose lateral angles
    are 40 degrees or more apart, until ``count`` (the chosen eight alone were all found
    on KEMAR by the estimator before its coherence weights, which found 21 of these 32)."""
    rng = np.random.default_rng(seed)
    pairs = list(CHOSEN_PAIRS)
    while len(pairs) < count:
        a, b = (float(v) for v in rng.uniform(0.0, 360.0, 2).round(1))
        if abs(folded(a) - folded(b)) >= 40.0:
            pairs.append((a, b))
    return pairs


def speech(fs: float, seconds: float = 2.0) -> np.ndarray:
    x, rate = afe.read_wav(os.path.join(HERE, "..", "data", "example_binaural.wav"))
    mono = np.asarray(x)[:, 0]
    from scipy.signal import resample_poly

    if rate != fs:
        up, down = int(round(fs)), int(round(rate))
        g = np.gcd(up, down)
        mono = resample_poly(mono, up // g, down // g)
    n = int(seconds * fs)
    return np.tile(mono, int(np.ceil(n / len(mono))))[:n]


def diffuse_noise(n: int, fs: float, head: str, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = np.zeros((n, 2))
    for az in np.arange(0.0, 360.0, 5.0):
        out += afe.render(rng.standard_normal(n), fs, float(az), head=head)
    return out


def with_snr(ears: np.ndarray, noise: np.ndarray, snr_db: float) -> np.ndarray:
    gain = np.sqrt(np.mean(ears ** 2) / np.mean(noise ** 2) / 10 ** (snr_db / 10))
    return ears + gain * noise


def source_position(az: float) -> List[float]:
    a = np.radians(az)
    return list(HEAD_AT + DISTANCE_M * np.array([np.cos(a), np.sin(a), 0.0]))


def kemar_room(x: np.ndarray, fs: float, az: float, t60: float, directivities) -> np.ndarray:
    import pyroomacoustics as pra

    e_abs, order = pra.inverse_sabine(t60, ROOM)
    room = pra.ShoeBox(ROOM, fs=int(fs), materials=pra.Material(e_abs), max_order=min(order, 40))
    room.add_source(source_position(az), signal=x)
    for d in directivities:
        room.add_microphone(list(HEAD_AT), directivity=d)
    room.simulate()
    return room.mic_array.signals[:, : len(x)].T.copy()


def sphere_room(x: np.ndarray, fs: float, az: float, t60: float, head: str, yaw: float = 0.0) -> np.ndarray:
    """Each image source through the sphere (turned ``yaw`` degrees to the left) from its
    horizontal direction (2-degree steps), its delay and 1/r and wall gains (the octave bands' mean) from
    pyroomacoustics' image sources: one binaural impulse response, then the source
    through it."""
    import pyroomacoustics as pra
    from scipy.signal import fftconvolve

    e_abs, order = pra.inverse_sabine(t60, ROOM)
    room = pra.ShoeBox(ROOM, fs=int(fs), materials=pra.Material(e_abs), max_order=min(order, 40))
    room.add_source(source_position(az))
    room.add_microphone(list(HEAD_AT))
    room.image_source_model()
    src = room.sources[0]
    rel = src.images - HEAD_AT[:, None]
    dist = np.linalg.norm(rel, axis=0)
    gain = np.mean(src.damping, axis=0) * DISTANCE_M / dist  # the direct path at unit gain
    azim = (np.degrees(np.arctan2(rel[1], rel[0])) - yaw) % 360.0
    delay = np.round((dist - DISTANCE_M) * fs / C).astype(int)
    keep = delay < len(x)
    step = 2.0
    bins = np.round(azim / step).astype(int) % int(360 / step)
    taps = 512
    rir = np.zeros((delay[keep].max() + taps, 2))
    impulse = np.zeros(taps)
    impulse[taps // 4] = 1.0
    for b in np.unique(bins[keep]):
        sel = keep & (bins == b)
        h = np.zeros(delay[sel].max() + 1)
        np.add.at(h, delay[sel], gain[sel])
        hrir = afe.render(impulse, fs, float(b * step), head=head)
        for ear in range(2):
            rir[: len(h) + taps - 1, ear] += fftconvolve(h, hrir[:, ear])
    return np.stack([fftconvolve(x, rir[:, ear])[taps // 4 : taps // 4 + len(x)] for ear in range(2)], -1)


TURNING_AZIMUTHS = [30.0, 150.0, 210.0, 330.0, 60.0, 120.0, 240.0, 300.0, 10.0, 170.0]


def turning_yaw(t: float, seconds: float) -> float:
    """30 degrees to the left by the middle of ``seconds``, back by the end."""
    half = seconds / 2
    return 30.0 * max(0.0, 1.0 - abs(t / half - 1.0))


def turning(render_at: Callable[[float], np.ndarray], yaw: Callable[[float], float], n: int,
            fs: float) -> np.ndarray:
    """A turning head: 50-ms Hann windows at half overlap (they add up to 1), each taken
    from ``render_at(yaw)`` of the whole signal at the yaw of its centre, rounded to
    5 degrees (renders cached)."""
    hop = int(fs) // 40
    window = 0.5 - 0.5 * np.cos(np.pi * np.arange(2 * hop) / hop)
    cache: Dict[float, np.ndarray] = {}
    out = np.zeros((n, 2))
    for start in range(-hop, n, hop):
        lo, hi = max(start, 0), min(start + 2 * hop, n)
        if lo >= hi:
            continue
        y = 5.0 * round(yaw((start + hop) / fs) / 5.0)
        if y not in cache:
            cache[y] = render_at(y)
        out[lo:hi] += cache[y][lo:hi] * window[lo - start : hi - start, None]
    return out


def turning_table(quick: bool) -> List[str]:
    """Front-back confusions with and without the yaw track, on a turning head."""
    from pyroomacoustics.directivities import MeasuredDirectivityFile, Rotation3D

    lines = ["| head | condition | renders | with the yaw track: within 5° | front-back |"
             " without it: within 5° | front-back |", "|---|---|---|---|---|---|---|"]
    azimuths = TURNING_AZIMUTHS[:4] if quick else TURNING_AZIMUTHS
    for head, fs in (("kemar", 16000.0), ("sphere", 24414.0)):
        x = speech(fs, 2.0)
        n, seconds = len(x), len(x) / fs
        track = [[t, turning_yaw(t, seconds)] for t in np.linspace(0.0, seconds, 41)]
        mean_yaw = float(np.mean([y for _, y in track]))
        if head == "kemar":
            sofa = MeasuredDirectivityFile(path=KEMAR_SOFA, fs=int(fs), interp_order=12, interp_n_points=1000)

        def room_render(world: float, y: float) -> np.ndarray:
            if head == "sphere":
                return sphere_room(x, fs, world, 0.6, head, yaw=y)
            rot = Rotation3D([y], "z", degrees=True)
            dirs = [sofa.get_mic_directivity(k, orientation=rot) for k in (0, 1)]
            return kemar_room(x, fs, world, 0.6, dirs)

        for cond in ("anechoic", "room T60 0.6 s"):
            stats = {"with": [0, 0], "without": [0, 0]}
            for world in azimuths:
                if cond == "anechoic":
                    ears = turning(lambda y: afe.render(x, fs, world - y, head=head),
                                   lambda t: turning_yaw(t, seconds), n, fs)
                else:
                    ears = turning(lambda y: room_render(world, y), lambda t: turning_yaw(t, seconds), n, fs)
                with_track = afe.locate(ears, fs, head=head, sources=1, head_yaw=track)["sources"][0]["azimuth_deg"]
                rel = afe.locate(ears, fs, head=head, sources=1)["sources"][0]["azimuth_deg"]
                mirror = (180.0 - (world - mean_yaw)) % 360.0 + mean_yaw
                for key, est in (("with", with_track), ("without", rel + mean_yaw)):
                    stats[key][0] += circular(est, world) <= 5.0
                    stats[key][1] += circular(est, mirror) < circular(est, world)
            k = len(azimuths)
            lines.append(f"| {head} | {cond} | {k} | {100 * stats['with'][0] / k:.0f} % | {100 * stats['with'][1] / k:.0f} % |"
                         f" {100 * stats['without'][0] / k:.0f} % | {100 * stats['without'][1] / k:.0f} % |")
            print(lines[-1], file=sys.stderr)
    return lines


def afe_estimate(head: str, sources: int) -> Callable[[np.ndarray, float], List[float]]:
    def run(ears: np.ndarray, fs: float) -> List[float]:
        found = afe.locate(ears, fs, head=head, sources=sources)
        return [s["azimuth_deg"] for s in found["sources"]]

    return run


def pra_estimate(name: str, spacing_m: float, sources: int) -> Callable[[np.ndarray, float], List[float]]:
    import pyroomacoustics as pra

    def run(ears: np.ndarray, fs: float) -> List[float]:
        nfft = 512 if fs < 30000 else 1024
        mics = np.array([[0.0, 0.0], [spacing_m / 2, -spacing_m / 2]])
        X = np.array([pra.transform.stft.analysis(ears[:, m], nfft, nfft // 2).T for m in range(2)])
        grid = np.radians(np.arange(0.0, 360.0, 1.0))
        doa = pra.doa.algorithms[name](mics, fs, nfft, c=C, num_src=sources, azimuth=grid)
        doa.locate_sources(X, freq_range=[100.0, 8000.0])
        return list(np.degrees(doa.azimuth_recon) % 360.0)

    return run


def score(truths: Sequence[float], found: Sequence[List[float]]) -> Dict[str, float]:
    errs, confused = [], 0
    for t, f in zip(truths, found):
        est = f[0] if f else float("nan")
        errs.append(abs(folded(est) - folded(t)))
        mirror = (180.0 - t) % 360.0
        if circular(est, mirror) + 1e-9 < circular(est, t) and circular(t, mirror) > 10.0:
            confused += 1
    errs_a = np.asarray(errs)
    return {"within5": 100.0 * np.mean(errs_a <= 5.0), "mae": float(np.mean(errs_a)),
            "fb": 100.0 * confused / len(truths)}


def conditions(head: str, fs: float, quick: bool) -> List[Tuple[str, Callable[[float], np.ndarray]]]:
    x = speech(fs)
    n = len(x)
    noise = diffuse_noise(n, fs, head, seed=11)
    conds: List[Tuple[str, Callable[[float], np.ndarray]]] = [
        ("anechoic", lambda az: afe.render(x, fs, az, head=head))]
    for snr in (20.0, 10.0, 0.0):
        conds.append((f"diffuse noise {snr:.0f} dB",
                      lambda az, snr=snr: with_snr(afe.render(x, fs, az, head=head), noise, snr)))
    if head == "kemar":
        from pyroomacoustics.directivities import MeasuredDirectivityFile, Rotation3D

        sofa = MeasuredDirectivityFile(path=KEMAR_SOFA, fs=int(fs), interp_order=12, interp_n_points=1000)
        rot = Rotation3D([0, 0], "yz", degrees=True)
        dirs = [sofa.get_mic_directivity(k, orientation=rot) for k in (0, 1)]
    for t60 in ((0.6,) if quick else (0.3, 0.6, 0.9)):
        if head == "kemar":
            conds.append((f"room T60 {t60} s", lambda az, t60=t60: kemar_room(x, fs, az, t60, dirs)))
        else:
            conds.append((f"room T60 {t60} s", lambda az, t60=t60: sphere_room(x, fs, az, t60, head)))
    return conds


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="one room, every other azimuth")
    ap.add_argument("--markdown", action="store_true", help="print the table as markdown")
    ap.add_argument("--turning", action="store_true", help="only the turning head's table (issue 60)")
    args = ap.parse_args()
    if args.turning:
        print("\n".join(turning_table(args.quick)))
        return 0
    azimuths = AZIMUTHS[::2] if args.quick else AZIMUTHS
    heads = [("kemar", "kemar", 16000.0, 0.18), ("kemar", "kemar", 44100.0, 0.18),
             ("sphere", "sphere", 24414.0, 0.15)]
    rows = []
    totals: Dict[str, List[float]] = {"afe": [], "cues": [], "SRP": [], "NormMUSIC": []}
    t0 = time.time()
    for label, head, fs, spacing in heads:
        methods = {"afe": afe_estimate(head, 1), "cues": cue_templates.estimate(head, fs),
                   "SRP": pra_estimate("SRP", spacing, 1),
                   "NormMUSIC": pra_estimate("NormMUSIC", spacing, 1)}
        for cond, render in conditions(head, fs, args.quick):
            ears = [render(az) for az in azimuths]
            row = [f"{label} {fs / 1000:g} kHz", cond]
            for name, method in methods.items():
                s = score(azimuths, [method(e, fs) for e in ears])
                totals[name].append(s["within5"])
                row.append(s)
            rows.append(row)
            print(f"[{time.time() - t0:6.1f} s] {row[0]}, {cond}: " + ", ".join(
                f"{n} {r['within5']:.0f}% ({r['mae']:.1f} deg, fb {r['fb']:.0f}%)"
                for n, r in zip(methods, row[2:])), file=sys.stderr)
    two = []
    pairs = two_talker_pairs()
    for label, head, fs, _ in heads[::2]:
        x1, x2 = speech(fs), np.roll(speech(fs), int(0.7 * fs))
        hits = 0
        for a, b in pairs:
            ears = afe.render(x1, fs, a, head=head) + afe.render(x2, fs, b, head=head)
            found = afe_estimate(head, 2)(ears, fs)
            ok = all(any(abs(folded(f) - folded(t)) <= 10.0 for f in found) for t in (a, b))
            hits += ok
        two.append((f"{label} {fs / 1000:g} kHz", 100.0 * hits / len(pairs)))
    if args.markdown:
        print("| head | condition | afe: within 5° | MAE | front-back | cue templates: within 5° | MAE |"
              " front-back | SRP-PHAT: within 5° | MAE | NormMUSIC: within 5° | MAE |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for head, cond, a, c, s, m in rows:
            print(f"| {head} | {cond} | {a['within5']:.0f} % | {a['mae']:.1f}° | {a['fb']:.0f} % |"
                  f" {c['within5']:.0f} % | {c['mae']:.1f}° | {c['fb']:.0f} % |"
                  f" {s['within5']:.0f} % | {s['mae']:.1f}° | {m['within5']:.0f} % | {m['mae']:.1f}° |")
        print(f"| all | single talkers | {np.mean(totals['afe']):.0f} % | | |"
              f" {np.mean(totals['cues']):.0f} % | | | {np.mean(totals['SRP']):.0f} % | |"
              f" {np.mean(totals['NormMUSIC']):.0f} % | |")
        for head, pct in two:
            print(f"\nTwo talkers 40° or more apart, anechoic, {head}: both within 10° in {pct:.0f} % of"
                  f" {len(pairs)} pairs.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
