//! A synthetic source placed in the world about a rigid-sphere head that may turn: the
//! ears' signals differ by Woodworth's interaural delay for the azimuth relative to the
//! head at each sample, and the head's yaw sweeps out and back so that a tracker sees it
//! turn (`synth:...,az=150,turn=30`).

/// Speed of sound, m/s.
const SOUND_M_S: f64 = 343.0;

/// Where a synthetic source is and how the head hearing it turns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placed {
    /// The source's azimuth in the world, deg (0 ahead of the head at yaw 0, 90 to the left).
    pub azimuth_deg: f64,
    /// The sphere's radius, m.
    pub radius_m: f64,
    /// The yaw the head turns to and back from, deg (positive to the left); 0: still.
    pub turn_deg: f64,
    /// How long one turn out and back takes, s; the head turns again after each.
    pub turn_s: f64,
}

impl Placed {
    /// A still head of radius 7.5 cm (the seed robots' ball, as the `sphere` head model's)
    /// hearing a source at `azimuth_deg`.
    pub fn at(azimuth_deg: f64) -> Self {
        Placed {
            azimuth_deg,
            radius_m: 0.075,
            turn_deg: 0.0,
            turn_s: 2.0,
        }
    }

    /// The head's yaw at `t_s`, deg: a raised cosine from 0 to `turn_deg` and back over
    /// each `turn_s`, so it starts and ends each turn at rest.
    pub fn yaw_deg_at(&self, t_s: f64) -> f64 {
        let phase = (t_s / self.turn_s).fract();
        self.turn_deg * 0.5 * (1.0 - (std::f64::consts::TAU * phase).cos())
    }

    /// How much later the right ear hears than the left at `t_s`, s (negative: the left is
    /// later): Woodworth's (a/c)(θ + sin θ) for the lateral angle θ of the source relative
    /// to the head, the same in front and behind as a sphere's cues are.
    pub fn right_lag_s(&self, t_s: f64) -> f64 {
        let relative = (self.azimuth_deg - self.yaw_deg_at(t_s)).to_radians();
        let lateral = relative.sin().asin();
        self.radius_m / SOUND_M_S * (lateral + lateral.sin())
    }

    /// The largest |[`Placed::right_lag_s`]|, s: a source at the side.
    pub fn max_lag_s(&self) -> f64 {
        self.radius_m / SOUND_M_S * (std::f64::consts::FRAC_PI_2 + 1.0)
    }
}

/// The ears of a [`Placed`] source: the dry signal's recent samples, read back at a
/// fractional delay for each ear (4-point Lagrange interpolation) about a common delay
/// that keeps both causal.
#[derive(Debug, Clone)]
pub(crate) struct Ears {
    ring: Vec<f64>,
    /// Where the newest sample is.
    newest: usize,
    /// The delay both ears share, samples.
    centre: f64,
}

impl Ears {
    /// Ears for interaural delays up to `max_lag` samples either way.
    pub(crate) fn new(max_lag: f64) -> Self {
        let centre = (max_lag / 2.0).ceil() + 1.0;
        let len = (centre + max_lag / 2.0).ceil() as usize + 4;
        Ears {
            ring: vec![0.0; len],
            newest: 0,
            centre,
        }
    }

    /// Takes the dry sample `x` and gives (left, right) with the right ear `right_lag`
    /// samples later than the left.
    pub(crate) fn hear(&mut self, x: f64, right_lag: f64) -> (f64, f64) {
        self.newest = (self.newest + 1) % self.ring.len();
        self.ring[self.newest] = x;
        (
            self.delayed(self.centre - right_lag / 2.0),
            self.delayed(self.centre + right_lag / 2.0),
        )
    }

    /// The signal `delay` samples ago (at least 1, within the ring).
    fn delayed(&self, delay: f64) -> f64 {
        let whole = delay.floor();
        let f = delay - whole;
        let n = self.ring.len();
        let at = |k: f64| self.ring[(self.newest + n - k as usize) % n];
        let (a, b, c, d) = (at(whole - 1.0), at(whole), at(whole + 1.0), at(whole + 2.0));
        -f * (f - 1.0) * (f - 2.0) / 6.0 * a + (f + 1.0) * (f - 1.0) * (f - 2.0) / 2.0 * b
            - (f + 1.0) * f * (f - 2.0) / 2.0 * c
            + (f + 1.0) * f * (f - 1.0) / 6.0 * d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_head_turns_out_and_back_at_rest_at_each_end() {
        let p = Placed {
            turn_deg: 30.0,
            ..Placed::at(150.0)
        };
        assert_eq!(p.yaw_deg_at(0.0), 0.0);
        assert!((p.yaw_deg_at(1.0) - 30.0).abs() < 1e-12);
        assert!(p.yaw_deg_at(2.0).abs() < 1e-12);
        assert!((p.yaw_deg_at(0.5) - 15.0).abs() < 1e-12);
        assert!((p.yaw_deg_at(3.0) - 30.0).abs() < 1e-12, "it turns again");
    }

    #[test]
    fn woodworths_delay_is_the_same_in_front_and_behind_and_largest_at_the_side() {
        let lag = |az: f64| Placed::at(az).right_lag_s(0.0);
        assert!((lag(90.0) - Placed::at(0.0).max_lag_s()).abs() < 1e-15);
        assert!(
            lag(90.0) > 5.5e-4,
            "a source on the left reaches the right ear later"
        );
        assert!((lag(30.0) - lag(150.0)).abs() < 1e-15);
        assert!((lag(330.0) + lag(30.0)).abs() < 1e-15);
        assert_eq!(lag(0.0), 0.0);
    }

    #[test]
    fn the_ears_read_the_signal_at_their_fractional_delays() {
        // a cubic is interpolated exactly: each ear hears it shifted by its delay
        let mut ears = Ears::new(8.0);
        let x = |n: f64| 1e-6 * n * n * n - 2e-4 * n * n + 0.3 * n;
        let lag = 3.3;
        for n in 0..50 {
            let (l, r) = ears.hear(x(f64::from(n)), lag);
            if n > 20 {
                let n = f64::from(n);
                assert!((l - x(n - ears.centre + lag / 2.0)).abs() < 1e-9, "{n}");
                assert!((r - x(n - ears.centre - lag / 2.0)).abs() < 1e-9, "{n}");
            }
        }
    }
}
