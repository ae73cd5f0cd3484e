//! The catalogue of requests and parameters, as `afe list --json` and Python's
//! `afe.parameters()` present it.

use afe_processors::{find_request, requests, Ears};
use serde_json::{json, Value};

/// The chain of request names from `name` down to `time` (empty if unknown).
pub fn chain(name: &str) -> Vec<&'static str> {
    let mut out = Vec::new();
    let mut cur = find_request(name).ok();
    while let Some(def) = cur {
        out.push(def.name);
        cur = find_request(def.dependency).ok();
    }
    out
}

/// Every request with its dependency chain, ear handling, meaning, output unit and
/// parameters (name, type, accepted values, default, unit, meaning).
///
/// ```
/// let list = afe::catalog::listing();
/// let ild = list.as_array().unwrap().iter().find(|r| r["name"] == "ild").unwrap();
/// assert_eq!(ild["binaural"], true);
/// assert_eq!(ild["parameters"][0]["name"], "ild_wname");
/// assert_eq!(ild["parameters"][0]["default"], "hann");
/// ```
pub fn listing() -> Value {
    let entries: Vec<Value> = requests()
        .iter()
        .map(|r| {
            let defaults = (r.defaults)();
            let params: Vec<Value> = r
                .params
                .iter()
                .map(|p| {
                    json!({
                        "name": p.name,
                        "type": p.kind.type_name(),
                        "accepts": p.kind.describe(),
                        "default": defaults.get(p.name).cloned().unwrap_or(Value::Null),
                        "unit": p.unit,
                        "description": p.description,
                    })
                })
                .collect();
            json!({
                "name": r.name,
                "depends_on": r.dependency,
                "chain": chain(r.name),
                "binaural": r.ears == Ears::Binaural,
                "description": r.description,
                "unit": r.output_unit,
                "parameters": params,
            })
        })
        .collect();
    Value::Array(entries)
}
