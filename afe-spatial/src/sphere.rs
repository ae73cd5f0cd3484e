//! The rigid sphere (Duda & Martens 1998): the pressure at a point of a rigid sphere's
//! surface from a point source at any distance beyond it (or a plane wave), over the
//! free-field pressure at the sphere's centre, as a series of Legendre polynomials and
//! spherical Hankel functions. Two microphones on the sphere make a head model without
//! pinnae: the robots' polystyrene balls.

use num_complex::Complex64;

/// Speed of sound, m/s (20 °C).
pub const SPEED_OF_SOUND: f64 = 343.0;

/// Terms beyond the normalised frequency μ that the series keeps at least; it stops once
/// no term of any angle can exceed 1e-17 of the first.
const EXTRA_TERMS: usize = 30;
/// Where the Hankel recurrences are rescaled (near source) or the series ends (far): they
/// grow as (2m − 1)!!/x^{m+1}, and a complex division squares its divisor.
const HUGE: f64 = 1e100;
/// The largest term, over the first, at which the series ends: below the sum's rounding
/// at any angle where |H| is above 1e-2.
const NEGLIGIBLE: f64 = 1e-17;
/// Most terms of the series (μ = 2πf·a/c is below 300 for any head at audio rates).
const MAX_TERMS: usize = 600;

/// A rigid sphere of radius `radius_m` with two microphones on its horizontal great circle.
#[derive(Debug, Clone, PartialEq)]
pub struct Sphere {
    /// Radius, m.
    pub radius_m: f64,
    /// The left microphone's azimuth, deg (0 = front, 90 = left); the right one is at its
    /// mirror image, `−ear_deg`.
    pub ear_deg: f64,
    /// The source's distance from the centre, m (`f64::INFINITY`: a plane wave).
    pub distance_m: f64,
}

impl Sphere {
    /// Antipodal microphones (ears at ±90°) and a far source: the seed robots' 15-cm ball
    /// has `radius_m = 0.075`.
    pub fn antipodal(radius_m: f64) -> Sphere {
        Sphere {
            radius_m,
            ear_deg: 90.0,
            distance_m: f64::INFINITY,
        }
    }

    /// The transfer functions to the left and the right microphone of a source at
    /// `azimuth_deg` on the horizontal plane, at `f_hz`, in the DFT's sign convention (a
    /// delay τ is `e^{−iωτ}`), relative to the free field at the centre.
    pub fn transfer(&self, azimuth_deg: f64, f_hz: f64) -> [Complex64; 2] {
        let left = incidence(azimuth_deg, self.ear_deg);
        let right = incidence(azimuth_deg, -self.ear_deg);
        let h = self.series(f_hz).responses(&[left, right]);
        [h[0], h[1]]
    }

    /// The series at `f_hz`, which every azimuth shares.
    pub fn series(&self, f_hz: f64) -> Series {
        let mu = 2.0 * std::f64::consts::PI * f_hz * self.radius_m / SPEED_OF_SOUND;
        Series::new(self.distance_m / self.radius_m, mu)
    }

    /// The transfer functions of each of `azimuths_deg` (outer) at each of `freqs_hz`
    /// (inner), as [`Sphere::transfer`] gives them, one series per frequency.
    pub fn transfers(&self, azimuths_deg: &[f64], freqs_hz: &[f64]) -> Vec<Vec<[Complex64; 2]>> {
        let mut out = vec![Vec::with_capacity(freqs_hz.len()); azimuths_deg.len()];
        // the left microphone's angle of each azimuth, then the right one's
        let cos_thetas: Vec<f64> = [self.ear_deg, -self.ear_deg]
            .iter()
            .flat_map(|&ear| azimuths_deg.iter().map(move |&az| incidence(az, ear)))
            .collect();
        let na = azimuths_deg.len();
        for &f in freqs_hz {
            let h = self.series(f).responses(&cos_thetas);
            for (a, row) in out.iter_mut().enumerate() {
                row.push([h[a], h[na + a]]);
            }
        }
        out
    }
}

/// cos of the angle between a source at `azimuth_deg` and a microphone at `ear_deg`, both
/// on the horizontal plane.
fn incidence(azimuth_deg: f64, ear_deg: f64) -> f64 {
    (azimuth_deg - ear_deg).to_radians().cos()
}

/// Duda & Martens' H(ρ, μ, θ) with `cos_theta` = cos θ, conjugated into the DFT's
/// convention: ρ = distance/radius (> 1, or infinite), μ = ωa/c. At μ = 0 the sphere is
/// transparent: 1.
pub fn response(rho: f64, mu: f64, cos_theta: f64) -> Complex64 {
    Series::new(rho, mu).responses(&[cos_theta])[0]
}

/// The part of the series that does not depend on the angle, at one (ρ, μ): each order's
/// coefficient, so that every microphone and azimuth at one frequency shares one run of
/// the Hankel recurrences and the angles are summed side by side.
pub struct Series {
    rho: f64,
    mu: f64,
    far: bool,
    /// (2m + 1)·h_m(μρ)/h'_m(μ) of each order m, or for a plane wave
    /// (2m + 1)·(−i)^{m−1}/h'_m(μ) (the far limit of h_m(μρ)·(−ρ/μ)·e^{−iμρ}, times μ²):
    /// H is their sum with P_m(cos θ), scaled.
    coef: Vec<Complex64>,
}

impl Series {
    /// The orders of the series at (`rho`, `mu`): h_m(μ) and h_m(μρ) by upward recurrence
    /// (spherical Hankel of the first kind, time convention e^{−iωt}), with
    /// h'_m = h_{m−1} − (m + 1)/x·h_m, up to the first order beyond μ + 30 whose largest
    /// term at any angle (|P_m| <= 1) is below 1e-17 of the first.
    pub fn new(rho: f64, mu: f64) -> Series {
        let far = rho.is_infinite();
        let mut coef = Vec::new();
        if mu > 0.0 {
            let i = Complex64::new(0.0, 1.0);
            let h0 = |x: f64| -i * Complex64::from_polar(1.0 / x, x);
            let h1 = |x: f64| -Complex64::from_polar(1.0 / (x * x), x) * Complex64::new(x, 1.0);
            let (mut ha_prev, mut ha) = (h0(mu), h1(mu));
            let (mut hr_prev, mut hr) = if far {
                (Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0))
            } else {
                (h0(mu * rho), h1(mu * rho))
            };
            // (−i)^{m−1}: i, 1, −i, −1, ...
            let phases = [i, Complex64::new(1.0, 0.0), -i, Complex64::new(-1.0, 0.0)];
            let order = |m: usize, h_rho: Complex64, h_prime: Complex64| {
                (2 * m + 1) as f64 * if far { phases[m % 4] } else { h_rho } / h_prime
            };
            // m = 0: h'_0 = −h_1
            coef.push(order(0, hr_prev, -ha));
            let first = coef[0].norm();
            for m in 1..=MAX_TERMS {
                let c = order(m, hr, ha_prev - (m as f64 + 1.0) / mu * ha);
                coef.push(c);
                if m > mu as usize + EXTRA_TERMS && c.norm() < NEGLIGIBLE * first {
                    break;
                }
                let k = (2 * m + 1) as f64;
                (ha_prev, ha) = (ha, k / mu * ha - ha_prev);
                if !far {
                    (hr_prev, hr) = (hr, k / (mu * rho) * hr - hr_prev);
                }
                if ha.norm() > HUGE {
                    if far {
                        // 1/h'_m below 1e-100 of the first terms: the rest is nothing
                        break;
                    }
                    // the near terms are ratios: both recurrences scaled alike keep them
                    for h in [&mut ha_prev, &mut ha, &mut hr_prev, &mut hr] {
                        *h /= HUGE;
                    }
                }
            }
        }
        Series { rho, mu, far, coef }
    }

    /// H(ρ, μ, θ) at each of `cos_thetas` (cos θ): the orders summed with P_m(cos θ), by
    /// the Legendre recurrence, all angles at once.
    pub fn responses(&self, cos_thetas: &[f64]) -> Vec<Complex64> {
        let n = cos_thetas.len();
        let Some(&c0) = self.coef.first() else {
            return vec![Complex64::new(1.0, 0.0); n];
        };
        let (mut re, mut im) = (vec![c0.re; n], vec![c0.im; n]);
        let (mut p_prev, mut p) = (vec![1.0; n], cos_thetas.to_vec());
        for (m, c) in self.coef.iter().enumerate().skip(1) {
            // P_{m+1} = ((2m + 1)·x·P_m − m·P_{m−1})/(m + 1)
            let a = (2 * m + 1) as f64 / (m + 1) as f64;
            let b = m as f64 / (m + 1) as f64;
            for k in 0..n {
                re[k] += c.re * p[k];
                im[k] += c.im * p[k];
                let next = a * cos_thetas[k] * p[k] - b * p_prev[k];
                p_prev[k] = p[k];
                p[k] = next;
            }
        }
        let scale = if self.far {
            Complex64::new(1.0 / (self.mu * self.mu), 0.0)
        } else {
            -(self.rho / self.mu) * Complex64::from_polar(1.0, -self.mu * self.rho)
        };
        re.iter()
            .zip(&im)
            .map(|(&r, &i)| (scale * Complex64::new(r, i)).conj())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Interaural time difference of `sphere` for a source at `azimuth_deg`, s: the phase
    /// delay of the right microphone behind the left at `f_hz`.
    fn itd(sphere: &Sphere, azimuth_deg: f64, f_hz: f64) -> f64 {
        let [l, r] = sphere.transfer(azimuth_deg, f_hz);
        (l / r).arg() / (2.0 * std::f64::consts::PI * f_hz)
    }

    /// The group delay of the right microphone behind the left over `band` (Hz), s: the
    /// least-squares slope of the unwrapped interaural phase (the creeping waves' ripple
    /// averages out over a band).
    fn group_itd(sphere: &Sphere, azimuth_deg: f64, band: (f64, f64)) -> f64 {
        let tau = 2.0 * std::f64::consts::PI;
        let freqs: Vec<f64> = (0..=400)
            .map(|k| band.0 + (band.1 - band.0) * k as f64 / 400.0)
            .collect();
        let mut phase: Vec<f64> = Vec::with_capacity(freqs.len());
        for &f in &freqs {
            let [l, r] = sphere.transfer(azimuth_deg, f);
            let p = (l / r).arg();
            let unwrapped = match phase.last() {
                Some(&last) => last + ((p - last + tau / 2.0).rem_euclid(tau) - tau / 2.0),
                None => p,
            };
            phase.push(unwrapped);
        }
        let n = freqs.len() as f64;
        let (mf, mp) = (freqs.iter().sum::<f64>() / n, phase.iter().sum::<f64>() / n);
        let cov: f64 = freqs
            .iter()
            .zip(&phase)
            .map(|(f, p)| (f - mf) * (p - mp))
            .sum();
        let var: f64 = freqs.iter().map(|f| (f - mf) * (f - mf)).sum();
        cov / var / tau
    }

    #[test]
    fn the_sphere_is_transparent_at_low_frequency_and_a_near_source_agrees_with_a_far_one() {
        for cos in [-1.0, -0.3, 0.0, 0.5, 1.0] {
            // far enough that the spreading over the sphere is negligible (1/ρ)
            for (rho, tol) in [(200.0, 1.2e-2), (f64::INFINITY, 1e-3)] {
                let h = response(rho, 1e-4, cos);
                assert!(
                    (h - Complex64::new(1.0, 0.0)).norm() < tol,
                    "{rho} {cos}: {h}"
                );
            }
            // a near source is louder at the facing side at any frequency (its range cue)
            let (near, far) = (response(1.5, 1e-3, 1.0), response(1.5, 1e-3, -1.0));
            assert!(
                near.norm() > 2.0 * far.norm() && near.is_finite(),
                "{near} {far}"
            );
            // a source 20000 radii away is a plane wave to 1e-3
            for mu in [0.5, 3.0, 20.0] {
                let near = response(20000.0, mu, cos);
                let far = response(f64::INFINITY, mu, cos);
                assert!(
                    (near - far).norm() < 1e-3 * far.norm(),
                    "{mu} {cos}: {near} vs {far}"
                );
            }
        }
    }

    /// One series per frequency for all azimuths gives each azimuth's transfer functions
    /// as one call per azimuth and frequency does, bit for bit, near and far.
    #[test]
    fn a_grid_of_azimuths_is_each_azimuths_transfer() {
        let freqs = [0.0, 100.0, 1500.0, 7000.0, 16000.0];
        let azimuths = [0.0, 37.5, 90.0, 181.0, 300.0];
        for distance_m in [f64::INFINITY, 0.5] {
            let sphere = Sphere {
                distance_m,
                ..Sphere::antipodal(0.075)
            };
            let grid = sphere.transfers(&azimuths, &freqs);
            for (row, &az) in grid.iter().zip(&azimuths) {
                let each: Vec<[Complex64; 2]> =
                    freqs.iter().map(|&f| sphere.transfer(az, f)).collect();
                assert_eq!(row, &each, "{az} deg at {distance_m} m");
            }
        }
    }

    #[test]
    fn the_facing_side_gains_6_db_at_high_frequency_and_the_far_side_is_shadowed() {
        let facing = response(f64::INFINITY, 40.0, 1.0).norm();
        assert!((20.0 * facing.log10() - 6.02).abs() < 0.3, "{facing}");
        // behind the sphere, short of the bright spot at the far pole
        let shadowed = response(f64::INFINITY, 10.0, (150f64).to_radians().cos()).norm();
        assert!(20.0 * shadowed.log10() < -8.0, "{shadowed}");
        let pole = response(f64::INFINITY, 10.0, -1.0).norm();
        assert!(pole > 2.0 * shadowed, "{pole} vs {shadowed}");
    }

    #[test]
    fn its_itd_follows_woodworth_at_high_and_kuhn_at_low_frequency() {
        let sphere = Sphere::antipodal(0.0875);
        let a_c = sphere.radius_m / SPEED_OF_SOUND;
        for az in [15.0f64, 30.0, 45.0, 60.0, 75.0] {
            let phi = az.to_radians();
            // a source to the left reaches the left microphone first: right behind left
            let low = itd(&sphere, az, 100.0);
            let kuhn = 3.0 * a_c * phi.sin();
            assert!((low / kuhn - 1.0).abs() < 0.05, "{az}: {low} vs {kuhn}");
            let high = group_itd(&sphere, az, (3000.0, 12000.0));
            let woodworth = a_c * (phi + phi.sin());
            assert!(
                (high / woodworth - 1.0).abs() < 0.05,
                "{az}: {high} vs {woodworth}"
            );
        }
    }
}
