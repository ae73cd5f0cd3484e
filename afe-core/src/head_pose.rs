//! The head's yaw as it is reported while the audio runs (a motor controller's Zenoh key,
//! Python's `Manager.set_head_yaw`, a CSV track, a synthetic sweep), shared with the
//! processors that turn head-relative azimuths into the world's.
//!
//! Times are seconds of audio since the processors started (the stream's first sample, or
//! the last reset: a whole-signal run starts at 0), so a live stream's times are its
//! frame index over its rate. Writers take a lock among themselves; readers (processors
//! on the audio path) take none and allocate nothing.

use std::sync::{Arc, Mutex, PoisonError};

use arc_swap::ArcSwap;

use crate::{Error, Result};

/// Points kept of a live feed: at 100 Hz, 40 s; older ones are let go (each point
/// copies the list, so that readers never wait).
pub const KEPT_POINTS: usize = 4096;

/// The head's yaw over time, shared (a clone is the same feed): points `(t_s, yaw_deg)`,
/// times strictly increasing, yaw positive to the left as azimuths are.
#[derive(Clone, Default)]
pub struct HeadPose {
    shared: Arc<Shared>,
}

#[derive(Default)]
struct Shared {
    points: ArcSwap<Vec<(f64, f64)>>,
    /// Serialises writers (each replaces the list readers see).
    writer: Mutex<()>,
}

impl std::fmt::Debug for HeadPose {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HeadPose")
            .field("points", &self.shared.points.load().len())
            .finish()
    }
}

impl HeadPose {
    /// A feed with no point yet: the head at yaw 0 until one comes.
    pub fn new() -> Self {
        HeadPose::default()
    }

    /// Adds the yaw `yaw_deg` at `t_s` (s since the processors started); refused unless
    /// both are finite and `t_s` comes after the last point's time.
    pub fn push(&self, t_s: f64, yaw_deg: f64) -> Result<()> {
        check_point(t_s, yaw_deg)?;
        let _writing = self
            .shared
            .writer
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let old = self.shared.points.load();
        if let Some(&(last, _)) = old.last() {
            if t_s <= last {
                return Err(Error::InvalidInput(format!(
                    "head yaw: a point at t_s = {t_s} does not follow the last one at t_s = \
                     {last}: times must increase"
                )));
            }
        }
        let keep = old.len().min(KEPT_POINTS - 1);
        let mut points = Vec::with_capacity(keep + 1);
        points.extend_from_slice(&old[old.len() - keep..]);
        points.push((t_s, yaw_deg));
        self.shared.points.store(Arc::new(points));
        Ok(())
    }

    /// Replaces the feed by the whole track `points` (e.g. a CSV file's), every point
    /// kept; checked as [`HeadPose::push`] checks each.
    pub fn set_track(&self, points: &[(f64, f64)]) -> Result<()> {
        for (i, &(t, yaw)) in points.iter().enumerate() {
            check_point(t, yaw)?;
            if i > 0 && t <= points[i - 1].0 {
                return Err(Error::InvalidInput(format!(
                    "head yaw: point {} at t_s = {t} does not follow t_s = {}: times must \
                     increase",
                    i + 1,
                    points[i - 1].0
                )));
            }
        }
        let _writing = self
            .shared
            .writer
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        self.shared.points.store(Arc::new(points.to_vec()));
        Ok(())
    }

    /// Forgets every point: the head at yaw 0 again.
    pub fn clear(&self) {
        let _writing = self
            .shared
            .writer
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        self.shared.points.store(Arc::new(Vec::new()));
    }

    /// Points held now.
    pub fn len(&self) -> usize {
        self.shared.points.load().len()
    }

    /// Whether no point has come (or all were cleared).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The yaw at `t_s`, deg in [0, 360): 0 with no point, held before the first point and
    /// after the last (a live feed's newest report stands until the next), and between
    /// two points along the shorter way round. Lock-free and allocation-free.
    pub fn yaw_at(&self, t_s: f64) -> f64 {
        yaw_at(&self.shared.points.load(), t_s)
    }
}

fn check_point(t_s: f64, yaw_deg: f64) -> Result<()> {
    if t_s.is_finite() && yaw_deg.is_finite() {
        Ok(())
    } else {
        Err(Error::InvalidInput(format!(
            "head yaw: the point ({t_s}, {yaw_deg}) is not finite"
        )))
    }
}

/// The signed turn from `from_deg` to `to_deg` the shorter way round, deg in [-180, 180).
pub fn turn_deg(from_deg: f64, to_deg: f64) -> f64 {
    (to_deg - from_deg + 540.0).rem_euclid(360.0) - 180.0
}

/// The yaw of track `points` (`(t_s, yaw_deg)`, times increasing) at `t_s`, deg in
/// [0, 360), as [`HeadPose::yaw_at`] reads it.
pub fn yaw_at(points: &[(f64, f64)], t_s: f64) -> f64 {
    let next = points.partition_point(|p| p.0 <= t_s);
    let yaw = match (next.checked_sub(1).map(|i| points[i]), points.get(next)) {
        (None, None) => 0.0,
        (None, Some(&(_, yaw))) | (Some((_, yaw)), None) => yaw,
        (Some((t0, a)), Some(&(t1, b))) => a + turn_deg(a, b) * (t_s - t0) / (t1 - t0),
    };
    yaw.rem_euclid(360.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_feed_is_read_between_its_points_the_short_way() {
        let pose = HeadPose::new();
        assert_eq!(pose.yaw_at(3.0), 0.0, "no point: the head at rest");
        pose.push(0.0, 350.0).expect("first");
        pose.push(1.0, 10.0).expect("second");
        let reader = pose.clone();
        assert_eq!(reader.yaw_at(-1.0), 350.0);
        assert!(reader.yaw_at(0.5).abs() < 1e-12, "{}", reader.yaw_at(0.5));
        assert!((reader.yaw_at(0.75) - 5.0).abs() < 1e-12);
        assert_eq!(reader.yaw_at(9.0), 10.0, "the newest report stands");
        assert_eq!(turn_deg(330.0, 30.0), 60.0);
        assert_eq!(turn_deg(30.0, 330.0), -60.0);
    }

    #[test]
    fn points_out_of_order_or_not_finite_are_refused_and_nothing_is_lost() {
        let pose = HeadPose::new();
        pose.push(1.0, 20.0).expect("first");
        let e = pose.push(1.0, 30.0).expect_err("same time").to_string();
        assert!(
            e.contains("t_s = 1 does not follow the last one at t_s = 1"),
            "{e}"
        );
        let e = pose.push(2.0, f64::NAN).expect_err("NaN").to_string();
        assert!(e.contains("(2, NaN) is not finite"), "{e}");
        assert_eq!(pose.len(), 1);
        let e = pose
            .set_track(&[(0.0, 0.0), (2.0, 1.0), (1.0, 2.0)])
            .expect_err("backwards")
            .to_string();
        assert!(
            e.contains("point 3 at t_s = 1 does not follow t_s = 2"),
            "{e}"
        );
        assert_eq!(pose.yaw_at(5.0), 20.0, "a refused track leaves the feed");
        pose.clear();
        assert!(pose.is_empty());
    }

    #[test]
    fn a_long_live_feed_keeps_its_newest_points() {
        let pose = HeadPose::new();
        for k in 0..KEPT_POINTS + 10 {
            pose.push(k as f64 * 0.01, (k % 360) as f64).expect("push");
        }
        assert_eq!(pose.len(), KEPT_POINTS);
        let newest = (KEPT_POINTS + 9) as f64 * 0.01;
        assert_eq!(pose.yaw_at(newest), ((KEPT_POINTS + 9) % 360) as f64);
    }
}
