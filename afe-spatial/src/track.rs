//! Tracking (binauloc's Stage B, as a grid Bayes filter): a posterior over world azimuth,
//! carried from frame to frame with the head's motion and each frame's localisation
//! scores, whose peaks are tracked sources with identities. A source stays put in the
//! world while the head turns; its front-back image, mirrored about the interaural axis,
//! moves by twice the turn and loses its probability: a turn tells front from back, which
//! the static cues of a head without pinnae cannot.

use crate::locate::Located;
use crate::peak::{local_maxima, refine};
use crate::yaw::score_at;
use crate::SpatialError;

/// Rate at which [`track`] reports the tracked sources, Hz (binauloc's Stage B runs at
/// about 6 Hz).
pub const REPORT_HZ: f64 = 6.0;

/// The tracked sources at one time.
#[derive(Debug, Clone, PartialEq)]
pub struct Tracked {
    /// The frame's centre, s.
    pub t_s: f64,
    /// The head's yaw then, deg.
    pub yaw_deg: f64,
    /// The sources tracked then, by identity.
    pub tracks: Vec<Track>,
}

/// The sources of a whole localisation tracked over its frames (their scores, the
/// head's yaw, their activity), reported at [`REPORT_HZ`] and at the last frame.
pub fn track(found: &Located, params: &TrackerParams) -> Result<Vec<Tracked>, SpatialError> {
    let mut tracker = Tracker::new(params, found.hop_s)?;
    let na = found.azimuths_deg.len();
    let every = ((1.0 / REPORT_HZ) / found.hop_s).round().max(1.0) as usize;
    let mut out = Vec::new();
    for (k, (frame, scores)) in found
        .frames
        .iter()
        .zip(found.scores.chunks_exact(na))
        .enumerate()
    {
        let seen = frame.active.then_some(scores);
        tracker.step(frame.t_s, frame.yaw_deg, &found.azimuths_deg, seen);
        if (k + 1) % every == 0 || k + 1 == found.frames.len() {
            out.push(Tracked {
                t_s: frame.t_s,
                yaw_deg: frame.yaw_deg,
                tracks: tracker.tracks().to_vec(),
            });
        }
    }
    Ok(out)
}

/// The tracker's parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerParams {
    /// How fast a source may move, deg/s: the spread of the random walk the posterior is
    /// blurred by between frames (`trk_driftDegPerSec`).
    pub drift_deg_per_sec: f64,
    /// Exponent of a frame's scores in the likelihood: how much one frame counts
    /// (`trk_sharpness`).
    pub sharpness: f64,
    /// Probability within ±10 deg of a peak for it to be a source
    /// (`trk_birth`).
    pub birth: f64,
    /// Seconds a source lives on without its peak (`trk_holdSec`).
    pub hold_sec: f64,
}

impl Default for TrackerParams {
    fn default() -> Self {
        TrackerParams {
            drift_deg_per_sec: 20.0,
            sharpness: 2.0,
            birth: 0.2,
            hold_sec: 0.5,
        }
    }
}

/// Half the width over which a peak's probability is summed, deg.
const PEAK_HALF_WIDTH_DEG: usize = 10;

/// The filter's grid: every whole degree, deg.
const GRID_DEG: [f64; 360] = {
    let mut grid = [0.0; 360];
    let mut k = 0;
    while k < 360 {
        grid[k] = k as f64;
        k += 1;
    }
    grid
};
/// Farthest a source moves between two frames and keeps its identity, deg.
const ASSOCIATE_DEG: f64 = 15.0;
/// Share of the posterior spread evenly each frame, so that a new source can be born
/// anywhere.
const UNIFORM_SHARE: f64 = 1e-3;

/// A tracked source.
#[derive(Debug, Clone, PartialEq)]
pub struct Track {
    /// Its identity, kept while it lives.
    pub id: usize,
    /// World azimuth, deg in [0, 360) (0 = the world's front, 90 = left).
    pub azimuth_deg: f64,
    /// Circular standard deviation of the posterior around it, deg.
    pub uncertainty_deg: f64,
    /// Probability within ±10 deg of it.
    pub mass: f64,
    /// Time it was last seen as a peak, s.
    pub seen_s: f64,
}

/// The grid Bayes filter over world azimuth (1-degree grid).
pub struct Tracker {
    params: TrackerParams,
    posterior: Vec<f64>,
    scratch: Vec<f64>,
    /// Random-walk kernel per frame, centred (odd length).
    kernel: Vec<f64>,
    tracks: Vec<Track>,
    next_id: usize,
}

impl Tracker {
    /// A tracker for frames `hop_s` apart, its posterior uniform.
    pub fn new(params: &TrackerParams, hop_s: f64) -> Result<Tracker, SpatialError> {
        let bad = |what: &str| Err(SpatialError::Invalid(what.to_string()));
        if !(hop_s > 0.0 && hop_s.is_finite()) {
            return bad("the frames' hop must be a positive number of seconds");
        }
        if !(params.drift_deg_per_sec >= 0.0 && params.drift_deg_per_sec <= 360.0) {
            return bad("trk_driftDegPerSec must be between 0 and 360 deg/s");
        }
        if !(params.sharpness > 0.0 && params.sharpness <= 100.0) {
            return bad("trk_sharpness must be above 0 and at most 100");
        }
        if !(params.birth > 0.0 && params.birth < 1.0) {
            return bad("trk_birth must be between 0 and 1");
        }
        if !(params.hold_sec >= 0.0 && params.hold_sec.is_finite()) {
            return bad("trk_holdSec must be a non-negative number of seconds");
        }
        // a random walk of drift·√hop deg per frame (at least a tenth of a degree)
        let sigma = (params.drift_deg_per_sec * hop_s.sqrt()).max(0.1);
        let half = (3.0 * sigma).ceil() as usize;
        let mut kernel: Vec<f64> = (0..=2 * half)
            .map(|k| (-0.5 * ((k as f64 - half as f64) / sigma).powi(2)).exp())
            .collect();
        let total: f64 = kernel.iter().sum();
        kernel.iter_mut().for_each(|k| *k /= total);
        Ok(Tracker {
            params: params.clone(),
            posterior: vec![1.0 / 360.0; 360],
            scratch: vec![0.0; 360],
            kernel,
            tracks: Vec::new(),
            next_id: 1,
        })
    }

    /// The posterior over world azimuth, one value per degree from 0.
    pub fn posterior(&self) -> &[f64] {
        &self.posterior
    }

    /// The sources tracked now, by identity.
    pub fn tracks(&self) -> &[Track] {
        &self.tracks
    }

    /// One frame at `t_s`: the head's `yaw_deg`, and, for an active frame, its `scores`
    /// over the head-relative `azimuths` (deg, ascending in [0, 360)); an inactive frame
    /// (`None`) only lets the posterior spread, and its sources are not seen.
    pub fn step(&mut self, t_s: f64, yaw_deg: f64, azimuths: &[f64], scores: Option<&[f64]>) {
        self.predict();
        if let Some(scores) = scores {
            let top = scores.iter().fold(0.0f64, |m, &s| m.max(s));
            if top > 0.0 {
                for (world, p) in self.posterior.iter_mut().enumerate() {
                    let s = score_at(azimuths, scores, world as f64 - yaw_deg) / top;
                    *p *= s.max(0.0).powf(self.params.sharpness);
                }
                let total: f64 = self.posterior.iter().sum();
                if total > 0.0 && total.is_finite() {
                    self.posterior.iter_mut().for_each(|p| *p /= total);
                } else {
                    self.posterior.fill(1.0 / 360.0);
                }
            }
            self.associate(t_s);
        }
        let hold = self.params.hold_sec;
        self.tracks.retain(|t| t_s - t.seen_s <= hold);
    }

    /// Blurs the posterior by the random walk and mixes in a little of the uniform.
    fn predict(&mut self) {
        let half = self.kernel.len() / 2;
        for (k, out) in self.scratch.iter_mut().enumerate() {
            *out = self
                .kernel
                .iter()
                .enumerate()
                .map(|(j, w)| w * self.posterior[(k + 360 * (half / 360 + 1) + j - half) % 360])
                .sum();
        }
        for (p, s) in self.posterior.iter_mut().zip(&self.scratch) {
            *p = (1.0 - UNIFORM_SHARE) * s + UNIFORM_SHARE / 360.0;
        }
    }

    /// The posterior's peaks with enough probability become or continue tracks (a track
    /// unseen, in active frames, for `hold_sec` ends).
    fn associate(&mut self, t_s: f64) {
        let p = &self.posterior;
        let mass = |k: usize| -> f64 {
            (0..=2 * PEAK_HALF_WIDTH_DEG)
                .map(|j| p[(k + 360 + j - PEAK_HALF_WIDTH_DEG) % 360])
                .sum()
        };
        let mut peaks: Vec<(usize, f64)> = local_maxima(p)
            .map(|k| (k, mass(k)))
            .filter(|&(_, m)| m >= self.params.birth)
            .collect();
        peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
        let mut taken = vec![false; self.tracks.len()];
        for (k, m) in peaks {
            let azimuth_deg = refine(&GRID_DEG, p, k);
            let uncertainty_deg = spread(p, azimuth_deg);
            let nearest = (0..self.tracks.len())
                .filter(|&i| !taken[i])
                .map(|i| {
                    (
                        i,
                        crate::turn_deg(self.tracks[i].azimuth_deg, azimuth_deg).abs(),
                    )
                })
                .filter(|&(_, d)| d <= ASSOCIATE_DEG)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let track = Track {
                id: 0,
                azimuth_deg,
                uncertainty_deg,
                mass: m,
                seen_s: t_s,
            };
            match nearest {
                Some((i, _)) => {
                    taken[i] = true;
                    self.tracks[i] = Track {
                        id: self.tracks[i].id,
                        ..track
                    };
                }
                None => {
                    self.tracks.push(Track {
                        id: self.next_id,
                        ..track
                    });
                    taken.push(true);
                    self.next_id += 1;
                }
            }
        }
        self.tracks.sort_by_key(|t| t.id);
    }
}

/// The circular standard deviation of `p` within ±30 deg of `centre_deg`, deg.
fn spread(p: &[f64], centre_deg: f64) -> f64 {
    let (mut total, mut second) = (0.0, 0.0);
    for (k, &v) in p.iter().enumerate() {
        let d = crate::turn_deg(centre_deg, k as f64);
        if d.abs() <= 30.0 {
            total += v;
            second += v * d * d;
        }
    }
    if total > 0.0 {
        (second / total).sqrt()
    } else {
        180.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Scores over a 1-degree relative grid: a bump at `at` deg and, as a head without
    /// pinnae hears it, the same at its front-back image `180 − at`.
    fn ambiguous(at: f64) -> (Vec<f64>, Vec<f64>) {
        let grid: Vec<f64> = (0..360).map(f64::from).collect();
        let bump = |c: f64, a: f64| (-0.5 * (crate::turn_deg(c, a) / 8.0).powi(2)).exp();
        let scores = grid
            .iter()
            .map(|&a| 0.3 + 0.7 * bump(at, a).max(bump(180.0 - at, a)))
            .collect();
        (grid, scores)
    }

    #[test]
    fn a_still_head_keeps_both_images_and_a_turn_keeps_the_source() {
        let params = TrackerParams::default();
        let hop = 0.02;
        // a source at 30 deg in the world, the head still: 30 and 150 are alike
        let mut still = Tracker::new(&params, hop).expect("tracker");
        let (grid, scores) = ambiguous(30.0);
        for t in 0..100 {
            still.step(t as f64 * hop, 0.0, &grid, Some(&scores));
        }
        let found: Vec<f64> = still.tracks().iter().map(|t| t.azimuth_deg).collect();
        assert_eq!(found.len(), 2, "{found:?}");
        assert!(found.iter().any(|a| (a - 30.0).abs() < 2.0), "{found:?}");
        assert!(found.iter().any(|a| (a - 150.0).abs() < 2.0), "{found:?}");
        // the head turns 30 deg to the left over a second and back: the image moves
        let mut turning = Tracker::new(&params, hop).expect("tracker");
        for t in 0..100 {
            let s = t as f64 * hop;
            let yaw = 30.0 * (1.0 - (s - 1.0).abs());
            let (grid, scores) = ambiguous(30.0 - yaw);
            turning.step(s, yaw, &grid, Some(&scores));
        }
        let tracks = turning.tracks();
        assert_eq!(tracks.len(), 1, "{tracks:?}");
        assert!((tracks[0].azimuth_deg - 30.0).abs() < 2.0, "{tracks:?}");
        assert!(tracks[0].uncertainty_deg < 10.0, "{tracks:?}");
    }

    #[test]
    fn a_moving_source_keeps_its_identity_and_a_silent_one_ends() {
        let params = TrackerParams::default();
        let hop = 0.02;
        let mut tracker = Tracker::new(&params, hop).expect("tracker");
        let grid: Vec<f64> = (0..360).map(f64::from).collect();
        let mut ids = Vec::new();
        for t in 0..150 {
            // 20 deg/s from 40 deg, seen by a head that tells front from back
            let at = 40.0 + 20.0 * t as f64 * hop;
            let scores: Vec<f64> = grid
                .iter()
                .map(|&a| 0.3 + 0.7 * (-0.5 * (crate::turn_deg(at, a) / 8.0).powi(2)).exp())
                .collect();
            tracker.step(t as f64 * hop, 0.0, &grid, Some(&scores));
            if let [one] = tracker.tracks() {
                ids.push(one.id);
                if t > 20 {
                    assert!((one.azimuth_deg - at).abs() < 5.0, "{t}: {one:?} for {at}");
                }
            }
        }
        assert!(
            ids.len() > 140 && ids.iter().all(|&i| i == ids[0]),
            "{ids:?}"
        );
        // silence: the posterior spreads out and the source ends after the hold
        for t in 150..250 {
            tracker.step(t as f64 * hop, 0.0, &grid, None);
        }
        assert!(tracker.tracks().is_empty(), "{:?}", tracker.tracks());
    }

    #[test]
    fn bad_parameters_are_named() {
        let e = |p: TrackerParams| Tracker::new(&p, 0.02).err().map(|e| e.to_string());
        let sharp = TrackerParams {
            sharpness: 0.0,
            ..TrackerParams::default()
        };
        assert!(e(sharp).is_some_and(|m| m.contains("trk_sharpness")));
        let birth = TrackerParams {
            birth: 1.5,
            ..TrackerParams::default()
        };
        assert!(e(birth).is_some_and(|m| m.contains("trk_birth")));
        assert!(Tracker::new(&TrackerParams::default(), 0.0).is_err());
    }
}
