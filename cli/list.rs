//! `afe list`: the requests with their parameters, or one request's chain, or one
//! parameter.

use serde_json::{json, Value};

use crate::error::CliError;
use crate::out;

/// `afe list [NAME] [--json]`.
#[derive(clap::Args)]
pub(crate) struct ListArgs {
    /// A request (its whole processing chain, as the AFE's parameterHelper shows
    /// it) or one parameter (its processor, type, accepted values, default, unit).
    name: Option<String>,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
    /// Print every request's parameters as the Markdown tables of docs/parameters.md.
    #[arg(long, conflicts_with_all = ["name", "json"])]
    markdown: bool,
}

impl ListArgs {
    pub(crate) fn run(self) -> Result<(), CliError> {
        if self.markdown {
            out(&afe::catalog::markdown());
            return Ok(());
        }
        list(self.name.as_deref(), self.json)
    }
}

fn list(name: Option<&str>, as_json: bool) -> Result<(), CliError> {
    let listing = afe::catalog::listing();
    let mut text = String::new();
    let mut entries = listing.as_array().cloned().unwrap_or_default();
    if let Some(name) = name {
        let by_name = |n: &str| entries.iter().find(|e| e["name"] == n).cloned();
        if let Some(request) = by_name(name) {
            // the request's chain, from the request down to the time-domain input
            entries = request["chain"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|n| n.as_str().and_then(by_name))
                .collect();
        } else {
            let found = entries.iter().find_map(|e| {
                e["parameters"]
                    .as_array()?
                    .iter()
                    .find(|p| p["name"] == name)
                    .map(|p| (e["name"].clone(), p.clone()))
            });
            let Some((processor, mut p)) = found else {
                return Err(format!(
                    "'{name}' is neither a request nor a parameter: `afe list` shows them all"
                )
                .into());
            };
            p["processor"] = processor;
            if as_json {
                out(&format!("{p}\n"));
            } else {
                for key in [
                    "name",
                    "processor",
                    "type",
                    "accepts",
                    "default",
                    "unit",
                    "description",
                ] {
                    let v = match &p[key] {
                        Value::String(s) => s.clone(),
                        Value::Null => "[]".into(),
                        v => v.to_string(),
                    };
                    text.push_str(&format!("{key:<12} {v}\n"));
                }
            }
            out(&text);
            return Ok(());
        }
    }
    if as_json {
        out(&format!("{}\n", Value::Array(entries)));
        return Ok(());
    }
    for e in &entries {
        text.push_str(&format!(
            "{}  ({}; from {})\n    {}\n",
            e["name"].as_str().unwrap_or_default(),
            if e["binaural"] == json!(true) {
                "binaural"
            } else {
                "per ear"
            },
            e["depends_on"].as_str().unwrap_or_default(),
            e["description"].as_str().unwrap_or_default()
        ));
        for p in e["parameters"].as_array().into_iter().flatten() {
            let default = match &p["default"] {
                Value::Null => "[]".to_string(),
                v => v.to_string(),
            };
            let unit = p["unit"].as_str().unwrap_or_default();
            text.push_str(&format!(
                "    {:<24} {:<10} {:<7} {}\n",
                p["name"].as_str().unwrap_or_default(),
                default,
                if unit.is_empty() { "-" } else { unit },
                p["description"].as_str().unwrap_or_default()
            ));
        }
        text.push('\n');
    }
    out(&text);
    Ok(())
}
