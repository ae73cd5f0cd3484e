//! Localisation by projection on the head's transfer functions, without training: per
//! frame and frequency bin, how much of the binaural spectrum lies along a direction's
//! steering vector V = [H_L, H_R] (the energy of the projection V V^H / V^H V over the
//! bin's energy, 1 for a single source from there in a free field), raised to the 8th
//! power and averaged over the bins of the band with each bin's weight: its onset (its
//! rise in log energy over two frames, squared: where the direct sound leads its
//! reflections) times its interaural coherence (where one source dominates); per frame a
//! score over azimuth, and the sources as the peaks of its weighted average over the
//! active frames.

use afe_core::real_fft::RealFft;
use num_complex::Complex64;

use crate::head::Head;
use crate::peak::{local_maxima, refine};
use crate::yaw::{score_at, HeadYaw};
use crate::SpatialError;

afe_core::params! {
    /// The localisation's parameters under their AFE-style names (`loc_*`), which its
    /// messages use too: the head that hears and the localiser's own.
    pub struct LocaliserParams / LocaliserNames {
        /// head model: sphere[:radius=M,ears=DEG,distance=M], kemar or a .sofa file
        #[afe = "loc_head", unit = ""]
        pub head: String = "sphere".to_string(),
        /// frame length
        #[afe = "loc_wSizeSec", unit = "s"]
        pub w_size_sec: f64 = 0.04,
        /// hop between frames
        #[afe = "loc_hSizeSec", unit = "s"]
        pub h_size_sec: f64 = 0.02,
        /// lowest frequency used
        #[afe = "loc_fLowHz", unit = "Hz"]
        pub f_low_hz: f64 = 100.0,
        /// highest frequency used
        #[afe = "loc_fHighHz", unit = "Hz"]
        pub f_high_hz: f64 = 8000.0,
        /// azimuth step of a sphere's grid (a measured head has its own)
        #[afe = "loc_stepDeg", unit = "deg"]
        pub step_deg: f64 = 1.0,
        /// frames this far below the loudest so far are inactive
        #[afe = "loc_activityDb", unit = "dB"]
        pub activity_db: f64 = 30.0,
    }
}

/// A source found: its azimuth and how salient it is.
#[derive(Debug, Clone, PartialEq)]
pub struct Source {
    /// Azimuth, deg in [0, 360) (0 = front, 90 = left): head-relative, or in the world
    /// when the head's yaw is given.
    pub azimuth_deg: f64,
    /// Its peak's mean score over the active frames (each weighted by its onsets), 0 to
    /// 1.
    pub salience: f64,
}

/// One frame's outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Its centre, s from the start.
    pub t_s: f64,
    /// Whether it holds sound (within `activity_db` of the loudest frame).
    pub active: bool,
    /// The azimuth of its best score, deg (in the world when the head's yaw is given).
    pub azimuth_deg: f64,
    /// The head's yaw then, deg (0 without a yaw track: world and head agree).
    pub yaw_deg: f64,
}

/// What [`locate`] found.
#[derive(Debug, Clone)]
pub struct Located {
    /// The grid of the scores, deg.
    pub azimuths_deg: Vec<f64>,
    /// The sources, most salient first.
    pub sources: Vec<Source>,
    /// Every frame.
    pub frames: Vec<Frame>,
    /// The mean score over the active frames (each weighted by its onsets), per azimuth
    /// of the grid (in the world when the head's yaw is given).
    pub mean_score: Vec<f64>,
    /// Each frame's scores over the grid, relative to the head: `frames × azimuths`.
    pub scores: Vec<f64>,
    /// Seconds between frames.
    pub hop_s: f64,
}

/// The sources in `ears` (left, right at `fs_hz`) as `head` hears them: at most
/// `max_sources` (`None`: the salient ones, at least 0.9 of the first's salience). With
/// the head's `yaw`, each frame's scores turn into the world (world = relative + yaw)
/// before they are averaged: a source that stays put adds up while its front-back image,
/// which moves against the turn, spreads out.
pub fn locate(
    head: &Head,
    ears: [&[f64]; 2],
    fs_hz: f64,
    params: &LocaliserParams,
    max_sources: Option<usize>,
    yaw: Option<&HeadYaw>,
) -> Result<Located, SpatialError> {
    let [left, right] = ears;
    if left.len() != right.len() {
        return Err(SpatialError::Invalid(format!(
            "the ears have {} and {} samples: they must have as many",
            left.len(),
            right.len()
        )));
    }
    if let Some(t) = left.iter().chain(right).position(|v| !v.is_finite()) {
        return Err(SpatialError::Invalid(format!(
            "sample {} is NaN or Inf",
            t % left.len().max(1)
        )));
    }
    let mut localiser = Localiser::new(head, fs_hz, params)?;
    let (w, hop) = (localiser.window.len(), localiser.hop);
    if left.len() < w {
        return Err(SpatialError::Invalid(format!(
            "{} samples are shorter than one {w}-sample frame ({} s)",
            left.len(),
            params.w_size_sec
        )));
    }
    let n_frames = (left.len() - w) / hop + 1;
    let mut scores = vec![0.0; n_frames * localiser.azimuths.len()];
    let mut scored = Vec::with_capacity(n_frames);
    for t in 0..n_frames {
        let at = t * hop;
        let row = &mut scores[t * localiser.azimuths.len()..(t + 1) * localiser.azimuths.len()];
        scored.push(localiser.score(&left[at..at + w], &right[at..at + w], row));
    }
    let loudest = scored.iter().fold(0.0f64, |m, s| m.max(s.energy));
    let floor = loudest * 10f64.powf(-params.activity_db / 10.0);
    let na = localiser.azimuths.len();
    let mut mean_score = vec![0.0; na];
    let mut active_weight = 0.0;
    let mut world = vec![0.0; if yaw.is_some() { na } else { 0 }];
    let frames: Vec<Frame> = (0..n_frames)
        .map(|t| {
            let t_s = (t * hop + w / 2) as f64 / fs_hz;
            let yaw_deg = yaw.map_or(0.0, |y| y.at(t_s));
            let relative = &scores[t * na..(t + 1) * na];
            let row = match yaw {
                Some(_) => {
                    for (g, &az) in world.iter_mut().zip(&localiser.azimuths) {
                        *g = score_at(&localiser.azimuths, relative, az - yaw_deg);
                    }
                    &world[..]
                }
                None => relative,
            };
            let Scored { energy, weight } = scored[t];
            let active = loudest > 0.0 && energy >= floor;
            if active {
                active_weight += weight;
                mean_score
                    .iter_mut()
                    .zip(row)
                    .for_each(|(m, s)| *m += weight * s);
            }
            let best = argmax(relative);
            Frame {
                t_s,
                active,
                azimuth_deg: crate::wrap_deg(refine(&localiser.azimuths, relative, best) + yaw_deg),
                yaw_deg,
            }
        })
        .collect();
    if active_weight > 0.0 {
        mean_score.iter_mut().for_each(|m| *m /= active_weight);
    }
    let sources = peaks(&localiser.azimuths, &mean_score, max_sources);
    Ok(Located {
        azimuths_deg: localiser.azimuths,
        sources,
        frames,
        mean_score,
        scores,
        hop_s: hop as f64 / fs_hz,
    })
}

/// The designed localiser of one head at one rate: window, transform, band and unit
/// steering vectors, with the scratch of a frame; it scores frame after frame without
/// allocating ([`Localiser::score`]).
pub struct Localiser {
    azimuths: Vec<f64>,
    window: Vec<f64>,
    hop: usize,
    /// First bin of the band.
    first_bin: usize,
    /// The steering vectors v = V/|V| as four rows per bin of the band, each over the
    /// azimuths: |v_L|², |v_R|², and the real and imaginary parts of conj(v_L)·v_R.
    gains: Vec<f64>,
    bins: usize,
    /// One frame's four values per bin that [`Localiser::gains`] weighs.
    weights: Vec<f64>,
    /// The log energy per bin of the band of the [`ONSET_LAG`] frames before, the
    /// oldest first.
    previous: Vec<f64>,
    /// Frames scored since the start or [`Localiser::reset`], up to [`ONSET_LAG`].
    primed: usize,
    /// Per bin of the band, the ears' powers |l|², |r|² and the real and imaginary parts
    /// of l·conj(r), smoothed over frames (time constant [`COHERENCE_TAU_S`]).
    smoothed: Vec<[f64; 4]>,
    /// The smoothing's weight of the frames before, `exp(−hop/τ)`.
    keep: f64,
    /// Each bin's weight in the current frame: onset times coherence.
    bin_weights: Vec<f64>,
    fft: RealFft,
    /// The two ears' spectra, real and imaginary parts.
    spectra: [(Vec<f64>, Vec<f64>); 2],
}

impl Localiser {
    /// The localiser of `head` for ears at `fs_hz` with parameters `p` (each one out of
    /// its range named).
    pub fn new(head: &Head, fs_hz: f64, p: &LocaliserParams) -> Result<Localiser, SpatialError> {
        let bad = |what: String| Err(SpatialError::Invalid(what));
        if !(fs_hz.is_finite() && fs_hz >= 8000.0) {
            return bad("the sampling rate must be at least 8000 Hz".into());
        }
        let names = LocaliserParams::NAMES;
        if !(p.w_size_sec > 0.0 && p.w_size_sec <= 1.0) {
            return bad(format!(
                "{} must be above 0 and at most 1 s",
                names.w_size_sec
            ));
        }
        if !(p.h_size_sec > 0.0 && p.h_size_sec <= p.w_size_sec) {
            return bad(format!(
                "{} must be above 0 and at most {}",
                names.h_size_sec, names.w_size_sec
            ));
        }
        if !(p.step_deg >= 0.1 && p.step_deg <= 30.0) {
            return bad(format!(
                "{} must be between 0.1 and 30 degrees",
                names.step_deg
            ));
        }
        if !(p.activity_db > 0.0 && p.activity_db.is_finite()) {
            return bad(format!(
                "{} must be a positive number of dB",
                names.activity_db
            ));
        }
        let top = p.f_high_hz.min(fs_hz / 2.0).min(head.max_frequency_hz());
        if !(p.f_low_hz >= 0.0 && p.f_low_hz < top) {
            return bad(format!(
                "{} ({} Hz) must be below the band's top, {top} Hz ({}, the Nyquist \
                 frequency and the head's)",
                names.f_low_hz, p.f_low_hz, names.f_high_hz
            ));
        }
        let w = ((p.w_size_sec * fs_hz).round() as usize).max(16);
        let hop = ((p.h_size_sec * fs_hz).round() as usize).max(1);
        let n = w.next_power_of_two();
        let df = fs_hz / n as f64;
        let first_bin = ((p.f_low_hz / df).ceil() as usize).max(1);
        let last_bin = ((top / df).floor() as usize).min(n / 2 - 1);
        let bins = last_bin + 1 - first_bin;
        let freqs: Vec<f64> = (first_bin..=last_bin).map(|k| k as f64 * df).collect();
        let azimuths = head.azimuths_deg(p.step_deg);
        let na = azimuths.len();
        if na.saturating_mul(bins) > MAX_STEERING {
            return Err(SpatialError::Invalid(format!(
                "{na} azimuths ({} {}) by {bins} frequency bins ({} {}, {} to {}) are {} \
                 steering vectors, more than {MAX_STEERING}: a coarser grid, a shorter frame \
                 or a narrower band",
                names.step_deg,
                p.step_deg,
                names.w_size_sec,
                p.w_size_sec,
                names.f_low_hz,
                names.f_high_hz,
                na * bins
            )));
        }
        let mut gains = vec![0.0; 4 * bins * na];
        for (a, row) in head.transfers(&azimuths, &freqs).into_iter().enumerate() {
            for (b, [l, r]) in row.into_iter().enumerate() {
                let energy = l.norm_sqr() + r.norm_sqr();
                let unit = if energy > 0.0 { 1.0 / energy } else { 0.0 };
                let cross = l.conj() * r * unit;
                let rows = [l.norm_sqr() * unit, r.norm_sqr() * unit, cross.re, cross.im];
                for (k, g) in rows.into_iter().enumerate() {
                    gains[(4 * b + k) * na + a] = g;
                }
            }
        }
        // a periodic Hann window
        let window = (0..w)
            .map(|k| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * k as f64 / w as f64).cos())
            .collect();
        let half = || (vec![0.0; n / 2 + 1], vec![0.0; n / 2 + 1]);
        Ok(Localiser {
            azimuths,
            window,
            hop,
            first_bin,
            gains,
            bins,
            weights: vec![0.0; 4 * bins],
            previous: vec![0.0; ONSET_LAG * bins],
            primed: 0,
            smoothed: vec![[0.0; 4]; bins],
            keep: (-(hop as f64 / fs_hz) / COHERENCE_TAU_S).exp(),
            bin_weights: vec![0.0; bins],
            fft: RealFft::new(n),
            spectra: [half(), half()],
        })
    }

    /// The azimuths scored, deg (0 = front, 90 = left).
    pub fn azimuths_deg(&self) -> &[f64] {
        &self.azimuths
    }

    /// Samples in a frame.
    pub fn frame_len(&self) -> usize {
        self.window.len()
    }

    /// Samples between frames.
    pub fn hop(&self) -> usize {
        self.hop
    }

    /// Multiply-adds a frame's projection takes (four per azimuth and bin of the band).
    pub fn work_per_frame(&self) -> usize {
        self.gains.len()
    }

    /// Forgets the previous frame: the next one is scored as the first.
    pub fn reset(&mut self) {
        self.primed = 0;
    }

    /// Scores one frame of each ear (`frame_len` samples) into `row`: per azimuth, the
    /// share of each bin's energy along its steering vector (0 to 1) to the 8th power
    /// ([`SHARE_SQUARINGS`]), averaged over the band's bins with each bin's onset weight
    /// (see [`ONSET_FLOOR`]) times its coherence (see [`COHERENCE_POWER`]); returns the
    /// band's energy and the frame's weight (the sum of its bins').
    pub fn score(&mut self, left: &[f64], right: &[f64], row: &mut [f64]) -> Scored {
        let w = self.window.len();
        for (x, (re, im)) in [left, right].into_iter().zip(&mut self.spectra) {
            let time = self.fft.input();
            time[..w]
                .iter_mut()
                .zip(x.iter().zip(&self.window))
                .for_each(|(t, (v, h))| *t = v * h);
            time[w..].fill(0.0);
            self.fft.run(re, im);
        }
        // |v^H x|² / |x|² = |v_L|²·|l|² + |v_R|²·|r|² + 2·Re(conj(v_L)·v_R · l·conj(r)),
        // over |x|² = |l|² + |r|²: four products per bin and azimuth
        let [(lr, li), (rr, ri)] = &self.spectra;
        let (mut energy, mut weight) = (0.0, 0.0);
        for (b, k) in (self.first_bin..self.first_bin + self.bins).enumerate() {
            let (l, r) = (Complex64::new(lr[k], li[k]), Complex64::new(rr[k], ri[k]));
            let e = l.norm_sqr() + r.norm_sqr();
            let level = (e + ENERGY_FLOOR).ln();
            let rise = if self.primed == ONSET_LAG {
                (level - self.previous[b]).max(0.0)
            } else {
                0.0
            };
            // the levels move one frame older; this frame's is the newest
            for lag in 1..ONSET_LAG {
                self.previous[(lag - 1) * self.bins + b] = self.previous[lag * self.bins + b];
            }
            self.previous[(ONSET_LAG - 1) * self.bins + b] = level;
            let cross = l * r.conj();
            let now = [l.norm_sqr(), r.norm_sqr(), cross.re, cross.im];
            let keep = if self.primed == 0 { 0.0 } else { self.keep };
            let smoothed = &mut self.smoothed[b];
            for (s, v) in smoothed.iter_mut().zip(now) {
                *s = keep * *s + (1.0 - keep) * v;
            }
            let [sl, sr, sc, ss] = *smoothed;
            let w = &mut self.weights[4 * b..4 * b + 4];
            if e <= 0.0 {
                w.fill(0.0);
                self.bin_weights[b] = 0.0;
                continue;
            }
            energy += e;
            // |γ|² = |⟨l·conj(r)⟩|² / (⟨|l|²⟩·⟨|r|²⟩), in [0, 1]
            // (a bin only one ear hears has a single direction: coherent)
            let both = sl * sr;
            let coherence = if both > 0.0 {
                ((sc * sc + ss * ss) / both).min(1.0)
            } else {
                1.0
            };
            let bin_weight = (rise * rise + ONSET_FLOOR) * coherence.powi(COHERENCE_POWER);
            self.bin_weights[b] = bin_weight;
            weight += bin_weight;
            let inv = 1.0 / e;
            w.copy_from_slice(&[
                now[0] * inv,
                now[1] * inv,
                2.0 * cross.re * inv,
                -2.0 * cross.im * inv,
            ]);
        }
        self.primed = (self.primed + 1).min(ONSET_LAG);
        project(row, &self.gains, &self.weights, &self.bin_weights);
        if weight > 0.0 {
            row.iter_mut().for_each(|s| *s /= weight);
        }
        Scored { energy, weight }
    }
}

/// Most steering vectors (azimuths × bins of the band) a localiser designs: 2^20, 32 MiB
/// of gains and about eight times the default's design time (found by fuzzing: a grid of
/// 0.1 degree over a 1-s frame asked for billions).
pub const MAX_STEERING: usize = 1 << 20;

/// What [`Localiser::score`] tells of a frame besides its scores.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scored {
    /// The band's energy (both ears).
    pub energy: f64,
    /// The sum of the bins' onset weights: how much the frame's scores count beside
    /// other frames'.
    pub weight: f64,
}

/// Added to a bin's energy before its logarithm, so that a silent bin has a level.
const ENERGY_FLOOR: f64 = 1e-30;

/// A bin's weight is the square of its rise in log energy from [`ONSET_LAG`] frames
/// before, plus this: onsets, where the direct sound leads its reflections (the
/// precedence effect), vote for a direction, while a frame without one still has its own
/// best direction. Measured on KEMAR renders of 16 talkers (tools/eval_localisation.py):
/// within 5 degrees (folded) in rooms at T60 0.6 and 0.9 s, the plain mean of the shares
/// put 38 % of them, the onset weights 81 % and 69 %.
pub const ONSET_FLOOR: f64 = 1e-6;

/// Frames between the two levels whose rise weighs a bin (2: 40 ms at the default hop).
/// Over one frame, the rise weighed noise as well: in diffuse noise at 0 and 10 dB, 81 %
/// and 94 % of 16 talkers within 5 degrees against 100 % over two.
pub const ONSET_LAG: usize = 2;

/// Time constant of the smoothing of each bin's powers and cross power, over which its
/// interaural coherence |γ|² is measured, s (two frames at the default hop).
pub const COHERENCE_TAU_S: f64 = 0.04;

/// A bin's onset weight is multiplied by its coherence |γ|² to this power: a bin that one
/// source dominates is coherent between the ears, while reverberation, diffuse noise and
/// two talkers mixed in it are not. Measured on the 336 single-talker renders of
/// tools/eval_localisation.py: the onset weights alone placed 91 % within 5 degrees, with
/// the coherence and [`SHARE_SQUARINGS`] 98 % (0.9-s rooms on KEMAR 69-75 % → 88-94 %, the
/// sphere in 0-dB diffuse noise 50 % → 94 %).
pub const COHERENCE_POWER: i32 = 2;

/// Each bin's share of energy along a direction is squared this many times (raised to the
/// 8th power) before the bins are added: 1 only along the bin's own direction, so a bin
/// that two talkers share no longer votes for the directions between them. Two talkers
/// 40 degrees or more apart (32 anechoic pairs, KEMAR): both found within 10 degrees in 21
/// without sharpening or coherence, 25 with the coherence alone, 31 with both.
pub const SHARE_SQUARINGS: u32 = 3;

afe_core::simd_kernel!(
    fma,
    /// `row[a] = Σ_b bin_weights[b]·s_b[a]^(2^SHARE_SQUARINGS)` over the `A = row.len()`
    /// azimuths, with the share `s_b[a] = Σ_k weights[4b + k]·gains[(4b + k)·A + a]` of
    /// bin `b`: one pass over the gains, four rows per bin across all azimuths (bins of
    /// weight 0 skipped).
    fn project(row: &mut [f64], gains: &[f64], weights: &[f64], bin_weights: &[f64]) {
        row.fill(0.0);
        let na = row.len();
        let bins = gains.chunks_exact(4 * na).zip(weights.chunks_exact(4));
        for ((g, w), &bin_weight) in bins.zip(bin_weights) {
            if bin_weight == 0.0 {
                continue;
            }
            let (g0, rest) = g.split_at(na);
            let (g1, rest) = rest.split_at(na);
            let (g2, g3) = rest.split_at(na);
            let rows = g0.iter().zip(g1).zip(g2.iter().zip(g3));
            for (s, ((a, b), (c, d))) in row.iter_mut().zip(rows) {
                let share = w[3].mul_add(*d, w[2].mul_add(*c, w[1].mul_add(*b, w[0] * a)));
                let mut sharp = share;
                for _ in 0..SHARE_SQUARINGS {
                    sharp *= sharp;
                }
                *s = bin_weight.mul_add(sharp, *s);
            }
        }
    }
);

fn argmax(v: &[f64]) -> usize {
    (0..v.len())
        .max_by(|&a, &b| v[a].total_cmp(&v[b]))
        .unwrap_or(0)
}

/// Salience, as a share of the first source's, that another source needs to be reported
/// by default: a single anechoic talker's side lobes reach 0.2 of its peak on the sphere
/// and 0.4 on KEMAR, while its front-back image on a head without pinnae equals it.
const SALIENT_SHARE: f64 = 0.9;

/// The lateral angle of `azimuth_deg`, deg in [−90, 90] (positive to the left): the same
/// for a direction and its front-back image (`a` and `180 − a`), which a head without
/// pinnae cannot tell apart. Scores errors "folded".
pub fn lateral_deg(azimuth_deg: f64) -> f64 {
    let a = (azimuth_deg + 180.0).rem_euclid(360.0) - 180.0;
    if a > 90.0 {
        180.0 - a
    } else if a < -90.0 {
        -180.0 - a
    } else {
        a
    }
}

/// Lateral angles closer than this are a direction and its front-back image, deg.
const IMAGE_DEG: f64 = 5.0;

/// The local maxima of the circular `scores`, most salient first: at most `max` (a peak
/// that is a stronger one's front-back image left out when more than one is asked
/// for), or the ones at least [`SALIENT_SHARE`] as salient as the first.
fn peaks(azimuths: &[f64], scores: &[f64], max: Option<usize>) -> Vec<Source> {
    let mut found: Vec<(usize, f64)> = local_maxima(scores).map(|k| (k, scores[k])).collect();
    found.sort_by(|a, b| b.1.total_cmp(&a.1));
    if max.is_some_and(|m| m > 1) {
        // a peak on the lateral angle of a stronger one is that one's front-back image
        // (as loud as it on a head without pinnae), not another source
        let mut kept: Vec<(usize, f64)> = Vec::with_capacity(found.len());
        for p in found {
            let lateral = lateral_deg(azimuths[p.0]);
            if kept
                .iter()
                .all(|q| (lateral_deg(azimuths[q.0]) - lateral).abs() > IMAGE_DEG)
            {
                kept.push(p);
            }
        }
        found = kept;
    }
    let first = found.first().map_or(0.0, |p| p.1);
    let keep = match max {
        Some(m) => m,
        None => found
            .iter()
            .take_while(|p| p.1 >= SALIENT_SHARE * first)
            .count(),
    };
    found
        .into_iter()
        .take(keep)
        .map(|(k, s)| Source {
            azimuth_deg: refine(azimuths, scores, k),
            salience: s,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sphere::Sphere;

    fn noise(len: usize, mut seed: u64) -> Vec<f64> {
        (0..len)
            .map(|_| {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                (seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0
            })
            .collect()
    }

    #[test]
    fn the_sphere_locates_its_own_renders_within_2_degrees_folded() {
        let head = Head::Sphere(Sphere::antipodal(0.075));
        let fs = 24414.0;
        let x = noise(12000, 7);
        for az in [0.0, 17.0, 40.0, 75.0, 110.0, 200.0, 263.0, 331.5] {
            let [l, r] = head.render(az, &x, fs).expect("render");
            let found = locate(
                &head,
                [&l, &r],
                fs,
                &LocaliserParams::default(),
                Some(1),
                None,
            )
            .expect("located");
            let got = found.sources[0].azimuth_deg;
            let err = (lateral_deg(got) - lateral_deg(az)).abs();
            assert!(err < 2.0, "{az}: found {got}");
            assert!(found.sources[0].salience > 0.9, "{az}: {:?}", found.sources);
        }
    }

    #[test]
    fn bad_input_is_named() {
        let head = Head::Sphere(Sphere::antipodal(0.075));
        let p = LocaliserParams::default();
        let e =
            locate(&head, [&[0.0; 100], &[0.0; 99]], 16000.0, &p, None, None).expect_err("lengths");
        assert!(e.to_string().contains("100 and 99 samples"), "{e}");
        let mut x = vec![0.0; 2000];
        x[1500] = f64::NAN;
        let e = locate(&head, [&x, &x], 16000.0, &p, None, None).expect_err("nan");
        assert!(e.to_string().contains("sample 1500 is NaN"), "{e}");
        let e =
            locate(&head, [&[0.0; 100], &[0.0; 100]], 16000.0, &p, None, None).expect_err("short");
        assert!(
            e.to_string().contains("shorter than one 640-sample frame"),
            "{e}"
        );
        let low = LocaliserParams {
            f_low_hz: 9000.0,
            ..p
        };
        let quiet = vec![0.0; 2000];
        let e = locate(&head, [&quiet, &quiet], 16000.0, &low, None, None).expect_err("band");
        assert!(e.to_string().contains("loc_fLowHz (9000 Hz)"), "{e}");
        let fine = LocaliserParams {
            step_deg: 0.1,
            w_size_sec: 0.5,
            ..LocaliserParams::default()
        };
        let e = locate(&head, [&quiet, &quiet], 16000.0, &fine, None, None).expect_err("size");
        assert!(
            e.to_string().contains("3600 azimuths (loc_stepDeg 0.1) by"),
            "{e}"
        );
    }

    #[test]
    fn heads_are_parsed_or_refused_by_name() {
        assert!(matches!(Head::parse("sphere"), Ok(Head::Sphere(s)) if s.radius_m == 0.075));
        let s = Head::parse("sphere:radius=0.09,ears=100").expect("sphere");
        assert_eq!(s.name(), "sphere:radius=0.09,ears=100");
        for bad in ["sphere:radius=-1", "sphere:size=3", "sphere:radius=abc"] {
            let e = Head::parse(bad).expect_err(bad).to_string();
            assert!(e.starts_with("bad sphere parameter"), "{e}");
        }
        let e = Head::parse("dummy").expect_err("unknown").to_string();
        assert!(e.starts_with("unknown head 'dummy'"), "{e}");
        let e = Head::parse("/nonexistent/head.sofa")
            .expect_err("missing")
            .to_string();
        assert!(e.contains("cannot read it"), "{e}");
    }
}
