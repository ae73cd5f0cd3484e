//! `afe list`: every request with its defaults, one request's chain or one parameter, as
//! text or JSON.

use crate::common;

use common::{afe, assert_clear_error, tmp};

use super::with_stdout_closed;

#[test]
fn list_json_names_every_request_with_defaults() {
    let out = afe(&["list", "--json"]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let ratemap = v
        .as_array()
        .expect("array")
        .iter()
        .find(|r| r["name"] == "ratemap")
        .expect("ratemap listed");
    let w = ratemap["parameters"]
        .as_array()
        .expect("params")
        .iter()
        .find(|p| p["name"] == "rm_wSizeSec")
        .expect("rm_wSizeSec");
    assert_eq!(w["default"], 0.02);
    assert_eq!(w["unit"], "s");
    assert_eq!(
        ratemap["chain"],
        serde_json::json!(["ratemap", "innerhaircell", "filterbank", "time"])
    );
    let text = afe(&["list"]);
    assert!(String::from_utf8_lossy(&text.stdout).contains("fb_nChannels"));
}

#[test]
fn list_one_request_or_one_parameter() {
    // a request: its chain, request first, as the AFE's parameterHelper
    let out = afe(&["list", "ild", "--json"]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let names: Vec<&str> = v
        .as_array()
        .expect("array")
        .iter()
        .filter_map(|e| e["name"].as_str())
        .collect();
    assert_eq!(names, ["ild", "innerhaircell", "filterbank", "time"]);
    let text = String::from_utf8_lossy(&afe(&["list", "ild"]).stdout).into_owned();
    assert!(
        text.starts_with("ild  (binaural")
            && text.contains("ihc_method")
            && !text.contains("rm_wSizeSec")
    );
    // a parameter: where it belongs and what it takes
    let one: serde_json::Value =
        serde_json::from_slice(&afe(&["list", "rm_wSizeSec", "--json"]).stdout).expect("json");
    assert_eq!(
        (
            one["processor"].as_str(),
            one["default"].as_f64(),
            one["unit"].as_str()
        ),
        (Some("ratemap"), Some(0.02), Some("s"))
    );
    assert_clear_error(
        &afe(&["list", "rm_wsize"]),
        "'rm_wsize' is neither a request nor a parameter",
        &tmp("none"),
    );
    // a reader that goes away (`afe list | head -1`) ends the listing quietly
    let stderr = with_stdout_closed(&["list"]);
    assert!(!stderr.contains("panicked"), "{stderr}");
}
