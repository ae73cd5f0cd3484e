//! Frequency-sampling FIR design, MATLAB's `fir2(n, f, m)` (spec 01-P14).

use std::f64::consts::PI;

use num_complex::Complex64;

/// Coefficients (`n + 1` taps) of MATLAB's `fir2(n, f, m)` with its default grid
/// and a symmetric Hamming window.
///
/// `f` are breakpoints normalised to Nyquist, starting at 0 and ending at 1,
/// non-decreasing; `m` the magnitudes at them.
pub fn fir2(n: usize, f: &[f64], m: &[f64]) -> Vec<f64> {
    let nn = n + 1;
    let npt = grid_points(nn);
    let h = grid(npt, f, m);
    let p = h.len();
    let dt = 0.5 * (nn as f64 - 1.0);
    let mut full = vec![Complex64::new(0.0, 0.0); 2 * npt];
    for (j, hv) in h.iter().enumerate() {
        let phase = -PI * dt * j as f64 / (p as f64 - 1.0);
        full[j] = Complex64::new(0.0, phase).exp() * hv;
    }
    for j in 1..npt {
        full[2 * npt - j] = full[j].conj();
    }
    let ifft = afe_fft::inverse(2 * npt);
    ifft.process(&mut full);
    let scale = 1.0 / (2 * npt) as f64;
    let win = crate::window::window(crate::window::Window::Hamming, nn);
    (0..nn).map(|k| full[k].re * scale * win[k]).collect()
}

/// Frequency grid intervals for a filter of `nn` taps: 512 below 1024 taps, else the
/// next power of two.
fn grid_points(nn: usize) -> usize {
    if nn < 1024 {
        512
    } else {
        nn.next_power_of_two()
    }
}

/// The magnitudes at the `npt + 1` grid points `0..=npt` (0 to Nyquist): each segment of
/// the breakpoints interpolated between its end indices, and a repeated breakpoint (a
/// jump) a ramp of `npt / 25` points centred on it.
fn grid(npt: usize, f: &[f64], m: &[f64]) -> Vec<f64> {
    let lap = npt / 25;
    let p = npt + 1;
    // 1-based grid H[1..=P] stored 0-based.
    let mut h = vec![0.0; p];
    let mut nb: i64 = 1;
    h[0] = m[0];
    for i in 0..f.len() - 1 {
        let ne: i64 = if f[i + 1] == f[i] {
            nb = (nb as f64 - lap as f64 / 2.0).ceil() as i64;
            nb + lap as i64
        } else {
            (f[i + 1] * p as f64).trunc() as i64
        };
        for j in nb..=ne {
            if j < 1 || j as usize > p {
                continue;
            }
            let inc = if nb == ne {
                0.0
            } else {
                (j - nb) as f64 / (ne - nb) as f64
            };
            h[(j - 1) as usize] = inc * m[i + 1] + (1.0 - inc) * m[i];
        }
        nb = ne + 1;
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_has_512_intervals_below_1024_taps_then_the_next_power_of_two() {
        assert_eq!(grid_points(65), 512);
        assert_eq!(grid_points(1023), 512);
        assert_eq!(grid_points(1024), 1024);
        assert_eq!(grid_points(1025), 2048);
    }

    #[test]
    fn a_jump_becomes_a_ramp_of_npt_over_25_points_centred_on_it() {
        // spec 01-P14 by hand, npt = 512 (P = 513, lap = 20): the first segment ends at
        // fix(0.5·513) = 256, so the jump's ramp starts at ceil(257 − 10) = 247 and ends
        // at 267 (1-based), falling linearly from 1 to 0
        let h = grid(512, &[0.0, 0.5, 0.5, 1.0], &[1.0, 1.0, 0.0, 0.0]);
        assert_eq!(h.len(), 513);
        for (g, v) in h.iter().enumerate() {
            let j = g as f64 + 1.0;
            let want = if j < 247.0 {
                1.0
            } else if j <= 267.0 {
                1.0 - (j - 247.0) / 20.0
            } else {
                0.0
            };
            assert!((v - want).abs() < 1e-15, "H[{j}] = {v}, want {want}");
        }
    }

    #[test]
    fn a_ramp_beyond_either_end_of_the_grid_is_cut_there() {
        // a jump at 0: the ramp from ceil(1 − 10) = −9 to 11 keeps its points 1..=11,
        // (j + 9)/20; the next segment ends at fix(1·513) = 513, all at 1
        let h = grid(512, &[0.0, 0.0, 1.0], &[0.0, 1.0, 1.0]);
        let want = |j: f64| if j <= 11.0 { (j + 9.0) / 20.0 } else { 1.0 };
        for (g, v) in h.iter().enumerate() {
            assert!(
                (v - want(g as f64 + 1.0)).abs() < 1e-15,
                "H[{}] = {v}",
                g + 1
            );
        }
        // a jump at Nyquist: the first segment fills 1..=513 with 1, then the ramp from
        // ceil(514 − 10) = 504 to 524 overwrites 504..=513 with 1 − (j − 504)/20
        let h = grid(512, &[0.0, 1.0, 1.0], &[1.0, 1.0, 0.0]);
        assert_eq!(h.len(), 513);
        let want = |j: f64| {
            if j < 504.0 {
                1.0
            } else {
                1.0 - (j - 504.0) / 20.0
            }
        };
        for (g, v) in h.iter().enumerate() {
            assert!(
                (v - want(g as f64 + 1.0)).abs() < 1e-15,
                "H[{}] = {v}",
                g + 1
            );
        }
    }

    #[test]
    fn lowpass_design_is_linear_phase_with_the_asked_gain() {
        let b = fir2(64, &[0.0, 0.3, 0.4, 1.0], &[1.0, 1.0, 0.0, 0.0]);
        assert_eq!(b.len(), 65);
        for k in 0..65 {
            assert!((b[k] - b[64 - k]).abs() < 1e-12, "not symmetric");
        }
        let dc: f64 = b.iter().sum();
        assert!((dc - 1.0).abs() < 0.01, "DC gain {dc}");
        let nyq: f64 = b
            .iter()
            .enumerate()
            .map(|(k, v)| if k % 2 == 0 { *v } else { -v })
            .sum();
        assert!(nyq.abs() < 0.01, "Nyquist gain {nyq}");
    }

    /// Against an independent NumPy reading of MATLAB's `fir2`
    /// (`tools/make_middle_ear_fixture.py`): a plain band edge, a jump (repeated
    /// breakpoint, ramped over `lap` grid points) and an odd order.
    #[test]
    fn matches_an_independent_reading_of_matlab_fir2() {
        let text = include_str!("../../data/middle_ear_fir2.json");
        let fixture: serde_json::Value = serde_json::from_str(text).expect("fixture");
        let designs = fixture["fir2"].as_array().expect("fir2 designs");
        assert_eq!(designs.len(), 3);
        let floats = |v: &serde_json::Value| -> Vec<f64> {
            v.as_array()
                .expect("array")
                .iter()
                .map(|x| x.as_f64().expect("number"))
                .collect()
        };
        for d in designs {
            let order = d["order"].as_u64().expect("order") as usize;
            let want = floats(&d["taps"]);
            let got = fir2(order, &floats(&d["f"]), &floats(&d["m"]));
            assert_eq!(got.len(), want.len());
            let peak = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                assert!(
                    (g - w).abs() <= 1e-12 * peak,
                    "order {order} tap {k}: {g} vs {w}"
                );
            }
        }
    }
}
