//! The RAA's internal constants (`parConf` of the AFE's `afeRAA`, set by its
//! `RAA_param_configuration.m`): the peak/dip thresholds of the stream segregation and the
//! weights and sigmoid scalings of the four predictors.

use afe_core::params::{closest, Params};
use afe_core::{ParamKind, ParamMap, ParamSpec};
use serde::{Deserialize, Serialize};

use super::RaaError;

/// The constants of the RAA, under the AFE's names (`parConf.mu_psi`, ...), with the
/// AFE's values as defaults (Osses Vecchi's thresholds, van Dorp Schuitman's scalings).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RaaConstants {
    /// Peak threshold of the direct stream, as a multiple of the band's mean absolute
    /// adaptation output (`mu_psi`, 1).
    #[serde(rename = "mu_psi")]
    pub mu_psi: f64,
    /// Dip threshold of the direct stream, as a multiple of the band's mean absolute
    /// adaptation output (`mu_psi_dip`, 1; negative: below zero).
    #[serde(rename = "mu_psi_dip")]
    pub mu_psi_dip: f64,
    /// Shortest peak or dip that counts as direct sound, first to last sample (`T_min`, s).
    #[serde(rename = "T_min")]
    pub t_min: f64,
    /// Slope of the reverberance sigmoid (`a_P_REV`, 1/MU).
    #[serde(rename = "a_P_REV")]
    pub a_p_rev: f64,
    /// Midpoint of the reverberance sigmoid (`b_P_REV`, MU).
    #[serde(rename = "b_P_REV")]
    pub b_p_rev: f64,
    /// Slope of the clarity sigmoid (`a_P_CLA`, 1).
    #[serde(rename = "a_P_CLA")]
    pub a_p_cla: f64,
    /// Midpoint of the clarity sigmoid (`b_P_CLA`, 1).
    #[serde(rename = "b_P_CLA")]
    pub b_p_cla: f64,
    /// Weight of the low-frequency level in the apparent source width (`mu_ASW`, 1/MU).
    #[serde(rename = "mu_ASW")]
    pub mu_asw: f64,
    /// Weight of the foreground ITD fluctuation in the apparent source width (`nu_ASW`,
    /// per ITD unit × 1e3; see [`super::RaaPsi::itd`]).
    #[serde(rename = "nu_ASW")]
    pub nu_asw: f64,
    /// Slope of the apparent-source-width sigmoid (`a_P_ASW`, 1).
    #[serde(rename = "a_P_ASW")]
    pub a_p_asw: f64,
    /// Midpoint of the apparent-source-width sigmoid (`b_P_ASW`, 1).
    #[serde(rename = "b_P_ASW")]
    pub b_p_asw: f64,
    /// Weight of the background level in the listener envelopment (`mu_LEV`, 1/MU).
    #[serde(rename = "mu_LEV")]
    pub mu_lev: f64,
    /// Weight of the background ITD fluctuation in the listener envelopment (`nu_LEV`,
    /// per ITD unit × 1e3).
    #[serde(rename = "nu_LEV")]
    pub nu_lev: f64,
    /// Slope of the listener-envelopment sigmoid (`a_P_LEV`, 1).
    #[serde(rename = "a_P_LEV")]
    pub a_p_lev: f64,
    /// Midpoint of the listener-envelopment sigmoid (`b_P_LEV`, 1).
    #[serde(rename = "b_P_LEV")]
    pub b_p_lev: f64,
}

impl Default for RaaConstants {
    fn default() -> Self {
        RaaConstants {
            mu_psi: 0.34,
            mu_psi_dip: -60.39e-3,
            t_min: 63.1e-3,
            a_p_rev: 0.207,
            b_p_rev: 21.4,
            a_p_cla: 2.76,
            b_p_cla: 2.84,
            mu_asw: 2e-2,
            nu_asw: 5.63e2,
            a_p_asw: 2.41,
            b_p_asw: 2.64,
            mu_lev: 2.76e-2,
            nu_lev: 6.80e2,
            a_p_lev: 1.17,
            b_p_lev: 2.20,
        }
    }
}

/// A constant that is a plain real number.
const fn number(name: &'static str, unit: &'static str, description: &'static str) -> ParamSpec {
    ParamSpec {
        name,
        kind: ParamKind::Number,
        unit,
        description,
    }
}

impl Params for RaaConstants {
    const SPECS: &'static [ParamSpec] = &[
        number(
            "mu_psi",
            "",
            "peak threshold of the direct stream, times the band's mean |adaptation output|",
        ),
        number(
            "mu_psi_dip",
            "",
            "dip threshold of the direct stream, times the band's mean |adaptation output|",
        ),
        number(
            "T_min",
            "s",
            "shortest peak or dip counted as direct sound (first to last sample)",
        ),
        number("a_P_REV", "1/MU", "slope of the reverberance sigmoid"),
        number("b_P_REV", "MU", "midpoint of the reverberance sigmoid"),
        number("a_P_CLA", "", "slope of the clarity sigmoid"),
        number("b_P_CLA", "", "midpoint of the clarity sigmoid"),
        number(
            "mu_ASW",
            "1/MU",
            "weight of the low-frequency level in the apparent source width",
        ),
        number(
            "nu_ASW",
            "",
            "weight of the foreground ITD fluctuation (x 1e3) in the apparent source width",
        ),
        number("a_P_ASW", "", "slope of the apparent-source-width sigmoid"),
        number(
            "b_P_ASW",
            "",
            "midpoint of the apparent-source-width sigmoid",
        ),
        number(
            "mu_LEV",
            "1/MU",
            "weight of the background level in the listener envelopment",
        ),
        number(
            "nu_LEV",
            "",
            "weight of the background ITD fluctuation (x 1e3) in the listener envelopment",
        ),
        number("a_P_LEV", "", "slope of the listener-envelopment sigmoid"),
        number(
            "b_P_LEV",
            "",
            "midpoint of the listener-envelopment sigmoid",
        ),
    ];
}

impl RaaConstants {
    /// The AFE names of the constants, in the order of `RAA_param_configuration.m`.
    pub fn names() -> impl Iterator<Item = &'static str> {
        Self::SPECS.iter().map(|s| s.name)
    }

    /// The defaults with the constants of `map` (AFE name → number) over them. A name
    /// that is not a constant is refused with the closest one (`T_Min` → `T_min`), a
    /// value that is not a finite number with its name.
    ///
    /// ```
    /// use afe::raa::RaaConstants;
    /// let map = [("T_min".to_string(), serde_json::json!(0.05))].into_iter().collect();
    /// assert_eq!(RaaConstants::from_params(&map)?.t_min, 0.05);
    /// let typo = [("mu_PSI".to_string(), serde_json::json!(0.3))].into_iter().collect();
    /// let e = RaaConstants::from_params(&typo).unwrap_err().to_string();
    /// assert!(e.contains("did you mean 'mu_psi'?"), "{e}");
    /// # Ok::<(), afe::raa::RaaError>(())
    /// ```
    pub fn from_params(map: &ParamMap) -> Result<Self, RaaError> {
        if let Some(name) = map.keys().find(|k| !Self::names().any(|n| n == k.as_str())) {
            return Err(RaaError::UnknownConstant {
                name: name.clone(),
                closest: closest(name, Self::names()).map(str::to_string),
            });
        }
        let constants = Self::from_map(map)?;
        constants.check()?;
        Ok(constants)
    }

    /// Checks every constant against the range where the predictors stay finite,
    /// refusing the first one outside it by name, value and range.
    ///
    /// ```
    /// use afe::raa::RaaConstants;
    /// let e = RaaConstants { nu_asw: -1.0, ..RaaConstants::default() }.check().unwrap_err();
    /// assert!(e.to_string().contains("nu_ASW = -1"), "{e}");
    /// ```
    pub fn check(&self) -> Result<(), RaaError> {
        let defaults = Self::default().values();
        for ((name, value), (_, default)) in self.values().into_iter().zip(defaults) {
            let range = self.range(name);
            if !range.holds(value) {
                return Err(RaaError::ConstantOutOfRange {
                    name,
                    value,
                    accepted: range.to_string(),
                    default,
                });
            }
        }
        Ok(())
    }

    /// Every constant under its AFE name, in the order of [`Self::names`].
    fn values(&self) -> [(&'static str, f64); 15] {
        [
            ("mu_psi", self.mu_psi),
            ("mu_psi_dip", self.mu_psi_dip),
            ("T_min", self.t_min),
            ("a_P_REV", self.a_p_rev),
            ("b_P_REV", self.b_p_rev),
            ("a_P_CLA", self.a_p_cla),
            ("b_P_CLA", self.b_p_cla),
            ("mu_ASW", self.mu_asw),
            ("nu_ASW", self.nu_asw),
            ("a_P_ASW", self.a_p_asw),
            ("b_P_ASW", self.b_p_asw),
            ("mu_LEV", self.mu_lev),
            ("nu_LEV", self.nu_lev),
            ("a_P_LEV", self.a_p_lev),
            ("b_P_LEV", self.b_p_lev),
        ]
    }

    /// The values of the constant `name` for which the predictors are finite: thresholds
    /// that leave samples between peak and dip (`mu_psi` above 0, `mu_psi_dip` below
    /// `mu_psi`: otherwise every sample is direct, `BL` is 0 and `pClar = FL/BL`
    /// infinite), no negative duration, ITD weights of at least 0 (`log10(1 + nu·ITD·1e3)`
    /// is NaN below -1), and every magnitude at most [`CONSTANT_LIMIT`] (`mu_ASW = 1e308`
    /// overflows `mu_ASW·Llow`).
    fn range(&self, name: &str) -> Range {
        let (low, high) = (-CONSTANT_LIMIT, CONSTANT_LIMIT);
        match name {
            "mu_psi" => Range::new(Bound::Above(0.0), Bound::Upto(high)),
            "mu_psi_dip" => Range::new(Bound::From(low), Bound::Below(self.mu_psi, "mu_psi")),
            "T_min" | "nu_ASW" | "nu_LEV" => Range::new(Bound::From(0.0), Bound::Upto(high)),
            _ => Range::new(Bound::From(low), Bound::Upto(high)),
        }
    }
}

/// The largest magnitude accepted for any RAA constant: far beyond the AFE's values (at
/// most 680) and low enough that the weighted levels and ITDs stay finite.
pub const CONSTANT_LIMIT: f64 = 1e9;

/// One end of a [`Range`].
#[derive(Debug, Clone, Copy)]
enum Bound {
    /// At least the value.
    From(f64),
    /// Above the value.
    Above(f64),
    /// At most the value.
    Upto(f64),
    /// Below another constant's value, named.
    Below(f64, &'static str),
}

/// The values a constant accepts.
#[derive(Debug, Clone, Copy)]
struct Range {
    low: Bound,
    high: Bound,
}

impl Range {
    fn new(low: Bound, high: Bound) -> Self {
        Range { low, high }
    }

    fn holds(&self, v: f64) -> bool {
        [self.low, self.high].iter().all(|b| match *b {
            Bound::From(x) => v >= x,
            Bound::Above(x) => v > x,
            Bound::Upto(x) => v <= x,
            Bound::Below(x, _) => v < x,
        })
    }
}

impl std::fmt::Display for Range {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let end = |b: Bound| match b {
            Bound::From(x) => format!("from {}", compact(x)),
            Bound::Above(x) => format!("above {}", compact(x)),
            Bound::Upto(x) => format!("up to {}", compact(x)),
            Bound::Below(x, name) => format!("below {name} ({})", compact(x)),
        };
        write!(f, "values {} {}", end(self.low), end(self.high))
    }
}

/// `x` as written by hand: plain below a million in magnitude, else in exponent form
/// (`1e308`, not 309 digits).
pub(crate) fn compact(x: f64) -> String {
    match x.abs() >= 1e6 {
        true => format!("{x:e}"),
        false => x.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_name_every_field_and_accept_the_defaults() {
        afe_core::params::check_param_specs::<RaaConstants>();
    }

    #[test]
    fn values_follow_the_names() {
        let c = RaaConstants::default();
        let names: Vec<_> = c.values().iter().map(|(n, _)| *n).collect();
        assert_eq!(names, RaaConstants::names().collect::<Vec<_>>());
        let json = serde_json::to_value(&c).expect("json");
        for (name, value) in c.values() {
            assert_eq!(json[name].as_f64(), Some(value), "{name}");
        }
        c.check().expect("the AFE's constants are in range");
    }

    #[test]
    fn a_value_that_is_not_a_number_is_refused_by_name() {
        let map = [("nu_LEV".to_string(), serde_json::json!("loud"))]
            .into_iter()
            .collect();
        let e = RaaConstants::from_params(&map).unwrap_err().to_string();
        assert!(e.contains("'nu_LEV'") && e.contains("a number"), "{e}");
    }

    #[test]
    fn an_unknown_name_far_from_every_constant_gets_no_guess() {
        let map = [("fb_nChannels".to_string(), serde_json::json!(32))]
            .into_iter()
            .collect();
        let e = RaaConstants::from_params(&map).unwrap_err().to_string();
        assert!(!e.contains("did you mean"), "{e}");
        assert!(e.contains("'fb_nChannels'") && e.contains("T_min"), "{e}");
    }
}
