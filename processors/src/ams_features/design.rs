//! The designs of the two modulation filterbanks (spec 15-ams-modulation): `log`'s
//! centre frequencies and Butterworth filters, `lin`'s triangular weights on the FFT bins.
//! Apart from the processor because they are computed once, at construction, from the
//! parameters alone, with the errors that name what would fit.

use afe_core::butter::{butter, ButterType};
use afe_core::erb::linspace;
use afe_core::filter::Df2t;
use afe_core::{Error, Result};

use super::AmsParams;

/// Log-spaced (or explicit) centre frequencies and one Butterworth filter per band: a
/// first-order low-pass for the first, first-order band-passes (Q = 1) for the others.
pub(super) fn log_bank(
    p: &AmsParams,
    fs_ds: f64,
    channels: usize,
) -> Result<(Vec<f64>, Vec<Df2t>)> {
    let mf = if p.cf_hz.is_empty() {
        linspace(p.low_freq_hz.log2(), p.high_freq_hz.log2(), p.n_filters)
            .into_iter()
            .map(|e| 2f64.powf(e))
            .collect()
    } else {
        if p.cf_hz.iter().any(|f| *f <= 0.0) {
            return Err(Error::invalid(
                AmsParams::NAMES.cf_hz,
                format!("{:?}", p.cf_hz),
                "centre frequencies must be > 0 Hz",
            ));
        }
        p.cf_hz.clone()
    };
    let nyq = fs_ds / 2.0;
    // Band edges of quality factor Q = 1: f·(√(1 + 1/(4Q²)) ∓ 1/(2Q)).
    let root = 1.25f64.sqrt();
    // Names what the user has: the range's top (saying when it is the default) or the
    // explicit centre, the band that reaches Nyquist, and what would fit.
    let too_high = |f: f64, edge: f64| {
        let (name, value, given) = if p.cf_hz.is_empty() {
            let default = AmsParams::default().high_freq_hz;
            let which = if p.high_freq_hz == default {
                // taken back by the graph if the request set it (afe_core::params::unless_set)
                afe_core::params::DEFAULT_NOTE
            } else {
                ""
            };
            let given = format!("with ams_highFreqHz = {}{which}, ", p.high_freq_hz);
            (AmsParams::NAMES.high_freq_hz, p.high_freq_hz, given)
        } else {
            (AmsParams::NAMES.cf_hz, f, String::new())
        };
        let fs = fs_ds * p.ds_ratio as f64;
        Error::invalid(
            name,
            value,
            format!(
                "{given}the modulation band centred at {f:.1} Hz reaches {edge:.1} Hz, not below the \
                 Nyquist frequency ({nyq} Hz) of the envelope decimated by ams_dsRatio = {} \
                 ({fs} Hz / {}): keep the centre frequencies below {:.1} Hz (a band-pass \
                 reaches {:.3} times its centre) or lower ams_dsRatio",
                p.ds_ratio,
                p.ds_ratio,
                nyq / (root + 0.5),
                root + 0.5,
            ),
        )
    };
    let mut filters = Vec::with_capacity(mf.len());
    for (j, &f) in mf.iter().enumerate() {
        let w0 = f / nyq;
        if w0 >= 1.0 {
            return Err(too_high(f, f));
        }
        let (b, a) = if j == 0 {
            butter(1, &[w0], ButterType::Low)
        } else {
            let f1 = f * (root - 0.5);
            let f2 = f * (root + 0.5);
            if f2 / nyq >= 1.0 {
                return Err(too_high(f, f2));
            }
            butter(1, &[f1 / nyq, f2 / nyq], ButterType::BandPass)
        };
        filters.push(Df2t::new(&b, &a, channels));
    }
    Ok((mf, filters))
}

/// Centre frequencies and triangular weights of `p` bands spaced linearly between
/// `fl` and `fh` on the bins `k·fs/nfft`, `k = 0..nfft/2` (the AFE's `melbankm` on a
/// linear axis).
pub(super) fn lin_weights(
    p: usize,
    fl: f64,
    fh: f64,
    fs: f64,
    nfft: usize,
) -> (Vec<f64>, Vec<(usize, Vec<f64>)>) {
    let delta = (fh - fl) / (p + 1) as f64;
    let centres = (1..=p).map(|j| fl + j as f64 * delta).collect();
    let weights = (1..=p)
        .map(|j| {
            let w: Vec<(usize, f64)> = (0..=nfft / 2)
                .filter_map(|k| {
                    let f = k as f64 * fs / nfft as f64;
                    let q = (f - fl) / delta;
                    let v = 1.0 - (q - j as f64).abs();
                    (f > fl && f < fh && v > 0.0).then_some((k, v))
                })
                .collect();
            let first = w.first().map_or(0, |(k, _)| *k);
            (first, w.into_iter().map(|(_, v)| v).collect())
        })
        .collect();
    (centres, weights)
}
