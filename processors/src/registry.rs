//! The registry: every request this build computes, as a list of the descriptors that
//! the processor modules declare (each module implements [`afe_core::Descriptor`] for
//! its processor and exports the type-erased [`RequestDef`] the graph works with as
//! `REQUEST`, or one per request where a module serves two, e.g. `ONSET_REQUEST` and
//! `OFFSET_REQUEST`).

use afe_core::{Error, RequestDef, Result};

use crate::{
    adaptation, ams_features, autocorrelation, butterworth, crosscorrelation, duet, filterbank,
    gabor, ic, ihc, ild, itd, moc, pitch, pre_proc, precedence, ratemap, spectral_features, stft,
    transient, transient_map,
};

/// Every request, in dependency order: one line per processor module.
static REQUESTS: &[&RequestDef] = &[
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
];

/// Every request this build knows, in dependency order.
pub fn requests() -> &'static [&'static RequestDef] {
    REQUESTS
}

/// The definition of request `name`, or an error listing the known names.
pub fn find_request(name: &str) -> Result<&'static RequestDef> {
    REQUESTS
        .iter()
        .find(|r| r.name == name)
        .copied()
        .ok_or_else(|| Error::UnknownRequest {
            name: name.to_string(),
            known: REQUESTS
                .iter()
                .map(|r| r.name)
                .collect::<Vec<_>>()
                .join(", "),
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use afe_core::{ParamMap, ParamSpec};

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
                        (q.kind, q.unit, q.description),
                        (p.kind, p.unit, p.description),
                        "{} declared twice with different meanings",
                        p.name
                    );
                }
            }
            assert!(requests().iter().filter(|d| d.name == r.name).count() == 1);
        }
    }

    /// The AFE's 23 representations, each with its chunking contract (spec 00-overview
    /// §11; `duet` buffers each ear from its own input, so it is invariant here) and the
    /// ratemap read beside a map's strength when `trm_minValuedB` is set.
    #[test]
    fn entries_carry_each_requests_chunking_and_inputs() {
        assert_eq!(requests().len(), 23);
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
