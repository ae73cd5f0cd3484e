//! `filterbank`: the basilar-membrane stage, a gammatone filterbank ([`crate::gammatone`])
//! or a dual-resonance non-linear one ([`crate::drnl`]) chosen by `fb_type` (spec
//! 00-overview §1, §3). This module owns the request and the dispatch; the parameters
//! and the centre-frequency grid that both types share are
//! [`crate::filterbank_params`]'s (re-exported here); each type's module owns its
//! processor.

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::{DrawAs, ParamMap, Result, SignalInfo};
use serde_json::json;

use crate::drnl::Drnl;
pub use crate::filterbank_params::{fb_type_of, CfGrid, FbType, FilterbankParams, MAX_CHANNELS};
use crate::gammatone::Gammatone;

/// The `filterbank` request: a [`Gammatone`] or a [`Drnl`], by `fb_type`.
#[derive(Debug)]
pub struct Filterbank;

impl Descriptor for Filterbank {
    type Params = FilterbankParams;
    const NAME: &'static str = "filterbank";
    const DEPENDENCY: &'static str = "time";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str =
        "basilar-membrane filterbank output per frequency channel (gammatone or DRNL)";
    const OUTPUT_UNIT: &'static str = "";
    /// The class and the channel grid, which every representation above is laid out on.
    const FIXED: &'static [&'static str] = &[
        FilterbankParams::NAMES.fb_type,
        FilterbankParams::NAMES.low_freq_hz,
        FilterbankParams::NAMES.high_freq_hz,
        FilterbankParams::NAMES.n_erbs,
        FilterbankParams::NAMES.cf_hz,
    ];

    fn build(params: &FilterbankParams, inputs: &[SignalInfo]) -> Result<Built> {
        let fs = inputs[0].fs_hz;
        let describe = |out: SignalInfo| {
            vec![out
                .with_unit(Self::OUTPUT_UNIT)
                .drawn_as(DrawAs::AmplitudeDecibels { range_db: 60.0 })]
        };
        Ok(match params.fb_type {
            FbType::Gammatone => {
                let (p, out) = Gammatone::new(params, fs)?;
                Built::new(p, describe(out))
            }
            FbType::Drnl => {
                let (p, out) = Drnl::new(params, fs)?;
                Built::new(p, describe(out))
            }
        })
    }

    /// The type's own verified parameters with `fb_type`, as the AFE's processor reports
    /// them: equal grids from different parameter sets are shared, a gammatone and a
    /// DRNL never are, and the other type's parameters do not matter.
    fn canonical(params: &FilterbankParams) -> Result<ParamMap> {
        let mut map = match params.fb_type {
            FbType::Gammatone => crate::gammatone::verified(params)?,
            FbType::Drnl => crate::drnl::verified(params)?,
        };
        map.insert(
            FilterbankParams::NAMES.fb_type.into(),
            json!(params.fb_type),
        );
        Ok(map)
    }
}

/// The registry entry of `filterbank`.
pub static REQUEST: RequestDef = request_def::<Filterbank>();

#[cfg(test)]
mod tests {
    use super::*;
    use afe_core::{Block, Params};

    /// Issue 18: `fb_highFreqHz = fs/2` with `fb_nChannels`, as AFE scripts write it,
    /// puts the top channel at Nyquist up to rounding (22050.000000000004): accepted, with
    /// finite output, for both filterbank types; 1 Hz beyond is refused.
    #[test]
    fn a_top_channel_at_nyquist_is_accepted() {
        for ty in [FbType::Gammatone, FbType::Drnl] {
            let p = FilterbankParams {
                fb_type: ty,
                high_freq_hz: 22050.0,
                n_channels: Some(16),
                ..Default::default()
            };
            let grid = p.grid().expect("grid");
            assert!(grid.cf_hz[15] >= 22050.0, "{:?}", grid.cf_hz[15]);
            let built = (REQUEST.configure)(&p.to_map())
                .and_then(|c| c.build(&[SignalInfo::time_domain(44100.0)], &Default::default()))
                .expect("accepted, as in the AFE");
            let mut proc_ = built.processor;
            let x = Block::from_vec(
                (0..512)
                    .map(|t| ((t * 7) % 13) as f64 / 13.0 - 0.5)
                    .collect(),
                1,
            );
            let mut out = vec![Block::new(16)];
            proc_.process(&[&x], &mut out);
            assert!(out[0].as_slice().iter().all(|v| v.is_finite()), "{ty:?}");
            let beyond = FilterbankParams {
                high_freq_hz: 22051.0,
                ..p
            };
            let e = (REQUEST.configure)(&beyond.to_map())
                .and_then(|c| c.build(&[SignalInfo::time_domain(44100.0)], &Default::default()));
            assert!(e.is_err(), "{ty:?}");
        }
    }

    use serde_json::Value;

    fn map(pairs: &[(&str, Value)]) -> ParamMap {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone()))
            .collect()
    }

    #[test]
    fn unknown_fb_type_is_a_clear_error() {
        let e = FilterbankParams::from_map(&map(&[("fb_type", json!("dnrl"))]))
            .expect_err("unknown type")
            .to_string();
        assert!(
            e.contains("'fb_type'") && e.contains("'gammatone', 'drnl'"),
            "{e}"
        );
        let e = fb_type_of(&map(&[("fb_type", json!("dnrl"))]))
            .expect_err("unknown type")
            .to_string();
        assert!(
            e.contains("'fb_type'") && e.contains("'gammatone', 'drnl'"),
            "{e}"
        );
        assert_eq!(
            fb_type_of(&map(&[("fb_type", json!("drnl"))])),
            Ok(FbType::Drnl)
        );
        assert_eq!(fb_type_of(&ParamMap::new()), Ok(FbType::Gammatone));
    }

    /// Each type's map holds its own parameters and `fb_type`; the other type's
    /// parameters are accepted and do not change it.
    #[test]
    fn canonical_maps_separate_the_types_and_ignore_the_other_types_parameters() {
        let canonical = |pairs: &[(&str, Value)]| {
            let p = FilterbankParams::from_map(&map(pairs)).expect("accepted");
            Filterbank::canonical(&p).expect("valid")
        };
        let gt = canonical(&[]);
        let gt_moc = canonical(&[("fb_mocIpsi", json!(0.5)), ("fb_model", json!("MAP"))]);
        assert_eq!(gt, gt_moc);
        assert_eq!(gt["fb_type"], json!("gammatone"));
        assert!(gt.contains_key("fb_nGamma") && !gt.contains_key("fb_model"));
        let drnl = canonical(&[("fb_type", json!("drnl"))]);
        let drnl_gamma = canonical(&[("fb_type", json!("drnl")), ("fb_nGamma", json!(2))]);
        assert_eq!(drnl, drnl_gamma);
        assert_ne!(gt, drnl);
        assert_eq!(drnl["fb_type"], json!("drnl"));
        assert!(!drnl.contains_key("fb_nGamma") && drnl.contains_key("fb_model"));
        assert_eq!(gt["fb_cfHz"], drnl["fb_cfHz"]);
    }
}
