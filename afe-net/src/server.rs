//! The server side: a Zenoh session that answers the catalogue and subscription queries
//! and watches its clients' liveliness, and the stream's observer ([`ServeTap`]) that
//! places and removes the subscribed requests between blocks and hands each block's
//! messages to a fixed pool of publishing threads without ever waiting for them.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, Sender, SyncSender};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;

use afe_graph::{Manager, RequestHandle};
use serde_json::{json, Value};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::query::Queryable;
use zenoh::sample::SampleKind;
use zenoh::{Session, Wait};

mod head_yaw;
mod publish;
mod queries;
#[cfg(feature = "ros2")]
mod ros;

use super::wire::{self, Header, Kind};
use super::{
    check_name, config, key, RemoteError, MAX_CLIENTS, MAX_CLIENTS_LIMIT, MAX_LOAD,
    MAX_SUBSCRIPTIONS, MAX_SUBSCRIPTIONS_LIMIT, PUBLISH_THREADS,
};
use afe::metadata::describe;
use afe::stream::{Observer, Timing};
use afe::trial::{LoadCap, Shape, Trials};
use publish::{Pool, SubEnd};
use queries::{answer, Edit, Event, Limits, Op, Outcome, QueryLoop, RequestSpec, QUERY_BACKLOG};

/// Audio blocks on their way to the network before the next are dropped.
const AUDIO_QUEUE: usize = 32;
/// Subscriptions being measured (or waiting to be) before they are placed: as many as
/// queries may wait to be read.
const TRIAL_SLOTS: usize = QUERY_BACKLOG;

/// Where and under which name to serve, and for how many clients.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// Zenoh endpoints to listen on, e.g. `tcp/127.0.0.1:7447`.
    pub listen: Vec<String>,
    /// The server's name: its keys are `afe/<name>/...`.
    pub name: String,
    /// A Zenoh configuration file (JSON5) to start from, e.g. with authentication.
    pub config_file: Option<PathBuf>,
    /// Clients holding subscriptions at once, 1 to [`MAX_CLIENTS_LIMIT`]; a further
    /// client is refused until one leaves.
    pub max_clients: usize,
    /// Subscriptions one client may hold, 1 to [`MAX_SUBSCRIPTIONS_LIMIT`].
    pub max_subscriptions: usize,
    /// The share of a block's budget requests may take (0 to 1): a subscription whose
    /// measured cost would take the stream beyond it is refused before it runs.
    pub max_load: f64,
    /// The robot's platform descriptor (its JSON form), published in the catalogue so
    /// that a client asks the robot what it is.
    pub platform: Option<Value>,
    /// The stream's head pose, fed from `afe/<name>/head/yaw` as the robot's motor
    /// controller publishes it (`{"t_s", "yaw_deg"}` samples; the same feed as the
    /// stream job's); `None`: the key is not listened to (a synthetic head reports its
    /// own yaw).
    pub head_pose: Option<afe::HeadPose>,
    /// The yaws accepted on that key (lowest, highest, deg; a platform's neck): others are
    /// refused.
    pub head_yaw_range_deg: Option<(f64, f64)>,
    /// Zenoh endpoints to connect to as well, e.g. a ROS 2 robot's router
    /// (`tcp/localhost:7447`, rmw_zenohd's).
    pub connect: Vec<String>,
    /// Be a ROS 2 node too (`docs/ros2.md`).
    #[cfg(feature = "ros2")]
    pub ros2: Option<crate::ros2::Ros2Options>,
}

impl Default for ServeOptions {
    fn default() -> Self {
        ServeOptions {
            listen: vec![super::DEFAULT_LISTEN.to_string()],
            name: super::DEFAULT_NAME.to_string(),
            config_file: None,
            max_clients: MAX_CLIENTS,
            max_subscriptions: MAX_SUBSCRIPTIONS,
            max_load: MAX_LOAD,
            platform: None,
            head_pose: Some(afe::HeadPose::new()),
            head_yaw_range_deg: None,
            connect: Vec::new(),
            #[cfg(feature = "ros2")]
            ros2: None,
        }
    }
}

impl ServeOptions {
    /// The limits, checked against their ranges.
    fn limits(&self) -> Result<Limits, RemoteError> {
        let check = |value: usize, most: usize, what: &str| {
            if (1..=most).contains(&value) {
                Ok(value)
            } else {
                Err(RemoteError::Options(format!(
                    "{what} = {value}: give 1 to {most}"
                )))
            }
        };
        if !(0.0..=1.0).contains(&self.max_load) {
            return Err(RemoteError::Options(format!(
                "max_load = {}: give a share of the block's budget, 0 to 1",
                self.max_load
            )));
        }
        Ok(Limits {
            max_clients: check(self.max_clients, MAX_CLIENTS_LIMIT, "max_clients")?,
            max_subscriptions: check(
                self.max_subscriptions,
                MAX_SUBSCRIPTIONS_LIMIT,
                "max_subscriptions",
            )?,
        })
    }
}

/// State the Zenoh callbacks, the query loop and the audio thread share.
struct Shared {
    /// The catalogue's JSON, once the stream has started.
    catalogue: Mutex<Option<String>>,
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
    _head_yaw: Option<Subscriber<()>>,
    head_yaw_counts: Arc<head_yaw::YawCounts>,
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
        let limits = options.limits()?;
        let name = options.name.clone();
        let base = match &options.config_file {
            Some(path) => Some(zenoh::Config::from_file(path).map_err(|e| {
                RemoteError::Zenoh(format!("configuration '{}': {e}", path.display()))
            })?),
            None => None,
        };
        let mut config = config(base, "peer", &options.listen, &options.connect)?;
        // room for bursts on every link (16 batches, not 2), and a wait for a busy link
        // long enough that a client which keeps up never loses a message to a scheduling
        // hiccup; a put that waits this long marks its client's link congested
        // (publish.rs), so the wait holds up no other client
        config.insert_json5("transport/link/tx/queue/size/data_high", "16")?;
        config.insert_json5(
            "transport/link/tx/queue/congestion_control/drop/wait_before_drop",
            "20000",
        )?;
        // as rmw_zenoh's sessions: samples carry their time, which an advanced
        // publisher's cache (a latched topic's) orders by
        #[cfg(feature = "ros2")]
        if options.ros2.is_some() {
            config.insert_json5("timestamping/enabled", "true")?;
        }
        let authenticated = config
            .get_json("transport/auth/usrpwd/user")
            .is_ok_and(|u| u != "null");
        let session = zenoh::open(config).wait()?;
        let (edits_tx, edits_rx) = mpsc::channel();
        let (events, events_rx) = mpsc::channel::<Event>();
        let shared = Arc::new(Shared {
            catalogue: Mutex::new(None),
        });
        let client_prefix = key(&name, "client/");
        let watch = events.clone();
        let clients = session
            .liveliness()
            .declare_subscriber(key(&name, "client/*"))
            .history(true)
            .callback(move |sample| {
                let Some(id) = sample.key_expr().as_str().strip_prefix(&client_prefix) else {
                    return;
                };
                let _ = watch.send(if sample.kind() == SampleKind::Put {
                    Event::ClientUp(id.to_string())
                } else {
                    Event::ClientGone(id.to_string())
                });
            })
            .wait()?;
        // one thread answers every query and waits on none: what must wait (a client's
        // token, the stream's start, the audio thread) is parked and answered later
        let queued = Arc::new(AtomicUsize::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let query_loop = QueryLoop::new(
            session.clone(),
            shared.clone(),
            edits_tx,
            limits,
            key(&name, "catalogue"),
            key(&name, "client/"),
        );
        let (stopped, counted) = (stop.clone(), queued.clone());
        let query_thread = std::thread::Builder::new()
            .name("afe-zenoh-queries".into())
            .spawn(move || query_loop.run(events_rx, &counted, &stopped))
            .map_err(|e| RemoteError::Zenoh(format!("cannot start the query thread: {e}")))?;
        let mut queryables = Vec::new();
        for (op, what) in [
            (Op::Catalogue, "catalogue"),
            (Op::Subscribe, "subscribe"),
            (Op::Unsubscribe, "unsubscribe"),
        ] {
            let (events, queued) = (events.clone(), queued.clone());
            queryables.push(
                session
                    .declare_queryable(key(&name, what))
                    .callback(move |q| {
                        if queued.fetch_add(1, Ordering::AcqRel) >= QUERY_BACKLOG {
                            queued.fetch_sub(1, Ordering::AcqRel);
                            answer(&q, Err("the server is busy: try again".into()));
                        } else if let Err(mpsc::SendError(Event::Query(_, q))) =
                            events.send(Event::Query(op, q))
                        {
                            answer(&q, Err("the server is stopping".into()));
                        }
                    })
                    .wait()?,
            );
        }
        let (head_yaw, head_yaw_counts) = match &options.head_pose {
            Some(pose) => {
                let (subscriber, counts) = head_yaw::subscribe(
                    &session,
                    key(&name, "head/yaw"),
                    pose.clone(),
                    options.head_yaw_range_deg,
                )?;
                (Some(subscriber), counts)
            }
            None => (None, Arc::default()),
        };
        let token = session
            .liveliness()
            .declare_token(key(&name, "server"))
            .wait()?;
        let audio = Outlet::spawn(&session, key(&name, "audio"), AUDIO_QUEUE)?;
        let report = Outlet::spawn(&session, key(&name, "report"), 2)?;
        // room in the ready queue for one client more: the ROS 2 node's
        let pool = Pool::start(
            PUBLISH_THREADS,
            limits.max_clients + 1,
            limits.max_subscriptions,
        )?;
        #[cfg(feature = "ros2")]
        let ros = match &options.ros2 {
            Some(o) => Some(ros::RosNode::start(
                &session,
                o,
                &pool,
                options.platform.as_ref().map(Value::to_string),
            )?),
            None => None,
        };
        let trials = Trials::start(TRIAL_SLOTS)
            .map_err(|e| RemoteError::Zenoh(format!("cannot start the trial thread: {e}")))?;
        let tap = ServeTap {
            session: session.clone(),
            name: name.clone(),
            platform: options.platform.clone(),
            shared,
            edits: edits_rx,
            events,
            pool,
            clients: Vec::new(),
            subs: Vec::new(),
            next_sid: 0,
            audio,
            audio_seq: 0,
            audio_dropped: 0,
            report,
            next_report: 0,
            started: false,
            trials,
            cap: LoadCap::new(options.max_load),
            measured: HashMap::new(),
            next_trial: 0,
            #[cfg(feature = "ros2")]
            ros,
        };
        Ok((
            Server {
                session,
                name,
                authenticated,
                _queryables: queryables,
                _clients: clients,
                _head_yaw: head_yaw,
                head_yaw_counts,
                _token: token,
                queries: Some(query_thread),
                stop,
            },
            tap,
        ))
    }

    /// Head yaws taken from `afe/<name>/head/yaw` and refused, so far.
    pub fn head_yaws(&self) -> (u64, u64) {
        let c = &self.head_yaw_counts;
        (
            c.taken.load(Ordering::Relaxed),
            c.refused.load(Ordering::Relaxed),
        )
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

/// A publishing thread with its pool of message buffers, for the audio and the report:
/// the audio thread takes a buffer, fills it and passes it on, never waiting; with no
/// free buffer the message is dropped.
struct Outlet {
    to: SyncSender<Vec<u8>>,
    pool: Receiver<Vec<u8>>,
    _thread: JoinHandle<()>,
}

impl Outlet {
    /// Declares a publisher on `key` (dropping messages for congested links, never
    /// blocking) and starts its thread with `depth` buffers.
    fn spawn(session: &Session, key: String, depth: usize) -> Result<Outlet, RemoteError> {
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
    end: SubEnd,
    seq: u64,
    dropped: u64,
}

/// The server's end of a stream (an [`Observer`]): after each block it publishes the
/// block's audio and every subscription's new frames, then applies the subscriptions
/// and departures that arrived.
pub struct ServeTap {
    session: Session,
    name: String,
    /// The platform descriptor the catalogue carries.
    platform: Option<Value>,
    shared: Arc<Shared>,
    edits: Receiver<Edit>,
    /// Outcomes and the stream's start, to the query loop.
    events: Sender<Event>,
    /// Publishes the subscriptions' messages; dropped (its threads joined) with the tap.
    pool: Pool,
    /// Each client's queue to the pool, while it holds subscriptions.
    clients: Vec<(String, Arc<publish::ClientOut>)>,
    subs: Vec<Sub>,
    next_sid: u64,
    audio: Outlet,
    audio_seq: u64,
    audio_dropped: u64,
    report: Outlet,
    next_report: u64,
    started: bool,
    /// Measures subscriptions before they are placed, off the audio path.
    trials: Trials,
    /// The stream's load and the share requests may take.
    cap: LoadCap,
    /// Subscriptions (and ROS 2 requests) being measured, by trial: who asked, and the
    /// requests.
    measured: HashMap<u64, (Asker, Vec<RequestSpec>)>,
    next_trial: u64,
    /// The ROS 2 node, with `--ros2`.
    #[cfg(feature = "ros2")]
    ros: Option<ros::RosNode>,
}

/// Who asked for requests being measured.
enum Asker {
    /// A Zenoh client's subscription: the query's ticket and the client.
    Zenoh(u64, String),
    /// A ROS 2 `add_request` or `modify_parameter` call.
    #[cfg(feature = "ros2")]
    Ros(ros::Incoming),
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
            "platform": self.platform,
        });
        *lock(&self.shared.catalogue) = Some(c.to_string());
        let _ = self.events.send(Event::Started);
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
            let Some(mut buf) = sub.end.buffer() else {
                sub.dropped += 1;
                self.pool.nudge(&sub.end);
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
            self.pool.send(&sub.end, buf);
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
                    "dropped_messages": s.dropped + s.end.outlet().dropped(),
                })
            })
            .collect();
        let report = json!({
            "stream": timing.report(),
            "processors": mgr.processor_count(),
            "audio_dropped_messages": self.audio_dropped,
            "clients": self.clients.len(),
            "subscriptions": subs,
        });
        buf.extend_from_slice(report.to_string().as_bytes());
        self.report.send(buf);
    }

    /// Places the subscriptions whose trial says they fit, and refuses the others.
    fn apply_measured(&mut self, timing: &Timing, mgr: &mut Manager) {
        for (trial, cost) in self.trials.finished() {
            let Some((asker, requests)) = self.measured.remove(&trial) else {
                continue;
            };
            let what = describe_specs(&requests);
            // computed already meanwhile (by an equal subscription placed since)
            let cost = if afe::trial::shared_entirely(&*mgr, &specs(&requests)) {
                Ok(afe::trial::Cost::free())
            } else {
                cost
            };
            let admitted = cost.and_then(|c| self.cap.admit(&what, c));
            self.settle(
                timing,
                mgr,
                asker,
                requests,
                admitted.map_err(|e| e.to_string()),
            );
        }
    }

    /// Places admitted requests for whoever asked, or tells it why not.
    fn settle(
        &mut self,
        timing: &Timing,
        mgr: &mut Manager,
        asker: Asker,
        requests: Vec<RequestSpec>,
        admitted: Result<(), String>,
    ) {
        match asker {
            Asker::Zenoh(ticket, client) => {
                let outcome = admitted.and_then(|()| self.subscribe(timing, mgr, client, requests));
                let _ = self.events.send(Event::Outcome(ticket, outcome));
            }
            #[cfg(feature = "ros2")]
            Asker::Ros(incoming) => {
                if let Some(ros) = &mut self.ros {
                    let response = match admitted {
                        Ok(()) => ros.settle(mgr, &self.pool, incoming.call(), &requests[0]),
                        Err(e) => crate::ros2::messages::Response::Refused(e),
                    };
                    ros.answer(incoming, &response);
                }
            }
        }
    }

    /// Asks for the trial of a subscription (placed at once when the stream has no
    /// deadline); its outcome goes to the query loop when it is placed or refused.
    fn measure(
        &mut self,
        timing: &Timing,
        mgr: &mut Manager,
        asker: Asker,
        requests: Vec<RequestSpec>,
    ) {
        let tried = specs(&requests);
        if !self.cap.has_deadline() || afe::trial::shared_entirely(&*mgr, &tried) {
            // no deadline, or nothing new to compute: placed at once
            self.settle(timing, mgr, asker, requests, Ok(()));
            return;
        }
        let shape = Shape {
            fs: mgr.fs(),
            ears: mgr.ears(),
            block_frames: timing.block_frames(),
        };
        self.next_trial += 1;
        let asked = self.cap.check_load().and_then(|()| {
            self.trials.submit(
                self.next_trial,
                shape,
                mgr.registry(),
                tried,
                self.cap.headroom_ms(),
            )
        });
        match asked {
            Ok(()) => {
                self.measured.insert(self.next_trial, (asker, requests));
            }
            Err(e) => self.settle(timing, mgr, asker, requests, Err(e.to_string())),
        }
    }

    fn apply_edits(&mut self, timing: &Timing, mgr: &mut Manager) {
        self.apply_measured(timing, mgr);
        while let Ok(edit) = self.edits.try_recv() {
            match edit {
                Edit::Subscribe {
                    ticket,
                    client,
                    requests,
                } => self.measure(timing, mgr, Asker::Zenoh(ticket, client), requests),
                Edit::Unsubscribe {
                    ticket,
                    client,
                    subscription,
                } => {
                    let found = self
                        .subs
                        .iter()
                        .position(|s| s.id == subscription && s.client == client);
                    let outcome = match found {
                        Some(i) => {
                            let sub = self.subs.remove(i);
                            release(mgr, &sub.handles);
                            self.forget_client_if_idle(&client);
                            Ok(json!({ "unsubscribed": subscription }))
                        }
                        None => Err(format!(
                            "client '{client}' has no subscription {subscription}"
                        )),
                    };
                    let _ = self.events.send(Event::Outcome(ticket, outcome));
                }
                Edit::ClientGone(client) => {
                    let left: Vec<u64> = self
                        .measured
                        .iter()
                        .filter(|(_, (a, _))| matches!(a, Asker::Zenoh(_, c) if *c == client))
                        .map(|(&trial, _)| trial)
                        .collect();
                    for trial in left {
                        if let Some((Asker::Zenoh(ticket, _), _)) = self.measured.remove(&trial) {
                            let why = format!("client '{client}' left while subscribing");
                            let _ = self.events.send(Event::Outcome(ticket, Err(why)));
                        }
                    }
                    let (gone, kept) = std::mem::take(&mut self.subs)
                        .into_iter()
                        .partition(|s| s.client == client);
                    self.subs = kept;
                    for sub in gone {
                        release(mgr, &sub.handles);
                    }
                    self.forget_client_if_idle(&client);
                }
            }
        }
    }

    /// Drops a client's queue once it holds no subscription.
    fn forget_client_if_idle(&mut self, client: &str) {
        if !self.subs.iter().any(|s| s.client == client) {
            self.clients.retain(|(id, _)| id != client);
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
        let queue = match self.clients.iter().find(|(c, _)| *c == client) {
            Some((_, q)) => q.clone(),
            None => {
                let q = self.pool.client();
                self.clients.push((client.clone(), q.clone()));
                q
            }
        };
        let end = match self.pool.subscription(
            &self.session,
            frames_key.clone(),
            &queue,
            #[cfg(feature = "ros2")]
            None,
        ) {
            Ok(end) => end,
            Err(e) => {
                release(mgr, &handles);
                self.forget_client_if_idle(&client);
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
            end,
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

/// Requests as names and parameters.
fn specs(requests: &[RequestSpec]) -> Vec<(String, afe_core::ParamMap)> {
    requests
        .iter()
        .map(|r| (r.name.clone(), r.params.clone()))
        .collect()
}

/// Requests as a short phrase for messages.
fn describe_specs(requests: &[RequestSpec]) -> String {
    afe::trial::describe(&specs(requests))
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

#[cfg(feature = "ros2")]
impl ServeTap {
    /// The ROS 2 node's part of a block: its topics, then its service calls.
    fn ros_block(&mut self, timing: &Timing, mgr: &mut Manager, input: &[Vec<f64>]) {
        let calls = match &mut self.ros {
            Some(ros) => {
                ros.publish(timing, mgr, &self.pool, input);
                ros.take_calls()
            }
            None => return,
        };
        for incoming in calls {
            let Some(ros) = &mut self.ros else { return };
            match ros.step(mgr, incoming.call()) {
                ros::Step::Measure(spec) => {
                    self.measure(timing, mgr, Asker::Ros(incoming), vec![spec]);
                }
                ros::Step::Answer(response) => ros.answer(incoming, &response),
            }
        }
    }
}

impl Observer for ServeTap {
    fn block(&mut self, timing: &Timing, mgr: &mut Manager, input: &[Vec<f64>]) {
        if !self.started {
            self.start(timing, mgr);
            #[cfg(feature = "ros2")]
            if let Some(ros) = &mut self.ros {
                if let Err(e) = ros.start_stream(timing, &self.pool) {
                    eprintln!("afe serve: the ROS 2 node cannot publish: {e}");
                    self.ros = None;
                }
            }
        }
        self.cap.observe(timing);
        self.publish_audio(timing, input);
        self.publish_frames(timing, mgr);
        #[cfg(feature = "ros2")]
        self.ros_block(timing, mgr, input);
        self.publish_report(timing, mgr);
        self.apply_edits(timing, mgr);
    }
}
