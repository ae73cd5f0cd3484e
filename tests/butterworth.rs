//! The Butterworth design against an independent one: scipy.signal.butter / freqz as
//! transfer functions (fixture `data/butterworth_scipy.json`, made by
//! `tools/make_butter_fixture.py`) and as second-order sections over every type, order
//! and band the parameters allow (`data/butterworth_scipy_sos.json`, made by
//! `tools/make_butter_sos_fixture.py`).

use afe::{Manager, ParamMap};
use afe_core::Params;
use afe_processors::butterworth::ButterworthParams;
use serde_json::{json, Value};

fn fixture() -> Vec<Value> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/butterworth_scipy.json");
    let v: Value =
        serde_json::from_str(&std::fs::read_to_string(path).expect("fixture")).expect("json");
    v["cases"].as_array().expect("cases").clone()
}

fn numbers(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

fn params_of(case: &Value) -> ParamMap {
    ["bw_type", "bw_order", "bw_cutoffHz"]
        .iter()
        .map(|k| (k.to_string(), case[*k].clone()))
        .collect()
}

/// |H(e^{iw})| at `f` Hz from the coefficients, and the condition number of that
/// evaluation (Σ|c| / |C(e^{iw})| summed over numerator and denominator): a relative
/// coefficient change ε moves |H| by up to about ε·condition.
fn magnitude(b: &[f64], a: &[f64], f: f64, fs: f64) -> (f64, f64) {
    let w = 2.0 * std::f64::consts::PI * f / fs;
    let eval = |c: &[f64]| {
        let (mut re, mut im) = (0.0, 0.0);
        for (k, v) in c.iter().enumerate() {
            re += v * (w * k as f64).cos();
            im -= v * (w * k as f64).sin();
        }
        let value = (re * re + im * im).sqrt();
        (value, c.iter().map(|v| v.abs()).sum::<f64>() / value)
    };
    let ((nb, cb), (na, ca)) = (eval(b), eval(a));
    (nb / na, cb + ca)
}

#[test]
fn coefficients_and_responses_match_scipy() {
    for case in fixture() {
        let p = ButterworthParams::from_map(&params_of(&case)).expect("valid params");
        let fs = case["fs"].as_f64().expect("fs");
        let (b, a) = p.design(fs).expect("design");
        let (sb, sa) = (numbers(&case["b"]), numbers(&case["a"]));
        assert_eq!((b.len(), a.len()), (sb.len(), sa.len()), "{case}");
        let scale_a = sa.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let scale_b = sb.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (x, y) in a.iter().zip(&sa) {
            assert!((x - y).abs() <= 1e-13 * scale_a, "a: {x} vs {y} in {case}");
        }
        for (x, y) in b.iter().zip(&sb) {
            assert!((x - y).abs() <= 1e-13 * scale_b, "b: {x} vs {y} in {case}");
        }
        // Responses, within what the coefficient agreement allows at each frequency: the
        // coefficients agree to about 1e-16 relative (measured), so with a tenfold margin
        // the response may move by 1e-15·condition (at most 4e-3 relative, for the 20 Hz
        // high-pass at 10 Hz, whose transfer-function form has a condition of 4e12).
        for (f, want) in numbers(&case["response_hz"])
            .iter()
            .zip(numbers(&case["response_mag"]))
        {
            let (got, condition) = magnitude(&b, &a, *f, fs);
            let tol = 1e-12 + 1e-15 * condition;
            assert!(
                (got - want).abs() <= tol * want.max(1e-6),
                "|H({f} Hz)| {got} vs {want} (tol {tol:e}) in {case}"
            );
        }
    }
}

#[test]
fn butterworth_request_filters_each_ear() {
    let fs = 16000.0;
    let tone = |f: f64| -> Vec<f64> {
        (0..16000)
            .map(|t| (2.0 * std::f64::consts::PI * f * t as f64 / fs).sin())
            .collect()
    };
    let (low, high) = (tone(200.0), tone(5000.0));
    let mut mgr = Manager::new(fs, 2).expect("manager");
    let p: ParamMap = [
        ("bw_type", json!("low")),
        ("bw_order", json!(4)),
        ("bw_cutoffHz", json!(1000)),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    let h = mgr.add_request("butterworth", &p).expect("request");
    mgr.process_signal(&[&low, &high]).expect("process");
    let out = mgr.request_signals(h).expect("signals");
    let peak = |s: &[f64]| s[8000..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert_eq!(out[0].key(), "butterworth_left");
    assert!(
        (peak(out[0].new.as_slice()) - 1.0).abs() < 0.01,
        "200 Hz passes"
    );
    assert!(
        peak(out[1].new.as_slice()) < 1e-3,
        "5 kHz is stopped by 4th order at 1 kHz"
    );
}

/// Issue 13, item 3: designs whose transfer function is unstable in double precision
/// (the default order as a 100–200 Hz band, a 45–55 Hz band stop, an order-8 100 Hz
/// low-pass) run as second-order sections and stay bounded by their unit gain.
#[test]
fn narrow_and_high_order_designs_stay_bounded() {
    let fs = 44100.0;
    let mut seed = 1u64;
    let mut noise = || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let x: Vec<f64> = (0..88200).map(|_| noise()).collect();
    for (kind, order, cutoff) in [
        ("bandpass", 4, json!([100, 200])),
        ("stop", 4, json!([45, 55])),
        ("low", 8, json!(100)),
    ] {
        let p: ParamMap = [
            ("bw_type", json!(kind)),
            ("bw_order", json!(order)),
            ("bw_cutoffHz", cutoff),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        let mut mgr = Manager::new(fs, 1).expect("manager");
        let h = mgr.add_request("butterworth", &p).expect("request");
        mgr.process_signal(&[&x]).expect("process");
        let out = mgr.request_signals(h).expect("signals");
        let peak = out[0]
            .new
            .as_slice()
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        // white noise of peak 1 through a unit-gain band: well below 2, never 1e8
        assert!(peak.is_finite() && peak < 2.0, "{kind}: peak {peak}");
        assert!(peak > 1e-3, "{kind}: something passes");
    }
}

fn sos_fixture() -> Vec<Value> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/data/butterworth_scipy_sos.json"
    );
    let v: Value =
        serde_json::from_str(&std::fs::read_to_string(path).expect("fixture")).expect("json");
    v["cases"].as_array().expect("cases").clone()
}

/// |H(e^{iw})| at `f` Hz of a cascade of second-order sections.
fn sos_magnitude(sections: &[([f64; 3], [f64; 3])], f: f64, fs: f64) -> f64 {
    sections
        .iter()
        .map(|(b, a)| magnitude(b, a, f, fs).0)
        .product()
}

/// The `butterworth` request's output for one ear's input `x` at `fs` Hz.
fn run_request(case: &Value, fs: f64, x: &[f64]) -> Vec<f64> {
    let mut mgr = Manager::new(fs, 1).expect("manager");
    let h = mgr
        .add_request("butterworth", &params_of(case))
        .expect("request");
    mgr.process_signal(&[x]).expect("process");
    mgr.request_signals(h).expect("signals")[0]
        .new
        .as_slice()
        .to_vec()
}

/// Issue 44, item 3: every design the parameters allow, as sections, against scipy's
/// `butter(..., output='sos')` (fixture `data/butterworth_scipy_sos.json`, made by
/// `tools/make_butter_sos_fixture.py`): 292 designs of every type, orders 1 to 32 (the
/// accepted maximum), cut-offs from 1 Hz to 1 Hz below Nyquist, band-passes and
/// band-stops as wide as [1, 22049] Hz at 44.1 kHz and as narrow as 1 Hz.
///
/// * The magnitude of afe's sections agrees with scipy's at 30 to 36 frequencies per
///   design to 1e-6 relative (to 1e-12 absolute where scipy's value is below 1e-6,
///   deep in the stop band; the peak gain is 1): both designs compute the poles by the same
///   formulas, which lose up to 1e-8 of the smallest poles of the widest bands (the
///   band-pass transform's cancellation) and up to 5e-7 of the response near them.
/// * The request's impulse response (the sections as run) agrees with scipy's
///   `sosfilt` over its first 64 samples to 1e-6 of its peak.
/// * Half a second of white noise of peak 1 gives a finite output of peak below 4
///   through every design (the wide band-passes peaked at 2.4e4 to 1.2e92).
/// * The designs refused are band-stops whose sections would amplify their round-off
///   beyond the bound (scipy's sections give 2 % to 1e42 errors on them), refused
///   naming `bw_order`; at least 200 designs are compared.
#[test]
fn every_design_matches_scipy_sections_and_stays_bounded() {
    let cases = sos_fixture();
    assert!(cases.len() >= 200, "{} designs", cases.len());
    let mut seed = 7u64;
    let mut noise = || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let x: Vec<f64> = (0..22050).map(|_| noise()).collect();
    let mut worst = (0.0f64, 0.0f64);
    let mut refused = Vec::new();
    for case in &cases {
        let p = ButterworthParams::from_map(&params_of(case)).expect("valid params");
        let fs = case["fs"].as_f64().expect("fs");
        let sections = match p.sections(fs) {
            Ok(sections) => sections,
            Err(e) => {
                let msg = e.to_string();
                assert!(
                    case["bw_type"] == "stop" && msg.contains("parameter 'bw_order'"),
                    "{msg}"
                );
                refused.push(format!("{} {}", case["bw_order"], case["bw_cutoffHz"]));
                continue;
            }
        };
        for (f, want) in numbers(&case["response_hz"])
            .iter()
            .zip(numbers(&case["response_mag"]))
        {
            let got = sos_magnitude(&sections, *f, fs);
            let err = (got - want).abs() / want.max(1e-6);
            worst.0 = worst.0.max(err);
            assert!(err <= 1e-6, "|H({f} Hz)| {got:e} vs {want:e} in {case}");
        }
        let want = numbers(&case["impulse"]);
        let mut impulse = vec![0.0; want.len()];
        impulse[0] = 1.0;
        let got = run_request(case, fs, &impulse);
        let peak = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (t, (g, w)) in got.iter().zip(&want).enumerate() {
            let err = (g - w).abs() / peak;
            worst.1 = worst.1.max(err);
            assert!(err <= 1e-6, "h[{t}] {g:e} vs {w:e} in {case}");
        }
        let out = run_request(case, fs, &x);
        let peak = out.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(
            peak.is_finite() && peak < 4.0,
            "noise peak {peak} in {case}"
        );
    }
    println!(
        "worst relative errors: response {:e}, impulse {:e}",
        worst.0, worst.1
    );
    println!("refused band-stops: {refused:?}");
    assert!(
        cases.len() - refused.len() >= 200,
        "{} designs compared",
        cases.len() - refused.len()
    );
}
