//! A head model: where its ears hear a source from, as transfer functions at any frequency
//! (a measured set from a SOFA file, or the rigid sphere), and binaural renders through it.

use std::path::{Path, PathBuf};

use afe_core::real_fft::{RealFft, RealIfft};
use num_complex::Complex64;

use crate::sofa::{self, Measured};
use crate::sphere::Sphere;
use crate::SpatialError;

/// Where Debian's `libmysofa1` installs the MIT KEMAR set (normal pinnae, 44.1 kHz).
pub const KEMAR_SOFA: &str = "/usr/share/libmysofa/MIT_KEMAR_normal_pinna.sofa";
/// Radius of the sphere that `sphere` alone names, m (the seed robots' 15-cm ball).
const DEFAULT_RADIUS_M: f64 = 0.075;

/// A head: measured, or the rigid sphere.
#[derive(Debug, Clone)]
pub enum Head {
    /// Measured responses on the horizontal plane, named by their file.
    Measured {
        /// The file it was read from.
        path: PathBuf,
        /// Its horizontal plane.
        set: Measured,
    },
    /// The rigid sphere with two microphones.
    Sphere(Sphere),
}

/// A head that `afe` names without a file: `(name, what it is)`.
pub const BUILT_IN: [(&str, &str); 2] = [
    (
        "kemar",
        "the MIT KEMAR set (normal pinnae, 44.1 kHz, 5-degree steps) from Debian's libmysofa1",
    ),
    (
        "sphere:radius=M[,ears=DEG]",
        "a rigid sphere of radius M metres (0.075: the seed robots' ball), ears at +-DEG (90)",
    ),
];

impl Head {
    /// `kemar`, `sphere[:radius=M][,ears=DEG]` or the path of a SOFA file.
    pub fn parse(spec: &str) -> Result<Head, SpatialError> {
        if spec == "kemar" {
            let path = std::env::var_os("AFE_KEMAR_SOFA")
                .map(PathBuf::from)
                .unwrap_or_else(|| PathBuf::from(KEMAR_SOFA));
            if !path.exists() {
                return Err(SpatialError::NoKemar(path.display().to_string()));
            }
            return Head::from_sofa(&path);
        }
        if let Some(rest) = spec.strip_prefix("sphere") {
            return parse_sphere(rest.strip_prefix(':').unwrap_or(rest)).map(Head::Sphere);
        }
        let path = Path::new(spec);
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("sofa"))
            || path.exists()
        {
            return Head::from_sofa(path);
        }
        Err(SpatialError::UnknownHead(spec.to_string()))
    }

    /// The measured head of a `SimpleFreeFieldHRIR` SOFA file.
    pub fn from_sofa(path: &Path) -> Result<Head, SpatialError> {
        Ok(Head::Measured {
            path: path.to_path_buf(),
            set: sofa::read(path)?,
        })
    }

    /// Its name in messages and outputs.
    pub fn name(&self) -> String {
        match self {
            Head::Measured { path, .. } => path.display().to_string(),
            Head::Sphere(s) => format!("sphere:radius={},ears={}", s.radius_m, s.ear_deg),
        }
    }

    /// The azimuths it is known at, deg in [0, 360): a measured head's own, the sphere's
    /// every `step_deg`.
    pub fn azimuths_deg(&self, step_deg: f64) -> Vec<f64> {
        match self {
            Head::Measured { set, .. } => set.azimuths_deg.clone(),
            Head::Sphere(_) => {
                let n = (360.0 / step_deg).round().max(1.0) as usize;
                (0..n).map(|k| k as f64 * 360.0 / n as f64).collect()
            }
        }
    }

    /// The highest frequency it has transfer functions for, Hz.
    pub fn max_frequency_hz(&self) -> f64 {
        match self {
            Head::Measured { set, .. } => set.fs_hz / 2.0,
            Head::Sphere(_) => f64::INFINITY,
        }
    }

    /// The left and right transfer functions of a source at `azimuth_deg` (one of
    /// [`Head::azimuths_deg`] for a measured head: the nearest measured one is taken) at
    /// each of `freqs_hz`, in the DFT's sign convention.
    pub fn transfer(&self, azimuth_deg: f64, freqs_hz: &[f64]) -> Vec<[Complex64; 2]> {
        match self {
            Head::Sphere(s) => freqs_hz
                .iter()
                .map(|&f| s.transfer(azimuth_deg, f))
                .collect(),
            Head::Measured { set, .. } => {
                let k = nearest(&set.azimuths_deg, azimuth_deg);
                let [l, r] = &set.responses[k];
                freqs_hz
                    .iter()
                    .map(|&f| [dtft(l, f / set.fs_hz), dtft(r, f / set.fs_hz)])
                    .collect()
            }
        }
    }

    /// [`Head::transfer`] of each of `azimuths_deg` (outer) at `freqs_hz` (inner): a
    /// sphere's series is run once per frequency for every azimuth.
    pub fn transfers(&self, azimuths_deg: &[f64], freqs_hz: &[f64]) -> Vec<Vec<[Complex64; 2]>> {
        match self {
            Head::Sphere(s) => s.transfers(azimuths_deg, freqs_hz),
            Head::Measured { .. } => azimuths_deg
                .iter()
                .map(|&az| self.transfer(az, freqs_hz))
                .collect(),
        }
    }

    /// `x` (a mono signal at `fs_hz`) as the two ears hear it from `azimuth_deg`: each
    /// ear's transfer function applied in one transform over the zero-padded signal, so
    /// that any head renders at any rate below its highest frequency.
    pub fn render(
        &self,
        azimuth_deg: f64,
        x: &[f64],
        fs_hz: f64,
    ) -> Result<[Vec<f64>; 2], SpatialError> {
        if fs_hz / 2.0 > self.max_frequency_hz() * 1.0001 {
            return Err(SpatialError::RateAboveHead {
                head: self.name(),
                fs_hz,
                max_hz: self.max_frequency_hz(),
            });
        }
        // room for the responses on both sides of the signal (the sphere's ipsilateral ear
        // leads its centre)
        let pad = (0.02 * fs_hz) as usize;
        let n = (x.len() + 2 * pad).next_power_of_two();
        let mut forward = RealFft::new(n);
        forward.input().fill(0.0);
        forward.input()[pad..pad + x.len()].copy_from_slice(x);
        let (mut re, mut im) = (vec![0.0; n / 2 + 1], vec![0.0; n / 2 + 1]);
        forward.run(&mut re, &mut im);
        let freqs: Vec<f64> = (0..re.len()).map(|k| k as f64 * fs_hz / n as f64).collect();
        let h = self.transfer(azimuth_deg, &freqs);
        let mut inverse = RealIfft::new(n);
        let mut ears = [Vec::new(), Vec::new()];
        for (ear, out) in ears.iter_mut().enumerate() {
            // (the inverse takes the DC and Nyquist bins as real)
            let (out_re, out_im) = inverse.spectrum();
            for (k, h) in h.iter().enumerate() {
                let y = Complex64::new(re[k], im[k]) * h[ear];
                (out_re[k], out_im[k]) = (y.re, y.im);
            }
            let y = inverse.run();
            *out = y[pad..pad + x.len()].iter().map(|v| v / n as f64).collect();
        }
        Ok(ears)
    }
}

/// The index of the azimuth of `grid` nearest `azimuth_deg`, on the circle.
pub fn nearest(grid: &[f64], azimuth_deg: f64) -> usize {
    let gap = |a: f64| {
        let d = (a - azimuth_deg).rem_euclid(360.0);
        d.min(360.0 - d)
    };
    (0..grid.len())
        .min_by(|&a, &b| gap(grid[a]).total_cmp(&gap(grid[b])))
        .unwrap_or(0)
}

/// The discrete-time Fourier transform of `h` at `f` cycles per sample.
fn dtft(h: &[f64], f: f64) -> Complex64 {
    let step = Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * f);
    let mut w = Complex64::new(1.0, 0.0);
    let mut sum = Complex64::new(0.0, 0.0);
    for &v in h {
        sum += v * w;
        w *= step;
    }
    sum
}

/// `radius=M[,ears=DEG][,distance=M]`, in any order; nothing: the 15-cm ball.
fn parse_sphere(args: &str) -> Result<Sphere, SpatialError> {
    let mut sphere = Sphere::antipodal(DEFAULT_RADIUS_M);
    for part in args.split(',').filter(|p| !p.is_empty()) {
        let bad = || SpatialError::BadSphere(part.to_string());
        let (key, value) = part.split_once('=').ok_or_else(bad)?;
        let value: f64 = value.trim().parse().map_err(|_| bad())?;
        match key.trim() {
            "radius" if value > 0.01 && value < 1.0 => sphere.radius_m = value,
            "ears" if (0.0..=180.0).contains(&value) => sphere.ear_deg = value,
            "distance" if value > sphere.radius_m => sphere.distance_m = value,
            _ => return Err(bad()),
        }
    }
    Ok(sphere)
}
