//! The peaks of a score over a circular azimuth grid, as the localiser and the tracker
//! read them.

/// The indices of the local maxima of the circular `scores` (a plateau counts once, at its
/// first index).
pub(crate) fn local_maxima(scores: &[f64]) -> impl Iterator<Item = usize> + '_ {
    let n = scores.len();
    (0..n).filter(move |&k| {
        let (a, c) = (scores[(k + n - 1) % n], scores[(k + 1) % n]);
        scores[k] > a && scores[k] >= c
    })
}

/// The azimuth of the peak at `k` of `scores` on the circular grid `azimuths`, refined
/// by the parabola through it and its neighbours.
pub(crate) fn refine(azimuths: &[f64], scores: &[f64], k: usize) -> f64 {
    let n = scores.len();
    if n < 3 {
        return azimuths[k];
    }
    let (a, b, c) = (scores[(k + n - 1) % n], scores[k], scores[(k + 1) % n]);
    let curve = a - 2.0 * b + c;
    let shift = if curve < 0.0 {
        (0.5 * (a - c) / curve).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    // the step towards the neighbour the shift leans to (grids may be uneven)
    let next = if shift >= 0.0 {
        (k + 1) % n
    } else {
        (k + n - 1) % n
    };
    let step = crate::turn_deg(azimuths[k], azimuths[next]);
    crate::wrap_deg(azimuths[k] + shift.abs() * step)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maxima_wrap_around_and_refine_between_grid_points() {
        let scores = [3.0, 1.0, 0.0, 1.0, 2.0, 2.0, 1.0, 2.5];
        assert_eq!(local_maxima(&scores).collect::<Vec<_>>(), [0, 4]);
        let grid: Vec<f64> = (0..8).map(|k| 45.0 * k as f64).collect();
        // the parabola through 2.5, 3 and 1 peaks 0.3 of a step towards 315 deg
        let a = refine(&grid, &scores, 0);
        assert!((a - (360.0 - 0.3 * 45.0)).abs() < 1e-12, "{a}");
        // a plateau of two points peaks between them (on an uneven grid, by its own step)
        let uneven = [0.0, 90.0, 100.0, 200.0];
        assert_eq!(refine(&uneven, &[0.0, 1.0, 1.0, 0.0], 1), 95.0);
    }
}
