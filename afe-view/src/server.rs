//! The web side of the live view: an HTTP server (axum) on its own thread that serves
//! the page and a WebSocket per page, and a bridge thread that encodes the tap's batches
//! once and broadcasts them. A page that falls behind loses batches (counted and told to
//! it), never the others' and never the audio path's time.

use std::net::TcpListener;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, Sender};
use std::sync::{Arc, Mutex};

use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::State;
use axum::response::{Html, IntoResponse};
use axum::routing::get;
use axum::Router;
use serde_json::{json, Value};
use tokio::sync::broadcast;

use super::tap::{Batch, Edit, ToServer};

/// The page, with its script inline: no CDN, works offline.
const PAGE: &str = concat!(
    include_str!("page.html"),
    "<script>\n",
    include_str!("page.js"),
    "</script>\n</body>\n</html>\n"
);

/// Batches a page may fall behind by before it loses some.
pub(crate) const PAGE_BACKLOG: usize = 32;

/// A message for every page, encoded once.
#[derive(Clone)]
pub(crate) enum Out {
    Text(Arc<str>),
    Binary(axum::body::Bytes),
    /// The stream has ended: pages are told and their sockets closed.
    End,
}

/// What the pages' tasks share.
pub(crate) struct Shared {
    pub out: broadcast::Sender<Out>,
    /// The last layout sent, for pages that connect later.
    pub layout: Mutex<String>,
    pub edits: Mutex<Sender<Edit>>,
    /// Pages that asked for the audio.
    pub listeners: Arc<AtomicUsize>,
    /// Pages connected.
    pub pages: AtomicUsize,
}

/// Encodes the tap's messages and broadcasts them, returning each batch to the pool.
pub(crate) fn bridge(from_tap: Receiver<ToServer>, pool: Sender<Batch>, shared: Arc<Shared>) {
    while let Ok(msg) = from_tap.recv() {
        match msg {
            ToServer::Text(text) => {
                if text.starts_with("{\"type\":\"layout\"") {
                    if let Ok(mut l) = shared.layout.lock() {
                        l.clone_from(&text);
                    }
                }
                let _ = shared.out.send(Out::Text(text.into()));
            }
            ToServer::Frames(mut batch) => {
                let _ = shared.out.send(Out::Binary(encode(&batch).into()));
                batch.clear();
                if pool.send(batch).is_err() {
                    break;
                }
            }
        }
    }
    let _ = shared.out.send(Out::End);
}

/// A batch as one binary message: a little-endian `u32` header length, the JSON header,
/// padding to a multiple of 4 bytes, then the little-endian `f32` values the header
/// points into (`offset` and `len` in values).
pub(crate) fn encode(b: &Batch) -> Vec<u8> {
    let mut offset = 0;
    let mut part = |len: usize| {
        let at = offset;
        offset += len;
        json!({ "offset": at, "len": len })
    };
    let signals: Vec<Value> = b
        .slots
        .iter()
        .map(|s| {
            let mut v = part(s.data.len());
            v["key"] = json!(s.key);
            v["first_frame"] = json!(s.first_frame);
            v["rows"] = json!(s.rows);
            v["frame_shape"] = json!(s.frame_shape);
            v
        })
        .collect();
    let wave = part(b.wave.len());
    let audio = part(b.audio.len());
    let header = json!({
        "type": "frames",
        "blocks": b.blocks,
        "frames_total": b.frames_total,
        "lost_frames": b.lost_frames,
        "dropped_frames": b.dropped_frames,
        "compute_ms_max": b.compute_ms_max,
        "budget_ms": b.budget_ms,
        "signals": signals,
        "wave": wave,
        "audio": audio,
    })
    .to_string();
    let pad = (4 - (4 + header.len()) % 4) % 4;
    let mut out = Vec::with_capacity(4 + header.len() + pad + 4 * offset);
    out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend(std::iter::repeat_n(b' ', pad));
    let values = b
        .slots
        .iter()
        .flat_map(|s| s.data.iter())
        .chain(&b.wave)
        .chain(&b.audio);
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Serves the page and the WebSockets on `listener` until `stop` fires.
pub(crate) fn serve(
    listener: TcpListener,
    shared: Arc<Shared>,
    stop: tokio::sync::oneshot::Receiver<()>,
) -> std::io::Result<()> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .build()?;
    rt.block_on(async move {
        let listener = tokio::net::TcpListener::from_std(listener)?;
        let app = Router::new()
            .route("/", get(|| async { Html(PAGE) }))
            .route("/ws", get(upgrade))
            .with_state(shared);
        axum::serve(listener, app)
            .with_graceful_shutdown(async {
                let _ = stop.await;
            })
            .await
    })
}

async fn upgrade(ws: WebSocketUpgrade, State(shared): State<Arc<Shared>>) -> impl IntoResponse {
    ws.on_upgrade(move |socket| page(socket, shared))
}

/// One page's connection: the current layout, then every broadcast
/// message; the page's requests (edits, audio on or off) go to the tap.
async fn page(mut socket: WebSocket, shared: Arc<Shared>) {
    let mut rx = shared.out.subscribe();
    shared.pages.fetch_add(1, Ordering::Relaxed);
    let layout = shared.layout.lock().map(|l| l.clone()).unwrap_or_default();
    let mut listening = false;
    let mut ok = true;
    if !layout.is_empty() {
        ok = socket.send(Message::Text(layout.into())).await.is_ok();
    }
    while ok {
        tokio::select! {
            out = rx.recv() => {
                ok = match out {
                    Ok(Out::Text(t)) => socket.send(Message::Text(t.as_ref().into())).await.is_ok(),
                    Ok(Out::Binary(b)) => socket.send(Message::Binary(b)).await.is_ok(),
                    Ok(Out::End) => {
                        let end = json!({ "type": "end" }).to_string();
                        let _ = socket.send(Message::Text(end.into())).await;
                        let _ = socket.send(Message::Close(None)).await;
                        false
                    }
                    Err(broadcast::error::RecvError::Lagged(n)) => {
                        let note = json!({ "type": "lagged", "batches": n }).to_string();
                        socket.send(Message::Text(note.into())).await.is_ok()
                    }
                    Err(broadcast::error::RecvError::Closed) => false,
                };
            }
            incoming = socket.recv() => {
                ok = match incoming {
                    Some(Ok(Message::Text(text))) => {
                        let reply = handle(text.as_str(), &shared, &mut listening);
                        match reply {
                            Some(r) => socket.send(Message::Text(r.into())).await.is_ok(),
                            None => true,
                        }
                    }
                    Some(Ok(Message::Close(_))) | None | Some(Err(_)) => false,
                    Some(Ok(_)) => true,
                };
            }
        }
    }
    if listening {
        shared.listeners.fetch_sub(1, Ordering::Relaxed);
    }
    shared.pages.fetch_sub(1, Ordering::Relaxed);
}

/// Acts on a page's message; returns a reply for that page alone (errors in the
/// message itself, the audio switch), or `None` when the tap will reply to all.
fn handle(text: &str, shared: &Shared, listening: &mut bool) -> Option<String> {
    let error = |m: String| Some(json!({ "type": "reply", "ok": false, "message": m }).to_string());
    let Ok(Value::Object(msg)) = serde_json::from_str::<Value>(text) else {
        return error(format!(
            "not a JSON object: {}",
            text.chars().take(80).collect::<String>()
        ));
    };
    let str_of = |k: &str| msg.get(k).and_then(Value::as_str).map(str::to_string);
    let edit = match msg.get("op").and_then(Value::as_str) {
        Some("add") => {
            let Some(name) = str_of("request") else {
                return error("add: give \"request\"".into());
            };
            let params = match msg.get("params") {
                None | Some(Value::Null) => afe_core::ParamMap::new(),
                Some(Value::Object(p)) => p.clone().into_iter().collect(),
                Some(_) => return error("add: \"params\" must be an object".into()),
            };
            Edit::Add { name, params }
        }
        Some("remove") => match msg.get("handle").and_then(Value::as_u64) {
            Some(h) => Edit::Remove(h as usize),
            None => return error("remove: give the request's \"handle\"".into()),
        },
        Some("set") => match (str_of("name"), msg.get("value")) {
            (Some(name), Some(value)) => Edit::Set {
                name,
                value: value.clone(),
            },
            _ => return error("set: give \"name\" and \"value\"".into()),
        },
        Some("audio") => {
            let on = msg.get("on").and_then(Value::as_bool).unwrap_or(false);
            if on != *listening {
                *listening = on;
                if on {
                    shared.listeners.fetch_add(1, Ordering::Relaxed);
                } else {
                    shared.listeners.fetch_sub(1, Ordering::Relaxed);
                }
            }
            return Some(json!({ "type": "reply", "op": "audio", "ok": true, "message": if on { "audio on" } else { "audio off" } }).to_string());
        }
        other => {
            return error(format!(
                "unknown op {other:?}: expected add, remove, set or audio"
            ))
        }
    };
    match shared.edits.lock().map(|tx| tx.send(edit)) {
        Ok(Ok(())) => None,
        _ => error("the stream has ended".into()),
    }
}
