//! The rigid sphere (Duda & Martens 1998): the pressure at a point of a rigid sphere's
//! surface from a point source at any distance beyond it (or a plane wave), over the
//! free-field pressure at the sphere's centre, as a series of Legendre polynomials and
//! spherical Hankel functions. Two microphones on the sphere make a head model without
//! pinnae: the robots' polystyrene balls.

use num_complex::Complex64;

/// Speed of sound, m/s (20 °C).
pub const SPEED_OF_SOUND: f64 = 343.0;

/// Terms beyond the normalised frequency μ that the series keeps at least; it stops once a
/// term falls below 1e-15 of the sum.
const EXTRA_TERMS: usize = 30;
/// Where the Hankel recurrences are rescaled (near source) or the series ends (far): they
/// grow as (2m − 1)!!/x^{m+1}, and a complex division squares its divisor.
const HUGE: f64 = 1e100;
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
        let mu = 2.0 * std::f64::consts::PI * f_hz * self.radius_m / SPEED_OF_SOUND;
        let rho = self.distance_m / self.radius_m;
        [response(rho, mu, left), response(rho, mu, right)]
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
    if mu <= 0.0 {
        return Complex64::new(1.0, 0.0);
    }
    let far = rho.is_infinite();
    // h_m(μ) and h_m(μρ) by upward recurrence (spherical Hankel of the first kind, time
    // convention e^{−iωt}), with P_m(cos θ); h'_m = h_{m−1} − (m + 1)/x·h_m
    let i = Complex64::new(0.0, 1.0);
    let h0 = |x: f64| -i * Complex64::from_polar(1.0 / x, x);
    let h1 = |x: f64| -Complex64::from_polar(1.0 / (x * x), x) * Complex64::new(x, 1.0);
    let (mut ha_prev, mut ha) = (h0(mu), h1(mu));
    let (mut hr_prev, mut hr) = if far {
        (Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0))
    } else {
        (h0(mu * rho), h1(mu * rho))
    };
    let (mut p_prev, mut p) = (1.0, cos_theta);
    // m = 0: h'_0 = −h_1
    let mut sum = term(0, far, hr_prev, -ha, 1.0);
    let mut m = 1usize;
    loop {
        let dh = ha_prev - (m as f64 + 1.0) / mu * ha;
        let t = term(m, far, hr, dh, p);
        sum += t;
        if (m > mu as usize + EXTRA_TERMS && t.norm() < 1e-15 * sum.norm()) || m >= MAX_TERMS {
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
        (p_prev, p) = (
            p,
            (k * cos_theta * p - m as f64 * p_prev) / (m as f64 + 1.0),
        );
        m += 1;
    }
    let h = if far {
        sum / (mu * mu)
    } else {
        -(rho / mu) * Complex64::from_polar(1.0, -mu * rho) * sum
    };
    h.conj()
}

/// The series' term of order `m`: (2m + 1)·P_m·h_m(μρ)/h'_m(μ), or for a plane wave
/// (2m + 1)·P_m·(−i)^{m−1}/h'_m(μ) (the far limit of h_m(μρ)·(−ρ/μ)·e^{−iμρ}, times μ²).
fn term(m: usize, far: bool, h_rho: Complex64, dh_mu: Complex64, p: f64) -> Complex64 {
    let k = (2 * m + 1) as f64 * p;
    if far {
        // (−i)^{m−1}: i, 1, −i, −1, ...
        let phase = match m % 4 {
            0 => Complex64::new(0.0, 1.0),
            1 => Complex64::new(1.0, 0.0),
            2 => Complex64::new(0.0, -1.0),
            _ => Complex64::new(-1.0, 0.0),
        };
        k * phase / dh_mu
    } else {
        k * h_rho / dh_mu
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
