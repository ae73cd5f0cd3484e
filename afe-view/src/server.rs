//! The web side of the live view: an HTTP server on its own thread that serves the page
//! and a WebSocket per page, and a bridge thread that encodes the tap's batches once and
//! broadcasts them. A page that falls behind loses batches (counted and told to it),
//! never the others' and never the audio path's time. Who may connect and how much a
//! page may ask are checked here ([`AllowedOrigins`], [`Limits`]); each refusal is told
//! to the page and logged (at most a line a second).

use std::net::TcpListener;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, Sender, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use axum::extract::ws::{close_code, CloseFrame, Message, WebSocket, WebSocketUpgrade};
use axum::extract::State;
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use axum::Router;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use serde_json::{json, Value};
use tokio::sync::{broadcast, Semaphore};

use super::csp;
use super::limits::Rate;
use super::tap::{Batch, Edit, ToServer};
use super::ViewOptions;

/// The page's script, as inlined (its hash is in the page's Content Security Policy).
const SCRIPT: &str = concat!("\n", include_str!("page.js"));

/// The page, with its script inline: no CDN, works offline.
const PAGE: &str = concat!(
    include_str!("page.html"),
    "<script>",
    "\n",
    include_str!("page.js"),
    "</script>\n</body>\n</html>\n"
);

/// Batches a page may fall behind by before it loses some.
pub(crate) const PAGE_BACKLOG: usize = 32;

/// Longest a stopping server waits for its pages to be told the stream ended.
const GOODBYE: Duration = Duration::from_secs(1);

/// A message for pages, encoded once.
#[derive(Clone)]
pub(crate) enum Out {
    /// For every page.
    Text(Arc<str>),
    /// For one page: the reply to its edit.
    Reply { page: u64, text: Arc<str> },
    /// A batch of frames: without the input samples, and with them (for the pages that
    /// asked for the audio) when someone listens.
    Frames {
        plain: axum::body::Bytes,
        with_audio: Option<axum::body::Bytes>,
    },
    /// The stream has ended: pages are told and their sockets closed.
    End,
}

/// What the pages' tasks share.
pub(crate) struct Shared {
    pub out: broadcast::Sender<Out>,
    /// The last layout sent, for pages that connect later.
    pub layout: Mutex<String>,
    /// Edits for the tap (bounded: a full channel is "busy").
    pub edits: SyncSender<Edit>,
    /// Pages that closed, for the tap to remove their requests.
    pub departed: Sender<u64>,
    /// Pages that asked for the audio.
    pub listeners: Arc<AtomicUsize>,
    /// Pages connected.
    pub pages: AtomicUsize,
    /// The next page's id (replies are addressed by it).
    pub next_page: AtomicU64,
    pub options: ViewOptions,
    /// Refusals logged, at most a line a second.
    pub log: Mutex<Throttle>,
}

impl Shared {
    /// Logs a refusal on stderr, unless one was logged less than a second ago (then it
    /// is counted and the count given with the next line).
    fn log(&self, line: &str) {
        if let Ok(mut t) = self.log.lock() {
            t.log(line, Instant::now());
        }
    }
}

/// At most one log line a second, with the number of lines left out since the last.
#[derive(Default)]
pub(crate) struct Throttle {
    last: Option<Instant>,
    skipped: u64,
}

impl Throttle {
    fn log(&mut self, line: &str, now: Instant) {
        if self
            .last
            .is_some_and(|t| now.saturating_duration_since(t) < Duration::from_secs(1))
        {
            self.skipped += 1;
            return;
        }
        let more = match std::mem::take(&mut self.skipped) {
            0 => String::new(),
            n => format!(" ({n} more refused since the last line)"),
        };
        eprintln!("afe live view: {line}{more}");
        self.last = Some(now);
    }
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
            ToServer::Reply { page, text } => {
                let _ = shared.out.send(Out::Reply {
                    page,
                    text: text.into(),
                });
            }
            ToServer::Frames(mut batch) => {
                let with_audio = (!batch.audio.is_empty()).then(|| encode(&batch, true).into());
                let plain = encode(&batch, false).into();
                let _ = shared.out.send(Out::Frames { plain, with_audio });
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
/// points into (`offset` and `len` in values). The input samples are included only
/// `with_audio` (else `audio` is empty).
pub(crate) fn encode(b: &Batch, with_audio: bool) -> Vec<u8> {
    let audio: &[f32] = if with_audio { &b.audio } else { &[] };
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
    let audio_part = part(audio.len());
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
        "audio": audio_part,
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
        .chain(audio);
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Serves the page and the WebSockets on `listener` until `stop` fires: at most
/// `limits.connections` HTTP connections at once (more wait in the system's queue),
/// each closed if its headers take longer than `limits.header_timeout`.
pub(crate) fn serve(
    listener: TcpListener,
    shared: Arc<Shared>,
    stop: tokio::sync::oneshot::Receiver<()>,
) -> std::io::Result<()> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .enable_time()
        .build()?;
    rt.block_on(async move {
        let listener = tokio::net::TcpListener::from_std(listener)?;
        let limits = shared.options.limits.clone();
        let app = Router::new()
            .route("/", get(|| async { (csp::headers(SCRIPT), Html(PAGE)) }))
            .route("/ws", get(upgrade))
            .with_state(shared.clone());
        let connections = Arc::new(Semaphore::new(limits.connections.max(1)));
        tokio::pin!(stop);
        loop {
            let permit = tokio::select! {
                _ = &mut stop => break,
                permit = connections.clone().acquire_owned() => match permit {
                    Ok(p) => p,
                    Err(_) => break,
                },
            };
            let tcp = tokio::select! {
                _ = &mut stop => break,
                accepted = listener.accept() => match accepted {
                    Ok((tcp, _)) => tcp,
                    Err(_) => {
                        // out of descriptors or a reset before accept: try again shortly
                        tokio::time::sleep(Duration::from_millis(50)).await;
                        continue;
                    }
                },
            };
            let service = TowerToHyperService::new(app.clone());
            let timeout = limits.header_timeout;
            tokio::spawn(async move {
                let _permit = permit;
                let _ = hyper::server::conn::http1::Builder::new()
                    .timer(TokioTimer::new())
                    .header_read_timeout(timeout)
                    .serve_connection(TokioIo::new(tcp), service)
                    .with_upgrades()
                    .await;
            });
        }
        // the stream has ended (or the view is dropped): let the pages say goodbye
        let deadline = Instant::now() + GOODBYE;
        while shared.pages.load(Ordering::Relaxed) > 0 && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        Ok(())
    })
}

/// Opens a page's WebSocket if its origin is allowed (else HTTP 403 with the reason),
/// with the message size bounded.
async fn upgrade(
    ws: WebSocketUpgrade,
    headers: HeaderMap,
    State(shared): State<Arc<Shared>>,
) -> Response {
    let text = |name| {
        headers
            .get(name)
            .map(|v: &header::HeaderValue| v.to_str().unwrap_or("(not text)"))
    };
    if let Err(why) = shared
        .options
        .origins
        .check(text(header::ORIGIN), text(header::HOST))
    {
        shared.log(&format!("refused a WebSocket: {why}"));
        return (StatusCode::FORBIDDEN, format!("afe live view: {why}\n")).into_response();
    }
    let max = shared.options.limits.message_bytes;
    ws.max_message_size(max)
        .max_frame_size(max)
        .on_upgrade(move |socket| admit(socket, shared))
        .into_response()
}

/// A close frame with `reason` cut to what a close frame holds (123 bytes).
fn close(code: u16, reason: &str) -> Message {
    let mut end = reason.len().min(123);
    while !reason.is_char_boundary(end) {
        end -= 1;
    }
    Message::Close(Some(CloseFrame {
        code,
        reason: reason[..end].into(),
    }))
}

/// Counts the page in if there is room, else tells it why and closes.
async fn admit(mut socket: WebSocket, shared: Arc<Shared>) {
    let most = shared.options.limits.pages;
    let counted = shared
        .pages
        .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |n| {
            (n < most).then_some(n + 1)
        })
        .is_ok();
    if !counted {
        let why = format!("too many pages: {most} are connected, the most this server takes");
        shared.log(&format!("refused a page: {why}"));
        let refused = json!({ "type": "refused", "message": why }).to_string();
        let _ = socket.send(Message::Text(refused.into())).await;
        let _ = socket.send(close(close_code::AGAIN, &why)).await;
        return;
    }
    page(socket, &shared).await;
    shared.pages.fetch_sub(1, Ordering::Relaxed);
}

/// One page's connection: the current layout, then every broadcast message (the input
/// samples only if this page asked for them); the page's messages, at most
/// `messages_per_s`, become edits for the tap or switch its audio.
async fn page(mut socket: WebSocket, shared: &Shared) {
    let id = shared.next_page.fetch_add(1, Ordering::Relaxed);
    let mut rx = shared.out.subscribe();
    let layout = shared.layout.lock().map(|l| l.clone()).unwrap_or_default();
    let mut listening = false;
    let mut rate = Rate::new(shared.options.limits.messages_per_s);
    let mut ok = true;
    if !layout.is_empty() {
        ok = socket.send(Message::Text(layout.into())).await.is_ok();
    }
    while ok {
        tokio::select! {
            out = rx.recv() => {
                ok = match out {
                    Ok(Out::Text(t)) => socket.send(Message::Text(t.as_ref().into())).await.is_ok(),
                    Ok(Out::Reply { page, text }) if page == id => {
                        socket.send(Message::Text(text.as_ref().into())).await.is_ok()
                    }
                    Ok(Out::Reply { .. }) => true,
                    Ok(Out::Frames { plain, with_audio }) => {
                        let b = match with_audio {
                            Some(a) if listening => a,
                            _ => plain,
                        };
                        socket.send(Message::Binary(b)).await.is_ok()
                    }
                    Ok(Out::End) => {
                        let end = json!({ "type": "end" }).to_string();
                        let _ = socket.send(Message::Text(end.into())).await;
                        let _ = socket.send(close(close_code::NORMAL, "the stream has ended")).await;
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
                let reply = match incoming {
                    Some(Ok(Message::Close(_))) | None => break,
                    Some(Err(e)) => {
                        let e = e.into_inner();
                        if let Some(tungstenite::Error::Capacity(too_big)) = e.downcast_ref() {
                            let why = format!(
                                "message refused, the largest taken is {} bytes ({too_big})",
                                shared.options.limits.message_bytes
                            );
                            shared.log(&format!("closed page {id}: {why}"));
                            let _ = socket.send(close(close_code::SIZE, &why)).await;
                        }
                        break;
                    }
                    Some(Ok(_)) if !rate.take() => Some(refusal(
                        None,
                        &format!(
                            "too many messages: at most {} a second; this one was dropped",
                            shared.options.limits.messages_per_s
                        ),
                    )),
                    Some(Ok(Message::Text(text))) => handle(text.as_str(), id, shared, &mut listening),
                    Some(Ok(Message::Binary(_))) => Some(refusal(None, "binary messages are not understood: send JSON text")),
                    Some(Ok(_)) => None,
                };
                if let Some(r) = reply {
                    ok = socket.send(Message::Text(r.into())).await.is_ok();
                }
            }
        }
    }
    if listening {
        shared.listeners.fetch_sub(1, Ordering::Relaxed);
    }
    // its requests leave with it
    let _ = shared.departed.send(id);
}

/// A refusal for this page alone, for `op` if known.
fn refusal(op: Option<&str>, message: &str) -> String {
    json!({ "type": "reply", "op": op, "ok": false, "message": message }).to_string()
}

/// Acts on a page's message; returns a reply for that page (errors in the message
/// itself, a full edit queue, the audio switch), or `None` when the tap will reply.
fn handle(text: &str, page: u64, shared: &Shared, listening: &mut bool) -> Option<String> {
    let Ok(Value::Object(msg)) = serde_json::from_str::<Value>(text) else {
        return Some(refusal(
            None,
            &format!(
                "not a JSON object: {}",
                text.chars().take(80).collect::<String>()
            ),
        ));
    };
    let str_of = |k: &str| msg.get(k).and_then(Value::as_str).map(str::to_string);
    let op = msg.get("op").and_then(Value::as_str);
    let edit = match op {
        Some("add") => {
            let Some(name) = str_of("request") else {
                return Some(refusal(op, "add: give \"request\""));
            };
            let params = match msg.get("params") {
                None | Some(Value::Null) => afe_core::ParamMap::new(),
                Some(Value::Object(p)) => p.clone().into_iter().collect(),
                Some(_) => return Some(refusal(op, "add: \"params\" must be an object")),
            };
            Edit::Add { page, name, params }
        }
        Some("remove") => match msg.get("handle").and_then(Value::as_u64) {
            Some(h) => Edit::Remove {
                page,
                handle: usize::try_from(h).unwrap_or(usize::MAX),
            },
            None => return Some(refusal(op, "remove: give the request's \"handle\"")),
        },
        Some("set") => match (str_of("name"), msg.get("value")) {
            (Some(name), Some(value)) => Edit::Set {
                page,
                name,
                value: value.clone(),
            },
            _ => return Some(refusal(op, "set: give \"name\" and \"value\"")),
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
            let message = if on { "audio on" } else { "audio off" };
            return Some(
                json!({ "type": "reply", "op": "audio", "ok": true, "message": message })
                    .to_string(),
            );
        }
        other => {
            return Some(refusal(
                None,
                &format!("unknown op {other:?}: expected add, remove, set or audio"),
            ))
        }
    };
    match shared.edits.try_send(edit) {
        Ok(()) => None,
        Err(TrySendError::Full(_)) => Some(refusal(
            op,
            &format!(
                "busy: {} edits wait for the stream; try again in a moment",
                shared.options.limits.edits_waiting
            ),
        )),
        Err(TrySendError::Disconnected(_)) => Some(refusal(op, "the stream has ended")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_are_logged_at_most_once_a_second() {
        let mut t = Throttle::default();
        let start = Instant::now();
        t.log("one", start);
        assert!(t.last == Some(start));
        for ms in 1..100 {
            t.log("more", start + Duration::from_millis(ms));
        }
        assert_eq!(t.skipped, 99);
        t.log("later", start + Duration::from_millis(1500));
        assert_eq!(t.skipped, 0);
    }
}
