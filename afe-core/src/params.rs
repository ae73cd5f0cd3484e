//! AFE parameters: the flat name → value map of a request, and typed parameter structs.
//!
//! A request carries one map of AFE parameter names (`fb_nChannels`, `ihc_method`, ...) to
//! JSON-like values. Each processor keeps the names it declares, fills in its defaults for
//! absent, empty (`[]`, `""`) or `'n-a'` values, as the AFE does, and type-checks the rest.

use std::collections::BTreeMap;

use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::Value;

use crate::error::{Error, Result};

/// A request's parameters: AFE parameter name → value.
pub type ParamMap = BTreeMap<String, Value>;

/// The type of value a parameter accepts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamKind {
    /// A finite real number.
    Number,
    /// A positive integer.
    Count,
    /// A positive integer up to the given one.
    CountUpTo(u64),
    /// A flag: `true`/`false` or `1`/`0`, as in MATLAB.
    Flag,
    /// One string out of the listed choices.
    Choice(&'static [&'static str]),
    /// A list of strings out of the listed choices (a single string is taken as a list
    /// of one).
    Choices(&'static [&'static str]),
    /// A vector of finite numbers (a scalar is taken as a vector of one).
    Numbers,
    /// A non-empty string that its processor reads (a head's name or file).
    Text,
}

impl ParamKind {
    /// A short human description of what is accepted, for error messages and `afe list`.
    pub fn describe(&self) -> String {
        match self {
            ParamKind::Number => "a number".into(),
            ParamKind::Count => "a positive integer".into(),
            ParamKind::CountUpTo(n) => format!("an integer from 1 to {n}"),
            ParamKind::Flag => "a flag (true/false or 1/0)".into(),
            ParamKind::Choice(c) => format!("one of {}", quoted(c)),
            ParamKind::Choices(c) => format!("one or a list of {}", quoted(c)),
            ParamKind::Numbers => "a number or an array of numbers".into(),
            ParamKind::Text => "a non-empty string".into(),
        }
    }

    /// A short name of the type, for listings.
    pub fn type_name(&self) -> &'static str {
        match self {
            ParamKind::Number => "number",
            ParamKind::Count | ParamKind::CountUpTo(_) => "integer",
            ParamKind::Flag => "flag",
            ParamKind::Choice(_) | ParamKind::Text => "string",
            ParamKind::Choices(_) => "strings",
            ParamKind::Numbers => "numbers",
        }
    }
}

fn quoted(items: &[&str]) -> String {
    items
        .iter()
        .map(|s| format!("'{s}'"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Declaration of one AFE parameter: its name, type, unit and meaning.
#[derive(Debug, Clone, Copy)]
pub struct ParamSpec {
    /// The AFE name, e.g. `rm_wSizeSec`.
    pub name: &'static str,
    /// Accepted values.
    pub kind: ParamKind,
    /// Unit (`"s"`, `"Hz"`, `"dB"`, or `""` when dimensionless).
    pub unit: &'static str,
    /// One-line meaning (a declaration's doc comment, as written).
    pub description: &'static str,
}

impl ParamSpec {
    /// The meaning without the doc comment's leading spaces or final full stop.
    pub fn meaning(&self) -> &'static str {
        self.description.trim().trim_end_matches('.')
    }
}

/// The name among `known` that `given` most likely misspells: the closest by edit
/// distance, case aside (`ITD` → `itd`, `rm_wSizeSecs` → `rm_wSizeSec`), if within
/// 2 + len/4 edits; `None` when nothing is that close. The one did-you-mean of the
/// workspace: request names, parameter names and string values all go through it.
///
/// ```
/// use afe_core::params::closest;
/// assert_eq!(closest("ITD", ["ild", "itd", "ic"]), Some("itd"));
/// assert_eq!(closest("Dau", ["halfwave", "dau", "hilbert"]), Some("dau"));
/// assert_eq!(closest("spectrogram", ["ild", "itd"]), None);
/// ```
pub fn closest<'a>(given: &str, known: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let given_lower = given.to_lowercase();
    known
        .into_iter()
        .map(|k| (edit_distance(&k.to_lowercase(), &given_lower), k))
        .min()
        .filter(|(d, _)| *d <= 2 + given.len() / 4)
        .map(|(_, k)| k)
}

/// ` (did you mean 'x'?)` for the [`closest`] name, or an empty string.
pub fn did_you_mean<'a>(given: &str, known: impl IntoIterator<Item = &'a str>) -> String {
    closest(given, known)
        .map(|k| format!(" (did you mean '{k}'?)"))
        .unwrap_or_default()
}

/// Levenshtein distance between `a` and `b`, in characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let cur = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != *cb)).min(row[j] + 1).min(cur + 1);
            prev = cur;
        }
    }
    row[b.len()]
}

/// What a message adds after a value equal to the parameter's default. A processor sees
/// only its typed parameters, defaults filled in, so it cannot tell a default from the
/// same value set on purpose; [`unless_set`], applied where the request's map is at hand
/// (the graph), takes the note back for a value the request set.
pub const DEFAULT_NOTE: &str = " (the default)";

/// `e` with [`DEFAULT_NOTE`] taken out of an [`Error::InvalidParameter`] whose parameter
/// `request` sets (to a value other than the AFE's "use the default" markers): a value the
/// user set is never called the default, even when it equals it (`fb_highFreqHz = 8000`
/// at 11025 Hz).
///
/// ```
/// use afe_core::params::{unless_set, DEFAULT_NOTE};
/// use afe_core::{Error, ParamMap};
/// let e = || Error::invalid("fb_highFreqHz", 8000.0, format!("8000{DEFAULT_NOTE} is too high"));
/// let set: ParamMap = [("fb_highFreqHz".to_string(), serde_json::json!(8000))].into_iter().collect();
/// assert_eq!(unless_set(e(), &set).to_string(), "invalid value 8000 for parameter 'fb_highFreqHz': 8000 is too high");
/// assert!(unless_set(e(), &ParamMap::new()).to_string().contains("8000 (the default) is"));
/// ```
pub fn unless_set(e: Error, request: &ParamMap) -> Error {
    match e {
        Error::InvalidParameter {
            name,
            value,
            reason,
        } if reason.contains(DEFAULT_NOTE)
            && request.get(&name).is_some_and(|v| !is_default_marker(v)) =>
        {
            Error::invalid(name, value, reason.replace(DEFAULT_NOTE, ""))
        }
        e => e,
    }
}

/// True for the values the AFE treats as "use the default": `[]`, `""`, `null`, `'n-a'`.
fn is_default_marker(v: &Value) -> bool {
    match v {
        Value::Null => true,
        Value::String(s) => s.is_empty() || s == "n-a",
        Value::Array(a) => a.is_empty(),
        _ => false,
    }
}

impl ParamSpec {
    /// Checks `value` against this parameter's kind and returns its canonical form,
    /// or `None` when the value asks for the default.
    pub fn normalize(&self, value: &Value) -> Result<Option<Value>> {
        if is_default_marker(value) {
            return Ok(None);
        }
        let bad = || {
            // a string that misspells a choice ("Dau" for 'dau') is named with it
            let hint = match (self.kind, value) {
                (ParamKind::Choice(c) | ParamKind::Choices(c), Value::String(s)) => {
                    did_you_mean(s, c.iter().copied())
                }
                (ParamKind::Choices(c), Value::Array(items)) => items
                    .iter()
                    .filter_map(Value::as_str)
                    .find(|s| !c.contains(s))
                    .map(|s| did_you_mean(s, c.iter().copied()))
                    .unwrap_or_default(),
                _ => String::new(),
            };
            Error::invalid(
                self.name,
                value,
                format!("expected {}{hint}", self.kind.describe()),
            )
        };
        let finite = |v: &Value| v.as_f64().filter(|x| x.is_finite());
        let out = match self.kind {
            ParamKind::Number => Value::from(finite(value).ok_or_else(bad)?),
            ParamKind::Count | ParamKind::CountUpTo(_) => {
                let top = match self.kind {
                    ParamKind::CountUpTo(n) => n as f64,
                    _ => u32::MAX as f64,
                };
                let x = finite(value).ok_or_else(bad)?;
                if x < 1.0 || x.fract() != 0.0 || x > top {
                    return Err(bad());
                }
                Value::from(x as u64)
            }
            ParamKind::Flag => match value {
                Value::Bool(b) => Value::Bool(*b),
                Value::Number(_) => match finite(value) {
                    Some(0.0) => Value::Bool(false),
                    Some(1.0) => Value::Bool(true),
                    _ => return Err(bad()),
                },
                _ => return Err(bad()),
            },
            ParamKind::Choice(choices) => match value.as_str() {
                Some(s) if choices.contains(&s) => Value::from(s),
                _ => return Err(bad()),
            },
            ParamKind::Choices(choices) => {
                let choice = |v: &Value| {
                    v.as_str()
                        .filter(|s| choices.contains(s))
                        .map(Value::from)
                        .ok_or_else(bad)
                };
                match value {
                    Value::Array(items) => {
                        Value::Array(items.iter().map(choice).collect::<Result<_>>()?)
                    }
                    _ => Value::Array(vec![choice(value)?]),
                }
            }
            ParamKind::Text => match value.as_str() {
                Some(s) if !s.trim().is_empty() => Value::from(s),
                _ => return Err(bad()),
            },
            ParamKind::Numbers => match value {
                Value::Array(items) => Value::Array(
                    items
                        .iter()
                        .map(|v| finite(v).map(Value::from).ok_or_else(bad))
                        .collect::<Result<_>>()?,
                ),
                _ => Value::Array(vec![Value::from(finite(value).ok_or_else(bad)?)]),
            },
        };
        Ok(Some(out))
    }
}

/// A processor's typed parameter struct, (de)serialised under the AFE names.
///
/// `Default` must equal the AFE defaults; `SPECS` lists every field under its AFE name.
pub trait Params: Serialize + DeserializeOwned + Default + Clone + PartialEq {
    /// Declarations of the parameters, in listing order.
    const SPECS: &'static [ParamSpec];

    /// Builds the struct from a request's map: keeps the declared names, fills defaults,
    /// type-checks every given value. Names this struct does not declare are ignored.
    fn from_map(map: &ParamMap) -> Result<Self> {
        let mut obj = match serde_json::to_value(Self::default()) {
            Ok(Value::Object(o)) => o,
            _ => unreachable!("parameter structs serialise to objects"),
        };
        for spec in Self::SPECS {
            if let Some(v) = map.get(spec.name) {
                if let Some(v) = spec.normalize(v)? {
                    obj.insert(spec.name.to_string(), v);
                }
            }
        }
        serde_json::from_value(Value::Object(obj)).map_err(|e| {
            Error::invalid(
                Self::SPECS
                    .iter()
                    .map(|s| s.name)
                    .collect::<Vec<_>>()
                    .join("/"),
                "(combination)",
                e.to_string(),
            )
        })
    }

    /// The parameters as an AFE name → value map.
    fn to_map(&self) -> ParamMap {
        match serde_json::to_value(self) {
            Ok(Value::Object(o)) => o.into_iter().collect(),
            _ => unreachable!("parameter structs serialise to objects"),
        }
    }
}

/// The parameters of a processor that has none of its own (e.g. `itd`, `ic`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize)]
pub struct NoParams {}

impl Params for NoParams {
    const SPECS: &'static [ParamSpec] = &[];
}

/// `values` as one value per channel for `channels` channels: a single value is repeated;
/// any other length than 1 or `channels` is an error naming parameter `name` (the AFE's
/// scalar-or-vector parameters, e.g. `fb_mocIpsi`, `moc_extIpsi`).
pub fn per_channel(name: &str, values: &[f64], channels: usize) -> Result<Vec<f64>> {
    match values.len() {
        1 => Ok(vec![values[0]; channels]),
        n if n == channels => Ok(values.to_vec()),
        n => Err(Error::invalid(
            name,
            format!("{values:?}"),
            format!("expected one value or {channels} (one per channel), got {n}"),
        )),
    }
}

/// Test helper for processor crates (panics on a mismatch): checks that `P::SPECS` and
/// the serialised default name the same parameters and that every default passes its own
/// declaration.
#[doc(hidden)]
pub fn check_param_specs<P: Params>() {
    let defaults = P::default().to_map();
    let mut declared: Vec<&str> = P::SPECS.iter().map(|s| s.name).collect();
    declared.sort_unstable();
    let serialised: Vec<&str> = defaults.keys().map(String::as_str).collect();
    assert_eq!(declared, serialised, "SPECS and struct fields differ");
    for spec in P::SPECS {
        let v = &defaults[spec.name];
        spec.normalize(v)
            .unwrap_or_else(|e| panic!("default of {} rejected: {e}", spec.name));
    }
    assert!(P::from_map(&defaults).is_ok_and(|p| p == P::default()));
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    const FLAG: ParamSpec = ParamSpec {
        name: "x_bFlag",
        kind: ParamKind::Flag,
        unit: "",
        description: "",
    };

    #[test]
    fn flags_accept_matlab_numbers() {
        assert_eq!(FLAG.normalize(&json!(1)).ok(), Some(Some(json!(true))));
        assert_eq!(FLAG.normalize(&json!(false)).ok(), Some(Some(json!(false))));
        assert!(FLAG.normalize(&json!(2)).is_err());
        assert!(FLAG.normalize(&json!("yes")).is_err());
    }

    #[test]
    fn bounded_counts_name_their_range() {
        let spec = ParamSpec {
            name: "fb_nGamma",
            kind: ParamKind::CountUpTo(8),
            unit: "",
            description: "",
        };
        assert_eq!(spec.normalize(&json!(8)).ok(), Some(Some(json!(8))));
        for bad in [json!(0), json!(9), json!(2.5)] {
            let e = spec.normalize(&bad).expect_err("refused").to_string();
            assert!(
                e.contains("fb_nGamma") && e.contains("an integer from 1 to 8"),
                "{e}"
            );
        }
    }

    #[test]
    fn empty_and_na_mean_default() {
        for v in [json!([]), json!(""), json!("n-a"), Value::Null] {
            assert_eq!(FLAG.normalize(&v).ok(), Some(None));
        }
    }

    #[test]
    fn choice_error_lists_accepted_values() {
        let spec = ParamSpec {
            name: "ihc_method",
            kind: ParamKind::Choice(&["dau", "none"]),
            unit: "",
            description: "",
        };
        let err = spec.normalize(&json!("daux")).unwrap_err().to_string();
        assert!(
            err.contains("ihc_method") && err.contains("'dau', 'none'"),
            "{err}"
        );
    }

    /// issue 46: a string value that misspells a choice is named with it; one far from
    /// every choice gets no guess.
    #[test]
    fn a_misspelt_choice_says_what_was_meant() {
        let spec = ParamSpec {
            name: "ihc_method",
            kind: ParamKind::Choice(&["halfwave", "dau", "hilbert"]),
            unit: "",
            description: "",
        };
        assert_eq!(
            spec.normalize(&json!("Dau")).unwrap_err().to_string(),
            "invalid value \"Dau\" for parameter 'ihc_method': expected one of 'halfwave', \
             'dau', 'hilbert' (did you mean 'dau'?)"
        );
        let far = spec
            .normalize(&json!("spectrogram"))
            .unwrap_err()
            .to_string();
        assert!(!far.contains("did you mean"), "{far}");
        let list = ParamSpec {
            name: "sf_requests",
            kind: ParamKind::Choices(&["all", "crest", "centroid"]),
            unit: "",
            description: "",
        };
        let e = list.normalize(&json!(["crest", "Centroid"])).unwrap_err();
        assert!(
            e.to_string().ends_with(" (did you mean 'centroid'?)"),
            "{e}"
        );
    }

    /// issue 46: "the default" is said only of a value the request did not set.
    #[test]
    fn a_value_set_is_not_called_the_default() {
        let e = || {
            Error::invalid(
                "fb_highFreqHz",
                "8000.0",
                format!("8000{DEFAULT_NOTE} puts a channel above Nyquist"),
            )
        };
        let set: ParamMap = [("fb_highFreqHz".to_string(), json!(8000))]
            .into_iter()
            .collect();
        assert_eq!(
            unless_set(e(), &set).to_string(),
            "invalid value 8000.0 for parameter 'fb_highFreqHz': 8000 puts a channel above Nyquist"
        );
        // not set, or set to a "use the default" marker: the default it is
        for request in [
            ParamMap::new(),
            [("fb_highFreqHz".to_string(), json!([]))]
                .into_iter()
                .collect(),
        ] {
            assert_eq!(
                unless_set(e(), &request).to_string(),
                "invalid value 8000.0 for parameter 'fb_highFreqHz': 8000 (the default) puts a \
                 channel above Nyquist"
            );
        }
    }

    #[test]
    fn closest_names_ignore_case_and_refuse_far_guesses() {
        assert_eq!(closest("ITD", ["ild", "itd"]), Some("itd"));
        assert_eq!(closest("ratemapp", ["ratemap", "ild"]), Some("ratemap"));
        assert_eq!(
            closest("rm_wSizeSecs", ["rm_wSizeSec", "rm_scaling"]),
            Some("rm_wSizeSec")
        );
        assert_eq!(closest("xyz", ["ratemap"]), None);
        assert_eq!(did_you_mean("Dau", ["dau"]), " (did you mean 'dau'?)");
        assert_eq!(did_you_mean("xyz", ["ratemap"]), "");
    }

    #[test]
    fn choice_lists_accept_single_strings_and_reject_unknown_entries() {
        let spec = ParamSpec {
            name: "sf_requests",
            kind: ParamKind::Choices(&["all", "crest"]),
            unit: "",
            description: "",
        };
        assert_eq!(
            spec.normalize(&json!("all")).ok(),
            Some(Some(json!(["all"])))
        );
        assert_eq!(
            spec.normalize(&json!(["crest", "all"])).ok(),
            Some(Some(json!(["crest", "all"])))
        );
        let err = spec.normalize(&json!(["crest", "crust"])).unwrap_err();
        assert!(err.to_string().contains("sf_requests"), "{err}");
        assert!(spec.normalize(&json!(3)).is_err());
    }

    #[test]
    fn counts_reject_fractions_and_zero() {
        let spec = ParamSpec {
            name: "fb_nChannels",
            kind: ParamKind::Count,
            unit: "",
            description: "",
        };
        assert_eq!(spec.normalize(&json!(16.0)).ok(), Some(Some(json!(16))));
        assert!(spec.normalize(&json!(1.5)).is_err());
        assert!(spec.normalize(&json!(0)).is_err());
    }

    #[test]
    fn counts_take_the_whole_u32_range() {
        let spec = ParamSpec {
            name: "fb_nChannels",
            kind: ParamKind::Count,
            unit: "",
            description: "",
        };
        let max = f64::from(u32::MAX);
        assert_eq!(spec.normalize(&json!(1)).ok(), Some(Some(json!(1))));
        assert_eq!(
            spec.normalize(&json!(max)).ok(),
            Some(Some(json!(u32::MAX)))
        );
        assert!(spec.normalize(&json!(max + 1.0)).is_err());
    }

    #[test]
    fn flags_take_zero_as_false_and_choices_keep_the_choice() {
        assert_eq!(FLAG.normalize(&json!(0)).ok(), Some(Some(json!(false))));
        let spec = ParamSpec {
            name: "ihc_method",
            kind: ParamKind::Choice(&["dau", "none"]),
            unit: "",
            description: "",
        };
        assert_eq!(spec.normalize(&json!("dau")).ok(), Some(Some(json!("dau"))));
    }

    #[test]
    fn kinds_name_their_type() {
        let names: Vec<&str> = [
            ParamKind::Number,
            ParamKind::Count,
            ParamKind::Flag,
            ParamKind::Choice(&["a"]),
            ParamKind::Choices(&["a"]),
            ParamKind::Numbers,
        ]
        .iter()
        .map(ParamKind::type_name)
        .collect();
        assert_eq!(
            names,
            ["number", "integer", "flag", "string", "strings", "numbers"]
        );
    }

    #[test]
    fn numbers_keep_every_entry_of_an_array() {
        let spec = ParamSpec {
            name: "fb_cfHz",
            kind: ParamKind::Numbers,
            unit: "Hz",
            description: "",
        };
        assert_eq!(
            spec.normalize(&json!([100, 2.5])).ok(),
            Some(Some(json!([100.0, 2.5])))
        );
    }

    /// A parameter struct as the processors declare theirs.
    #[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
    struct Demo {
        #[serde(rename = "d_nTaps")]
        taps: u32,
        #[serde(rename = "d_bOn")]
        on: bool,
    }

    impl Default for Demo {
        fn default() -> Self {
            Demo { taps: 4, on: false }
        }
    }

    const TAPS: ParamSpec = ParamSpec {
        name: "d_nTaps",
        kind: ParamKind::Count,
        unit: "",
        description: "",
    };

    const ON: ParamSpec = ParamSpec {
        name: "d_bOn",
        kind: ParamKind::Flag,
        unit: "",
        description: "",
    };

    impl Params for Demo {
        const SPECS: &'static [ParamSpec] = &[TAPS, ON];
    }

    #[test]
    fn a_struct_takes_its_names_from_the_map_and_gives_them_back() {
        let map: ParamMap = [
            ("d_nTaps".to_string(), json!(7)),
            ("d_bOn".to_string(), json!(1)),
            ("other_name".to_string(), json!("ignored")),
        ]
        .into();
        let demo = Demo::from_map(&map).unwrap();
        assert_eq!(demo, Demo { taps: 7, on: true });
        let back = demo.to_map();
        assert_eq!(back.keys().collect::<Vec<_>>(), ["d_bOn", "d_nTaps"]);
        assert_eq!(
            (back["d_nTaps"].clone(), back["d_bOn"].clone()),
            (json!(7), json!(true))
        );
        let err = Demo::from_map(&[("d_nTaps".to_string(), json!(0))].into()).unwrap_err();
        assert!(err.to_string().contains("d_nTaps"), "{err}");
        check_param_specs::<Demo>();
    }

    /// Declares one field of two.
    #[derive(Debug, Clone, Default, PartialEq, Serialize, serde::Deserialize)]
    struct Undeclared {
        #[serde(rename = "d_nTaps")]
        taps: u32,
        #[serde(rename = "d_bOn")]
        on: bool,
    }

    impl Params for Undeclared {
        const SPECS: &'static [ParamSpec] = &[TAPS];
    }

    #[test]
    #[should_panic(expected = "SPECS and struct fields differ")]
    fn the_spec_check_finds_an_undeclared_field() {
        check_param_specs::<Undeclared>();
    }

    #[test]
    fn per_channel_repeats_one_value_or_takes_one_per_channel() {
        assert_eq!(per_channel("x", &[2.0], 3).unwrap(), [2.0, 2.0, 2.0]);
        assert_eq!(
            per_channel("x", &[1.0, 2.0, 3.0], 3).unwrap(),
            [1.0, 2.0, 3.0]
        );
        let err = per_channel("fb_mocIpsi", &[1.0, 2.0], 3).unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("fb_mocIpsi") && text.contains("expected one value or 3"),
            "{text}"
        );
    }

    #[test]
    fn numbers_accept_scalars() {
        let spec = ParamSpec {
            name: "pp_refSPLdB",
            kind: ParamKind::Numbers,
            unit: "dB",
            description: "",
        };
        assert_eq!(spec.normalize(&json!(80)).ok(), Some(Some(json!([80.0]))));
        assert!(spec.normalize(&json!([1, "a"])).is_err());
    }
}
