//! A representation added from outside the workspace's crates: a processor defined in
//! this file (its own module) and one registration. Its metadata (its NaN rule and its
//! axis of a kind no crate knows among them), its figure and its live-view panel (drawn
//! by headless Chromium) come from its own description, with nothing in the facade, the
//! plots or the page taught about it.
#![cfg(all(feature = "plot", feature = "view"))]

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use afe::extract::{run_with, Job};
use afe::stream::{run, StreamJob};
use afe::{Manager, ParamMap};
use afe_bass_source::{Pacing, Synth};
use afe_plot::{render, Format, Layout};
use afe_view::{View, ViewOptions};
use serde_json::{json, Value};
use tungstenite::Message;

/// The ratemap of each frame in dB about the frame's mean over channels: a signed cue.
mod centred {
    use afe_core::erb::freq2erb;
    use afe_core::{
        request_def, Axis, Block, Built, Descriptor, DrawAs, Ears, NoParams, OtherAxis, Processor,
        RequestDef, Result, SignalInfo,
    };

    /// Each frame's channels in dB, minus their mean.
    pub struct Centred;

    impl Processor for Centred {
        fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
            let x = inputs[0];
            let width = x.width();
            let out = outputs[0].resize_to(x.frames());
            for (o, row) in out.chunks_exact_mut(width).zip(x.rows()) {
                let db: Vec<f64> = row.iter().map(|v| 10.0 * v.max(1e-30).log10()).collect();
                let mean = db.iter().sum::<f64>() / width as f64;
                for (o, d) in o.iter_mut().zip(db) {
                    *o = d - mean;
                }
            }
        }

        fn reset(&mut self) {}
    }

    impl Descriptor for Centred {
        type Params = NoParams;
        const NAME: &'static str = "testCentred";
        const DEPENDENCY: &'static str = "ratemap";
        const EARS: Ears = Ears::PerEar;
        const DESCRIPTION: &'static str = "each ratemap frame in dB about its mean";
        const OUTPUT_UNIT: &'static str = "dB";

        fn build(_: &NoParams, inputs: &[SignalInfo]) -> Result<Built> {
            // its channels along an axis of its own: the ERB-number scale
            let band = Axis::Other(OtherAxis {
                name: AXIS_NAME,
                quantity: AXIS_QUANTITY,
                unit: AXIS_UNIT,
                values: inputs[0].cf_hz().iter().map(|&f| freq2erb(f)).collect(),
            });
            let info = SignalInfo {
                axes: vec![band],
                ..inputs[0].clone()
            }
            .with_unit(Self::OUTPUT_UNIT)
            .drawn_as(DrawAs::Signed)
            .nan_where(NAN_WHERE);
            Ok(Built::new(Centred, vec![info]))
        }
    }

    /// Where it is NaN: a rule of its own, which no code outside this module knows.
    pub const NAN_WHERE: &str = "never, unless a test's processor says so";
    /// Its axis, of a kind no crate has: name, quantity and unit.
    pub const AXIS_NAME: &str = "erb_number";
    pub const AXIS_QUANTITY: &str = "ERB-rate";
    pub const AXIS_UNIT: &str = "Cam";

    /// Its registry entry: the one line a new representation adds.
    pub static REQUEST: RequestDef = request_def::<Centred>();
}

fn tone(fs: f64, seconds: f64) -> Vec<Vec<f64>> {
    let left: Vec<f64> = (0..(fs * seconds) as usize)
        .map(|n| (2.0 * std::f64::consts::PI * 500.0 * n as f64 / fs).sin() * 0.1)
        .collect();
    let right = left.iter().map(|v| 0.5 * v).collect();
    vec![left, right]
}

#[test]
fn a_processor_defined_here_gets_metadata_a_figure_and_a_panel() {
    let mut registry = afe::Registry::default();
    registry.register(&centred::REQUEST).expect("a new request");
    let params: ParamMap = [("fb_nChannels".to_string(), json!(8))]
        .into_iter()
        .collect();

    // metadata: its unit, its framing (the ratemap's) and how it is drawn
    let fs = 16000.0;
    let audio = tone(fs, 0.5);
    let refs: Vec<&[f64]> = audio.iter().map(Vec::as_slice).collect();
    let mut mgr = Manager::new(fs, 2).expect("manager");
    mgr.set_registry(registry.clone()).expect("no request yet");
    let job = Job {
        requests: vec!["testCentred".into()],
        params: params.clone(),
        ..Job::default()
    };
    let rec = run_with(&mut mgr, &job, &refs).expect("computed");
    let s = rec.get("testCentred_left").expect("recorded");
    let d = &s.description;
    assert_eq!(d["unit"], "dB");
    assert_eq!(d["window_s"], 0.02);
    assert_eq!(d["hop_s"], 0.01);
    assert_eq!(d["display"], json!({"draw": "signed"}));
    assert_eq!(d["nan_where"], centred::NAN_WHERE);
    assert_eq!(d["processors"][0], "testCentred");
    assert_eq!(s.data.width(), 8);
    // its axis: named, with its values, and the plan that draws it
    assert_eq!(d["axes"], json!(["time_or_frame", centred::AXIS_NAME]));
    let axis = &d["frame_axes"][0];
    assert_eq!(
        (&axis["name"], &axis["unit"]),
        (&json!(centred::AXIS_NAME), &json!(centred::AXIS_UNIT))
    );
    let erb = axis["values"].as_array().expect("values");
    assert_eq!(erb.len(), 8);
    assert!(
        erb.windows(2).all(|w| w[0].as_f64() < w[1].as_f64()),
        "{erb:?}"
    );
    let plan = &d["plan"];
    assert_eq!(
        (&plan["panel"], &plan["scale"]["scale"]),
        (&json!("over-time"), &json!("signed"))
    );
    assert_eq!(plan["rows"]["label"], AXIS_LABEL);

    // its figure: a PNG with one panel per ear
    let png = render(&rec, Format::Png, &Layout::default()).expect("drawn");
    assert!(png.starts_with(b"\x89PNG"), "not a PNG");
    let header = png::Decoder::new(png.as_slice())
        .read_info()
        .expect("decodes")
        .info()
        .clone();
    assert_eq!(header.width, Layout::default().width);
    assert!(header.height >= 2 * Layout::default().panel_height);
    let svg = render(&rec, Format::Svg, &Layout::default()).expect("drawn");
    let svg = String::from_utf8(svg).expect("SVG text");
    assert!(
        svg.contains(AXIS_LABEL),
        "the figure does not title the axis"
    );

    // its live-view panel: listed in the page's catalogue, described, and streamed
    let (view, tap) = View::start(
        "127.0.0.1:0".parse().expect("addr"),
        10.0,
        &ViewOptions::default(),
    )
    .expect("view");
    let (mut ws, _) =
        tungstenite::connect(format!("ws://{}/ws", view.addr())).expect("a WebSocket");
    if let tungstenite::stream::MaybeTlsStream::Plain(s) = ws.get_ref() {
        s.set_read_timeout(Some(Duration::from_secs(5)))
            .expect("timeout");
    }
    let stream_job = StreamJob {
        requests: vec!["testCentred".into()],
        params,
        // long enough for Chromium to start and draw frames as they come
        duration_s: Some(3.0),
        pacing: Pacing::Realtime,
        registry,
        ..StreamJob::default()
    };
    let synth = Synth::parse("fs=16000,tone=500,seed=1").expect("synth");
    let page = std::thread::spawn({
        let url = format!("http://{}/", view.addr());
        move || chromium_dom(&url, "panel-testCentred_left")
    });
    // the stream starts once Chromium's page has connected beside this test's socket (a
    // loaded host can take seconds to start a browser), or once there is no browser
    let deadline = Instant::now() + Duration::from_secs(30);
    while view.pages() < 2 && !page.is_finished() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    let streamer = std::thread::spawn(move || run(synth, &stream_job, tap).expect("stream"));
    let mut layout: Option<Value> = None;
    let mut batches = 0;
    while let Ok(msg) = ws.read() {
        match msg {
            Message::Text(t) => {
                let v: Value = serde_json::from_str(t.as_str()).expect("json");
                if v["type"] == "layout" {
                    layout = Some(v);
                } else if v["type"] == "end" {
                    break;
                }
            }
            Message::Binary(_) => batches += 1,
            Message::Close(_) => break,
            _ => {}
        }
    }
    streamer.join().expect("stream thread");
    let dom = page.join().expect("page thread");
    drop(view);
    let layout = layout.expect("a layout");
    let listed = layout["catalogue"].as_array().expect("catalogue");
    assert!(listed.iter().any(|r| r == "testCentred"), "{listed:?}");
    let panel = &layout["signals"]["testCentred_right"];
    assert_eq!(panel["display"], json!({"draw": "signed"}), "{layout}");
    assert_eq!(panel["unit"], "dB");
    assert_eq!(panel["plan"]["rows"]["label"], AXIS_LABEL);
    assert!(batches > 0, "no frames reached the page");

    // the page as headless Chromium draws it: the panel, its axis and its frames
    let Some(dom) = dom else { return };
    let at = dom
        .find("id=\"panel-testCentred_left\"")
        .expect("no panel for the test's signal in the page");
    let panel = &dom[at..dom[at..].find("</canvas>").map_or(dom.len(), |e| at + e)];
    assert!(
        panel.contains(AXIS_LABEL),
        "the panel's axis is not titled: {panel}"
    );
    assert!(
        panel.contains(" Cam</span>"),
        "no tick of the axis: {panel}"
    );
    let drawn = panel
        .split("data-drawn=\"")
        .nth(1)
        .and_then(|r| r.split('"').next())
        .and_then(|n| n.parse::<usize>().ok());
    // the page's status line (connection, frames received, lost) says why if none was
    let status = dom
        .find("id=\"frames\"")
        .map_or("", |at| &dom[at..(at + 400).min(dom.len())]);
    assert!(
        drawn.is_some_and(|n| n > 0),
        "the panel drew no frame: {panel}\nthe page's status: {status}"
    );
}

/// The axis title the plan gives the test's axis.
const AXIS_LABEL: &str = "ERB-rate (Cam)";

/// The DOM of the live page at `url` once its element `#{panel}` has drawn a frame (its
/// `data-drawn`), or as it is after 20 s, read in real time from headless Chromium through
/// its DevTools protocol (a DOM dumped after a virtual-time budget raced the WebSocket's
/// frames: Chromium's virtual time runs ahead of them); `None` where no Chromium is
/// installed, outside CI (which installs it).
fn chromium_dom(url: &str, panel: &str) -> Option<String> {
    let profile = crate::common::tmp("custom-processor-chromium");
    let spawn = |binary: &str| {
        Command::new(binary)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--remote-debugging-port=0",
                &format!("--user-data-dir={}", profile.display()),
                url,
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .ok()
    };
    let Some(mut browser) = spawn("chromium").or_else(|| spawn("chromium-browser")) else {
        assert!(std::env::var_os("CI").is_none(), "CI installs chromium");
        eprintln!("no chromium: the page is not rendered");
        return None;
    };
    let dom = dom_when_drawn(&mut browser, panel);
    let _ = browser.kill();
    let _ = browser.wait();
    Some(dom.unwrap_or_else(|e| panic!("chromium: {e}")))
}

/// The page's DOM from `browser`'s DevTools endpoint (the line it prints on stderr), once
/// `#{panel}` has drawn a frame or after 20 s.
fn dom_when_drawn(browser: &mut Child, panel: &str) -> Result<String, String> {
    let stderr = browser.stderr.take().ok_or("no stderr")?;
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr)
            .lines()
            .map_while(std::io::Result::ok)
        {
            if let Some(at) = line.find("ws://") {
                let _ = tx.send(line[at..].trim().to_string());
            }
        }
    });
    let endpoint = rx
        .recv_timeout(Duration::from_secs(30))
        .map_err(|_| "no DevTools endpoint within 30 s")?;
    let (ws, _) = tungstenite::connect(endpoint.as_str()).map_err(|e| e.to_string())?;
    let mut cdp = Cdp { ws, next: 0 };
    let deadline = Instant::now() + Duration::from_secs(20);
    let page = loop {
        let targets = cdp.call("Target.getTargets", json!({}), None)?;
        let page = targets["targetInfos"]
            .as_array()
            .and_then(|t| t.iter().find(|t| t["type"] == "page"))
            .and_then(|t| t["targetId"].as_str().map(str::to_string));
        match page {
            Some(page) => break page,
            None if Instant::now() > deadline => return Err("no page within 20 s".into()),
            None => std::thread::sleep(Duration::from_millis(100)),
        }
    };
    let attached = cdp.call(
        "Target.attachToTarget",
        json!({"targetId": page, "flatten": true}),
        None,
    )?;
    let session = attached["sessionId"]
        .as_str()
        .ok_or("no session")?
        .to_string();
    let drawn = format!(
        "(() => {{ const p = document.getElementById('{panel}'); \
         return p && +p.dataset.drawn > 0 ? document.documentElement.outerHTML : null; }})()"
    );
    loop {
        let late = Instant::now() > deadline;
        let expression = if late {
            "document.documentElement.outerHTML"
        } else {
            &drawn
        };
        let v = cdp.call(
            "Runtime.evaluate",
            json!({"expression": expression, "returnByValue": true}),
            Some(&session),
        )?;
        if let Some(dom) = v["result"]["value"].as_str() {
            return Ok(dom.to_string());
        }
        if late {
            return Err(format!("no DOM: {v}"));
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// A DevTools protocol connection: numbered calls, each answered by its result.
struct Cdp {
    ws: tungstenite::WebSocket<tungstenite::stream::MaybeTlsStream<std::net::TcpStream>>,
    next: u64,
}

impl Cdp {
    /// Calls `method` (in `session`, if given) and returns its result; events between are
    /// let go.
    fn call(
        &mut self,
        method: &str,
        params: Value,
        session: Option<&str>,
    ) -> Result<Value, String> {
        self.next += 1;
        let mut msg = json!({"id": self.next, "method": method, "params": params});
        if let Some(s) = session {
            msg["sessionId"] = json!(s);
        }
        self.ws
            .send(Message::text(msg.to_string()))
            .map_err(|e| e.to_string())?;
        loop {
            let Message::Text(t) = self.ws.read().map_err(|e| e.to_string())? else {
                continue;
            };
            let v: Value = serde_json::from_str(t.as_str()).map_err(|e| e.to_string())?;
            if v["id"] == self.next {
                return match v.get("error") {
                    Some(e) => Err(format!("{method}: {e}")),
                    None => Ok(v["result"].clone()),
                };
            }
        }
    }
}
