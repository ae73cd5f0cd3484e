//! Target 4: every request with parameters drawn over the ranges its parser accepts, the
//! extremes included (issue 44): refused when placed, or finite output within the case's
//! time and the process's heap limit.

use afe::{Manager, ParamMap};
use afe_core::ParamKind;
use serde_json::{json, Value};

use super::draws::default_numbers;
use super::{check_error, count, fuzz, note, Rng};

/// Whether the parser of `def` accepts `params` (with the value under test in it).
fn parses(def: &afe::RequestDef, params: &ParamMap) -> bool {
    (def.configure)(params).is_ok()
}

/// `x` moved by bisection in log space towards the farthest value on its side (`up`:
/// larger, else closer to zero) that the parser of `def` still accepts for `name`.
fn extreme(def: &afe::RequestDef, params: &ParamMap, name: &str, x: f64, up: bool) -> f64 {
    let with = |v: f64| {
        let mut p = params.clone();
        p.insert(name.to_string(), json!(v));
        parses(def, &p)
    };
    let far = if up { x * 1e12 } else { x * 1e-12 };
    if with(far) {
        return far;
    }
    let (mut good, mut bad) = (x, far);
    for _ in 0..40 {
        let mid = (good.abs().ln() * 0.5 + bad.abs().ln() * 0.5).exp() * x.signum();
        if with(mid) {
            good = mid;
        } else {
            bad = mid;
        }
    }
    good
}

/// A value of `spec` drawn over what its parser may accept: numbers across twelve orders
/// of magnitude around the default, counts up to the channel limit, every choice.
fn accepted_draw(rng: &mut Rng, spec: &afe_core::ParamSpec, default: Option<&Value>) -> Value {
    let magnitude = |rng: &mut Rng, x: f64| x * 10f64.powf(rng.unit() * 12.0 - 6.0);
    match spec.kind {
        ParamKind::Number => {
            let x = default
                .and_then(Value::as_f64)
                .filter(|x| *x != 0.0)
                .unwrap_or(1.0);
            json!(match rng.below(6) {
                0 => 0.0,
                1 => -magnitude(rng, x),
                _ => magnitude(rng, x),
            })
        }
        ParamKind::Count | ParamKind::CountUpTo(_) => json!(match rng.below(4) {
            0 => 1 + rng.below(4),
            1 => *rng.pick(&[256, 512, 1000, 1024, 4096, 65_536]),
            _ => 1 + rng.below(128),
        }),
        ParamKind::Flag => json!(rng.one_in(2)),
        ParamKind::Choice(choices) => json!(*rng.pick(choices)),
        ParamKind::Choices(choices) => json!((0..1 + rng.below(choices.len()))
            .map(|_| *rng.pick(choices))
            .collect::<Vec<_>>()),
        ParamKind::Text => json!(*rng.pick(&["sphere", "sphere:radius=0.0875"])),
        ParamKind::Numbers => {
            let base = default_numbers(default);
            if base.is_empty() || rng.one_in(3) {
                let n = 1 + rng.below(40);
                let mut v: Vec<f64> = (0..n).map(|_| rng.unit() * 8000.0).collect();
                v.sort_by(f64::total_cmp);
                json!(v)
            } else {
                let k = 10f64.powf(rng.unit() * 4.0 - 2.0);
                json!(base.iter().map(|x| x * k).collect::<Vec<_>>())
            }
        }
    }
}

/// Parameters for the chain of `request`: each parameter with probability 1/3, drawn by
/// [`accepted_draw`] until its processor's parser accepts it (else left out), and a
/// quarter of the numbers then pushed to the largest or smallest value accepted.
fn accepted_params(rng: &mut Rng, request: &str) -> ParamMap {
    let mut params = ParamMap::new();
    for def in afe::catalog::chain(request)
        .iter()
        .filter_map(|n| afe::find_request(n).ok())
    {
        let defaults = (def.defaults)();
        for spec in def.params {
            if !rng.one_in(3) {
                continue;
            }
            for _ in 0..8 {
                let mut trial = params.clone();
                let value = accepted_draw(rng, spec, defaults.get(spec.name));
                trial.insert(spec.name.to_string(), value.clone());
                if !parses(def, &trial) {
                    continue;
                }
                let pushed = match value.as_f64() {
                    Some(x) if x != 0.0 && spec.kind == ParamKind::Number && rng.one_in(4) => {
                        json!(extreme(def, &params, spec.name, x, rng.one_in(2)))
                    }
                    _ => value,
                };
                params.insert(spec.name.to_string(), pushed);
                break;
            }
        }
    }
    params
}

/// Most values the processors of a case's chain may write over its input (2^23, 64 MiB
/// of f64): an autocorrelation with a hop of 2 samples writes 60 million over 0.2 s of
/// audio, seconds of work (10.7 s on a loaded CI host) that test no more than the first
/// tenth of it.
const VALUE_BUDGET: f64 = (1u64 << 23) as f64;

/// Frames of its slowest output a case gets, whatever [`VALUE_BUDGET`] allows.
const FEWEST_FRAMES: f64 = 4.0;

/// The longest input in samples that keeps the chain of `name` within [`VALUE_BUDGET`]
/// (every output of every processor in it at its own rate, read from a second manager
/// that requests each of them) yet gives its slowest output [`FEWEST_FRAMES`].
fn longest_input(name: &str, fs: f64, ears: usize, params: &ParamMap) -> Result<usize, String> {
    let mut probe = Manager::with_threads(fs, ears, 0).map_err(|e| e.to_string())?;
    let links = afe::catalog::chain(name);
    for link in links.into_iter().filter(|n| afe::find_request(n).is_ok()) {
        probe
            .add_request(link, params)
            .map_err(|e| format!("{link} of the chain of {name}: {e}"))?;
    }
    let signals = probe.signals(false);
    let per_sample: f64 = (signals.iter())
        .map(|s| s.info.fs_hz / fs * s.info.width() as f64)
        .sum();
    let slowest = (signals.iter()).fold(fs, |r, s| r.min(s.info.fs_hz));
    Ok((VALUE_BUDGET / per_sample).max(FEWEST_FRAMES * fs / slowest) as usize)
}

/// Checks that every requested output shown holds finite values, from an input that is
/// not silent: NaN only in the representations whose description says where the AFE
/// gives it (`nan_where`: an unvoiced pitch frame, an autocorrelation frame of zeros, the
/// logarithms of a signed ratemap, ...), and ±Inf only in the Gabor features of a chunk
/// whose features do not vary.
fn check_finite(mgr: &Manager) -> Result<(), String> {
    for s in mgr.signals(false) {
        let nan_allowed = s.info.nan_where.is_some();
        let inf_allowed = s.name == "gabor";
        let wrong = |v: &f64| {
            !(v.is_finite() || (nan_allowed && v.is_nan()) || (inf_allowed && v.is_infinite()))
        };
        if let Some(i) = s.new.as_slice().iter().position(wrong) {
            return Err(format!(
                "{}: value {i} is {} from a finite, audible input",
                s.key(),
                s.new.as_slice()[i]
            ));
        }
    }
    Ok(())
}

#[test]
fn accepted_ranges() {
    let names: Vec<&str> = afe::requests().iter().map(|r| r.name).collect();
    fuzz("accepted_ranges", |rng, _| {
        let name = *rng.pick(&names);
        let fs = *rng.pick(&[16000.0, 22050.0, 44100.0, 48000.0]);
        let binaural = afe::catalog::chain(name)
            .iter()
            .filter_map(|n| afe::find_request(n).ok())
            .any(|d| d.ears == afe_core::Ears::Binaural);
        let ears = if binaural { 2 } else { 1 + rng.below(2) };
        let params = accepted_params(rng, name);
        note(|| format!("add_request({name:?}, {}) at {fs} Hz", json!(params)));
        let mut mgr = Manager::with_threads(fs, ears, 0).map_err(|e| e.to_string())?;
        if let Err(e) = mgr.add_request(name, &params) {
            count("refused when placed");
            return check_error(&e);
        }
        // a quarter of a second at most (at the output limit, 0.5 GB of blocks in one
        // chunk), within the value budget: noise or a tone, at full scale or 40 dB below
        let len = 1 + rng.below(fs as usize / 4);
        let len = len.min(longest_input(name, fs, ears, &params)?.max(1));
        let gain = *rng.pick(&[1.0, 0.01]);
        let f = 0.001 + rng.unit() * 0.2;
        let x: Vec<f64> = (0..len)
            .map(|t| {
                gain * if rng.one_in(2) {
                    rng.unit() * 2.0 - 1.0
                } else {
                    (2.0 * std::f64::consts::PI * f * t as f64).sin()
                }
            })
            .collect();
        let chunk = 1 + rng.below(len);
        note(|| format!("{len} samples in chunks of {chunk}"));
        for part in x.chunks(chunk) {
            let ears: Vec<&[f64]> = vec![part; ears];
            if let Err(e) = mgr.process_chunk(&ears) {
                count("refused when processing");
                return check_error(&e);
            }
            check_finite(&mgr)?;
        }
        count("computed, finite");
        Ok(())
    });
}
