//! The live view end to end on loopback: the page is served, a WebSocket client gets
//! the layout and every frame of the stream (equal to the recorded output, as f32), its
//! edits change the graph, bad messages get error replies, and a client that never
//! reads costs the others nothing. A page of another origin is refused; what one page
//! (or many) may ask is bounded, and the others are served meanwhile.
#![cfg(feature = "view")]

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use afe::stream::{run, StreamJob, Streamed};
use afe_bass_source::{Pacing, Synth};
use afe_view::{AllowedOrigins, Limits, View, ViewOptions};
use serde_json::{json, Value};
use tungstenite::client::IntoClientRequest;
use tungstenite::protocol::frame::coding::CloseCode;
use tungstenite::Message;

type Socket = tungstenite::WebSocket<tungstenite::stream::MaybeTlsStream<TcpStream>>;

/// What a client saw: text messages, and per signal the frames from its first batch on.
#[derive(Default)]
struct Seen {
    texts: Vec<Value>,
    first: BTreeMap<String, u64>,
    frames: BTreeMap<String, Vec<f32>>,
    gaps: usize,
    batches: usize,
    /// Input samples received (values, all ears).
    audio_values: usize,
    /// The close frame's code and reason, if the server sent one.
    closed: Option<(CloseCode, String)>,
}

impl Seen {
    /// The replies received, in order.
    fn replies(&self) -> Vec<&Value> {
        self.texts.iter().filter(|v| v["type"] == "reply").collect()
    }
}

fn connect(addr: SocketAddr) -> Socket {
    connect_from(addr, None).expect("connect")
}

/// A WebSocket to the view as a page of `origin` would open it (`None`: no `Origin`
/// header, as a non-browser client).
fn connect_from(addr: SocketAddr, origin: Option<&str>) -> tungstenite::Result<Socket> {
    let mut request = format!("ws://{addr}/ws")
        .into_client_request()
        .expect("request");
    if let Some(origin) = origin {
        let value = tungstenite::http::HeaderValue::from_str(origin).expect("origin");
        request.headers_mut().insert("Origin", value);
    }
    let (ws, _) = tungstenite::connect(request)?;
    if let tungstenite::stream::MaybeTlsStream::Plain(s) = ws.get_ref() {
        s.set_read_timeout(Some(Duration::from_secs(5)))
            .expect("timeout");
    }
    Ok(ws)
}

/// A view with `options`, and a synthetic stream of `requests` at 16 kHz in real time
/// for `seconds` feeding it.
fn start(options: &ViewOptions, requests: &[&str], seconds: f64) -> (View, JoinHandle<Streamed>) {
    let (view, tap) =
        View::start("127.0.0.1:0".parse().expect("addr"), 10.0, options).expect("view");
    let job = StreamJob {
        requests: requests.iter().map(|r| r.to_string()).collect(),
        params: [("fb_nChannels".to_string(), json!(8))]
            .into_iter()
            .collect(),
        duration_s: Some(seconds),
        pacing: Pacing::Realtime,
        ..StreamJob::default()
    };
    let synth = Synth::parse("fs=16000,tone=500,noise=0.1,ild_db=-6,seed=3").expect("synth");
    let streamer = std::thread::spawn(move || run(synth, &job, tap).expect("stream"));
    (view, streamer)
}

/// Reads until the server says the stream ended (or the socket closes).
fn read_all(mut ws: Socket, mut on_text: impl FnMut(&Value, &mut Socket)) -> Seen {
    let mut seen = Seen::default();
    while let Ok(msg) = ws.read() {
        match msg {
            Message::Text(t) => {
                let v: Value = serde_json::from_str(t.as_str()).expect("json");
                on_text(&v, &mut ws);
                let end = v["type"] == "end";
                seen.texts.push(v);
                if end {
                    break;
                }
            }
            Message::Binary(b) => {
                seen.batches += 1;
                let n = u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize;
                let header: Value = serde_json::from_slice(&b[4..4 + n]).expect("header");
                let start = 4 + n + (4 - (4 + n) % 4) % 4;
                let values: Vec<f32> = b[start..]
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect();
                seen.audio_values += header["audio"]["len"].as_u64().expect("audio") as usize;
                for s in header["signals"].as_array().expect("signals") {
                    let key = s["key"].as_str().expect("key").to_string();
                    let (at, len) = (
                        s["offset"].as_u64().expect("o") as usize,
                        s["len"].as_u64().expect("l") as usize,
                    );
                    let first = s["first_frame"].as_u64().expect("first");
                    let rows = s["rows"].as_u64().expect("rows");
                    let start_frame = *seen.first.entry(key.clone()).or_insert(first);
                    let got = seen.frames.entry(key).or_default();
                    let width = (len as u64).checked_div(rows).unwrap_or(0);
                    if width > 0 && start_frame + got.len() as u64 / width != first {
                        seen.gaps += 1;
                    }
                    got.extend_from_slice(&values[at..at + len]);
                }
            }
            Message::Close(frame) => {
                seen.closed = frame.map(|f| (f.code, f.reason.to_string()));
                break;
            }
            _ => {}
        }
    }
    seen
}

#[test]
fn a_page_sees_every_frame_and_edits_the_graph() {
    let (view, tap) = View::start(
        "127.0.0.1:0".parse().expect("addr"),
        10.0,
        &ViewOptions::default(),
    )
    .expect("view");
    let addr = view.addr();
    // the page's own origin, as a browser sends it
    let own = format!("http://{addr}");

    // the page itself, offline: no external script or style
    let mut http = TcpStream::connect(addr).expect("http");
    http.write_all(b"GET / HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        .expect("get");
    let mut page = String::new();
    http.read_to_string(&mut page).expect("page");
    assert!(
        page.starts_with("HTTP/1.1 200") && page.contains("<canvas"),
        "{page:.200}"
    );
    assert!(!page.contains("http://") && !page.contains("https://"));

    let job = StreamJob {
        requests: vec!["ratemap".into(), "ild".into()],
        params: [("fb_nChannels".to_string(), json!(8))]
            .into_iter()
            .collect(),
        duration_s: Some(3.0),
        pacing: Pacing::Realtime,
        record: true,
        ..StreamJob::default()
    };
    let synth = Synth::parse("fs=16000,tone=500,noise=0.1,ild_db=-6,seed=3").expect("synth");
    let streamer = std::thread::spawn(move || run(synth, &job, tap).expect("stream"));
    // a client that never reads
    let stalled = connect(addr);
    let reader = connect_from(addr, Some(&own)).expect("the page's own origin");
    let mut sent = false;
    let seen = read_all(reader, |v, ws| {
        if v["type"] == "layout" && !sent {
            sent = true;
            for bad in [
                json!({"op": "add", "request": "nope"}).to_string(),
                "not json".to_string(),
                json!({"op": "fly"}).to_string(),
                json!({"op": "add", "request": "itd", "params": {"cc_wSizeSec": 0.04}}).to_string(),
            ] {
                ws.send(Message::text(bad)).expect("send");
            }
        }
    });
    let out = streamer.join().expect("stream thread");
    drop(stalled);

    assert_eq!(out.report.lost_frames, 0);
    assert!(seen.batches > 20, "{} batches", seen.batches);
    assert_eq!(seen.gaps, 0, "a client that keeps up loses nothing");
    let replies: Vec<&Value> = seen.texts.iter().filter(|v| v["type"] == "reply").collect();
    assert_eq!(replies.len(), 4, "{replies:?}");
    assert!(replies
        .iter()
        .any(|r| r["ok"] == false && r["message"].as_str().is_some_and(|m| m.contains("nope"))));
    assert!(replies.iter().any(|r| r["ok"] == false
        && r["message"]
            .as_str()
            .is_some_and(|m| m.contains("not a JSON object"))));
    assert!(replies.iter().any(|r| r["ok"] == false
        && r["message"]
            .as_str()
            .is_some_and(|m| m.contains("unknown op"))));
    assert!(replies.iter().any(|r| r["ok"] == true && r["op"] == "add"));
    // the added ITD is in a later layout, with its parameters, and its frames arrive
    let last = seen
        .texts
        .iter()
        .rfind(|v| v["type"] == "layout")
        .expect("layout");
    assert_eq!(last["signals"]["itd_mono"]["window_s"], 0.04);
    assert!(seen.frames.get("itd_mono").is_some_and(|f| !f.is_empty()));
    // every frame sent equals the recorded output, from the page's first frame on
    for key in ["ratemap_left", "ratemap_right", "ild_mono"] {
        let rec = out.recorded.get(key).expect("recorded");
        let width: usize = rec.info.frame_shape().iter().product();
        let first = seen.first[key] as usize;
        let want: Vec<f32> = rec.data.as_slice()[first * width..]
            .iter()
            .map(|&v| v as f32)
            .collect();
        let got = &seen.frames[key];
        assert!(got.len() > width * 150, "{key}: {} values", got.len());
        assert_eq!(got[..], want[..got.len()], "{key}");
    }
}

#[test]
fn afe_serve_runs_for_its_time_and_names_a_busy_address() {
    let serve = |addr: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_afe"))
            .args([
                "serve",
                "--source",
                "synth:fs=16000,tone=440",
                "-r",
                "ratemap",
            ])
            .args([
                "--http",
                addr,
                "--listen",
                "tcp/127.0.0.1:0",
                "--for",
                "0.5",
            ])
            .output()
            .expect("run afe serve")
    };
    let out = serve("127.0.0.1:0");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("live view: http://127.0.0.1:"), "{stderr}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("0 frame(s) lost"));
    let busy = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = busy.local_addr().expect("addr").to_string();
    let out = serve(&addr);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr.contains(&format!("cannot serve the live view on {addr}")),
        "{stderr}"
    );
}

#[test]
fn a_page_of_another_origin_is_refused_with_403() {
    let allowed = AllowedOrigins::parse(&["http://lab.example:8000"]).expect("origins");
    let options = ViewOptions {
        origins: allowed,
        ..ViewOptions::default()
    };
    let (view, streamer) = start(&options, &["ratemap"], 1.0);
    let addr = view.addr();
    for foreign in [
        "http://evil.example".to_string(),
        format!("http://127.0.0.1:{}", addr.port() + 1),
        "null".to_string(),
        "http://lab.example:8001".to_string(),
    ] {
        match connect_from(addr, Some(&foreign)) {
            Err(tungstenite::Error::Http(response)) => {
                assert_eq!(response.status(), 403, "{foreign}");
                let body =
                    String::from_utf8_lossy(response.body().as_deref().unwrap_or(&[])).to_string();
                assert!(body.contains("--http-allow-origin"), "{foreign}: {body}");
            }
            Err(e) => panic!("{foreign}: {e}"),
            Ok(_) => panic!("{foreign} was accepted"),
        }
    }
    // the page's own origin, an allowed one and a client without Origin are served
    for origin in [
        Some(format!("http://{addr}")),
        Some("http://lab.example:8000".into()),
        None,
    ] {
        let mut ws = connect_from(addr, origin.as_deref()).expect("accepted");
        let first = ws.read().expect("a first message");
        let layout: Value = serde_json::from_str(first.to_text().expect("text")).expect("json");
        assert_eq!(layout["type"], "layout", "{origin:?}");
    }
    streamer.join().expect("stream");
}

/// Reads `ws` until `n` replies have come (other messages are skipped).
fn replies(ws: &mut Socket, n: usize) -> Vec<Value> {
    let mut got = Vec::new();
    while got.len() < n {
        if let Message::Text(t) = ws.read().expect("a reply") {
            let v: Value = serde_json::from_str(t.as_str()).expect("json");
            if v["type"] == "reply" {
                got.push(v);
            }
        }
    }
    got
}

fn message(v: &Value) -> &str {
    v["message"].as_str().unwrap_or_default()
}

#[test]
fn a_flood_of_requests_from_one_page_is_bounded_and_the_others_are_served() {
    let limits = Limits::default();
    // started without requests: pages add them
    let (view, streamer) = start(&ViewOptions::default(), &[], 4.0);
    let addr = view.addr();
    let watcher = std::thread::spawn(move || read_all(connect(addr), |_, _| {}));
    let mut flood = connect(addr);
    if let tungstenite::stream::MaybeTlsStream::Plain(s) = flood.get_ref() {
        s.set_write_timeout(Some(Duration::from_secs(5)))
            .expect("timeout");
    }
    const SENT: usize = 1000;
    for i in 0..SENT {
        let add = json!({"op": "add", "request": "ild", "params": {"fb_nChannels": 4 + i % 40}});
        flood.send(Message::text(add.to_string())).expect("send");
    }
    let flooded = read_all(flood, |_, _| {});
    let watched = watcher.join().expect("watcher");
    let out = streamer.join().expect("stream");

    // every message had its answer, and at most the page's share was placed
    let replies = flooded.replies();
    assert_eq!(replies.len(), SENT);
    let placed = replies.iter().filter(|r| r["ok"] == true).count();
    assert!(
        (1..=limits.requests_per_page).contains(&placed),
        "{placed} placed"
    );
    for r in replies.iter().filter(|r| r["ok"] == false) {
        let m = message(r);
        assert!(
            m.starts_with("too many messages: at most 20 a second")
                || m.starts_with("this page has 8 requests in place")
                || m.starts_with("busy: 16 edits wait"),
            "{m}"
        );
    }
    let last = watched
        .texts
        .iter()
        .rfind(|v| v["type"] == "layout")
        .expect("layout");
    assert_eq!(last["requests"].as_array().expect("requests").len(), placed);
    // the other page was served all along, and the stream kept its time
    assert!(watched.batches > 50, "{} batches", watched.batches);
    assert_eq!(watched.gaps, 0);
    assert_eq!(out.report.lost_frames, 0);
}

#[test]
fn requests_are_bounded_per_page_and_over_all_pages() {
    let options = ViewOptions {
        limits: Limits {
            requests_per_page: 2,
            requests: 3,
            ..Limits::default()
        },
        ..ViewOptions::default()
    };
    let (view, streamer) = start(&options, &["ratemap"], 2.0);
    let (mut a, mut b) = (connect(view.addr()), connect(view.addr()));
    let add = |ws: &mut Socket, channels: u32| {
        let msg = json!({"op": "add", "request": "ild", "params": {"fb_nChannels": channels}});
        ws.send(Message::text(msg.to_string())).expect("send");
        replies(ws, 1).remove(0)
    };
    assert_eq!(add(&mut a, 5)["ok"], true);
    assert_eq!(add(&mut a, 6)["ok"], true);
    let third = add(&mut a, 7);
    assert!(
        message(&third).starts_with("this page has 2 requests in place"),
        "{third}"
    );
    assert_eq!(add(&mut b, 8)["ok"], true);
    let fourth = add(&mut b, 9);
    assert!(
        message(&fourth).starts_with("pages have 3 requests in place"),
        "{fourth}"
    );
    // a removed request frees its place (ratemap is request 0, a's first is 1)
    a.send(Message::text(
        json!({"op": "remove", "handle": 1}).to_string(),
    ))
    .expect("send");
    assert_eq!(replies(&mut a, 1)[0]["ok"], true);
    assert_eq!(add(&mut b, 9)["ok"], true);
    drop((a, b));
    streamer.join().expect("stream");
}

#[test]
fn an_add_is_refused_while_the_stream_is_above_its_load_limit() {
    let options = ViewOptions {
        limits: Limits {
            // any compute at all is above it
            max_load: 0.0,
            ..Limits::default()
        },
        ..ViewOptions::default()
    };
    let (view, streamer) = start(&options, &["ratemap"], 1.0);
    let mut ws = connect(view.addr());
    // the load is an average over blocks: let a few pass
    std::thread::sleep(Duration::from_millis(200));
    ws.send(Message::text(
        json!({"op": "add", "request": "ild"}).to_string(),
    ))
    .expect("send");
    let reply = replies(&mut ws, 1).remove(0);
    assert_eq!(reply["ok"], false);
    assert!(
        message(&reply).contains("% of its real-time budget (above 0 %)"),
        "{reply}"
    );
    drop(ws);
    streamer.join().expect("stream");
}

#[test]
fn an_oversized_message_closes_its_page_only() {
    let (view, streamer) = start(&ViewOptions::default(), &["ratemap"], 3.0);
    let addr = view.addr();
    let watcher = std::thread::spawn(move || read_all(connect(addr), |_, _| {}));
    let mut big = connect(addr);
    big.send(Message::text("x".repeat(20_000))).expect("send");
    let seen = read_all(big, |_, _| {});
    let (code, reason) = seen.closed.expect("a close frame");
    assert_eq!(code, CloseCode::Size);
    assert!(
        reason.contains("the largest taken is 16384 bytes"),
        "{reason}"
    );
    let watched = watcher.join().expect("watcher");
    streamer.join().expect("stream");
    assert!(
        watched.batches > 40 && watched.gaps == 0,
        "{}",
        watched.batches
    );
}

#[test]
fn a_page_beyond_the_limit_is_told_why() {
    let options = ViewOptions {
        limits: Limits {
            pages: 2,
            ..Limits::default()
        },
        ..ViewOptions::default()
    };
    let (view, streamer) = start(&options, &["ratemap"], 2.0);
    let addr = view.addr();
    let first = connect(addr);
    let _second = connect(addr);
    let third = read_all(connect(addr), |_, _| {});
    assert_eq!(third.texts.len(), 1, "{:?}", third.texts);
    assert_eq!(third.texts[0]["type"], "refused");
    assert!(message(&third.texts[0]).starts_with("too many pages: 2 are connected"));
    assert_eq!(third.closed.expect("close").0, CloseCode::Again);
    assert_eq!(third.batches, 0);
    // a page that leaves makes room
    drop(first);
    let deadline = Instant::now() + Duration::from_secs(2);
    while view.pages() > 1 && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(10));
    }
    let mut fourth = connect(addr);
    let layout = fourth.read().expect("layout");
    assert!(layout
        .to_text()
        .expect("text")
        .contains("\"type\":\"layout\""));
    streamer.join().expect("stream");
}

#[test]
fn the_audio_goes_only_to_the_page_that_asked_for_it() {
    let (view, streamer) = start(&ViewOptions::default(), &["ratemap"], 2.0);
    let addr = view.addr();
    let quiet = std::thread::spawn(move || read_all(connect(addr), |_, _| {}));
    let mut asked = false;
    let listener = read_all(connect(addr), |v, ws| {
        if v["type"] == "layout" && !asked {
            asked = true;
            ws.send(Message::text(
                json!({"op": "audio", "on": true}).to_string(),
            ))
            .expect("send");
        }
    });
    let quiet = quiet.join().expect("quiet page");
    streamer.join().expect("stream");
    assert!(listener
        .replies()
        .iter()
        .any(|r| r["op"] == "audio" && r["ok"] == true));
    // about 2 s of two ears at 16 kHz, less the time before it asked
    assert!(listener.audio_values > 16_000, "{}", listener.audio_values);
    assert_eq!(quiet.audio_values, 0);
    assert!(quiet.batches > 20);
}

#[test]
fn a_stream_started_without_requests_has_a_layout_and_draws_what_is_added() {
    let (view, streamer) = start(&ViewOptions::default(), &[], 2.0);
    let mut added = false;
    let seen = read_all(connect(view.addr()), |v, ws| {
        if v["type"] == "layout" && !added {
            added = true;
            assert_eq!(v["order"], json!([]));
            assert!(v["fs_hz"] == 16000.0 && v["ears"] == 2, "{v}");
            ws.send(Message::text(
                json!({"op": "add", "request": "ratemap"}).to_string(),
            ))
            .expect("send");
        }
    });
    streamer.join().expect("stream");
    assert!(added, "no layout before any request");
    let last = seen
        .texts
        .iter()
        .rfind(|v| v["type"] == "layout")
        .expect("layout");
    assert_eq!(last["order"], json!(["ratemap_left", "ratemap_right"]));
    assert!(seen
        .frames
        .get("ratemap_left")
        .is_some_and(|f| f.len() > 8 * 100));
}

#[test]
fn idle_connections_are_bounded_and_timed_out() {
    let options = ViewOptions {
        limits: Limits {
            connections: 2,
            header_timeout: Duration::from_millis(500),
            ..Limits::default()
        },
        ..ViewOptions::default()
    };
    let (view, _tap) =
        View::start("127.0.0.1:0".parse().expect("addr"), 10.0, &options).expect("view");
    let addr = view.addr();
    let start = Instant::now();
    let mut idle: Vec<TcpStream> = (0..2)
        .map(|_| TcpStream::connect(addr).expect("connect"))
        .collect();
    std::thread::sleep(Duration::from_millis(50));
    let mut http = TcpStream::connect(addr).expect("http");
    http.set_read_timeout(Some(Duration::from_secs(5)))
        .expect("timeout");
    http.write_all(b"GET / HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        .expect("get");
    let mut page = String::new();
    http.read_to_string(&mut page).expect("page");
    let waited = start.elapsed();
    assert!(page.starts_with("HTTP/1.1 200"), "{page:.100}");
    // served once the idle connections were dropped, not before
    assert!(
        (Duration::from_millis(450)..Duration::from_secs(3)).contains(&waited),
        "{waited:?}"
    );
    for s in &mut idle {
        s.set_read_timeout(Some(Duration::from_secs(1)))
            .expect("timeout");
        let mut buf = [0u8; 256];
        // closed (perhaps with a 408 first)
        let n = s.read(&mut buf).unwrap_or(0);
        if n > 0 {
            assert!(buf.starts_with(b"HTTP/1.1 408"), "{:?}", &buf[..n]);
        }
    }
}

#[test]
fn afe_serve_logs_a_refused_origin_and_checks_its_allowed_ones() {
    let mut serve = std::process::Command::new(env!("CARGO_BIN_EXE_afe"))
        .args(["serve", "--source", "synth:fs=16000,tone=440"])
        .args(["--http", "127.0.0.1:0", "--listen", "tcp/127.0.0.1:0"])
        .args(["--for", "2"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run afe serve");
    let mut stderr = BufReader::new(serve.stderr.take().expect("stderr"));
    let mut log = String::new();
    let addr: SocketAddr = loop {
        let mut line = String::new();
        assert!(stderr.read_line(&mut line).expect("stderr") > 0, "{log}");
        log.push_str(&line);
        if let Some(a) = line.trim().strip_prefix("live view: http://") {
            break a.trim_end_matches('/').parse().expect("address");
        }
    };
    let refused = connect_from(addr, Some("http://evil.example"));
    assert!(
        matches!(&refused, Err(tungstenite::Error::Http(r)) if r.status() == 403),
        "{refused:?}"
    );
    // started without -r: the page gets a layout with no signal
    let mut own = connect_from(addr, Some(&format!("http://{addr}"))).expect("own origin");
    let first = own.read().expect("layout");
    let layout: Value = serde_json::from_str(first.to_text().expect("text")).expect("json");
    assert_eq!(layout["order"], json!([]));
    drop(own);
    stderr.read_to_string(&mut log).expect("stderr");
    assert!(serve.wait().expect("wait").success(), "{log}");
    assert!(
        log.contains("afe live view: refused a WebSocket: origin http://evil.example"),
        "{log}"
    );

    let out = std::process::Command::new(env!("CARGO_BIN_EXE_afe"))
        .args(["serve", "--source", "synth:fs=16000,tone=440", "--for", "1"])
        .args(["--http", "127.0.0.1:0", "--listen", "tcp/127.0.0.1:0"])
        .args(["--http-allow-origin", "robot.local"])
        .output()
        .expect("run afe serve");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("'robot.local' is not an origin"),
        "{stderr}"
    );
}

/// Issue 57: the page is served with headers that forbid framing it and guessing its
/// type, and a Content Security Policy that runs its own script only.
#[test]
fn the_page_cannot_be_framed_and_runs_only_its_own_script() {
    let (view, streamer) = start(&ViewOptions::default(), &["ratemap"], 0.5);
    let mut http = TcpStream::connect(view.addr()).expect("http");
    http.write_all(b"GET / HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        .expect("get");
    let mut page = String::new();
    http.read_to_string(&mut page).expect("page");
    let (head, _) = page.split_once("\r\n\r\n").expect("headers");
    let head = head.to_ascii_lowercase();
    assert!(head.contains("\r\nx-frame-options: deny"), "{head}");
    assert!(
        head.contains("\r\nx-content-type-options: nosniff"),
        "{head}"
    );
    let csp = head
        .lines()
        .find_map(|l| l.strip_prefix("content-security-policy: "))
        .expect("a content security policy");
    for part in [
        "frame-ancestors 'none'",
        "default-src 'none'",
        "script-src 'sha256-",
        "connect-src 'self'",
    ] {
        assert!(csp.contains(part), "{part} not in {csp}");
    }
    assert!(!csp.contains("unsafe-eval"), "{csp}");
    streamer.join().expect("stream");
}

/// Issue 57: a page edits only the requests it placed: it cannot remove the stream's
/// own or another page's, and its `set` changes its own requests alone (placed again
/// with the value), never a request another page or the stream shares processors with.
#[test]
fn a_page_edits_only_the_requests_it_placed() {
    let (view, streamer) = start(&ViewOptions::default(), &["ratemap"], 3.0);
    let (mut a, mut b) = (connect(view.addr()), connect(view.addr()));
    let ask = |ws: &mut Socket, msg: Value| {
        ws.send(Message::text(msg.to_string())).expect("send");
        replies(ws, 1).remove(0)
    };
    // the stream's ratemap is request 0; a's ratemap shares all its processors
    let placed = ask(
        &mut a,
        json!({"op": "add", "request": "ratemap", "params": {"fb_nChannels": 8}}),
    );
    assert_eq!(placed["ok"], true, "{placed}");
    assert_eq!(message(&placed), "placed ratemap (request 1)");
    for handle in [0, 1] {
        let r = ask(&mut b, json!({"op": "remove", "handle": handle}));
        assert_eq!(r["ok"], false);
        assert_eq!(
            message(&r),
            format!("request {handle} was not placed by this page: a page removes only the requests it added")
        );
    }
    let r = ask(&mut b, json!({"op": "remove", "handle": 7}));
    assert_eq!(message(&r), "no request 7 is in place");
    let r = ask(
        &mut b,
        json!({"op": "set", "name": "rm_wSizeSec", "value": 0.05}),
    );
    assert_eq!(r["ok"], false);
    assert!(
        message(&r).starts_with("no request this page placed uses parameter 'rm_wSizeSec'"),
        "{r}"
    );
    // a's set places its request again; the stream's ratemap keeps its window
    let r = ask(
        &mut a,
        json!({"op": "set", "name": "rm_wSizeSec", "value": 0.05}),
    );
    assert_eq!(r["ok"], true, "{r}");
    assert!(
        message(&r).starts_with("rm_wSizeSec = 0.05 in 1 request(s) of this page"),
        "{r}"
    );
    let layout = loop {
        let Message::Text(t) = a.read().expect("a layout") else {
            continue;
        };
        let v: Value = serde_json::from_str(t.as_str()).expect("json");
        if v["type"] == "layout" && v["signals"].get("ratemap_2_left").is_some() {
            break v;
        }
    };
    assert_eq!(
        layout["signals"]["ratemap_left"]["window_s"], 0.02,
        "the stream's own"
    );
    assert_eq!(layout["signals"]["ratemap_2_left"]["window_s"], 0.05, "a's");
    let handles: Vec<u64> = layout["requests"]
        .as_array()
        .expect("requests")
        .iter()
        .map(|r| r["handle"].as_u64().expect("handle"))
        .collect();
    assert_eq!(handles.len(), 2, "{layout}");
    assert!(handles.contains(&0) && !handles.contains(&1), "{handles:?}");
    drop((a, b));
    streamer.join().expect("stream");
}

/// Issue 57: a page's requests leave with it, so closed pages hold no room.
#[test]
fn the_requests_of_a_page_that_closed_are_freed() {
    let options = ViewOptions {
        limits: Limits {
            requests_per_page: 2,
            requests: 2,
            ..Limits::default()
        },
        ..ViewOptions::default()
    };
    let (view, streamer) = start(&options, &[], 4.0);
    let add = |ws: &mut Socket, channels: u32| {
        let msg = json!({"op": "add", "request": "ild", "params": {"fb_nChannels": channels}});
        ws.send(Message::text(msg.to_string())).expect("send");
        replies(ws, 1).remove(0)
    };
    for round in 0..3 {
        let mut page = connect(view.addr());
        assert_eq!(add(&mut page, 4 + round)["ok"], true, "round {round}");
        assert_eq!(add(&mut page, 10 + round)["ok"], true, "round {round}");
        let full = add(&mut page, 20);
        assert!(
            message(&full).starts_with("this page has 2 requests in place"),
            "{full}"
        );
        page.close(None).expect("close");
        while page.read().is_ok() {}
    }
    // the last page's requests went too: a watcher sees an empty layout
    let mut watcher = connect(view.addr());
    let deadline = Instant::now() + Duration::from_secs(2);
    let mut empty = false;
    while !empty && Instant::now() < deadline {
        if let Ok(Message::Text(t)) = watcher.read() {
            let v: Value = serde_json::from_str(t.as_str()).expect("json");
            empty = v["type"] == "layout" && v["requests"].as_array().is_some_and(Vec::is_empty);
        }
    }
    assert!(empty, "the closed pages' requests are still in place");
    drop(watcher);
    streamer.join().expect("stream");
}

/// Issue 57, item 11: a request whose cost would take the stream past its deadline is
/// refused before it runs, with its measured cost, the budget and what to change; the
/// stream keeps its deadlines, and a light request is still taken.
#[test]
fn a_request_too_heavy_for_the_deadline_is_refused_before_it_runs() {
    let (view, tap) = View::start(
        "127.0.0.1:0".parse().expect("addr"),
        10.0,
        &ViewOptions::default(),
    )
    .expect("view");
    let job = StreamJob {
        requests: vec!["ratemap".into()],
        duration_s: Some(4.0),
        pacing: Pacing::Realtime,
        ..StreamJob::default()
    };
    let synth = Synth::parse("fs=44100,tone=500,noise=0.1,seed=3").expect("synth");
    let streamer = std::thread::spawn(move || run(synth, &job, tap).expect("stream"));
    let mut ws = connect(view.addr());
    std::thread::sleep(Duration::from_millis(300));
    let heavy = json!({"op": "add", "request": "autocorrelation", "params": {
        "fb_nChannels": 64, "ac_hSizeSec": 0.002, "ac_wSizeSec": 0.05}});
    ws.send(Message::text(heavy.to_string())).expect("send");
    let reply = replies(&mut ws, 1).remove(0);
    assert_eq!(reply["ok"], false, "{reply}");
    let m = message(&reply);
    assert!(
        m.starts_with("'autocorrelation' would cost ")
            && m.contains(" of each 10.0-ms block (measured on a trial before placing it)")
            && m.contains("(80 %) requests may use: ask for less (fewer channels, a longer hop"),
        "{m}"
    );
    let light = json!({"op": "add", "request": "ild"});
    ws.send(Message::text(light.to_string())).expect("send");
    let reply = replies(&mut ws, 1).remove(0);
    assert_eq!(reply["ok"], true, "{reply}");
    let seen = read_all(ws, |_, _| {});
    let out = streamer.join().expect("stream");
    assert!(
        seen.texts
            .iter()
            .filter(|v| v["type"] == "layout")
            .all(|v| v["signals"].get("autocorrelation_left").is_none()),
        "the refused request was placed"
    );
    assert_eq!(out.report.lost_frames, 0, "{:?}", out.report);
}
