//! The random draws the targets share: JSON and parameter values, parameter maps for a
//! request, signals and sampling rates.

use afe::ParamMap;
use afe_core::ParamKind;
use serde_json::{json, Value};

use super::Rng;

/// Any JSON value, nested up to `depth`.
fn random_json(rng: &mut Rng, depth: usize) -> Value {
    match rng.below(if depth == 0 { 5 } else { 7 }) {
        0 => Value::Null,
        1 => Value::Bool(rng.one_in(2)),
        2 => random_number(rng),
        3 => json!(*rng.pick(&[
            "", "n-a", "NaN", "Infinity", "-inf", "1e999", "0x10", "hann", "dB", "none",
            "halfwave", "\u{0}", "ratemap", "🎧", "   ", "[]"
        ])),
        4 => json!((0..rng.below(12))
            .map(|_| char::from(32 + rng.below(95) as u8))
            .collect::<String>()),
        5 => Value::Array(
            (0..rng.below(6))
                .map(|_| random_json(rng, depth - 1))
                .collect(),
        ),
        _ => Value::Object(
            (0..rng.below(4))
                .map(|_| (format!("k{}", rng.below(4)), random_json(rng, depth - 1)))
                .collect(),
        ),
    }
}

/// A number that tests limits: zero, signs, huge, tiny, integers at type limits.
fn random_number(rng: &mut Rng) -> Value {
    match rng.below(6) {
        0 => json!(*rng.pick(&[
            0.0,
            -0.0,
            1e308,
            -1e308,
            5e-324,
            f64::MAX,
            f64::MIN_POSITIVE,
            1e-300
        ])),
        1 => json!(*rng.pick(&[
            i64::MIN,
            i64::MAX,
            -1,
            0,
            1,
            2,
            3,
            1023,
            1024,
            1025,
            65536,
            4_294_967_296
        ])),
        2 => json!(u64::MAX),
        3 => json!((rng.unit() - 0.5) * 10f64.powi(rng.below(40) as i32 - 12)),
        4 => json!(rng.below(100)),
        _ => json!(rng.unit()),
    }
}

/// The numbers of a parameter's default: a vector's, a scalar as one, none without one.
pub(super) fn default_numbers(default: Option<&Value>) -> Vec<f64> {
    match default {
        Some(Value::Array(a)) => a.iter().filter_map(Value::as_f64).collect(),
        Some(v) => v.as_f64().into_iter().collect(),
        None => Vec::new(),
    }
}

/// A value aimed at a parameter of kind `kind` whose default is `default`: often valid or
/// near it, sometimes out of range, sometimes of another type.
fn value_for(rng: &mut Rng, kind: ParamKind, default: Option<&Value>) -> Value {
    if rng.one_in(5) {
        return random_json(rng, 2);
    }
    let scale = |rng: &mut Rng, x: f64| {
        x * *rng.pick(&[
            0.0, -1.0, 0.5, 0.9, 1.0, 1.1, 2.0, 10.0, 1e3, 1e6, 1e-6, 1e12,
        ])
    };
    match kind {
        ParamKind::Number => match default.and_then(Value::as_f64) {
            Some(x) if !rng.one_in(4) => json!(scale(rng, if x == 0.0 { 1.0 } else { x })),
            _ => random_number(rng),
        },
        ParamKind::Count | ParamKind::CountUpTo(_) => json!(*rng.pick(&[
            0.0,
            1.0,
            2.0,
            3.0,
            4.0,
            7.0,
            16.0,
            64.0,
            512.0,
            1024.0,
            1025.0,
            1e6,
            4294967295.0,
            -1.0,
            2.5
        ])),
        ParamKind::Flag => rng
            .pick(&[
                json!(true),
                json!(false),
                json!(0),
                json!(1),
                json!(2),
                json!("true"),
            ])
            .clone(),
        ParamKind::Choice(choices) => match rng.below(5) {
            0 => random_json(rng, 0),
            _ => json!(*rng.pick(choices)),
        },
        ParamKind::Choices(choices) => match rng.below(4) {
            0 => json!(*rng.pick(choices)),
            1 => random_json(rng, 1),
            _ => json!((0..rng.below(5))
                .map(|_| *rng.pick(choices))
                .collect::<Vec<_>>()),
        },
        ParamKind::Text => match rng.below(4) {
            0 => random_json(rng, 0),
            _ => json!(*rng.pick(&["sphere", "sphere:radius=0.09,ears=100", "", "dummy"])),
        },
        ParamKind::Numbers => {
            let base = default_numbers(default);
            match rng.below(4) {
                0 if !base.is_empty() => {
                    json!(base.iter().map(|x| scale(rng, *x)).collect::<Vec<_>>())
                }
                1 => random_number(rng),
                _ => {
                    let n = *rng.pick(&[0, 1, 2, 3, 5, 8, 40, 2000]);
                    let mut v: Vec<f64> = (0..n).map(|_| rng.unit() * 8000.0).collect();
                    if rng.one_in(2) {
                        v.sort_by(f64::total_cmp);
                    }
                    json!(v)
                }
            }
        }
    }
}

/// A parameter name a user could type: a real one with a typo or another case, or junk.
pub(super) fn junk_name(rng: &mut Rng, real: &str) -> String {
    let mut s: Vec<char> = real.chars().collect();
    match rng.below(4) {
        0 if !s.is_empty() => {
            s.remove(rng.below(s.len()));
        }
        1 => s = s.iter().flat_map(|c| c.to_uppercase()).collect(),
        2 => s.push(char::from(b'a' + rng.below(26) as u8)),
        _ => {
            return (0..rng.below(20))
                .map(|_| char::from(32 + rng.below(95) as u8))
                .collect()
        }
    }
    s.into_iter().collect()
}

/// Random request parameters for request `name`: mostly names of its own chain, some of
/// other processors, some junk; values from [`value_for`].
pub(super) fn random_params(rng: &mut Rng, name: &str, entries: usize) -> ParamMap {
    let own: Vec<&'static afe::RequestDef> = afe::catalog::chain(name)
        .iter()
        .filter_map(|n| afe::find_request(n).ok())
        .collect();
    let all = afe::requests();
    let mut map = ParamMap::new();
    for _ in 0..entries {
        let def = if own.is_empty() || rng.one_in(4) {
            *rng.pick(all)
        } else {
            *rng.pick(&own)
        };
        if def.params.is_empty() {
            continue;
        }
        let spec = rng.pick(def.params);
        let defaults = (def.defaults)();
        let key = if rng.one_in(12) {
            junk_name(rng, spec.name)
        } else {
            spec.name.to_string()
        };
        let mut value = value_for(rng, spec.kind, defaults.get(spec.name));
        if spec.unit == "s" {
            value = shorter(value);
        }
        map.insert(key, value);
    }
    map
}

/// Longest duration drawn in the range the processors accept, in s. A window is valid up
/// to 2^24 values over all channels, and the processors hold several times that (per
/// window value: 8 bytes in the ratemap, 40 in the cross-correlation, 100 in the
/// precedence processor): what the user asked for, not a fault, so such windows are not
/// drawn; durations past the accepted range (≥ 1e4 s) are, to test their refusal.
const LONGEST_DRAWN_S: f64 = 0.05;

/// `value` with durations between [`LONGEST_DRAWN_S`] and 1e4 s folded below it.
fn shorter(value: Value) -> Value {
    match value {
        Value::Number(_) => match value.as_f64() {
            Some(x) if x.abs() > LONGEST_DRAWN_S && x.abs() < 1e4 => json!(x % LONGEST_DRAWN_S),
            _ => value,
        },
        Value::Array(items) => Value::Array(items.into_iter().map(shorter).collect()),
        _ => value,
    }
}

/// A random signal of `len` samples: noise, a tone, silence, clicks, or loud noise.
pub(super) fn random_signal(rng: &mut Rng, len: usize) -> Vec<f64> {
    let kind = rng.below(6);
    let f = rng.unit() * 0.5;
    let gain = *rng.pick(&[1.0, 0.01, 1e-12, 1e6, 1e90]);
    (0..len)
        .map(|t| {
            gain * match kind {
                0 => 0.0,
                1 => (2.0 * std::f64::consts::PI * f * t as f64).sin(),
                2 => f64::from(u8::from(rng.one_in(200))),
                _ => rng.unit() * 2.0 - 1.0,
            }
        })
        .collect()
}

/// A sampling rate: mostly usual ones, some random, some invalid.
pub(super) fn random_fs(rng: &mut Rng) -> f64 {
    match rng.below(10) {
        0 => *rng.pick(&[
            0.0,
            -44100.0,
            f64::NAN,
            f64::INFINITY,
            1e-3,
            1.0,
            2.0,
            7.0,
            50.0,
            100.0,
            300.0,
            1000.0,
            999_999.0,
            1e6,
            1e7,
        ]),
        1 => 1000.0 + rng.unit() * 200_000.0,
        _ => *rng.pick(&[8000.0, 16000.0, 22050.0, 44100.0, 48000.0, 96000.0]),
    }
}
