//! `moc`: medial olivo-cochlear attenuation from the ratemap level, fed back to the DRNL
//! filterbank's non-linear path (spec 28-moc).
//!
//! The output is the attenuation in dB per ratemap frame and channel. The feedback is a
//! second output, two rows of per-channel factors (the new `fb_mocIpsi`, then the new
//! `fb_mocContra`) computed from the first frame of each chunk with frames; the graph hands
//! it to the filterbank before that filterbank processes the next chunk, so the
//! attenuation of chunk k first shows in the filterbank output of chunk k+1, as in the AFE.
//! A gammatone filterbank ignores it, as the AFE's does.

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::params::per_channel;
use afe_core::{Block, Error, Processor, Result, SignalInfo};

afe_core::params! {
    /// Parameters of the MOC, under their AFE names.
    pub struct MocParams / MocNames {
        /// external ipsilateral MOC factor, one value or one per channel
        #[afe = "moc_extIpsi"]
        pub ext_ipsi: Vec<f64> = vec![1.0],
        /// external contralateral MOC factor, one value or one per channel
        #[afe = "moc_extContra"]
        pub ext_contra: Vec<f64> = vec![1.0],
        /// ratemap level below which the level is clamped
        #[afe = "moc_thresholdRatedB", unit = "dB"]
        pub threshold_rate_db: f64 = -180.0,
        /// largest attenuation
        #[afe = "moc_maxAttenuationdB", unit = "dB"]
        pub max_attenuation_db: f64 = 40.0,
    }
}

/// Cubic fit of attenuation (dB) against ratemap level (dB), highest power first.
const FIT: [f64; 4] = [-0.00012411, -0.051322, -6.3528, -206.11];

/// The MOC of one ear: ratemap `[frame][channel]` in; attenuation `[frame][channel]` (dB)
/// and the feedback factors out.
#[derive(Debug, Clone)]
pub struct Moc {
    ext_ipsi: Vec<f64>,
    ext_contra: Vec<f64>,
    threshold_db: f64,
    max_db: f64,
}

impl Moc {
    /// Builds the MOC for the ratemap `input`; returns it with its attenuation and
    /// feedback outputs.
    pub fn new(params: &MocParams, input: &SignalInfo) -> Result<(Self, [SignalInfo; 2])> {
        let nc = input.channels();
        if params.max_attenuation_db < 0.0 {
            return Err(Error::invalid(
                MocParams::NAMES.max_attenuation_db,
                format_args!("{:?}", params.max_attenuation_db),
                "must be >= 0 dB",
            ));
        }
        let moc = Moc {
            ext_ipsi: per_channel(MocParams::NAMES.ext_ipsi, &params.ext_ipsi, nc)?,
            ext_contra: per_channel(MocParams::NAMES.ext_contra, &params.ext_contra, nc)?,
            threshold_db: params.threshold_rate_db,
            max_db: params.max_attenuation_db,
        };
        let attenuation = input.framed(input.fs_hz).with_unit(Self::OUTPUT_UNIT);
        let feedback = SignalInfo {
            feedback: true,
            ..attenuation.clone()
        };
        Ok((moc, [attenuation, feedback]))
    }

    /// Attenuation in dB for ratemap value `x` (spec 28: `20·log10` of the power
    /// ratemap, clamped below, fitted cubic, limited to `[0, max]`; 0 where `x ≤ 0`).
    fn attenuation_db(&self, x: f64) -> f64 {
        if x <= 0.0 {
            return 0.0;
        }
        let level = (20.0 * x.log10()).max(self.threshold_db);
        let a = ((FIT[0] * level + FIT[1]) * level + FIT[2]) * level + FIT[3];
        a.clamp(0.0, self.max_db)
    }
}

impl Processor for Moc {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let rm = inputs[0];
        let nc = rm.width();
        let (attenuation, feedback) = outputs.split_at_mut(1);
        let out = attenuation[0].reset_to(rm.frames());
        for (o, x) in out.iter_mut().zip(rm.as_slice()) {
            *o = self.attenuation_db(*x);
        }
        let Some(first) = out.get(..nc) else {
            feedback[0].clear();
            return;
        };
        let factors = feedback[0].reset_to(2);
        let (ipsi, contra) = factors.split_at_mut(nc);
        for ((f, a), e) in ipsi.iter_mut().zip(first).zip(&self.ext_ipsi) {
            *f = e * 10f64.powf(-a / 20.0);
        }
        contra.copy_from_slice(&self.ext_contra);
    }

    fn reset(&mut self) {}
}

impl Descriptor for Moc {
    type Params = MocParams;
    const NAME: &'static str = "moc";
    const DEPENDENCY: &'static str = "ratemap";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str =
        "medial olivo-cochlear attenuation per frame and channel, fed back to a DRNL filterbank";
    const OUTPUT_UNIT: &'static str = "dB";
    const FEEDS_BACK_TO: Option<&'static str> = Some("filterbank");

    fn build(params: &MocParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, outputs) = Moc::new(params, &inputs[0])?;
        Ok(Built::new(p, outputs.into()))
    }
}

/// The registry entry of `moc`.
pub static REQUEST: RequestDef = request_def::<Moc>();

#[cfg(test)]
mod tests {
    use super::*;

    fn ratemap(channels: usize) -> SignalInfo {
        SignalInfo::time_frequency(44100.0, vec![500.0; channels]).framed(100.0)
    }

    /// The fit at its clamp level is negative (no attenuation); it peaks above the
    /// maximum near −100 dB and falls below 0 again by 0 dB; silence gives 0.
    #[test]
    fn attenuation_follows_the_fit_within_its_limits() {
        let (moc, _) = Moc::new(&MocParams::default(), &ratemap(1)).expect("valid");
        assert_eq!(moc.attenuation_db(0.0), 0.0);
        assert_eq!(moc.attenuation_db(1e-300), 0.0);
        assert_eq!(moc.attenuation_db(1e-5), 40.0);
        assert_eq!(moc.attenuation_db(1.0), 0.0);
        // At −150 dB the cubic, worked by hand from the spec's coefficients:
        // 418.87125 − 1154.745 + 952.92 − 206.11.
        let x: f64 = 10f64.powf(-150.0 / 20.0);
        assert!((moc.attenuation_db(x) - 10.93625).abs() < 1e-9);
    }

    /// The feedback comes from the first frame of a chunk only, with the external
    /// factors applied; a chunk without frames feeds nothing back.
    #[test]
    fn feedback_uses_the_first_frame_and_the_external_factors() {
        let p = MocParams {
            ext_ipsi: vec![0.5, 2.0],
            ext_contra: vec![0.25],
            ..Default::default()
        };
        let (mut moc, infos) = Moc::new(&p, &ratemap(2)).expect("valid");
        assert!(!infos[0].feedback && infos[1].feedback);
        let x = Block::from_vec(vec![1e-5, 0.0, 0.0, 1e-5], 2);
        let mut out = vec![Block::new(2), Block::new(2)];
        moc.process(&[&x], &mut out);
        assert_eq!(out[0].as_slice(), &[40.0, 0.0, 0.0, 40.0]);
        let first = 0.5 * 10f64.powf(-2.0);
        assert_eq!(out[1].as_slice(), &[first, 2.0, 0.25, 0.25]);
        moc.process(&[&Block::new(2)], &mut out);
        assert!(out[0].is_empty() && out[1].is_empty());
    }

    #[test]
    fn factor_vectors_of_the_wrong_length_are_named() {
        let p = MocParams {
            ext_ipsi: vec![1.0; 3],
            ..Default::default()
        };
        let e = Moc::new(&p, &ratemap(31)).expect_err("3 of 31").to_string();
        assert!(
            e.contains("moc_extIpsi")
                && e.contains("expected one value or 31 (one per channel), got 3"),
            "{e}"
        );
        let p = MocParams {
            max_attenuation_db: -1.0,
            ..Default::default()
        };
        let e = Moc::new(&p, &ratemap(2)).expect_err("negative").to_string();
        assert!(
            e.contains("moc_maxAttenuationdB") && e.contains(">= 0 dB"),
            "{e}"
        );
    }
}
