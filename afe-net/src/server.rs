//! The server side: a Zenoh session that answers the catalogue and subscription queries
//! and watches its clients' liveliness, and the stream's observer ([`ServeTap`]) that
//! places and removes the subscribed requests between blocks and hands each block's
//! messages to publishing threads without ever waiting for them.

use std::collections::HashSet;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender, SyncSender};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use afe_core::ParamMap;
use afe_graph::{Manager, RequestHandle};
use serde::Deserialize;
use serde_json::{json, Value};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::query::{Query, Queryable};
use zenoh::sample::SampleKind;
use zenoh::{Session, Wait};

use super::wire::{self, Header, Kind};
use super::{
    check_name, config, key, RemoteError, MAX_QUERY_BYTES, MAX_REQUESTS, MAX_SUBSCRIPTIONS,
};
use afe::metadata::describe;
use afe::stream::{Observer, Timing};

/// Messages a subscription may have on their way to its client before the next are
/// dropped for it alone (at 10-ms blocks, 0.32 s).
const SUB_QUEUE: usize = 32;
/// Audio blocks on their way to the network before the next are dropped.
const AUDIO_QUEUE: usize = 32;
/// How long a new subscription's messages wait for its client's subscriber.
const MATCH_WAIT: Duration = Duration::from_secs(2);
/// How long a query waits for the audio thread to act on it.
const EDIT_WAIT: Duration = Duration::from_secs(5);
/// How long a subscription waits for its client's liveliness token to be seen.
const CLIENT_WAIT: Duration = Duration::from_secs(2);
/// How often the query thread looks whether its server has gone.
const QUERY_POLL: Duration = Duration::from_millis(50);

/// Where and under which name to serve.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// Zenoh endpoints to listen on, e.g. `tcp/127.0.0.1:7447`.
    pub listen: Vec<String>,
    /// The server's name: its keys are `afe/<name>/...`.
    pub name: String,
    /// A Zenoh configuration file (JSON5) to start from, e.g. with authentication.
    pub config_file: Option<PathBuf>,
}

impl Default for ServeOptions {
    fn default() -> Self {
        ServeOptions {
            listen: vec![super::DEFAULT_LISTEN.to_string()],
            name: super::DEFAULT_NAME.to_string(),
            config_file: None,
        }
    }
}

/// Queries waiting for the query thread before the next are turned away.
const QUERY_BACKLOG: usize = 64;

/// The server's queryables.
#[derive(Debug, Clone, Copy)]
enum Op {
    Catalogue,
    Subscribe,
    Unsubscribe,
}

/// A query's outcome, sent back from the audio thread.
type Outcome = Result<Value, String>;

/// What the Zenoh side asks of the audio thread.
enum Edit {
    Subscribe {
        client: String,
        requests: Vec<RequestSpec>,
        reply: SyncSender<Outcome>,
    },
    Unsubscribe {
        client: String,
        subscription: u64,
        reply: SyncSender<Outcome>,
    },
    ClientGone(String),
}

/// One request of a subscription.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RequestSpec {
    name: String,
    #[serde(default)]
    params: ParamMap,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SubscribeQuery {
    client: String,
    requests: Vec<RequestSpec>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct UnsubscribeQuery {
    client: String,
    subscription: u64,
}

/// State the Zenoh callbacks share.
struct Shared {
    edits: Mutex<Sender<Edit>>,
    /// The catalogue's JSON, once the stream has started.
    catalogue: Mutex<Option<String>>,
    /// Clients whose liveliness token is up.
    clients: Mutex<HashSet<String>>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A running server; its keys go when it is dropped.
pub struct Server {
    session: Session,
    name: String,
    authenticated: bool,
    _queryables: Vec<Queryable<()>>,
    _clients: Subscriber<()>,
    _token: LivelinessToken,
    /// The thread answering queries, joined when the server goes; `stop` ends it.
    queries: Option<JoinHandle<()>>,
    stop: Arc<AtomicBool>,
}

impl Server {
    /// Opens a Zenoh peer listening on `options.listen` (multicast scouting off) and
    /// declares the server's keys; returns it and the stream's observer.
    pub fn start(options: &ServeOptions) -> Result<(Server, ServeTap), RemoteError> {
        check_name(&options.name)?;
        let name = options.name.clone();
        let base = match &options.config_file {
            Some(path) => Some(zenoh::Config::from_file(path).map_err(|e| {
                RemoteError::Zenoh(format!("configuration '{}': {e}", path.display()))
            })?),
            None => None,
        };
        let mut config = config(base, "peer", &options.listen, &[])?;
        // room for bursts on every link (16 batches, not 2), and a wait for a busy link
        // long enough that a client which keeps up never loses a message to a scheduling
        // hiccup; the wait is on the subscription's own publishing thread
        config.insert_json5("transport/link/tx/queue/size/data_high", "16")?;
        config.insert_json5(
            "transport/link/tx/queue/congestion_control/drop/wait_before_drop",
            "20000",
        )?;
        let authenticated = config
            .get_json("transport/auth/usrpwd/user")
            .is_ok_and(|u| u != "null");
        let session = zenoh::open(config).wait()?;
        let (edits_tx, edits_rx) = mpsc::channel();
        let shared = Arc::new(Shared {
            edits: Mutex::new(edits_tx),
            catalogue: Mutex::new(None),
            clients: Mutex::new(HashSet::new()),
        });
        let client_prefix = key(&name, "client/");
        let watch = shared.clone();
        let clients = session
            .liveliness()
            .declare_subscriber(key(&name, "client/*"))
            .history(true)
            .callback(move |sample| {
                let Some(id) = sample.key_expr().as_str().strip_prefix(&client_prefix) else {
                    return;
                };
                if sample.kind() == SampleKind::Put {
                    lock(&watch.clients).insert(id.to_string());
                } else {
                    lock(&watch.clients).remove(id);
                    let _ = lock(&watch.edits).send(Edit::ClientGone(id.to_string()));
                }
            })
            .wait()?;
        // queries are answered on a thread of their own: one that waits (for a client's
        // token, for the audio thread) must not hold up Zenoh's reception on its link
        let (queries, pending) = mpsc::sync_channel::<(Op, Query)>(QUERY_BACKLOG);
        let worker = shared.clone();
        let catalogue_key = key(&name, "catalogue");
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = stop.clone();
        let query_thread = std::thread::Builder::new()
            .name("afe-zenoh-queries".into())
            .spawn(move || {
                while !stopped.load(Ordering::Relaxed) {
                    let (op, q) = match pending.recv_timeout(QUERY_POLL) {
                        Ok(query) => query,
                        Err(mpsc::RecvTimeoutError::Timeout) => continue,
                        Err(mpsc::RecvTimeoutError::Disconnected) => break,
                    };
                    let outcome = match op {
                        Op::Catalogue => catalogue(&worker),
                        Op::Subscribe => subscribe(&worker, &q),
                        Op::Unsubscribe => unsubscribe(&worker, &q),
                    };
                    // on the queryable's own key: a query for afe/*/catalogue learns the name
                    let on = match op {
                        Op::Catalogue => catalogue_key.as_str(),
                        _ => q.key_expr().as_str(),
                    };
                    answer(&q, on, outcome);
                }
            })
            .map_err(|e| RemoteError::Zenoh(format!("cannot start the query thread: {e}")))?;
        let mut queryables = Vec::new();
        for (op, what) in [
            (Op::Catalogue, "catalogue"),
            (Op::Subscribe, "subscribe"),
            (Op::Unsubscribe, "unsubscribe"),
        ] {
            let queries = queries.clone();
            queryables.push(
                session
                    .declare_queryable(key(&name, what))
                    .callback(move |q| {
                        if let Err(mpsc::TrySendError::Full((_, q))) = queries.try_send((op, q)) {
                            answer(
                                &q,
                                q.key_expr().as_str(),
                                Err("the server is busy: try again".into()),
                            );
                        }
                    })
                    .wait()?,
            );
        }
        let token = session
            .liveliness()
            .declare_token(key(&name, "server"))
            .wait()?;
        let audio = Outlet::spawn(&session, key(&name, "audio"), AUDIO_QUEUE, false)?;
        let report = Outlet::spawn(&session, key(&name, "report"), 2, false)?;
        let tap = ServeTap {
            session: session.clone(),
            name: name.clone(),
            shared,
            edits: edits_rx,
            subs: Vec::new(),
            next_sid: 0,
            audio,
            audio_seq: 0,
            audio_dropped: 0,
            report,
            next_report: 0,
            started: false,
        };
        Ok((
            Server {
                session,
                name,
                authenticated,
                _queryables: queryables,
                _clients: clients,
                _token: token,
                queries: Some(query_thread),
                stop,
            },
            tap,
        ))
    }

    /// The server's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Whether its Zenoh configuration asks clients for a user and password.
    pub fn authenticated(&self) -> bool {
        self.authenticated
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.session.close().wait();
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.queries.take() {
            let _ = thread.join();
        }
    }
}

/// Replies to `q` on key `on` with the JSON of `outcome`, or an error reply
/// `{"error": message}`.
fn answer(q: &Query, on: &str, outcome: Outcome) {
    let _ = match outcome {
        Ok(v) => q.reply(on.to_string(), v.to_string()).wait(),
        Err(message) => q.reply_err(json!({ "error": message }).to_string()).wait(),
    };
}

/// The catalogue, once the stream runs.
fn catalogue(shared: &Shared) -> Outcome {
    let start = Instant::now();
    loop {
        if let Some(c) = lock(&shared.catalogue).as_ref() {
            return serde_json::from_str(c).map_err(|e| e.to_string());
        }
        if start.elapsed() > EDIT_WAIT {
            return Err("the server's stream has not started".into());
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The query's JSON payload, bounded in size.
fn payload<T: serde::de::DeserializeOwned>(q: &Query) -> Result<T, String> {
    let bytes = q
        .payload()
        .map(|p| p.to_bytes().into_owned())
        .unwrap_or_default();
    if bytes.len() > MAX_QUERY_BYTES {
        return Err(format!(
            "a query of {} bytes: at most {MAX_QUERY_BYTES} are read",
            bytes.len()
        ));
    }
    serde_json::from_slice(&bytes).map_err(|e| format!("invalid query JSON: {e}"))
}

/// Passes an edit to the audio thread and waits for its outcome.
fn ask(shared: &Shared, edit: impl FnOnce(SyncSender<Outcome>) -> Edit) -> Outcome {
    let (tx, rx) = mpsc::sync_channel(1);
    lock(&shared.edits)
        .send(edit(tx))
        .map_err(|_| "the server's stream has ended".to_string())?;
    rx.recv_timeout(EDIT_WAIT)
        .map_err(|_| "the server's stream did not take the query in time".to_string())?
}

fn subscribe(shared: &Shared, q: &Query) -> Outcome {
    let query: SubscribeQuery = payload(q)?;
    if query.requests.is_empty() || query.requests.len() > MAX_REQUESTS {
        return Err(format!(
            "a subscription holds 1 to {MAX_REQUESTS} requests, not {}",
            query.requests.len()
        ));
    }
    let start = Instant::now();
    while !lock(&shared.clients).contains(&query.client) {
        if start.elapsed() > CLIENT_WAIT {
            return Err(format!(
                "client '{}' has no liveliness token on afe/<name>/client/<id>: declare it first",
                query.client
            ));
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    ask(shared, |reply| Edit::Subscribe {
        client: query.client,
        requests: query.requests,
        reply,
    })
}

fn unsubscribe(shared: &Shared, q: &Query) -> Outcome {
    let query: UnsubscribeQuery = payload(q)?;
    ask(shared, |reply| Edit::Unsubscribe {
        client: query.client,
        subscription: query.subscription,
        reply,
    })
}

/// A publishing thread with its pool of message buffers: the audio thread takes a buffer,
/// fills it and passes it on, never waiting; with no free buffer the message is dropped.
struct Outlet {
    to: SyncSender<Vec<u8>>,
    pool: Receiver<Vec<u8>>,
    _thread: JoinHandle<()>,
}

impl Outlet {
    /// Declares a publisher on `key` (dropping messages for congested links, never
    /// blocking) and starts its thread with `depth` buffers. With `await_subscriber`, the
    /// thread holds its first messages until a subscriber matches (at most
    /// [`MATCH_WAIT`]): a client declares its subscriber once it has the key, and must
    /// not lose the blocks computed in between.
    fn spawn(
        session: &Session,
        key: String,
        depth: usize,
        await_subscriber: bool,
    ) -> Result<Outlet, RemoteError> {
        let publisher = session
            .declare_publisher(key.clone())
            .congestion_control(CongestionControl::Drop)
            .priority(Priority::DataHigh)
            .wait()?;
        let (to, from) = mpsc::sync_channel::<Vec<u8>>(depth);
        let (back, pool) = mpsc::channel();
        for _ in 0..depth {
            let _ = back.send(Vec::new());
        }
        let thread = std::thread::Builder::new()
            .name(format!("afe-zenoh-{key}"))
            .spawn(move || {
                let start = Instant::now();
                while await_subscriber && start.elapsed() < MATCH_WAIT {
                    match publisher.matching_status().wait() {
                        Ok(m) if !m.matching() => std::thread::sleep(Duration::from_millis(1)),
                        _ => break,
                    }
                }
                for message in from {
                    let _ = publisher.put(message.as_slice()).wait();
                    if back.send(message).is_err() {
                        break;
                    }
                }
            })
            .map_err(|e| RemoteError::Zenoh(format!("cannot start a publishing thread: {e}")))?;
        Ok(Outlet {
            to,
            pool,
            _thread: thread,
        })
    }

    /// An empty buffer, if one is free.
    fn buffer(&self) -> Option<Vec<u8>> {
        let mut b = self.pool.try_recv().ok()?;
        b.clear();
        Some(b)
    }

    /// Passes a filled buffer on (there is always room: as many slots as buffers).
    fn send(&self, message: Vec<u8>) {
        let _ = self.to.try_send(message);
    }
}

/// One client's subscription.
struct Sub {
    id: u64,
    client: String,
    requests: Vec<String>,
    handles: Vec<RequestHandle>,
    outlet: Outlet,
    seq: u64,
    dropped: u64,
}

/// The server's end of a stream (an [`Observer`]): after each block it publishes the
/// block's audio and every subscription's new frames, then applies the subscriptions
/// and departures that arrived.
pub struct ServeTap {
    session: Session,
    name: String,
    shared: Arc<Shared>,
    edits: Receiver<Edit>,
    subs: Vec<Sub>,
    next_sid: u64,
    audio: Outlet,
    audio_seq: u64,
    audio_dropped: u64,
    report: Outlet,
    next_report: u64,
    started: bool,
}

impl ServeTap {
    /// Publishes the catalogue: the stream's rate, ears and block, and the requests.
    fn start(&mut self, timing: &Timing, mgr: &Manager) {
        let c = json!({
            "server": self.name,
            "wire_version": wire::VERSION,
            "fs_hz": timing.fs(),
            "ears": mgr.ears(),
            "block_frames": timing.block_frames(),
            "requests": afe::catalog::listing(),
        });
        *lock(&self.shared.catalogue) = Some(c.to_string());
        self.started = true;
    }

    fn publish_audio(&mut self, timing: &Timing, input: &[Vec<f64>]) {
        let Some(mut buf) = self.audio.buffer() else {
            self.audio_dropped += 1;
            return;
        };
        let n = timing.last_block_frames();
        header(Kind::Audio, self.audio_seq, timing, input.len()).write(&mut buf);
        for t in 0..n {
            wire::put_values(&mut buf, input.iter().map(|ear| ear[t]));
        }
        self.audio_seq += 1;
        self.audio.send(buf);
    }

    fn publish_frames(&mut self, timing: &Timing, mgr: &Manager) {
        for sub in &mut self.subs {
            let seq = sub.seq;
            sub.seq += 1;
            let Some(mut buf) = sub.outlet.buffer() else {
                sub.dropped += 1;
                continue;
            };
            header(Kind::Frames, seq, timing, 0).write(&mut buf);
            let mut count: u32 = 0;
            for &h in &sub.handles {
                for s in (0..).map_while(|k| mgr.request_signal(h, k)) {
                    wire::put_signal(&mut buf, s.first_frame, s.new.width(), s.new.as_slice());
                    count += 1;
                }
            }
            buf[28..32].copy_from_slice(&count.to_le_bytes());
            sub.outlet.send(buf);
        }
    }

    /// The report, once per second of audio.
    fn publish_report(&mut self, timing: &Timing, mgr: &Manager) {
        if timing.input_end() < self.next_report {
            return;
        }
        self.next_report = timing.input_end() + timing.fs() as u64;
        let Some(mut buf) = self.report.buffer() else {
            return;
        };
        let subs: Vec<Value> = self
            .subs
            .iter()
            .map(|s| {
                json!({
                    "subscription": s.id,
                    "client": s.client,
                    "requests": s.requests,
                    "messages": s.seq,
                    "dropped_messages": s.dropped,
                })
            })
            .collect();
        let report = json!({
            "stream": timing.report(),
            "processors": mgr.processor_count(),
            "audio_dropped_messages": self.audio_dropped,
            "subscriptions": subs,
        });
        buf.extend_from_slice(report.to_string().as_bytes());
        self.report.send(buf);
    }

    fn apply_edits(&mut self, timing: &Timing, mgr: &mut Manager) {
        while let Ok(edit) = self.edits.try_recv() {
            match edit {
                Edit::Subscribe {
                    client,
                    requests,
                    reply,
                } => {
                    let _ = reply.send(self.subscribe(timing, mgr, client, requests));
                }
                Edit::Unsubscribe {
                    client,
                    subscription,
                    reply,
                } => {
                    let found = self
                        .subs
                        .iter()
                        .position(|s| s.id == subscription && s.client == client);
                    let outcome = match found {
                        Some(i) => {
                            let sub = self.subs.remove(i);
                            release(mgr, &sub.handles);
                            Ok(json!({ "unsubscribed": subscription }))
                        }
                        None => Err(format!(
                            "client '{client}' has no subscription {subscription}"
                        )),
                    };
                    let _ = reply.send(outcome);
                }
                Edit::ClientGone(client) => {
                    let (gone, kept) = std::mem::take(&mut self.subs)
                        .into_iter()
                        .partition(|s| s.client == client);
                    self.subs = kept;
                    for sub in gone {
                        release(mgr, &sub.handles);
                    }
                }
            }
        }
    }

    /// Places a client's requests (all or none) and starts publishing their frames.
    fn subscribe(
        &mut self,
        timing: &Timing,
        mgr: &mut Manager,
        client: String,
        requests: Vec<RequestSpec>,
    ) -> Outcome {
        if self.subs.iter().filter(|s| s.client == client).count() >= MAX_SUBSCRIPTIONS {
            return Err(format!(
                "client '{client}' already holds {MAX_SUBSCRIPTIONS} subscriptions"
            ));
        }
        let mut handles = Vec::new();
        for r in &requests {
            match mgr.add_request(&r.name, &r.params) {
                Ok(h) => handles.push(h),
                Err(e) => {
                    release(mgr, &handles);
                    return Err(format!("request '{}': {e}", r.name));
                }
            }
        }
        let id = self.next_sid;
        let frames_key = key(&self.name, &format!("frames/{id}"));
        let outlet = match Outlet::spawn(&self.session, frames_key.clone(), SUB_QUEUE, true) {
            Ok(o) => o,
            Err(e) => {
                release(mgr, &handles);
                return Err(e.to_string());
            }
        };
        self.next_sid += 1;
        let signals: Vec<Value> = handles
            .iter()
            .flat_map(|&h| mgr.request_signals(h).unwrap_or_default())
            .map(|s| {
                let mut d = describe(mgr, &s);
                if let Some(o) = d.as_object_mut() {
                    // the index and time of the first frame the subscription will get
                    let rows = s.new.frames();
                    let next_s = s.first_time_s + rows as f64 / s.info.fs_hz;
                    o.insert("first_frame".into(), json!(s.first_frame + rows as u64));
                    o.insert("first_time_s".into(), json!(next_s));
                }
                d
            })
            .collect();
        self.subs.push(Sub {
            id,
            client,
            requests: requests.into_iter().map(|r| r.name).collect(),
            handles,
            outlet,
            seq: 0,
            dropped: 0,
        });
        Ok(json!({
            "subscription": id,
            "key": frames_key,
            "signals": signals,
            "fs_hz": timing.fs(),
            "ears": mgr.ears(),
            "block_frames": timing.block_frames(),
            "start_frame": timing.input_end(),
            "wire_version": wire::VERSION,
        }))
    }
}

/// Removes requests; their processors go when no other request uses them.
fn release(mgr: &mut Manager, handles: &[RequestHandle]) {
    for &h in handles {
        let _ = mgr.remove_request(h);
    }
}

/// The header of the last block's message.
fn header(kind: Kind, seq: u64, timing: &Timing, count: usize) -> Header {
    let frames = timing.last_block_frames();
    Header {
        kind,
        seq,
        first_input_frame: timing.input_end() - frames as u64,
        input_frames: frames as u32,
        count: count as u32,
        t_ns: timing.block_end_unix_ns(),
    }
}

impl Observer for ServeTap {
    fn block(&mut self, timing: &Timing, mgr: &mut Manager, input: &[Vec<f64>]) {
        if !self.started {
            self.start(timing, mgr);
        }
        self.publish_audio(timing, input);
        self.publish_frames(timing, mgr);
        self.publish_report(timing, mgr);
        self.apply_edits(timing, mgr);
    }
}
