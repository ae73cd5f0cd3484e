//! The head's yaw over time, for turning head-relative azimuths into world azimuths
//! (world = relative + yaw): a track of `(t_s, yaw_deg)` points, yaw positive to the left
//! as azimuths are, linearly interpolated along the shorter way round.

use crate::SpatialError;

/// A head's yaw track: times strictly increasing, s; yaw, deg (positive to the left).
#[derive(Debug, Clone, PartialEq)]
pub struct HeadYaw {
    points: Vec<(f64, f64)>,
}

impl HeadYaw {
    /// The track through `points` (`(t_s, yaw_deg)`): at least one, finite, times
    /// strictly increasing.
    pub fn new(points: &[(f64, f64)]) -> Result<Self, SpatialError> {
        let bad = |why: String| Err(SpatialError::Invalid(format!("head yaw: {why}")));
        if points.is_empty() {
            return bad("no (t_s, yaw_deg) point".into());
        }
        for (i, &(t, yaw)) in points.iter().enumerate() {
            if !(t.is_finite() && yaw.is_finite()) {
                return bad(format!("point {} ({t}, {yaw}) is not finite", i + 1));
            }
            if i > 0 && t <= points[i - 1].0 {
                return bad(format!(
                    "point {} at t_s = {t} does not follow t_s = {}: times must increase",
                    i + 1,
                    points[i - 1].0
                ));
            }
        }
        Ok(HeadYaw {
            points: points.to_vec(),
        })
    }

    /// The track in a CSV text: a row `t_s,yaw_deg` per point, after an optional header
    /// row of those two names; blank lines are skipped. Errors name the line.
    pub fn parse_csv(text: &str) -> Result<Self, SpatialError> {
        let mut points = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || (points.is_empty() && line.replace(' ', "") == "t_s,yaw_deg") {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let parsed = match fields.as_slice() {
                [t, yaw] => t.parse::<f64>().ok().zip(yaw.parse::<f64>().ok()),
                _ => None,
            };
            let Some(point) = parsed else {
                return Err(SpatialError::Invalid(format!(
                    "head yaw, line {}: '{line}' is not t_s,yaw_deg (two numbers)",
                    i + 1
                )));
            };
            points.push(point);
        }
        HeadYaw::new(&points)
    }

    /// The track's points, `(t_s, yaw_deg)`, as given.
    pub fn points(&self) -> &[(f64, f64)] {
        &self.points
    }

    /// The yaw at `t_s`, deg in [0, 360): held before the first point and after the last,
    /// and between two points along the shorter way from one to the other (as the live
    /// [`afe_core::HeadPose`] reads its points).
    pub fn at(&self, t_s: f64) -> f64 {
        afe_core::head_pose::yaw_at(&self.points, t_s)
    }
}

/// `scores` over the circular, ascending grid `azimuths` (deg in [0, 360)) read at
/// `azimuth_deg`, linearly between the two grid points around it.
pub(crate) fn score_at(azimuths: &[f64], scores: &[f64], azimuth_deg: f64) -> f64 {
    let n = azimuths.len();
    let a = azimuth_deg.rem_euclid(360.0);
    let above = azimuths.partition_point(|&g| g <= a);
    let (lo, hi) = ((above + n - 1) % n, above % n);
    let span = (azimuths[hi] - azimuths[lo]).rem_euclid(360.0);
    if span == 0.0 {
        return scores[lo];
    }
    let w = (a - azimuths[lo]).rem_euclid(360.0) / span;
    scores[lo] + w * (scores[hi] - scores[lo])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaw_is_interpolated_the_short_way_and_held_at_the_ends() {
        let track = HeadYaw::parse_csv("t_s,yaw_deg\n0,350\n1,10\n\n2, 40\n").expect("csv");
        assert_eq!(track.at(-1.0), 350.0);
        assert!((track.at(0.5) - 0.0).abs() < 1e-12, "{}", track.at(0.5));
        assert!((track.at(0.75) - 5.0).abs() < 1e-12);
        assert!((track.at(1.5) - 25.0).abs() < 1e-12);
        assert_eq!(track.at(9.0), 40.0);
        assert_eq!(HeadYaw::new(&[(0.0, -30.0)]).expect("one").at(3.0), 330.0);
    }

    #[test]
    fn bad_tracks_are_named() {
        let e = |text: &str| HeadYaw::parse_csv(text).expect_err(text).to_string();
        assert_eq!(e(""), "head yaw: no (t_s, yaw_deg) point");
        assert!(e("0,1\n1,2,3").contains("line 2: '1,2,3' is not t_s,yaw_deg"));
        assert!(e("0,abc").contains("line 1: '0,abc'"));
        assert!(e("0,1\n0,2").contains("point 2 at t_s = 0 does not follow t_s = 0"));
        assert!(e("0,inf").contains("point 1 (0, inf) is not finite"));
    }

    #[test]
    fn scores_are_read_between_grid_points_round_the_circle() {
        let grid = [0.0, 90.0, 180.0, 270.0];
        let scores = [1.0, 0.0, 0.5, 0.0];
        assert_eq!(score_at(&grid, &scores, 45.0), 0.5);
        assert_eq!(score_at(&grid, &scores, 180.0), 0.5);
        assert_eq!(score_at(&grid, &scores, 315.0), 0.5);
        assert_eq!(score_at(&grid, &scores, -45.0), 0.5);
        assert_eq!(score_at(&grid, &scores, 360.0), 1.0);
    }
}
