//! The RAA's segregation of Psi into a direct (foreground) and a reverberant (background)
//! stream, per ear and band: runs of samples at or above a peak threshold, or at or below
//! a dip threshold, lasting at least `T_min` are direct; the rest is reverberant.

use afe_core::Block;

use super::{RaaConstants, RaaError};

/// Thresholds and minimum length of one ear's segmentation.
pub struct Segmentation<'a> {
    /// The constants (`mu_psi`, `mu_psi_dip`, `T_min`).
    pub constants: &'a RaaConstants,
    /// Sampling rate, Hz.
    pub fs: f64,
    /// `"left"` or `"right"`, for errors.
    pub ear: &'static str,
    /// Centre frequency of each band, Hz, for errors.
    pub cf_hz: &'a [f64],
}

impl Segmentation<'_> {
    /// The direct-stream mask of `psi` (`[sample][band]`, true where direct and nonzero,
    /// the AFE's `PsiLdir ~= 0`), with the
    /// thresholds `mu_psi · L` and `mu_psi_dip · L` of each band, `L` being its entry of
    /// `levels` (see [`mean_levels`]). A band with no sample on the far side of a
    /// threshold is an error, as in the AFE; a mask the memory cannot take, an
    /// allocation error.
    pub fn direct_mask(&self, psi: &Block, levels: &[f64]) -> Result<Vec<bool>, RaaError> {
        let bands = psi.width();
        let samples = psi.frames();
        let mut mask = Vec::new();
        mask.try_reserve_exact(samples * bands)
            .map_err(|_| too_large(samples * bands, "a direct-stream mask"))?;
        mask.resize(samples * bands, false);
        for (band, &level) in levels.iter().enumerate().take(bands) {
            let column: Vec<f64> = psi.rows().map(|r| r[band]).collect();
            let peak = self.constants.mu_psi * level;
            let dip = self.constants.mu_psi_dip * level;
            let mut mark = |passes: &dyn Fn(f64) -> bool| {
                let mut any = false;
                for (first, last) in runs(&column, passes) {
                    any = true;
                    if (last - first) as f64 / self.fs >= self.constants.t_min {
                        for t in first..=last {
                            mask[t * bands + band] = column[t] != 0.0;
                        }
                    }
                }
                any
            };
            if !mark(&|v| v >= peak) {
                return Err(self.none_beyond(band, "peak", peak));
            }
            if !mark(&|v| v <= dip) {
                return Err(self.none_beyond(band, "dip", dip));
            }
        }
        Ok(mask)
    }

    fn none_beyond(&self, band: usize, kind: &'static str, threshold: f64) -> RaaError {
        let peak = kind == "peak";
        RaaError::NoPeakOrDip {
            ear: self.ear,
            band,
            cf_hz: self.cf_hz[band],
            kind,
            side: if peak { "at or above" } else { "at or below" },
            constant: if peak { "mu_psi" } else { "mu_psi_dip" },
            value: if peak {
                self.constants.mu_psi
            } else {
                self.constants.mu_psi_dip
            },
            threshold,
            fix: if peak { "lower" } else { "higher" },
        }
    }
}

/// The runs of consecutive samples of `x` that pass `passes`, as `(first, last)` indices.
fn runs(x: &[f64], passes: &dyn Fn(f64) -> bool) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = None;
    for (t, v) in x.iter().enumerate() {
        match (passes(*v), start) {
            (true, None) => start = Some(t),
            (false, Some(s)) => {
                out.push((s, t - 1));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push((s, x.len() - 1));
    }
    out
}

/// `psi` where `mask` is `keep`, 0 elsewhere: the direct stream (`keep` true) or the
/// reverberant one (false).
pub fn masked(psi: &Block, mask: &[bool], keep: bool) -> Result<Block, RaaError> {
    let values = psi.as_slice();
    let mut data = Vec::new();
    data.try_reserve_exact(values.len())
        .map_err(|_| too_large(8 * values.len(), "a stream of Psi"))?;
    data.extend(
        values
            .iter()
            .zip(mask)
            .map(|(v, m)| if *m == keep { *v } else { 0.0 }),
    );
    Ok(Block::from_vec(data, psi.width()))
}

/// The mean of `|adaptation|` over all samples of each band (`[sample][band]`, the
/// adaptation output before the low-pass that gives Psi): the scale of the band's
/// thresholds.
pub fn mean_levels(adaptation: &Block) -> Vec<f64> {
    let samples = adaptation.frames();
    (0..adaptation.width())
        .map(|band| (1.0 / samples as f64) * adaptation.rows().map(|r| r[band].abs()).sum::<f64>())
        .collect()
}

/// The error of an allocation of `bytes` for `what` that the memory could not take.
fn too_large(bytes: usize, what: &str) -> RaaError {
    RaaError::Afe(afe_core::Error::AllocationFailed {
        need: afe_graph::work::size(bytes as f64),
        what: format!("{what} of the RAA"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_are_first_and_last_indices_of_consecutive_passing_samples() {
        let x = [1.0, 5.0, 5.0, 0.0, 5.0, 1.0, 5.0, 5.0];
        assert_eq!(runs(&x, &|v| v >= 5.0), vec![(1, 2), (4, 4), (6, 7)]);
        assert_eq!(runs(&x, &|v| v > 9.0), vec![]);
    }

    #[test]
    fn a_run_is_direct_from_t_min_between_its_first_and_last_sample() {
        // fs = 10 Hz, T_min = 0.2 s: a run whose first and last sample are 2 apart
        let constants = RaaConstants {
            t_min: 0.2,
            mu_psi: 1.0,
            mu_psi_dip: -1.0,
            ..RaaConstants::default()
        };
        let seg = Segmentation {
            constants: &constants,
            fs: 10.0,
            ear: "left",
            cf_hz: &[500.0],
        };
        // mean |adaptation| = 1: thresholds +1 and -1
        let adaptation = Block::from_vec(vec![1.0; 10], 1);
        let psi = Block::from_vec(vec![2.0, 2.0, 0.0, 2.0, 2.0, 2.0, 0.0, -1.0, -1.0, -1.0], 1);
        let mask = seg
            .direct_mask(&psi, &mean_levels(&adaptation))
            .expect("peaks and dips");
        let expect = [
            false, false, false, true, true, true, false, true, true, true,
        ];
        assert_eq!(mask, expect);
        let direct = masked(&psi, &mask, true).expect("memory");
        let reverberant = masked(&psi, &mask, false).expect("memory");
        for t in 0..10 {
            assert_eq!(direct.row(t)[0] + reverberant.row(t)[0], psi.row(t)[0]);
        }
    }

    #[test]
    fn a_band_without_a_dip_is_an_error_naming_it() {
        let constants = RaaConstants::default();
        let seg = Segmentation {
            constants: &constants,
            fs: 16000.0,
            ear: "right",
            cf_hz: &[167.8],
        };
        let ones = Block::from_vec(vec![1.0; 100], 1);
        let e = seg
            .direct_mask(&ones, &mean_levels(&ones))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("right ear's band 0 (167.8 Hz)") && e.contains("mu_psi_dip"),
            "{e}"
        );
    }
}
