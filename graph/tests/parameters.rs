//! A request's parameters are parsed once and a value that fails to parse is reported,
//! whichever processor of the chain reads it.

use afe_core::{Error, ParamMap};
use afe_graph::Manager;
use serde_json::json;

/// The pre-processing reads `fb_type` (a DRNL chain turns its unity compensation off),
/// also in chains without a filterbank. A mistyped class there was taken for the default
/// gammatone and the request placed; now it is refused, naming the parameter and the
/// accepted values.
#[test]
fn a_mistyped_filterbank_class_is_reported_in_a_chain_without_a_filterbank() {
    let mistyped = ParamMap::from([("fb_type".to_string(), json!("dnrl"))]);
    for request in ["time", "stft", "ratemap"] {
        let mut m = Manager::new(16000.0, 2).expect("manager");
        let e = m
            .add_request(request, &mistyped)
            .expect_err("an unknown filterbank class");
        assert!(
            matches!(&e, Error::InvalidParameter { name, .. } if name == "fb_type"),
            "{request}: {e}"
        );
        assert!(
            e.to_string().contains("'gammatone', 'drnl'"),
            "{request}: {e}"
        );
        assert!(m.signals(true).is_empty(), "{request}: nothing placed");
    }
    let mut m = Manager::new(16000.0, 2).expect("manager");
    let drnl = ParamMap::from([("fb_type".to_string(), json!("drnl"))]);
    m.add_request("time", &drnl).expect("a known class");
}
