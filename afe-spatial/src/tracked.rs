//! A whole localisation tracked (Stage B) and the turns its tracks ask for (Stage C),
//! reported at a fixed rate: what `afe locate --track` prints.

use serde::Serialize;

use crate::locate::Located;
use crate::track::{Track, Tracker, TrackerParams};
use crate::turn::{suggest, Neck, Suggestion};
use crate::SpatialError;

/// Rate at which [`track`] reports the tracked sources, Hz (binauloc's Stage B runs at
/// about 6 Hz).
pub const REPORT_HZ: f64 = 6.0;

/// The tracked sources at one time.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Tracked {
    /// The frame's centre, s.
    pub t_s: f64,
    /// The head's yaw then, deg.
    pub yaw_deg: f64,
    /// The sources tracked then, by identity.
    pub tracks: Vec<Track>,
    /// The head turn they ask for then (Stage C), if any.
    #[serde(rename = "suggested_turn")]
    pub suggestion: Option<Suggestion>,
}

/// The sources of a whole localisation tracked over its frames (their scores, the
/// head's yaw, their activity), reported at [`REPORT_HZ`] and at the last frame, each
/// report with the turn its tracks ask of `neck`.
pub fn track(
    found: &Located,
    params: &TrackerParams,
    neck: &Neck,
) -> Result<Vec<Tracked>, SpatialError> {
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
                suggestion: suggest(tracker.tracks(), frame.yaw_deg, neck),
            });
        }
    }
    Ok(out)
}
