//! Tracking (binauloc's Stage B, on a grid): the evidence over world azimuth, each active
//! frame's scores turned into the world with the head's yaw and averaged over the last
//! half second (as the Two!Ears localisation averages its posteriors), whose peaks are
//! tracked sources with identities and velocities. A head without pinnae hears a source
//! and its front-back image (mirrored about the interaural axis) alike: both are tracked,
//! linked as mirror images, until the head turns. Then the source stays put in the world
//! while its image moves by twice the turn: the track that moved is the image and ends,
//! and the other is told from back (`resolved`), its image no longer born as a track.

use serde::Serialize;

use crate::locate::lateral_deg;
use crate::peak::{local_maxima, refine};
use crate::yaw::score_at;
use crate::SpatialError;

afe_core::params! {
    /// The tracker's parameters under their AFE-style names (`trk_*`), which its messages
    /// use too.
    pub struct TrackerParams / TrackerNames {
        /// how far old evidence spreads, as a source may move: the random walk it is
        /// blurred by between frames, spreading this far in a second (drift·√t in t s)
        #[afe = "trk_driftDegPerSec", unit = "deg/√s"]
        pub drift_deg_per_sec: f64 = 10.0,
        /// exponent of a frame's scores (above their median, over their range) in its
        /// evidence: how sharply one frame points
        #[afe = "trk_sharpness", unit = ""]
        pub sharpness: f64 = 4.0,
        /// evidence within ±10 deg of a peak for it to be a source (of a whole that rises
        /// to 1 over the first average_sec)
        #[afe = "trk_birth", unit = ""]
        pub birth: f64 = 0.08,
        /// how long a source lives on without its peak
        #[afe = "trk_holdSec", unit = "s"]
        pub hold_sec: f64 = 0.5,
        /// time constant over which the frames' evidence is averaged
        #[afe = "trk_averageSec", unit = "s"]
        pub average_sec: f64 = 0.5,
    }
}

/// Half the width over which a peak's evidence is summed, deg.
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
/// Farthest a peak lies from where a source was predicted and keeps its identity, deg.
const ASSOCIATE_DEG: f64 = 15.0;
/// Time constant of a track's velocity, s: long against a frame's jitter of the peak, short
/// against a walker's change of pace.
pub const VELOCITY_TAU_S: f64 = 0.5;
/// How far the evidence's peak of a moving source lags it, as a share of `average_sec`: a
/// track lies ahead of its peak by its velocity times this lag. Measured on two talkers
/// walking at 20 deg/s on the sphere (tests/locate.rs): their peaks lagged by 3 to 5 deg.
const LAG_SHARE: f64 = 0.3;
/// Two tracks predicted closer than this have one merged peak between them, deg: they
/// coast through it on their velocities (two peaks' half widths).
const MERGED_DEG: f64 = 2.0 * PEAK_HALF_WIDTH_DEG as f64;
/// Two tracks whose head-relative lateral angles are this close, and that lie farther
/// apart than twice this, are a source and its front-back image, deg.
pub const MIRROR_DEG: f64 = 10.0;
/// Turn of the head since two tracks were linked as mirror images that tells which is
/// the image, deg.
pub const TELLING_TURN_DEG: f64 = 10.0;

/// A tracked source.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Track {
    /// Its identity, kept while it lives.
    pub id: usize,
    /// World azimuth, deg in [0, 360) (0 = the world's front, 90 = left).
    pub azimuth_deg: f64,
    /// Circular standard deviation of the evidence around it, deg.
    pub uncertainty_deg: f64,
    /// The evidence within ±10 deg of it (of a whole of at most 1).
    pub mass: f64,
    /// How fast it moves in the world, deg/s (positive to the left), smoothed over about
    /// [`VELOCITY_TAU_S`]: between frames it is predicted to move on so, which keeps two
    /// sources apart through a crossing, where their peaks merge.
    pub velocity_deg_s: f64,
    /// Time it was last seen as a peak, s.
    pub seen_s: f64,
    /// Whether a turn of the head has told it from its front-back image.
    pub resolved: bool,
}

/// Two tracks taken for a source and its front-back image: where each was, and the yaw,
/// when they were linked.
#[derive(Debug, Clone, Copy)]
struct Mirror {
    ids: [usize; 2],
    at_deg: [f64; 2],
    yaw_deg: f64,
}

/// Most tracks (and mirror links) kept at once: a frame's peaks beyond them are not born.
pub const MAX_TRACKS: usize = 32;

/// A frame's working lists, kept between frames so that tracking allocates nothing once
/// they have grown to their largest.
#[derive(Debug, Default)]
struct Work {
    /// The evidence's peaks: (azimuth, deg; share within ±10 deg).
    peaks: Vec<(f64, f64)>,
    /// Per track, whether another is predicted within [`MERGED_DEG`].
    contested: Vec<bool>,
    /// (gap, deg; track; peak) within [`ASSOCIATE_DEG`].
    pairs: Vec<(f64, usize, usize)>,
    /// Per track, the peak it took.
    peak_of: Vec<Option<usize>>,
    /// Per peak, whether a track took it.
    taken: Vec<bool>,
    /// The front-back images of the resolved tracks, deg.
    images: Vec<f64>,
    /// Track identities (those told from their images, or ended).
    ids: Vec<usize>,
    /// More track identities (those resolved as their images end).
    more_ids: Vec<usize>,
}

impl Work {
    /// Room for [`MAX_TRACKS`] tracks and a grid's peaks.
    fn new() -> Self {
        Work {
            peaks: Vec::with_capacity(180),
            contested: Vec::with_capacity(MAX_TRACKS),
            pairs: Vec::with_capacity(MAX_TRACKS * 16),
            peak_of: Vec::with_capacity(MAX_TRACKS),
            taken: Vec::with_capacity(180),
            images: Vec::with_capacity(MAX_TRACKS),
            ids: Vec::with_capacity(MAX_TRACKS),
            more_ids: Vec::with_capacity(MAX_TRACKS),
        }
    }

    /// Empties the per-frame lists (keeping their room).
    fn clear(&mut self) {
        self.peaks.clear();
        self.contested.clear();
        self.pairs.clear();
        self.peak_of.clear();
        self.taken.clear();
        self.images.clear();
    }
}

/// The tracker: the evidence over world azimuth (1-degree grid) and its tracks.
pub struct Tracker {
    params: TrackerParams,
    evidence: Vec<f64>,
    scratch: Vec<f64>,
    /// A frame's evidence in any order, for its median.
    order: Vec<f64>,
    /// Random-walk kernel per frame, centred (odd length).
    kernel: Vec<f64>,
    /// Weight of a new frame's evidence in the average.
    share: f64,
    tracks: Vec<Track>,
    mirrors: Vec<Mirror>,
    work: Work,
    next_id: usize,
    /// Time of the last active frame, s (`None` before the first).
    last_active_s: Option<f64>,
}

impl Tracker {
    /// A tracker for frames `hop_s` apart, with no evidence yet.
    pub fn new(params: &TrackerParams, hop_s: f64) -> Result<Tracker, SpatialError> {
        let bad = |what: String| Err(SpatialError::Invalid(what));
        let names = TrackerParams::NAMES;
        if !(hop_s > 0.0 && hop_s.is_finite()) {
            return bad("the frames' hop must be a positive number of seconds".into());
        }
        if !(params.drift_deg_per_sec >= 0.0 && params.drift_deg_per_sec <= 360.0) {
            return bad(format!(
                "{} must be between 0 and 360 deg/s",
                names.drift_deg_per_sec
            ));
        }
        if !(params.sharpness > 0.0 && params.sharpness <= 100.0) {
            return bad(format!(
                "{} must be above 0 and at most 100",
                names.sharpness
            ));
        }
        if !(params.birth > 0.0 && params.birth < 1.0) {
            return bad(format!("{} must be between 0 and 1", names.birth));
        }
        if !(params.hold_sec >= 0.0 && params.hold_sec.is_finite()) {
            return bad(format!(
                "{} must be a non-negative number of seconds",
                names.hold_sec
            ));
        }
        if !(params.average_sec > 0.0 && params.average_sec <= 60.0) {
            return bad(format!(
                "{} must be above 0 and at most 60 s",
                names.average_sec
            ));
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
            evidence: vec![0.0; 360],
            scratch: vec![0.0; 360],
            order: vec![0.0; 360],
            kernel,
            share: (hop_s / params.average_sec).min(1.0),
            tracks: Vec::with_capacity(MAX_TRACKS),
            mirrors: Vec::with_capacity(MAX_TRACKS),
            work: Work::new(),
            next_id: 1,
            last_active_s: None,
        })
    }

    /// The evidence over world azimuth, one value per degree from 0: each active frame
    /// adds its own (summing to 1) with the weight hop/`average_sec`, so the whole rises
    /// from 0 towards 1 (0.63 after the first `average_sec` of active frames).
    pub fn evidence(&self) -> &[f64] {
        &self.evidence
    }

    /// Forgets every frame: no evidence and no track, the next identity 1 again.
    pub fn reset(&mut self) {
        self.evidence.fill(0.0);
        self.tracks.clear();
        self.mirrors.clear();
        self.next_id = 1;
        self.last_active_s = None;
    }

    /// The sources tracked now, by identity.
    pub fn tracks(&self) -> &[Track] {
        &self.tracks
    }

    /// One frame at `t_s`: the head's `yaw_deg`, and, for an active frame, its `scores`
    /// over the head-relative `azimuths` (deg, ascending in [0, 360)); an inactive frame
    /// (`None`) only lets the evidence spread, and its sources are not seen.
    pub fn step(&mut self, t_s: f64, yaw_deg: f64, azimuths: &[f64], scores: Option<&[f64]>) {
        self.blur();
        if let Some(scores) = scores {
            if self.add_frame(yaw_deg, azimuths, scores) {
                self.associate(t_s, yaw_deg);
            }
        }
        self.end_unseen(t_s, yaw_deg);
    }

    /// Blurs the evidence by the random walk.
    fn blur(&mut self) {
        let half = self.kernel.len() / 2;
        for (k, out) in self.scratch.iter_mut().enumerate() {
            *out = self
                .kernel
                .iter()
                .enumerate()
                .map(|(j, w)| w * self.evidence[(k + 360 * (half / 360 + 1) + j - half) % 360])
                .sum();
        }
        std::mem::swap(&mut self.evidence, &mut self.scratch);
    }

    /// Mixes a frame's evidence into the average: its scores read at world − yaw, above
    /// their median, over their range, to the power `sharpness`, summing to 1. False for a
    /// frame that points nowhere (flat or not finite).
    fn add_frame(&mut self, yaw_deg: f64, azimuths: &[f64], scores: &[f64]) -> bool {
        for (world, e) in self.scratch.iter_mut().enumerate() {
            *e = score_at(azimuths, scores, world as f64 - yaw_deg);
        }
        self.order.copy_from_slice(&self.scratch);
        let (_, &mut median, _) = self.order.select_nth_unstable_by(180, f64::total_cmp);
        let top = self
            .scratch
            .iter()
            .fold(f64::NEG_INFINITY, |m, &v| m.max(v));
        if !(top > median && top.is_finite() && median.is_finite()) {
            return false;
        }
        let sharpness = self.params.sharpness;
        self.scratch
            .iter_mut()
            .for_each(|e| *e = ((*e - median) / (top - median)).max(0.0).powf(sharpness));
        let total: f64 = self.scratch.iter().sum();
        let share = self.share;
        for (e, s) in self.evidence.iter_mut().zip(&self.scratch) {
            *e = (1.0 - share) * *e + share * s / total;
        }
        true
    }

    /// The evidence's peaks with enough of it become or continue tracks: each track moves
    /// on by its velocity since the last active frame, then takes the nearest peak to
    /// that prediction (the nearest pairs first, each peak to one track). Two tracks
    /// predicted within [`MERGED_DEG`] of each other take no peak: they coast on their
    /// predictions and velocities (a merged peak between them would drag them together),
    /// as does one whose nearest peak another took; each is seen while a peak lies within
    /// reach of its prediction. A peak within
    /// [`MERGED_DEG`] of a track (a side lobe of its source: two sources that close are
    /// one peak) or at the front-back image of a resolved track is no new source.
    fn associate(&mut self, t_s: f64, yaw_deg: f64) {
        let dt = self.last_active_s.map_or(0.0, |last| (t_s - last).max(0.0));
        self.last_active_s = Some(t_s);
        for t in &mut self.tracks {
            t.azimuth_deg = crate::wrap_deg(t.azimuth_deg + t.velocity_deg_s * dt);
        }
        let e = &self.evidence;
        let mass = |k: usize| -> f64 {
            (0..=2 * PEAK_HALF_WIDTH_DEG)
                .map(|j| e[(k + 360 + j - PEAK_HALF_WIDTH_DEG) % 360])
                .sum()
        };
        let mut w = std::mem::take(&mut self.work);
        w.clear();
        w.peaks.extend(
            local_maxima(e)
                .map(|k| (k, mass(k)))
                .filter(|&(_, m)| m >= self.params.birth)
                .map(|(k, m)| (refine(&GRID_DEG, e, k), m)),
        );
        let peaks = &w.peaks;
        // tracks predicted this close to another have their peaks merged: they coast
        w.contested.extend((0..self.tracks.len()).map(|i| {
            let at = self.tracks[i].azimuth_deg;
            self.tracks
                .iter()
                .enumerate()
                .any(|(k, t)| k != i && crate::turn_deg(at, t.azimuth_deg).abs() < MERGED_DEG)
        }));
        let lag_s = LAG_SHARE * self.params.average_sec;
        for (i, t) in self.tracks.iter().enumerate() {
            let behind = t.azimuth_deg - t.velocity_deg_s * lag_s;
            for (j, &(az, _)) in peaks.iter().enumerate() {
                let d = crate::turn_deg(behind, az).abs();
                if d <= ASSOCIATE_DEG {
                    w.pairs.push((d, i, j));
                }
            }
        }
        w.pairs.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        w.peak_of.resize(self.tracks.len(), None);
        w.taken.resize(peaks.len(), false);
        for &(_, i, j) in &w.pairs {
            if w.contested[i] {
                w.taken[j] = true;
            } else if w.peak_of[i].is_none() && !w.taken[j] {
                w.peak_of[i] = Some(j);
                w.taken[j] = true;
            }
        }
        let smoothing = (dt / VELOCITY_TAU_S).min(1.0);
        for (i, track) in self.tracks.iter_mut().enumerate() {
            match w.peak_of[i] {
                Some(j) => {
                    let (peak, m) = peaks[j];
                    let az = peak + track.velocity_deg_s * lag_s;
                    if dt > 0.0 {
                        let moved = crate::turn_deg(track.azimuth_deg, az) / dt;
                        track.velocity_deg_s += smoothing * moved;
                    }
                    track.azimuth_deg = crate::wrap_deg(peak + track.velocity_deg_s * lag_s);
                    track.uncertainty_deg = spread(e, peak);
                    track.mass = m;
                    track.seen_s = t_s;
                }
                // coasting (through a merged peak, or beside one another track took):
                // seen while a peak lies within reach of its prediction
                None if w.pairs.iter().any(|&(_, k, _)| k == i) => {
                    let at = (track.azimuth_deg.round() as usize) % 360;
                    track.mass = mass(at);
                    track.uncertainty_deg = spread(e, track.azimuth_deg);
                    track.seen_s = t_s;
                }
                None => {}
            }
        }
        w.images.extend(
            self.tracks
                .iter()
                .filter(|t| t.resolved)
                .map(|t| image_deg(t.azimuth_deg, yaw_deg)),
        );
        for (j, &(azimuth_deg, m)) in peaks.iter().enumerate() {
            let an_image = w
                .images
                .iter()
                .any(|&i| crate::turn_deg(i, azimuth_deg).abs() <= ASSOCIATE_DEG);
            let crowded = self
                .tracks
                .iter()
                .any(|t| crate::turn_deg(t.azimuth_deg, azimuth_deg).abs() < MERGED_DEG);
            if !w.taken[j] && !an_image && !crowded && self.tracks.len() < MAX_TRACKS {
                self.tracks.push(Track {
                    id: self.next_id,
                    azimuth_deg,
                    uncertainty_deg: spread(e, azimuth_deg),
                    mass: m,
                    velocity_deg_s: 0.0,
                    seen_s: t_s,
                    resolved: false,
                });
                self.next_id += 1;
            }
        }
        self.work = w;
        self.link_mirrors(yaw_deg);
    }

    /// Links the unresolved tracks that are front-back images of each other at `yaw_deg`,
    /// and, once the head has turned by [`TELLING_TURN_DEG`] since a link, tells them
    /// apart when one has moved in the world by the turn more than the other (an image
    /// moves by twice the turn, a source as it walks): the other is resolved and the
    /// image ends.
    fn link_mirrors(&mut self, yaw_deg: f64) {
        let position = |tracks: &[Track], id: usize| {
            tracks
                .iter()
                .position(|t| t.id == id)
                .expect("a linked track lives")
        };
        for (i, a) in self.tracks.iter().enumerate() {
            for b in &self.tracks[i + 1..] {
                let images = mirror_images(a, b, yaw_deg);
                let linked = self
                    .mirrors
                    .iter()
                    .any(|m| m.ids.contains(&a.id) || m.ids.contains(&b.id));
                if images && !linked && self.mirrors.len() < MAX_TRACKS {
                    self.mirrors.push(Mirror {
                        ids: [a.id, b.id],
                        at_deg: [a.azimuth_deg, b.azimuth_deg],
                        yaw_deg,
                    });
                }
            }
        }
        let mut told = std::mem::take(&mut self.work.ids);
        told.clear();
        self.mirrors.retain(|m| {
            let turn = crate::turn_deg(m.yaw_deg, yaw_deg).abs();
            if turn < TELLING_TURN_DEG {
                return true;
            }
            let moved = |k: usize| {
                let t = &self.tracks[position(&self.tracks, m.ids[k])];
                crate::turn_deg(m.at_deg[k], t.azimuth_deg).abs()
            };
            let (a, b) = (moved(0), moved(1));
            if (a - b).abs() < turn {
                return true;
            }
            told.push(if a < b { m.ids[0] } else { m.ids[1] });
            false
        });
        for &source in &told {
            self.resolve(source, yaw_deg);
        }
        self.work.ids = told;
    }

    /// Marks track `id` told from back, and ends the unresolved tracks at its front-back
    /// image for a head at `yaw_deg`.
    fn resolve(&mut self, id: usize, yaw_deg: f64) {
        let Some(source) = self.tracks.iter_mut().find(|t| t.id == id) else {
            return;
        };
        source.resolved = true;
        let image = image_deg(source.azimuth_deg, yaw_deg);
        self.tracks
            .retain(|t| t.resolved || crate::turn_deg(image, t.azimuth_deg).abs() > ASSOCIATE_DEG);
        let tracks = &self.tracks;
        self.mirrors
            .retain(|m| m.ids.iter().all(|&id| tracks.iter().any(|t| t.id == id)));
    }

    /// Ends the tracks unseen, in active frames, for `hold_sec`; a track whose linked image
    /// ended after the head turned by [`TELLING_TURN_DEG`] is resolved (its image lost
    /// its evidence where it would have stayed, were it the source), and a link whose
    /// track ended otherwise is dropped.
    fn end_unseen(&mut self, t_s: f64, yaw_deg: f64) {
        let hold = self.params.hold_sec;
        if self.tracks.iter().all(|t| t_s - t.seen_s <= hold) {
            return;
        }
        let mut ended = std::mem::take(&mut self.work.ids);
        let mut resolved = std::mem::take(&mut self.work.more_ids);
        ended.clear();
        resolved.clear();
        ended.extend(
            self.tracks
                .iter()
                .filter(|t| t_s - t.seen_s > hold)
                .map(|t| t.id),
        );
        self.tracks.retain(|t| !ended.contains(&t.id));
        self.mirrors.retain(|m| {
            let [a, b] = m.ids;
            let gone = [ended.contains(&a), ended.contains(&b)];
            let turned = crate::turn_deg(m.yaw_deg, yaw_deg).abs() >= TELLING_TURN_DEG;
            match gone {
                [false, false] => return true,
                [true, false] if turned => resolved.push(b),
                [false, true] if turned => resolved.push(a),
                _ => {}
            }
            false
        });
        for &id in &resolved {
            self.resolve(id, yaw_deg);
        }
        (self.work.ids, self.work.more_ids) = (ended, resolved);
    }
}

/// Whether unresolved tracks `a` and `b` are a source and its front-back image for a head
/// at `yaw_deg`: their head-relative lateral angles within [`MIRROR_DEG`], and they lie
/// farther apart than twice that.
pub(crate) fn mirror_images(a: &Track, b: &Track, yaw_deg: f64) -> bool {
    let relative = |t: &Track| crate::wrap_deg(t.azimuth_deg - yaw_deg);
    let (ra, rb) = (relative(a), relative(b));
    !a.resolved
        && !b.resolved
        && (lateral_deg(ra) - lateral_deg(rb)).abs() <= MIRROR_DEG
        && crate::turn_deg(ra, rb).abs() > 2.0 * MIRROR_DEG
}

/// Where the front-back image of a source at `world_deg` lies in the world for a head at
/// `yaw_deg`: mirrored about the interaural axis, deg in [0, 360).
fn image_deg(world_deg: f64, yaw_deg: f64) -> f64 {
    crate::wrap_deg(180.0 - world_deg + 2.0 * yaw_deg)
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
        assert!(tracks[0].resolved, "{tracks:?}");
        assert!(
            still.tracks().iter().all(|t| !t.resolved),
            "{:?}",
            still.tracks()
        );
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

    /// Scores over a 1-degree grid with a bump at each of `at` (deg), as a head that tells
    /// front from back hears them.
    fn bumps(grid: &[f64], at: &[f64]) -> Vec<f64> {
        grid.iter()
            .map(|&a| {
                let near = at
                    .iter()
                    .map(|&c| (-0.5 * (crate::turn_deg(c, a) / 8.0).powi(2)).exp())
                    .fold(0.0, f64::max);
                0.3 + 0.7 * near
            })
            .collect()
    }

    #[test]
    fn two_sources_keep_their_identities_through_a_crossing() {
        let params = TrackerParams::default();
        let hop = 0.02;
        let mut tracker = Tracker::new(&params, hop).expect("tracker");
        let grid: Vec<f64> = (0..360).map(f64::from).collect();
        // one walks from 10 to 70 deg, the other from 70 to 10, 20 deg/s each: they meet
        // at 1.5 s, where their peaks merge into one, and part 60 deg apart
        let (a, b) = (|t: f64| 10.0 + 20.0 * t, |t: f64| 70.0 - 20.0 * t);
        let nearest = |tracks: &[Track], at: f64| {
            tracks
                .iter()
                .min_by(|x, y| {
                    let d = |t: &Track| crate::turn_deg(t.azimuth_deg, at).abs();
                    d(x).total_cmp(&d(y))
                })
                .cloned()
                .expect("a track")
        };
        let mut ids = None;
        for k in 0..=150 {
            let t = k as f64 * hop;
            tracker.step(t, 0.0, &grid, Some(&bumps(&grid, &[a(t), b(t)])));
            if k == 25 {
                let tracks = tracker.tracks();
                assert_eq!(tracks.len(), 2, "{tracks:?}");
                ids = Some((nearest(tracks, a(t)).id, nearest(tracks, b(t)).id));
            }
        }
        let t = 150.0 * hop;
        let tracks = tracker.tracks();
        assert_eq!(tracks.len(), 2, "{tracks:?}");
        let (first, second) = (nearest(tracks, a(t)), nearest(tracks, b(t)));
        assert_eq!(Some((first.id, second.id)), ids, "{tracks:?}");
        for (track, truth, speed) in [(&first, a(t), 20.0), (&second, b(t), -20.0)] {
            assert!(
                crate::turn_deg(track.azimuth_deg, truth).abs() < 3.0,
                "{track:?} for {truth}"
            );
            assert!((track.velocity_deg_s - speed).abs() < 5.0, "{track:?}");
        }
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
