//! The client side: [`Client`] finds a server and subscribes to requests; a
//! [`Subscription`] yields each block's new frames with their indices and counts what
//! was lost on the way.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use afe_core::ParamMap;
use serde_json::{json, Value};
use zenoh::handlers::{RingChannel, RingChannelHandler};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::sample::{Sample, SampleKind};
use zenoh::{Session, Wait};

use super::wire::{self, SignalPart};
use super::{check_name, config, key, RemoteError};
use afe::frames::{FrameBlock, Frames};

/// Blocks a subscription keeps for a reader that has not taken them (0.64 s at 10 ms).
const RECEIVE_QUEUE: usize = 64;
/// How long a query waits for the server's reply.
const QUERY_WAIT: Duration = Duration::from_secs(10);

/// A connection to an `afe serve` server.
pub struct Client {
    session: Session,
    name: String,
    id: String,
    /// The secret the server gave with this client's first subscription: it must come
    /// with every later subscription and cancellation. Held while a subscription is
    /// asked for, so that two first subscriptions are not asked for at once.
    secret: Arc<Mutex<Option<String>>>,
    catalogue: Value,
    gone: Arc<AtomicBool>,
    _token: LivelinessToken,
    _watch: Subscriber<()>,
}

impl Client {
    /// Connects (as a Zenoh client, multicast scouting off) to the server listening on
    /// `endpoint`, e.g. `tcp/127.0.0.1:7447`; `name` picks a server when several answer.
    pub fn connect(endpoint: &str, name: Option<&str>) -> Result<Client, RemoteError> {
        let session = zenoh::open(config(None, "peer", &[], &[endpoint.to_string()])?)
            .wait()
            .map_err(|e| RemoteError::NoServer(format!("cannot reach {endpoint}: {e}")))?;
        let name = match name {
            Some(n) => {
                check_name(n)?;
                n.to_string()
            }
            None => discover(&session, endpoint)?,
        };
        let catalogue = query(&session, &key(&name, "catalogue"), None)?;
        let id = session.zid().to_string();
        let token = session
            .liveliness()
            .declare_token(key(&name, &format!("client/{id}")))
            .wait()?;
        let gone = Arc::new(AtomicBool::new(false));
        let flag = gone.clone();
        let watch = session
            .liveliness()
            .declare_subscriber(key(&name, "server"))
            .callback(move |s| {
                if s.kind() == SampleKind::Delete {
                    flag.store(true, Ordering::Relaxed);
                }
            })
            .wait()?;
        Ok(Client {
            session,
            name,
            id,
            secret: Arc::new(Mutex::new(None)),
            catalogue,
            gone,
            _token: token,
            _watch: watch,
        })
    }

    /// The server's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The server's catalogue: `fs_hz`, `ears`, `block_frames`, `wire_version` and
    /// `requests` (as `afe list --json` gives them).
    pub fn catalogue(&self) -> &Value {
        &self.catalogue
    }

    /// Sampling rate of the server's stream, Hz.
    pub fn fs(&self) -> f64 {
        self.catalogue["fs_hz"].as_f64().unwrap_or(0.0)
    }

    /// The Zenoh session, for the remote source's own subscriber.
    pub(super) fn session(&self) -> &Session {
        &self.session
    }

    /// Reports the robot head's yaw `yaw_deg` (deg, positive to the left) at `t_s` (s of
    /// the server's stream) on `afe/<name>/head/yaw`, as a motor controller does; the
    /// server refuses (and counts) a time that does not increase or a yaw beyond its neck.
    pub fn set_head_yaw(&self, t_s: f64, yaw_deg: f64) -> Result<(), RemoteError> {
        if !(t_s.is_finite() && yaw_deg.is_finite()) {
            return Err(RemoteError::Options(format!(
                "head yaw: the point ({t_s}, {yaw_deg}) is not finite"
            )));
        }
        let point = serde_json::json!({ "t_s": t_s, "yaw_deg": yaw_deg }).to_string();
        self.session
            .put(key(&self.name, "head/yaw"), point)
            .wait()?;
        Ok(())
    }

    /// Whether the server has gone.
    pub fn server_gone(&self) -> bool {
        self.gone.load(Ordering::Relaxed)
    }

    /// Subscribes to requests, each with its parameters; equal requests of other clients
    /// share their processors. The frames start with the server's next block. The first
    /// subscription's reply gives this client's secret token, sent with every later
    /// subscription and cancellation; beyond the server's limits (clients, subscriptions
    /// per client) the server refuses, naming the limit.
    pub fn subscribe(&self, requests: &[(&str, ParamMap)]) -> Result<Subscription, RemoteError> {
        let mut secret = self.secret.lock().unwrap_or_else(PoisonError::into_inner);
        let mut body = json!({
            "client": self.id,
            "requests": requests
                .iter()
                .map(|(name, params)| json!({ "name": name, "params": params }))
                .collect::<Vec<_>>(),
        });
        if let Some(token) = secret.as_ref() {
            body["token"] = json!(token);
        }
        let reply = query(&self.session, &key(&self.name, "subscribe"), Some(body))?;
        let bad = |what: &str| RemoteError::Malformed(format!("subscription reply without {what}"));
        let id = reply["subscription"].as_u64().ok_or_else(|| bad("an id"))?;
        let token = reply["token"].as_str().ok_or_else(|| bad("a token"))?;
        *secret = Some(token.to_string());
        drop(secret);
        let frames_key = reply["key"]
            .as_str()
            .ok_or_else(|| bad("a key"))?
            .to_string();
        let signals: Vec<SignalMeta> = reply["signals"]
            .as_array()
            .ok_or_else(|| bad("signals"))?
            .iter()
            .map(SignalMeta::from_description)
            .collect::<Result<_, _>>()?;
        // a ring: a reader that stalls loses its oldest blocks (counted from the message
        // numbers) instead of holding up the session's reception
        let subscriber = self
            .session
            .declare_subscriber(frames_key)
            .with(RingChannel::new(RECEIVE_QUEUE))
            .wait()?;
        Ok(Subscription {
            session: self.session.clone(),
            name: self.name.clone(),
            client: self.id.clone(),
            secret: self.secret.clone(),
            id,
            next_frame: reply["signals"]
                .as_array()
                .map(|v| v.iter().map(|d| d["first_frame"].as_u64()).collect())
                .unwrap_or_default(),
            lost_frames: vec![0; signals.len()],
            signals,
            subscriber,
            next_seq: 0,
            lost_messages: 0,
            reply,
            gone: self.gone.clone(),
        })
    }
}

/// The name of the one server answering at `endpoint`.
fn discover(session: &Session, endpoint: &str) -> Result<String, RemoteError> {
    let replies = session.get("afe/*/catalogue").timeout(QUERY_WAIT).wait()?;
    let mut names: Vec<String> = Vec::new();
    while let Ok(reply) = replies.recv() {
        if let Ok(sample) = reply.result() {
            let k = sample.key_expr().as_str();
            if let Some(n) = k
                .strip_prefix("afe/")
                .and_then(|r| r.strip_suffix("/catalogue"))
            {
                names.push(n.to_string());
            }
        }
    }
    names.sort();
    names.dedup();
    match names.len() {
        0 => Err(RemoteError::NoServer(format!(
            "no afe server answered at {endpoint}"
        ))),
        1 => Ok(names.remove(0)),
        _ => Err(RemoteError::NoServer(format!(
            "several afe servers answer at {endpoint} ({}): name one",
            names.join(", ")
        ))),
    }
}

/// Sends a query to `k` and returns its one reply's JSON; an error reply is
/// [`RemoteError::Refused`].
pub(super) fn query(session: &Session, k: &str, body: Option<Value>) -> Result<Value, RemoteError> {
    let mut get = session.get(k).timeout(QUERY_WAIT);
    if let Some(b) = body {
        get = get.payload(b.to_string());
    }
    let replies = get.wait()?;
    let reply = replies
        .recv()
        .map_err(|_| RemoteError::NoServer(format!("no reply on {k}: is the server running?")))?;
    let parse = |bytes: &[u8]| -> Result<Value, RemoteError> {
        serde_json::from_slice(bytes).map_err(|e| RemoteError::Malformed(e.to_string()))
    };
    match reply.result() {
        Ok(sample) => parse(&sample.payload().to_bytes()),
        Err(e) => {
            let bytes = e.payload().to_bytes();
            match parse(&bytes) {
                Ok(v) => Err(RemoteError::Refused(
                    v["error"].as_str().unwrap_or("no reason given").to_string(),
                )),
                // Zenoh's own error replies (e.g. "Timeout") are plain text
                Err(_) => Err(RemoteError::NoServer(format!(
                    "no answer on {k}: {}",
                    String::from_utf8_lossy(&bytes)
                ))),
            }
        }
    }
}

/// What a subscriber knows of one of its signals.
#[derive(Debug, Clone)]
struct SignalMeta {
    key: String,
    frame_shape: Vec<usize>,
    complex: bool,
}

impl SignalMeta {
    fn from_description(d: &Value) -> Result<Self, RemoteError> {
        let bad = || RemoteError::Malformed(format!("signal description {d}"));
        Ok(SignalMeta {
            key: d["key"].as_str().ok_or_else(bad)?.to_string(),
            frame_shape: d["frame_shape"]
                .as_array()
                .ok_or_else(bad)?
                .iter()
                .map(|v| v.as_u64().map(|n| n as usize).ok_or_else(bad))
                .collect::<Result<_, _>>()?,
            complex: d["dtype"] == "complex128",
        })
    }
}

/// A subscription: its blocks in order, with what was lost counted; it is released on the
/// server when dropped (or when its client goes).
pub struct Subscription {
    session: Session,
    name: String,
    client: String,
    secret: Arc<Mutex<Option<String>>>,
    id: u64,
    signals: Vec<SignalMeta>,
    subscriber: Subscriber<RingChannelHandler<Sample>>,
    next_seq: u64,
    lost_messages: u64,
    next_frame: Vec<Option<u64>>,
    lost_frames: Vec<u64>,
    reply: Value,
    gone: Arc<AtomicBool>,
}

impl Subscription {
    /// The server's reply: `subscription`, `key`, `signals` (each signal's description,
    /// as [`afe::metadata::describe`] gives it, with its `first_frame`), `fs_hz`,
    /// `ears`, `block_frames`, `start_frame`.
    pub fn reply(&self) -> &Value {
        &self.reply
    }

    /// The subscription's number on the server.
    pub fn id(&self) -> u64 {
        self.id
    }

    /// Output names of the signals, in order.
    pub fn keys(&self) -> Vec<&str> {
        self.signals.iter().map(|s| s.key.as_str()).collect()
    }

    /// Messages lost so far (a slow client's, or the network's).
    pub fn lost_messages(&self) -> u64 {
        self.lost_messages
    }

    /// Frames lost so far per signal, in order.
    pub fn lost_frames(&self) -> &[u64] {
        &self.lost_frames
    }

    /// The next block's frames; `None` if none came within `timeout`. An error when the
    /// server has gone or sent a malformed message.
    pub fn recv(&mut self, timeout: Duration) -> Result<Option<Frames>, RemoteError> {
        let sample = match self.subscriber.recv_timeout(timeout) {
            Ok(Some(s)) => s,
            Ok(None) if self.gone.load(Ordering::Relaxed) => {
                return Err(RemoteError::ServerGone(self.name.clone()))
            }
            Ok(None) => return Ok(None),
            Err(e) => return Err(RemoteError::Zenoh(e.to_string())),
        };
        let (h, parts) = wire::read_frames(&sample.payload().to_bytes())?;
        if parts.len() != self.signals.len() {
            return Err(RemoteError::Malformed(format!(
                "{} signals in a message of a subscription to {}",
                parts.len(),
                self.signals.len()
            )));
        }
        // every subscription's messages are numbered from 0
        let lost_messages = h.seq.saturating_sub(self.next_seq);
        self.lost_messages += lost_messages;
        self.next_seq = h.seq + 1;
        let mut signals = Vec::with_capacity(parts.len());
        for (i, (meta, part)) in self.signals.iter().zip(parts).enumerate() {
            let SignalPart {
                first_frame,
                rows,
                values,
                ..
            } = part;
            if let Some(expected) = self.next_frame.get(i).copied().flatten() {
                self.lost_frames[i] += first_frame.saturating_sub(expected);
            }
            if let Some(next) = self.next_frame.get_mut(i) {
                *next = Some(first_frame + rows as u64);
            }
            signals.push(FrameBlock {
                key: meta.key.clone(),
                first_frame,
                frame_shape: meta.frame_shape.clone(),
                complex: meta.complex,
                rows,
                values,
            });
        }
        Ok(Some(Frames {
            seq: h.seq,
            first_input_frame: h.first_input_frame,
            input_frames: h.input_frames as usize,
            t_ns: h.t_ns,
            lost_messages,
            signals,
        }))
    }
}

impl Drop for Subscription {
    fn drop(&mut self) {
        if !self.gone.load(Ordering::Relaxed) {
            let token = self
                .secret
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .clone();
            let body = json!({ "client": self.client, "subscription": self.id, "token": token });
            let _ = query(&self.session, &key(&self.name, "unsubscribe"), Some(body));
        }
    }
}
