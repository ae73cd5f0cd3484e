//! The RAA's predictors from its streams and ITDs (van Dorp Schuitman 2011, Eqs. 3.20 to
//! 3.27; the sigmoid scalings of his Eq. 6.4 with `afeRAA`'s constants).

use afe_core::Block;

use super::{RaaConstants, RaaError, RaaPar, RaaPsi};

/// Centre frequencies, Hz, whose nearest bands bound the low-frequency level `Llow`.
const LOW_BAND_HZ: (f64, f64) = (168.0, 387.0);
/// Centre frequencies, Hz, whose nearest bands bound the ITD fluctuations.
const ITD_BAND_HZ: (f64, f64) = (387.0, 1836.4);

/// `afeRAA`'s `par` from its `psi`.
pub fn predictors(psi: &RaaPsi, c: &RaaConstants) -> RaaPar {
    let all = 0..psi.num_bands;
    let bl = mean_magnitude(&psi.psi_l_rev, &psi.psi_r_rev, all.clone());
    let fl = mean_magnitude(&psi.psi_l_dir, &psi.psi_r_dir, all);
    let p_clar = fl / bl;
    let low = nearest(&psi.f, LOW_BAND_HZ.0)..nearest(&psi.f, LOW_BAND_HZ.1) + 1;
    let l_low = mean_magnitude(&psi.psi_l, &psi.psi_r, low);
    let itd_bands = nearest(&psi.f, ITD_BAND_HZ.0)..nearest(&psi.f, ITD_BAND_HZ.1) + 1;
    let itd_f = mean_std(&psi.itd_dir, itd_bands.clone());
    let itd_b = mean_std(&psi.itd_rev, itd_bands);
    let p_asw = c.mu_asw * l_low + (1.0 + c.nu_asw * itd_f * 1e3).log10();
    let p_lev = c.mu_lev * bl + (1.0 + c.nu_lev * itd_b * 1e3).log10();
    RaaPar {
        bl,
        s_rev: sigmoid(c.a_p_rev, c.b_p_rev, bl),
        fl,
        p_clar,
        s_clar: sigmoid(c.a_p_cla, c.b_p_cla, p_clar),
        l_low,
        itd_f,
        p_asw,
        s_asw: sigmoid(c.a_p_asw, c.b_p_asw, p_asw),
        itd_b,
        p_lev,
        s_lev: sigmoid(c.a_p_lev, c.b_p_lev, p_lev),
    }
}

/// `1 / (1 + exp(−a·(p − b)))`.
/// Refuses predictors of which one is NaN or infinite, naming the first with how it is
/// computed and the constants it depends on.
pub fn check_finite(par: &RaaPar) -> Result<(), RaaError> {
    let levels = "mu_psi, mu_psi_dip, T_min";
    let how = |name| match name {
        "sREV" => (format!("sigmoid of BL = {}", par.bl), "a_P_REV, b_P_REV"),
        "pClar" => (format!("FL/BL = {}/{}", par.fl, par.bl), levels),
        "sClar" => (
            format!("sigmoid of pClar = {}", par.p_clar),
            "a_P_CLA, b_P_CLA",
        ),
        "pASW" => (
            format!(
                "mu_ASW·Llow + log10(1 + nu_ASW·ITDf·1e3), Llow = {}, ITDf = {}",
                par.l_low, par.itd_f
            ),
            "mu_ASW, nu_ASW",
        ),
        "sASW" => (
            format!("sigmoid of pASW = {}", par.p_asw),
            "a_P_ASW, b_P_ASW",
        ),
        "pLEV" => (
            format!(
                "mu_LEV·BL + log10(1 + nu_LEV·ITDb·1e3), BL = {}, ITDb = {}",
                par.bl, par.itd_b
            ),
            "mu_LEV, nu_LEV",
        ),
        "sLEV" => (
            format!("sigmoid of pLEV = {}", par.p_lev),
            "a_P_LEV, b_P_LEV",
        ),
        _ => (
            "a level or ITD fluctuation of the streams".to_string(),
            levels,
        ),
    };
    match par.fields().into_iter().find(|f| !f.value.is_finite()) {
        None => Ok(()),
        Some(f) => {
            let (formula, constants) = how(f.name);
            Err(RaaError::UndefinedPredictor {
                name: f.name,
                value: f.value,
                formula,
                constants,
            })
        }
    }
}

fn sigmoid(a: f64, b: f64, p: f64) -> f64 {
    1.0 / (1.0 + (-a * (p - b)).exp())
}

/// The first band whose centre frequency is nearest `hz`.
fn nearest(cf_hz: &[f64], hz: f64) -> usize {
    let mut best = 0;
    for (i, f) in cf_hz.iter().enumerate() {
        if (f - hz).abs() < (cf_hz[best] - hz).abs() {
            best = i;
        }
    }
    best
}

/// `Σ sqrt(l² + r²) / (samples · bands)` over every sample and the bands of `bands`,
/// summed over time per band first, then over the bands, as MATLAB's `sum(sum(·))`.
fn mean_magnitude(l: &Block, r: &Block, bands: std::ops::Range<usize>) -> f64 {
    let count = bands.len();
    let total: f64 = bands
        .map(|b| {
            l.rows()
                .zip(r.rows())
                .map(|(x, y)| (x[b] * x[b] + y[b] * y[b]).sqrt())
                .sum::<f64>()
        })
        .sum();
    total / (l.frames() * count) as f64
}

/// The mean over the bands of `bands` of the standard deviation over frames (normalised
/// by frames − 1) of `x` (`[frame][band]`).
fn mean_std(x: &Block, bands: std::ops::Range<usize>) -> f64 {
    let n = x.frames() as f64;
    let count = bands.len() as f64;
    bands
        .map(|b| {
            let mean = x.rows().map(|r| r[b]).sum::<f64>() / n;
            let var = x.rows().map(|r| (r[b] - mean).powi(2)).sum::<f64>() / (n - 1.0);
            var.sqrt()
        })
        .sum::<f64>()
        / count
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_takes_the_first_of_the_closest_bands() {
        assert_eq!(nearest(&[100.0, 200.0, 300.0], 160.0), 1);
        assert_eq!(nearest(&[100.0, 200.0, 300.0], 150.0), 0);
        assert_eq!(nearest(&[100.0, 200.0, 300.0], 5000.0), 2);
    }

    #[test]
    fn the_sigmoid_is_one_half_at_its_midpoint() {
        assert_eq!(sigmoid(2.0, 3.0, 3.0), 0.5);
        assert!(sigmoid(2.0, 3.0, 10.0) > 0.99);
    }

    #[test]
    fn mean_std_is_the_sample_standard_deviation_averaged_over_bands() {
        // band 0: 1, 2, 3 (std 1); band 1: 0, 0, 6 (mean 2, var (4 + 4 + 16)/2 = 12)
        let x = Block::from_vec(vec![1.0, 0.0, 2.0, 0.0, 3.0, 6.0], 2);
        assert!((mean_std(&x, 0..1) - 1.0).abs() < 1e-15);
        assert!((mean_std(&x, 0..2) - (1.0 + 12f64.sqrt()) / 2.0).abs() < 1e-15);
    }

    #[test]
    fn mean_magnitude_combines_the_ears_per_sample() {
        let l = Block::from_vec(vec![3.0, 1.0, 0.0, 1.0], 2);
        let r = Block::from_vec(vec![4.0, 0.0, 0.0, 1.0], 2);
        // band 0: 5 + 0; band 1: 1 + sqrt 2
        assert!((mean_magnitude(&l, &r, 0..1) - 2.5).abs() < 1e-15);
        let both = (5.0 + 1.0 + 2f64.sqrt()) / 4.0;
        assert!((mean_magnitude(&l, &r, 0..2) - both).abs() < 1e-15);
    }
}
