//! The registry: every request this build computes, as a list of the descriptors that
//! the processor modules declare (each module implements [`afe_core::Descriptor`] for
//! its processor and exports the type-erased [`RequestDef`] the graph works with as
//! `REQUEST`, or one per request where a module serves two, e.g. `ONSET_REQUEST` and
//! `OFFSET_REQUEST`), and [`Registry`]: the requests one manager computes, the built-in
//! ones and those a program adds to it (no list the whole process shares).

use afe_core::{Error, RequestDef, Result};

use crate::{
    adaptation, ams_features, autocorrelation, butterworth, crosscorrelation, duet, filterbank,
    gabor, ic, ihc, ild, itd, localisation, moc, pitch, pre_proc, precedence, ratemap,
    spectral_features, stft, tracking, transient, transient_map,
};

/// The requests this crate computes, in dependency order: one line per processor module.
static BUILT_IN: &[&RequestDef] = &[
    &pre_proc::REQUEST,
    &butterworth::REQUEST,
    &filterbank::REQUEST,
    &ihc::REQUEST,
    &adaptation::REQUEST,
    &ratemap::REQUEST,
    &moc::REQUEST,
    &ild::REQUEST,
    &crosscorrelation::REQUEST,
    &itd::REQUEST,
    &ic::REQUEST,
    &precedence::REQUEST,
    &autocorrelation::REQUEST,
    &pitch::REQUEST,
    &transient::ONSET_REQUEST,
    &transient::OFFSET_REQUEST,
    &transient_map::ONSET_REQUEST,
    &transient_map::OFFSET_REQUEST,
    &spectral_features::REQUEST,
    &ams_features::REQUEST,
    &gabor::REQUEST,
    &stft::REQUEST,
    &duet::REQUEST,
    &localisation::REQUEST,
    &tracking::REQUEST,
];

/// Every request this build computes, in dependency order.
pub fn requests() -> &'static [&'static RequestDef] {
    BUILT_IN
}

/// The definition of built-in request `name`, or an error listing the known names.
pub fn find_request(name: &str) -> Result<&'static RequestDef> {
    find_in(BUILT_IN, name)
}

fn find_in(known: &[&'static RequestDef], name: &str) -> Result<&'static RequestDef> {
    known
        .iter()
        .find(|r| r.name == name)
        .copied()
        .ok_or_else(|| Error::UnknownRequest {
            name: name.to_string(),
            hint: afe_core::params::did_you_mean(name, known.iter().map(|r| r.name)),
            known: names(known),
        })
}

/// The requests a manager computes: the built-in ones, then those added with
/// [`Registry::register`], in dependency order. Each manager holds its own (a
/// registration reaches the managers given that registry, and no other).
#[derive(Debug, Clone)]
pub struct Registry {
    defs: Vec<&'static RequestDef>,
}

impl Default for Registry {
    /// The built-in requests.
    fn default() -> Self {
        Registry {
            defs: BUILT_IN.to_vec(),
        }
    }
}

impl Registry {
    /// Every request, in dependency order.
    pub fn requests(&self) -> &[&'static RequestDef] {
        &self.defs
    }

    /// The definition of request `name`, or an error listing the known names.
    pub fn find(&self, name: &str) -> Result<&'static RequestDef> {
        find_in(&self.defs, name)
    }

    /// Adds `def` after the requests known so far. A processor module outside this crate
    /// implements [`afe_core::Descriptor`] and registers `afe_core::request_def::<Its>()`
    /// kept in a `static`.
    ///
    /// Refused, with the reason, when the name is taken (or is `input`), when its
    /// dependency or an extra input it reads at its defaults is not known yet (register
    /// those first), when its defaults do not configure, or when a parameter name it
    /// declares is declared by another request with another kind, unit or meaning.
    pub fn register(&mut self, def: &'static RequestDef) -> Result<()> {
        check_registration(def, &self.defs)?;
        self.defs.push(def);
        Ok(())
    }

    /// Checks that every parameter name is declared by some request.
    pub fn check_parameter_names<'a>(
        &self,
        names: impl IntoIterator<Item = &'a String>,
    ) -> Result<()> {
        let known = || {
            self.defs
                .iter()
                .flat_map(|r| r.params.iter().map(|p| p.name))
        };
        for name in names {
            if !known().any(|k| k == name) {
                return Err(Error::UnknownParameter {
                    name: name.clone(),
                    hint: afe_core::params::did_you_mean(name, known()),
                });
            }
        }
        Ok(())
    }
}

/// Why `def` cannot follow the requests `known`, if it cannot.
fn check_registration(def: &RequestDef, known: &[&RequestDef]) -> Result<()> {
    let refuse = |reason: String| Error::RegistrationRefused {
        name: def.name.to_string(),
        reason,
    };
    let is_known = |name: &str| known.iter().any(|r| r.name == name);
    if def.name == "input" || is_known(def.name) {
        return Err(refuse(
            "a request of that name is already registered; choose another name".into(),
        ));
    }
    let missing = |what: &str, name: &str| {
        refuse(format!(
            "{what} '{name}' is not registered; register it first (known requests: {})",
            names(known)
        ))
    };
    if def.dependency != "input" && !is_known(def.dependency) {
        return Err(missing("its dependency", def.dependency));
    }
    let configured = (def.configure)(&(def.defaults)())
        .map_err(|e| refuse(format!("its defaults do not configure: {e}")))?;
    if let Some(extra) = configured.extra_inputs().iter().find(|e| !is_known(e)) {
        return Err(missing("the extra input", extra));
    }
    for p in def.params {
        let other = known
            .iter()
            .flat_map(|r| r.params.iter().map(move |q| (r.name, q)))
            .find(|(_, q)| q.name == p.name);
        if let Some((owner, q)) = other {
            if (q.kind, q.unit, q.meaning()) != (p.kind, p.unit, p.meaning()) {
                return Err(refuse(format!(
                    "parameter '{}' is declared by '{owner}' with another kind, unit or \
                     meaning; rename it or declare it as '{owner}' does",
                    p.name
                )));
            }
        }
    }
    Ok(())
}

/// The names of `requests`, comma-separated.
fn names(requests: &[&RequestDef]) -> String {
    requests
        .iter()
        .map(|r| r.name)
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use afe_core::{ParamKind, ParamMap, ParamSpec};

    /// issue 46: a request name given in the wrong case or with a typo is named with the
    /// request meant; the known names follow either way.
    #[test]
    fn an_unknown_request_says_which_was_meant() {
        let e = find_request("ITD").map(|_| ()).unwrap_err().to_string();
        assert!(
            e.starts_with("unknown request 'ITD' (did you mean 'itd'?) (known requests: time, "),
            "{e}"
        );
        let e = find_request("zzzzzzzzzz")
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("unknown request 'zzzzzzzzzz' (known requests: time, "),
            "{e}"
        );
    }

    /// Dependencies and extra inputs resolve to earlier requests (the list is in
    /// dependency order); a parameter name declared by several requests (`trm_*` of the
    /// onset and offset maps) means the same thing in each; defaults are valid.
    #[test]
    fn registry_is_in_dependency_order_and_names_mean_one_thing() {
        let mut specs: std::collections::BTreeMap<&str, &ParamSpec> = Default::default();
        for (i, r) in requests().iter().enumerate() {
            let earlier = |name: &str| requests()[..i].iter().any(|d| d.name == name);
            assert!(
                r.dependency == "input" || earlier(r.dependency),
                "{}",
                r.name
            );
            let configured = (r.configure)(&(r.defaults)()).expect("defaults are valid");
            for extra in configured.extra_inputs() {
                assert!(earlier(extra), "{} reads {extra}", r.name);
            }
            for p in r.params {
                if let Some(q) = specs.insert(p.name, p) {
                    assert_eq!(
                        (q.kind, q.unit, q.meaning()),
                        (p.kind, p.unit, p.meaning()),
                        "{} declared twice with different meanings",
                        p.name
                    );
                }
            }
            assert!(requests().iter().filter(|d| d.name == r.name).count() == 1);
        }
    }

    /// The AFE's 23 representations, the localisation and its tracking, each with its chunking
    /// contract (spec 00-overview §11; `duet` buffers each ear from its own input, so it
    /// is invariant here) and the ratemap read beside a map's strength when
    /// `trm_minValuedB` is set.
    #[test]
    fn entries_carry_each_requests_chunking_and_inputs() {
        assert_eq!(requests().len(), 25);
        let per_chunk = ["pitch", "onsetMap", "offsetMap", "gabor"];
        for r in requests() {
            let defaults = (r.defaults)();
            let names: Vec<&str> = r.params.iter().map(|p| p.name).collect();
            assert_eq!(defaults.len(), names.len(), "{}", r.name);
            assert!(
                names.iter().all(|n| defaults.contains_key(*n)),
                "{}",
                r.name
            );
            for p in r.params {
                let given = p.normalize(&defaults[p.name]);
                assert!(given.is_ok(), "{}'s default {}: {given:?}", r.name, p.name);
                // an unknown string for a choice is refused with the parameter named and
                // what it accepts listed (`rm_wname = 'kaiser'`)
                if let ParamKind::Choice(accepted) | ParamKind::Choices(accepted) = p.kind {
                    let map = ParamMap::from([(p.name.to_string(), serde_json::json!("kaiser"))]);
                    let e = (r.configure)(&map).map(|_| ()).unwrap_err().to_string();
                    let first = format!(
                        "'{}'",
                        accepted.iter().find(|a| !a.is_empty()).unwrap_or(&"")
                    );
                    assert!(e.contains(p.name) && e.contains(&first), "{}: {e}", p.name);
                }
            }
            let configured = (r.configure)(&defaults).expect("defaults are valid");
            assert_eq!(
                configured.chunk_invariant(),
                !per_chunk.contains(&r.name),
                "{}",
                r.name
            );
            let prefix = configured.one_call_prefix_s();
            assert_eq!(prefix, (r.name == "time").then_some(0.5), "{}", r.name);
            assert!(configured.extra_inputs().is_empty(), "{}", r.name);
        }
        let configure = |name: &str, key: &str, value: serde_json::Value| {
            let map = ParamMap::from([(key.to_string(), value)]);
            (find_request(name).expect("registered").configure)(&map).expect("valid")
        };
        let agc = configure("time", "pp_bNormalizeRMS", serde_json::json!(true));
        assert!(!agc.chunk_invariant());
        let hilbert = configure("innerhaircell", "ihc_method", serde_json::json!("hilbert"));
        assert!(!hilbert.chunk_invariant());
        let floor = configure("onsetMap", "trm_minValuedB", serde_json::json!(-80.0));
        assert_eq!(floor.extra_inputs(), ["ratemap"]);
    }

    /// A registration is checked against the requests known before it: its name, its
    /// dependency, and the meaning of each parameter name it shares with them.
    #[test]
    fn registrations_are_checked_against_the_known_requests() {
        use afe_core::{request_def, ParamKind};
        let refused = |def: &RequestDef| {
            check_registration(def, BUILT_IN)
                .expect_err("refused")
                .to_string()
        };
        let fresh = RequestDef {
            name: "testCue",
            ..request_def::<crate::itd::Itd>()
        };
        assert_eq!(check_registration(&fresh, BUILT_IN), Ok(()));
        assert!(refused(&request_def::<crate::itd::Itd>()).contains("already registered"));
        let input = RequestDef {
            name: "input",
            ..request_def::<crate::itd::Itd>()
        };
        assert!(refused(&input).contains("already registered"));
        let conflicting = RequestDef {
            name: "testCue",
            params: &[ParamSpec {
                name: "rm_wSizeSec",
                kind: ParamKind::Number,
                unit: "ms",
                description: "window length",
            }],
            ..request_def::<crate::itd::Itd>()
        };
        let e = refused(&conflicting);
        assert!(e.contains("'rm_wSizeSec' is declared by 'ratemap'"), "{e}");
    }

    #[test]
    fn unknown_request_lists_the_known_ones() {
        let found = find_request("ratemap").expect("known");
        assert!(format!("{found:?}").contains("\"ratemap\""));
        let e = find_request("ratemapp").unwrap_err().to_string();
        assert!(
            e.contains("'ratemapp'") && e.contains("ratemap, moc, ild"),
            "{e}"
        );
    }
}
