//! Head turns that ask for it (binauloc's Stage C): when the tracked sources leave front
//! from back undecided (a source and its mirror image about the interaural axis both
//! tracked) or the likeliest source is behind the head, a turn of [`TURN_STEP_DEG`]
//! towards its side, within the neck's limits. A turn moves a source's image in the world
//! by twice the turn, and the tracker lets it go (see [`mod@crate::track`]).

use serde::Serialize;

use crate::locate::lateral_deg;
use crate::platform::{JointKind, Platform};
use crate::track::{mirror_images, Track};

/// The turn asked for, deg (binauloc's head rotation: ±20 degrees).
pub const TURN_STEP_DEG: f64 = 20.0;

/// A source whose head-relative azimuth lies this far or farther from the front is
/// behind the head, deg.
pub const BEHIND_DEG: f64 = 120.0;

/// Smallest turn worth asking for, deg: at a limit, the head turns the other way instead.
const LEAST_TURN_DEG: f64 = 5.0;

/// How the head may turn: its yaw joint's limits and speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neck {
    /// Lowest yaw, deg (to the right).
    pub min_deg: f64,
    /// Highest yaw, deg (to the left).
    pub max_deg: f64,
    /// Fastest turn, deg/s.
    pub speed_deg_s: f64,
}

impl Default for Neck {
    /// A pan unit turning ±90 degrees at 60 deg/s.
    fn default() -> Self {
        Neck {
            min_deg: -90.0,
            max_deg: 90.0,
            speed_deg_s: 60.0,
        }
    }
}

impl Neck {
    /// A head that cannot turn (a platform without a yaw joint).
    pub const STILL: Neck = Neck {
        min_deg: 0.0,
        max_deg: 0.0,
        speed_deg_s: 0.0,
    };

    /// The platform's first yaw joint (`None` when it has none: the head cannot turn).
    pub fn of(platform: &Platform) -> Option<Neck> {
        platform
            .joints
            .iter()
            .find(|j| j.kind == JointKind::Yaw)
            .map(|j| Neck {
                min_deg: j.min_deg,
                max_deg: j.max_deg,
                speed_deg_s: j.speed_deg_s,
            })
    }

    /// The yaw after `s` seconds of turning from `yaw_deg` towards `target_deg` at full
    /// speed, deg.
    pub fn step_towards(&self, yaw_deg: f64, target_deg: f64, s: f64) -> f64 {
        let reach = self.speed_deg_s * s;
        yaw_deg + (target_deg - yaw_deg).clamp(-reach, reach)
    }
}

/// Why a turn is asked for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(tag = "why", rename_all = "snake_case")]
pub enum Ambiguity {
    /// Tracks `ids` lie at mirror images about the interaural axis: one is the other's
    /// front-back confusion, the likelier first.
    Mirror {
        /// The two tracks' identities.
        ids: (usize, usize),
    },
    /// The likeliest track, `id`, is behind the head.
    Behind {
        /// Its identity.
        id: usize,
    },
}

/// A head rotation that would tell front from back.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Suggestion {
    /// The turn, deg (positive to the left).
    pub turn_deg: f64,
    /// The yaw it ends at, deg (within the neck's limits).
    pub target_yaw_deg: f64,
    /// Why.
    #[serde(flatten)]
    pub why: Ambiguity,
}

/// The turn that `tracks` (world azimuths) ask of a head at `yaw_deg` (any turn: 330 is
/// 30 deg to the right) with `neck`, or `None` when front and back are told apart and no
/// source is behind. Mirror images (as the tracker links them) are looked for among the
/// unresolved tracks, the pair with the likeliest track first. The turn goes towards the
/// side of the likeliest track of the pair (or of the one behind), left when it is
/// straight ahead or behind; at a limit, the other way. Allocates nothing.
pub fn suggest(tracks: &[Track], yaw_deg: f64, neck: &Neck) -> Option<Suggestion> {
    let yaw_deg = crate::turn_deg(0.0, yaw_deg);
    let relative = |t: &Track| crate::wrap_deg(t.azimuth_deg - yaw_deg);
    let likelier = |a: &Track, b: &Track| a.mass.total_cmp(&b.mass).then(b.id.cmp(&a.id));
    let likeliest = tracks.iter().max_by(|a, b| likelier(a, b))?;
    let mirror = tracks
        .iter()
        .enumerate()
        .flat_map(|(i, a)| tracks[i + 1..].iter().map(move |b| (a, b)))
        .filter(|&(a, b)| mirror_images(a, b, yaw_deg))
        .map(|(a, b)| match likelier(a, b) {
            std::cmp::Ordering::Less => (b, a),
            _ => (a, b),
        })
        .max_by(|x, y| likelier(x.0, y.0).then(likelier(x.1, y.1)));
    let (towards, why) = match mirror {
        Some((a, b)) => (relative(a), Ambiguity::Mirror { ids: (a.id, b.id) }),
        None => {
            let r = relative(likeliest);
            if crate::turn_deg(0.0, r).abs() < BEHIND_DEG {
                return None;
            }
            (r, Ambiguity::Behind { id: likeliest.id })
        }
    };
    let side = if lateral_deg(towards) < 0.0 {
        -1.0
    } else {
        1.0
    };
    let clamp = |turn: f64| (yaw_deg + turn).clamp(neck.min_deg, neck.max_deg);
    let mut target = clamp(side * TURN_STEP_DEG);
    if (target - yaw_deg).abs() < LEAST_TURN_DEG {
        target = clamp(-side * TURN_STEP_DEG);
    }
    ((target - yaw_deg).abs() >= LEAST_TURN_DEG).then_some(Suggestion {
        turn_deg: target - yaw_deg,
        target_yaw_deg: target,
        why,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn track(id: usize, azimuth_deg: f64, mass: f64) -> Track {
        Track {
            id,
            azimuth_deg,
            uncertainty_deg: 5.0,
            mass,
            velocity_deg_s: 0.0,
            seen_s: 0.0,
            resolved: false,
        }
    }

    #[test]
    fn mirror_images_ask_for_a_turn_towards_the_likelier_side() {
        let neck = Neck::default();
        // 30 and 150 deg are images; 30 the likelier, on the left: turn left
        let s = suggest(&[track(1, 150.0, 0.3), track(2, 30.0, 0.4)], 0.0, &neck);
        let s = s.expect("a turn");
        assert_eq!(s.why, Ambiguity::Mirror { ids: (2, 1) });
        assert_eq!((s.turn_deg, s.target_yaw_deg), (20.0, 20.0));
        // on the right (330 and 210); and the same head-relative pair with the head
        // turned 10 deg to the left
        let s = suggest(&[track(1, 330.0, 0.5), track(2, 210.0, 0.4)], 0.0, &neck);
        assert_eq!(s.map(|s| s.turn_deg), Some(-20.0));
        let s = suggest(&[track(1, 340.0, 0.5), track(2, 220.0, 0.4)], 10.0, &neck);
        assert_eq!(s.map(|s| s.target_yaw_deg), Some(-10.0));
        // a head 30 deg to the right given as 330: images on its left, 40 and 140 deg
        let s = suggest(&[track(1, 10.0, 0.5), track(2, 110.0, 0.4)], 330.0, &neck);
        assert_eq!(
            s.map(|s| (s.turn_deg, s.target_yaw_deg)),
            Some((20.0, -10.0))
        );
        // a resolved track and its image are no ambiguity
        let told = Track {
            resolved: true,
            ..track(1, 30.0, 0.5)
        };
        assert_eq!(suggest(&[told, track(2, 150.0, 0.2)], 0.0, &neck), None);
    }

    #[test]
    fn a_source_told_apart_in_front_asks_nothing_and_one_behind_asks_to_face_it() {
        let neck = Neck::default();
        assert_eq!(suggest(&[track(1, 40.0, 0.6)], 0.0, &neck), None);
        assert_eq!(suggest(&[], 0.0, &neck), None);
        // two sources apart, not images: nothing
        assert_eq!(
            suggest(&[track(1, 40.0, 0.4), track(2, 300.0, 0.3)], 0.0, &neck),
            None
        );
        let s = suggest(&[track(3, 200.0, 0.6)], 0.0, &neck).expect("a turn");
        assert_eq!(s.why, Ambiguity::Behind { id: 3 });
        assert_eq!(s.turn_deg, -20.0, "200 deg is behind on the right");
        // with the head turned 90 deg to the left, 200 is 110 deg to its left: not behind
        assert_eq!(suggest(&[track(3, 200.0, 0.6)], 90.0, &neck), None);
    }

    #[test]
    fn at_a_limit_the_turn_goes_the_other_way_or_is_shortened() {
        let neck = Neck {
            min_deg: -30.0,
            max_deg: 30.0,
            speed_deg_s: 45.0,
        };
        // at the left limit, images 40 and 140 deg to the left: the turn goes right
        let pair = [track(1, 70.0, 0.5), track(2, 170.0, 0.4)];
        let s = suggest(&pair, 30.0, &neck).expect("a turn");
        assert_eq!((s.turn_deg, s.target_yaw_deg), (-20.0, 10.0));
        // 10 deg short of it: the turn left is shortened to reach it
        let pair = [track(1, 60.0, 0.5), track(2, 160.0, 0.4)];
        let s = suggest(&pair, 20.0, &neck).expect("a turn");
        assert_eq!((s.turn_deg, s.target_yaw_deg), (10.0, 30.0));
        let still = Neck {
            min_deg: 0.0,
            max_deg: 0.0,
            speed_deg_s: 45.0,
        };
        assert_eq!(suggest(&pair, 0.0, &still), None, "a head that cannot turn");
        assert_eq!(suggest(&pair, 0.0, &Neck::STILL), None);
        assert_eq!(neck.step_towards(0.0, 20.0, 0.1), 4.5);
        assert_eq!(neck.step_towards(19.0, 20.0, 0.1), 20.0);
    }
}
