//! The parameters of a `filterbank` request and the centre-frequency grid (spec
//! 11-gammatone) that both filterbank types ([`crate::gammatone`], [`crate::drnl`])
//! share: each type's module and the request's dispatch ([`crate::filterbank`]) import
//! them from here, so that neither type depends on the dispatch that chooses it.

use afe_core::erb::{colon_range, erb2freq, freq2erb, linspace};
use afe_core::{Error, ParamKind, ParamMap, Params, Result};
use serde_json::json;

/// Largest gammatone order accepted (`fb_nGamma`): higher orders' expanded denominators
/// lose the filter's stability in double precision.
pub const MAX_N_GAMMA: u64 = 8;

afe_core::choices! {
    /// The filterbank class of a `filterbank` request (AFE `fb_type`).
    pub enum FbType {
        /// Linear complex gammatone filters (spec 11-gammatone).
        Gammatone = "gammatone",
        /// Dual-resonance non-linear filters (spec 12-drnl).
        Drnl = "drnl",
    }
}

afe_core::choices! {
    /// DRNL parameter set (AFE `fb_model`).
    pub enum DrnlModel {
        /// Lopez-Poveda & Meddis (2001) as used in CASP (Jepsen et al. 2008): low-pass
        /// sections on both paths, broken-stick compression.
        Casp = "CASP",
        /// MAP 1.14h: middle-ear (tympanic membrane and stapes) stage, no low-pass sections,
        /// compression above a threshold.
        Map = "MAP",
    }
}

afe_core::params! {
    /// Parameters of a `filterbank` request, under their AFE names: the grid shared by both types
    /// and those of each type. Every one is accepted whatever `fb_type` says (as in the AFE); a
    /// type ignores the others', and its canonical map (which decides sharing) holds only its own.
    pub struct FilterbankParams / FilterbankNames {
        /// filterbank type: linear gammatone or dual-resonance non-linear
        #[afe = "fb_type"]
        pub fb_type: FbType = FbType::Gammatone,
        /// lowest centre frequency
        #[afe = "fb_lowFreqHz", unit = "Hz"]
        pub low_freq_hz: f64 = 80.0,
        /// highest requested centre frequency
        #[afe = "fb_highFreqHz", unit = "Hz"]
        pub high_freq_hz: f64 = 8000.0,
        /// channel spacing on the ERB-number scale
        #[afe = "fb_nERBs", unit = "ERB"]
        pub n_erbs: f64 = 1.0,
        /// number of channels (overrides fb_nERBs; [] = derive from the spacing)
        #[afe = "fb_nChannels"]
        pub n_channels: Option<u32> = None,
        /// explicit centre frequencies (overrides everything; [] = derive)
        #[afe = "fb_cfHz", unit = "Hz"]
        pub cf_hz: Vec<f64> = Vec::new(),
        /// gammatone filter order (gammatone only)
        #[afe = "fb_nGamma", kind = ParamKind::CountUpTo(MAX_N_GAMMA)]
        pub n_gamma: u32 = 4,
        /// gammatone bandwidth in ERBs (gammatone only)
        #[afe = "fb_bwERBs", unit = "ERB"]
        pub bw_erbs: f64 = 1.018,
        /// phase-align the channels' impulse responses (gammatone only)
        #[afe = "fb_bAlign"]
        pub align: bool = false,
        /// ipsilateral MOC gain on the non-linear path, one or one per channel (drnl only)
        #[afe = "fb_mocIpsi"]
        pub moc_ipsi: Vec<f64> = vec![1.0],
        /// contralateral MOC gain on the non-linear path, one or one per channel (drnl only)
        #[afe = "fb_mocContra"]
        pub moc_contra: Vec<f64> = vec![1.0],
        /// DRNL parameter set: CASP (Jepsen et al. 2008) or MAP 1.14h (drnl only)
        #[afe = "fb_model"]
        pub model: DrnlModel = DrnlModel::Casp,
    }
}

/// Highest `fb_highFreqHz` accepted, Hz: far above any sampling rate's Nyquist frequency,
/// low enough that the ERB grid up to it stays countable.
const MAX_HIGH_FREQ_HZ: f64 = 1e7;

/// Largest filterbank: more channels than this is a parameter mistake, not a use case.
pub const MAX_CHANNELS: usize = 1024;

/// The centre-frequency grid of a parameter set and the grid parameters as the AFE
/// reports them after its verify step.
#[derive(Debug, Clone, PartialEq)]
pub struct CfGrid {
    /// Centre frequencies in Hz.
    pub cf_hz: Vec<f64>,
    /// Spacing in ERBs: the given one, `(E(high) − E(low))/N` for a channel count, or
    /// `None` ("n/a") for explicit centre frequencies.
    pub n_erbs: Option<f64>,
    /// `fb_lowFreqHz` as reported (the first centre frequency when they are explicit).
    pub low_freq_hz: f64,
    /// `fb_highFreqHz` as reported (the last centre frequency when they are explicit).
    pub high_freq_hz: f64,
}

impl CfGrid {
    /// The grid's parameters under their AFE names, in `map`.
    pub fn insert_into(&self, map: &mut ParamMap) {
        map.insert(FilterbankParams::NAMES.cf_hz.into(), json!(self.cf_hz));
        map.insert(
            FilterbankParams::NAMES.n_channels.into(),
            json!(self.cf_hz.len()),
        );
        map.insert(
            FilterbankParams::NAMES.n_erbs.into(),
            self.n_erbs.map_or_else(|| json!("n/a"), |e| json!(e)),
        );
        map.insert(
            FilterbankParams::NAMES.low_freq_hz.into(),
            json!(self.low_freq_hz),
        );
        map.insert(
            FilterbankParams::NAMES.high_freq_hz.into(),
            json!(self.high_freq_hz),
        );
    }

    /// Refuses a grid beyond the Nyquist frequency of input rate `fs` Hz, naming the
    /// parameter the user set (`params` is what the grid was derived from). A top channel
    /// at Nyquist (`fb_highFreqHz = fs/2`, as AFE scripts write it) is accepted, as in the
    /// AFE, up to the rounding of the ERB round trip (22050.000000000004 for 44.1 kHz).
    pub fn check_below_nyquist(&self, params: &FilterbankParams, fs: f64) -> Result<()> {
        let nyquist = fs / 2.0;
        let limit = nyquist * (1.0 + 1e-12);
        let Some(bad) = self.cf_hz.iter().find(|f| **f > limit) else {
            return Ok(());
        };
        let top = self.cf_hz.iter().fold(*bad, |m, f| m.max(*f));
        let channels = match self.cf_hz.iter().filter(|f| **f > limit).count() {
            1 => format!("a centre frequency at {bad:.0} Hz"),
            n => format!("{n} centre frequencies, from {bad:.0} Hz up to {top:.0} Hz,"),
        };
        Err(if params.cf_hz.is_empty() {
            let default = FilterbankParams::default().high_freq_hz;
            let which = if params.high_freq_hz == default {
                // taken back by the graph if the request set it (afe_core::params::unless_set)
                afe_core::params::DEFAULT_NOTE
            } else {
                ""
            };
            Error::invalid(
                FilterbankParams::NAMES.high_freq_hz,
                format_args!("{:?}", params.high_freq_hz),
                format!(
                    "{}{which} puts {channels} above the Nyquist frequency ({nyquist} Hz) of \
                     the {fs} Hz input: set fb_highFreqHz to at most {nyquist} Hz",
                    params.high_freq_hz
                ),
            )
        } else {
            Error::invalid(
                FilterbankParams::NAMES.cf_hz,
                format_args!("{bad:?}"),
                format!(
                    "centre frequencies must not exceed the Nyquist frequency ({nyquist} Hz) \
                     of the {fs} Hz input"
                ),
            )
        })
    }
}

impl FilterbankParams {
    /// Checks the grid parameters and derives the centre frequencies (priority `fb_cfHz`
    /// > `fb_nChannels` > `fb_nERBs`), as the AFE's verify step does for both types.
    pub fn grid(&self) -> Result<CfGrid> {
        if !self.cf_hz.is_empty() {
            if let Some(bad) = self.cf_hz.iter().find(|f| **f <= 0.0) {
                return Err(Error::invalid(
                    FilterbankParams::NAMES.cf_hz,
                    format_args!("{bad:?}"),
                    "centre frequencies must be > 0 Hz",
                ));
            }
            if self.cf_hz.len() > MAX_CHANNELS {
                return Err(Error::invalid(
                    FilterbankParams::NAMES.cf_hz,
                    format_args!("[{} values]", self.cf_hz.len()),
                    format!("at most {MAX_CHANNELS} channels are supported"),
                ));
            }
            return Ok(CfGrid {
                cf_hz: self.cf_hz.clone(),
                n_erbs: None,
                low_freq_hz: self.cf_hz[0],
                high_freq_hz: self.cf_hz[self.cf_hz.len() - 1],
            });
        }
        if self.low_freq_hz <= 0.0 {
            return Err(Error::invalid(
                FilterbankParams::NAMES.low_freq_hz,
                format_args!("{:?}", self.low_freq_hz),
                "must be > 0 Hz",
            ));
        }
        if self.high_freq_hz.is_nan() || self.high_freq_hz > MAX_HIGH_FREQ_HZ {
            return Err(Error::invalid(
                FilterbankParams::NAMES.high_freq_hz,
                format_args!("{:?}", self.high_freq_hz),
                "must be a frequency in Hz below the Nyquist frequency of the input",
            ));
        }
        if self.high_freq_hz < self.low_freq_hz {
            return Err(Error::invalid(
                FilterbankParams::NAMES.high_freq_hz,
                format_args!("{:?}", self.high_freq_hz),
                format!("must be ≥ fb_lowFreqHz ({} Hz)", self.low_freq_hz),
            ));
        }
        let (elo, ehi) = (freq2erb(self.low_freq_hz), freq2erb(self.high_freq_hz));
        let (cf_hz, n_erbs): (Vec<f64>, f64) = match self.n_channels {
            Some(0) => {
                return Err(Error::invalid(
                    FilterbankParams::NAMES.n_channels,
                    0,
                    "must be at least 1",
                ))
            }
            Some(n) if n as usize > MAX_CHANNELS => {
                return Err(Error::invalid(
                    FilterbankParams::NAMES.n_channels,
                    n,
                    format!("at most {MAX_CHANNELS} channels are supported"),
                ))
            }
            Some(n) => {
                let e = linspace(elo, ehi, n as usize);
                let spacing = (e[e.len() - 1] - e[0]) / f64::from(n);
                (e.into_iter().map(erb2freq).collect(), spacing)
            }
            None => {
                let count = (ehi - elo) / self.n_erbs;
                if self.n_erbs <= 0.0 || count >= MAX_CHANNELS as f64 {
                    return Err(Error::invalid(
                        FilterbankParams::NAMES.n_erbs,
                        format_args!("{:?}", self.n_erbs),
                        format!(
                            "must be > 0 and give at most {MAX_CHANNELS} channels between \
                             fb_lowFreqHz and fb_highFreqHz"
                        ),
                    ));
                }
                let cf = colon_range(elo, self.n_erbs, ehi)
                    .into_iter()
                    .map(erb2freq)
                    .collect();
                (cf, self.n_erbs)
            }
        };
        Ok(CfGrid {
            cf_hz,
            n_erbs: Some(n_erbs),
            low_freq_hz: self.low_freq_hz,
            high_freq_hz: self.high_freq_hz,
        })
    }
}

/// The class a request's parameter map selects: its `fb_type`, or the default gammatone
/// when the map has none. A value the filterbank would refuse is refused here too, so
/// that a chain without a filterbank (the pre-processing reads `fb_type`) does not take
/// a mistyped class for the default.
pub fn fb_type_of(map: &ParamMap) -> Result<FbType> {
    // the declaration of fb_type, the first field
    let spec = &FilterbankParams::SPECS[0];
    let Some(given) = map.get(spec.name) else {
        return Ok(FbType::Gammatone);
    };
    match spec.normalize(given)? {
        None => Ok(FbType::Gammatone),
        Some(v) => serde_json::from_value(v)
            .map_err(|e| Error::invalid(spec.name, given, format!("not a filterbank type ({e})"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_grid_has_31_channels_with_the_afe_bits() {
        // fb_type_of reads the first declaration
        assert_eq!(
            FilterbankParams::SPECS[0].name,
            FilterbankParams::NAMES.fb_type
        );
        let grid = FilterbankParams::default().grid().expect("valid");
        assert_eq!(grid.cf_hz.len(), 31);
        assert_eq!(grid.cf_hz[0], 80.00000000000001);
        assert_eq!(grid.cf_hz[1], 115.20010915768904);
        assert_eq!(grid.cf_hz[30], 7641.313909478947);
    }

    #[test]
    fn channel_count_mode_spans_both_ends() {
        let p = FilterbankParams {
            n_channels: Some(16),
            low_freq_hz: 100.0,
            ..Default::default()
        };
        let grid = p.grid().expect("valid");
        assert_eq!(grid.cf_hz.len(), 16);
        assert!((grid.cf_hz[0] - 100.0).abs() < 1e-9);
        assert!((grid.cf_hz[15] - 8000.0).abs() < 1e-9);
    }

    #[test]
    fn absurd_channel_counts_are_errors_not_allocations() {
        for p in [
            FilterbankParams {
                n_erbs: 1e-9,
                ..Default::default()
            },
            FilterbankParams {
                n_erbs: 1e-300,
                ..Default::default()
            },
            FilterbankParams {
                n_channels: Some(u32::MAX),
                ..Default::default()
            },
        ] {
            let e = p.grid().expect_err("too many channels");
            assert!(e.to_string().contains("at most 1024 channels"), "{e}");
        }
        let p = FilterbankParams {
            n_channels: Some(0),
            ..Default::default()
        };
        let e = p.grid().expect_err("no channel");
        assert!(e.to_string().contains("at least 1"), "{e}");
    }

    #[test]
    fn every_limit_is_itself_accepted() {
        let grid = |p: FilterbankParams| p.grid();
        let cf_list = |n: usize| FilterbankParams {
            cf_hz: vec![1000.0; n],
            ..Default::default()
        };
        assert!(grid(cf_list(MAX_CHANNELS)).is_ok());
        assert!(grid(cf_list(MAX_CHANNELS + 1)).is_err());
        let counted = FilterbankParams {
            n_channels: Some(MAX_CHANNELS as u32),
            ..Default::default()
        };
        assert_eq!(
            grid(counted).expect("the largest count").cf_hz.len(),
            MAX_CHANNELS
        );
        let top = FilterbankParams {
            high_freq_hz: MAX_HIGH_FREQ_HZ,
            n_channels: Some(4),
            ..Default::default()
        };
        assert!(grid(top).is_ok());
        let flat = FilterbankParams {
            low_freq_hz: 500.0,
            high_freq_hz: 500.0,
            n_channels: Some(3),
            ..Default::default()
        };
        let flat = grid(flat).expect("equal ends");
        assert!(
            flat.cf_hz.iter().all(|f| (f - 500.0).abs() < 1e-9),
            "{flat:?}"
        );
        // The Nyquist allowance for the ERB round trip, exactly.
        let at = FilterbankParams {
            cf_hz: vec![1000.0, 22050.0 * (1.0 + 1e-12)],
            ..Default::default()
        };
        let at_grid = grid(at.clone()).expect("valid");
        assert!(at_grid.check_below_nyquist(&at, 44100.0).is_ok());
    }

    #[test]
    fn spacing_mode_counts_its_channels_before_making_them() {
        let span = freq2erb(8000.0) - freq2erb(80.0);
        let spaced = |n_erbs: f64| FilterbankParams {
            n_erbs,
            ..Default::default()
        };
        // 1023.5 spacings: 1024 channels, the most accepted.
        let grid = spaced(span / 1023.5).grid().expect("1024 channels");
        assert_eq!(grid.cf_hz.len(), MAX_CHANNELS);
        let e = spaced(span / 1100.0).grid().expect_err("1101 channels");
        assert!(e.to_string().contains("at most 1024 channels"), "{e}");
    }

    #[test]
    fn channel_count_mode_reports_the_spacing_over_n() {
        let p = FilterbankParams {
            n_channels: Some(31),
            ..Default::default()
        };
        let grid = p.grid().expect("valid");
        let want = (freq2erb(8000.0) - freq2erb(80.0)) / 31.0;
        let got = grid.n_erbs.expect("a spacing");
        assert!((got - want).abs() < 1e-12, "{got} vs {want}");
    }
}
