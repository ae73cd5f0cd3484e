//! Parameters are declared once (issue 58): each AFE name appears once in the workspace's
//! code, outside tests and comments; the listing in `docs/parameters.md` is the one the
//! declarations generate; and the declared defaults and units are the spec's.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde_json::Value;

/// The workspace's root (this crate's manifest directory).
fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every `.rs` file under `dir`, but test modules and test helpers.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if p.is_dir() && name != "tests" && name != "target" {
            sources(&p, out);
        } else if name.ends_with(".rs") && name != "tests.rs" && name != "testing.rs" {
            out.push(p);
        }
    }
}

/// `text` without its test module (at the end of a file) and its comment lines.
fn code_of(text: &str) -> String {
    let code = text
        .split("#[cfg(test)]\nmod tests {")
        .next()
        .unwrap_or_default();
    code.lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn every_parameter_is_named_once_in_the_code() {
    let mut files = Vec::new();
    for dir in std::fs::read_dir(root()).expect("workspace").flatten() {
        if dir.path().join("Cargo.toml").is_file() {
            sources(&dir.path().join("src"), &mut files);
        }
    }
    sources(&root().join("cli"), &mut files);
    assert!(files.len() > 50, "only {} sources found", files.len());
    let code: Vec<(PathBuf, String)> = files
        .into_iter()
        .map(|f| {
            let text = std::fs::read_to_string(&f).unwrap_or_default();
            (f, code_of(&text))
        })
        .collect();
    let mut wrong = Vec::new();
    for r in afe::requests() {
        for p in r.params {
            let quoted = format!("\"{}\"", p.name);
            let at: Vec<String> = code
                .iter()
                .flat_map(|(f, c)| {
                    let n = c.matches(&quoted).count();
                    let f = f.strip_prefix(root()).unwrap_or(f).display().to_string();
                    std::iter::repeat_n(f, n)
                })
                .collect();
            if at.len() != 1 && !wrong.iter().any(|(n, _)| n == &p.name) {
                wrong.push((p.name, at));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "parameters named other than once in the code: {wrong:?}"
    );
}

#[test]
fn the_parameter_table_in_docs_is_the_generated_one() {
    let path = root().join("docs/parameters.md");
    let written = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        written == afe::catalog::markdown(),
        "docs/parameters.md is not what the declarations give: run \
         `afe list --markdown > docs/parameters.md`"
    );
}

/// The spec's parameter tables (`| `name` | meaning | unit | default |`), name →
/// (unit, default) as written.
fn spec_rows(dir: &Path) -> BTreeMap<String, (String, String)> {
    let mut rows = BTreeMap::new();
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    files.sort();
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap_or_default();
        let mut header: Vec<String> = Vec::new();
        for line in text.lines().filter(|l| l.starts_with('|')) {
            let cells: Vec<String> = line
                .trim_matches('|')
                .split('|')
                .map(|c| c.trim().to_string())
                .collect();
            if cells.first().is_some_and(|c| c == "name") {
                header = cells;
                continue;
            }
            let col = |name: &str| header.iter().position(|h| h == name);
            let (Some(u), Some(d)) = (col("unit"), col("default")) else {
                continue;
            };
            let name = cells[0].trim_matches('`').to_string();
            if let (Some(unit), Some(default)) = (cells.get(u), cells.get(d)) {
                rows.entry(name).or_insert((unit.clone(), default.clone()));
            }
        }
    }
    rows
}

/// The spec's default as a value: the first word (`'hann'`, `0.020`, `[80 400]`, `[]`,
/// `−180`, `0 (false)`, `1/6`).
fn spec_value(written: &str) -> Value {
    let w = written.replace('−', "-");
    let w = w.trim_matches('`').trim();
    if let Some(rest) = w.strip_prefix('[') {
        let inner = rest.split(']').next().unwrap_or_default();
        return Value::Array(
            inner
                .split_whitespace()
                .filter_map(|x| x.parse::<f64>().ok())
                .map(Value::from)
                .collect(),
        );
    }
    if let Some(rest) = w.strip_prefix('\'') {
        return Value::from(rest.split('\'').next().unwrap_or_default());
    }
    let first = w.split_whitespace().next().unwrap_or_default();
    let number = |x: &str| x.parse::<f64>().ok();
    match first.split_once('/') {
        _ if first == "true" || first == "false" => Value::Bool(first == "true"),
        Some((a, b)) => number(a)
            .zip(number(b))
            .map_or(Value::Null, |(a, b)| Value::from(a / b)),
        None => number(first).map_or(Value::Null, Value::from),
    }
}

/// Whether our default `ours` is the spec's `spec` (a flag is 0 or 1 there, a vector of
/// one a scalar, an empty vector or an absent count `[]`).
fn same_default(ours: &Value, spec: &Value) -> bool {
    let num = |v: &Value| match v {
        Value::Bool(b) => Some(f64::from(u8::from(*b))),
        v => v.as_f64(),
    };
    match (ours, spec) {
        (Value::Array(a), Value::Array(b)) => {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| same_default(x, y))
        }
        (Value::Array(a), s) if a.len() == 1 => same_default(&a[0], s),
        (Value::Array(a), Value::String(s)) => a.is_empty() && s.is_empty(),
        (Value::Null, Value::Array(b)) => b.is_empty(),
        (Value::String(a), Value::String(b)) => a == b,
        (a, b) => match (num(a), num(b)) {
            (Some(x), Some(y)) => (x - y).abs() <= 1e-12 * y.abs().max(1.0),
            _ => false,
        },
    }
}

#[test]
fn declared_defaults_and_units_are_the_specs() {
    let dir = std::env::var_os("AFE_SPEC_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("../shared/spec"));
    if !dir.is_dir() {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI=true but the spec is not at {} (set AFE_SPEC_DIR)",
            dir.display()
        );
        eprintln!("spec not found at {}: skipped", dir.display());
        return;
    }
    let rows = spec_rows(&dir);
    let mut checked = 0;
    let mut wrong = Vec::new();
    for r in afe::requests() {
        let defaults = (r.defaults)();
        for p in r.params {
            let Some((unit, default)) = rows.get(p.name) else {
                continue;
            };
            checked += 1;
            let spec_unit = match unit.as_str() {
                "–" | "-" | "bool" | "cells" => "",
                u => u,
            };
            if spec_unit != p.unit {
                wrong.push(format!("{}: unit '{}', spec '{unit}'", p.name, p.unit));
            }
            let ours = defaults.get(p.name).cloned().unwrap_or(Value::Null);
            if !same_default(&ours, &spec_value(default)) {
                wrong.push(format!("{}: default {ours}, spec {default}", p.name));
            }
        }
    }
    assert!(checked >= 60, "only {checked} parameters found in the spec");
    assert!(
        wrong.is_empty(),
        "declarations that differ from the spec: {wrong:#?}"
    );
}
