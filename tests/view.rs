//! The live view end to end on loopback: the page is served, a WebSocket client gets
//! the layout and every frame of the stream (equal to the recorded output, as f32), its
//! edits change the graph, bad messages get error replies, and a client that never
//! reads costs the others nothing.
#![cfg(feature = "view")]

use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use afe::stream::{run, StreamJob};
use afe_bass_source::{Pacing, Synth};
use afe_view::{View, ViewOptions};
use serde_json::{json, Value};
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
}

fn connect(addr: std::net::SocketAddr) -> Socket {
    let (ws, _) = tungstenite::connect(format!("ws://{addr}/ws")).expect("connect");
    if let tungstenite::stream::MaybeTlsStream::Plain(s) = ws.get_ref() {
        s.set_read_timeout(Some(Duration::from_secs(5)))
            .expect("timeout");
    }
    ws
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
            Message::Close(_) => break,
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
    let reader = connect(addr);
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
