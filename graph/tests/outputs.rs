//! Outputs describe themselves: every request's default outputs, computed in one graph,
//! carry the unit, framing window and drawing that consumers read instead of knowing
//! requests by name.

use afe_core::{DrawAs, ParamMap};
use afe_graph::{Manager, Signal};
use afe_processors::{find_request, requests};

/// The window-length parameter of each processor that cuts frames. A framed signal's
/// window is that of the nearest one in its chain (the rule the metadata applied by name
/// before outputs carried it).
const WINDOW_PARAMETERS: &[&str] = &[
    "rm_wSizeSec",
    "ild_wSizeSec",
    "cc_wSizeSec",
    "ac_wSizeSec",
    "ams_wSizeSec",
    "prec_wSizeSec",
    "stft_wSizeSec",
    "duet_wDUETSec",
    "loc_wSizeSec",
];

/// A graph of every request with its defaults, after one second of a 440 Hz tone on the
/// left and a 450 Hz one on the right, at 16 kHz.
fn every_request() -> Manager {
    let mut m = Manager::new(16000.0, 2).expect("manager");
    for r in requests().iter() {
        m.add_request(r.name, &ParamMap::new())
            .unwrap_or_else(|e| panic!("{}: {e}", r.name));
    }
    let tone = |f: f64| -> Vec<f64> {
        (0..16000)
            .map(|n| 0.1 * (2.0 * std::f64::consts::PI * f * n as f64 / 16000.0).sin())
            .collect()
    };
    m.process_signal(&[&tone(440.0), &tone(450.0)])
        .expect("processed");
    m
}

/// The request that made `s` (its node's, the first of its chain).
fn request_of<'a>(m: &'a Manager, s: &Signal<'_>) -> &'a str {
    m.signal_chain(s.source)[0].0
}

#[test]
fn every_output_carries_its_requests_unit() {
    let m = every_request();
    let signals = m.signals(false);
    assert!(signals.len() >= requests().len(), "{}", signals.len());
    for s in &signals {
        let request = request_of(&m, s);
        let expected = match s.name {
            "precedence_itd" => "s",
            "precedence_ild" => "dB",
            "precedence_cc" | "localisation_activity" => "",
            name => {
                assert_eq!(name, request);
                find_request(name).expect("registered").output_unit
            }
        };
        assert_eq!(s.info.unit, expected, "{}", s.key());
    }
}

#[test]
fn framed_outputs_carry_the_window_of_the_processor_that_cut_their_frames() {
    let m = every_request();
    for s in m.signals(false) {
        let chain = m.signal_chain(s.source);
        let nearest = chain
            .iter()
            .find_map(|(_, p)| WINDOW_PARAMETERS.iter().find_map(|w| p.get(*w)))
            .and_then(serde_json::Value::as_f64);
        match s.info.hop_s() {
            Some(hop_s) => {
                assert_eq!(hop_s, 1.0 / s.info.fs_hz, "{}", s.key());
                assert!(nearest.is_some(), "{} has no window parameter", s.key());
                assert_eq!(s.info.window_s, nearest, "{}", s.key());
            }
            None => assert_eq!(s.info.window_s, None, "{}", s.key()),
        }
    }
}

/// The drawings the plots and the live page gave each signal by name before outputs
/// carried them: signed cues on a diverging map, the ratemap's powers in dB, envelopes
/// and waveforms over 60 dB and the spectrum over 80 dB in the live view, pitch as a line.
#[test]
fn outputs_are_drawn_as_the_plots_drew_them_by_name() {
    let m = every_request();
    for s in m.signals(false) {
        let expected = match s.name {
            "ild" | "itd" | "precedence_itd" | "precedence_ild" => DrawAs::Signed,
            "ratemap" => DrawAs::PowerDecibels { range_db: 60.0 },
            "innerhaircell" | "adaptation" | "filterbank" | "time" => {
                DrawAs::AmplitudeDecibels { range_db: 60.0 }
            }
            "stft" => DrawAs::AmplitudeDecibels { range_db: 80.0 },
            "pitch" => DrawAs::Trajectory,
            _ => DrawAs::Linear,
        };
        assert_eq!(s.info.display, expected, "{}", s.key());
    }
}
