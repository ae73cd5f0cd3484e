//! The server as a ROS 2 node (`afe serve --ros2`), over rmw_zenoh's protocol on the
//! server's own Zenoh session: the node's and its entities' liveliness tokens, a topic
//! per output of each request placed through its services, the input on `~/audio`, the
//! platform latched on `~/platform`, and the services themselves as queryables.
//!
//! Service calls are read (and malformed ones refused) in Zenoh's callbacks, queued for
//! the audio thread, which acts on them between blocks as on the Zenoh clients'
//! subscriptions, and answered from a thread of their own. Topics are published through
//! the server's publishing pool, as one client of it.

use std::collections::{BTreeMap, HashMap};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;

use afe_core::ParamMap;
use afe_graph::{Manager, RequestHandle, Signal};
use zenoh::bytes::ZBytes;
use zenoh::liveliness::LivelinessToken;
use zenoh::query::{Query, Queryable};
use zenoh::{Session, Wait};
use zenoh_ext::{AdvancedPublisher, AdvancedPublisherBuilderExt, CacheConfig, MissDetectionConfig};

use super::publish::{ClientOut, Pool, SubEnd};
use super::queries::RequestSpec;
use crate::ros2::idl::{self, dds_name, Field};
use crate::ros2::messages::{self, Call, Described, Listed, Placed, Response};
use crate::ros2::names::{self, attachment, read_attachment, Kind, NodeName, Qos};
use crate::ros2::{hash, Ros2Options};
use crate::RemoteError;
use afe::stream::Timing;

/// Service calls waiting for the audio thread before the next are refused as busy.
const CALL_BACKLOG: usize = 64;
/// Service calls the audio thread acts on per block, at most.
const CALLS_PER_BLOCK: usize = 8;
/// Requests the node holds at once.
pub(super) const MAX_ROS_REQUESTS: usize = 32;
/// Topics the node publishes at most (its pool queue is sized for them).
const MAX_TOPICS: usize = 128;

/// A service call on its way to the audio thread.
pub(super) struct Incoming {
    service: &'static str,
    call: Call,
    query: Query,
    sequence: i64,
    gid: [u8; 16],
}

impl Incoming {
    /// What was asked.
    pub(super) fn call(&self) -> &Call {
        &self.call
    }
}

/// A reply on its way to the network.
struct Reply {
    query: Query,
    payload: Vec<u8>,
    attachment: [u8; names::ATTACHMENT_BYTES],
}

impl Reply {
    /// The response `response` to a call of `service` with `sequence` from `gid`.
    fn to(
        query: Query,
        service: &str,
        response: &Response,
        sequence: i64,
        gid: &[u8; 16],
    ) -> Reply {
        Reply {
            query,
            payload: messages::response(service, response),
            attachment: attachment(sequence, names::now_ns(), gid),
        }
    }

    /// Sends it on the service's key (with the congestion control the caller's query
    /// asked for).
    fn send(self) {
        let key = self.query.key_expr().clone();
        let _ = self
            .query
            .reply(key, self.payload)
            .attachment(self.attachment.to_vec())
            .wait();
    }
}

/// A topic the node publishes through the pool, with its liveliness token.
struct Published {
    full_name: String,
    end: SubEnd,
    _token: LivelinessToken,
}

impl Published {
    /// A buffer for its next message, or none: the message is dropped (its sequence
    /// number spent, so that subscribers see the gap) and the pool asked to look again.
    fn buffer(&self, pool: &Pool) -> Option<Vec<u8>> {
        let buf = self.end.buffer();
        if buf.is_none() {
            self.end.outlet().skip();
            pool.nudge(&self.end);
        }
        buf
    }
}

/// One output of a request, published.
struct Topic {
    published: Published,
    described: Described,
}

/// What the audio thread does with a call.
pub(super) enum Step {
    /// Answers it at once.
    Answer(Response),
    /// Measures the request an add or a modify asks for, then settles it.
    Measure(RequestSpec),
}

/// A request placed through `add_request`.
struct RosRequest {
    id: u64,
    name: String,
    params: ParamMap,
    /// Its number among the node's requests of the same name (1, 2, ...): its topics'.
    ordinal: usize,
    handle: RequestHandle,
    topics: Vec<Topic>,
}

/// The node's state, held by the server's stream observer.
pub(super) struct RosNode {
    session: Session,
    name: NodeName,
    zid: String,
    types: BTreeMap<String, Vec<Field>>,
    /// Type hashes computed so far, by type.
    hashes: HashMap<String, String>,
    next_entity: u64,
    _node_token: LivelinessToken,
    _services: Vec<(Queryable<()>, LivelinessToken)>,
    calls: Receiver<Incoming>,
    /// Calls taken from `calls` and not yet answered on the network: at most
    /// [`CALL_BACKLOG`], so that a reply always has room on its way.
    unanswered: Arc<AtomicUsize>,
    replies: Option<SyncSender<Reply>>,
    reply_thread: Option<JoinHandle<()>>,
    client: Arc<ClientOut>,
    audio: Option<Published>,
    latched: Option<(AdvancedPublisher<'static>, LivelinessToken)>,
    requests: Vec<RosRequest>,
    next_request: u64,
    /// Unix time of the stream's first frame, ns.
    start_ns: i64,
}

/// How often a latched topic tells its subscribers its last sequence number, so that
/// they fetch what they missed (rmw_zenoh's period for reliable transient-local topics).
const LATCHED_HEARTBEAT: std::time::Duration = std::time::Duration::from_millis(500);

/// The node's id among its entities (rmw_zenoh numbers them from 0 per session).
const NODE_ID: u64 = 0;

impl RosNode {
    /// Declares the node and its services on `session`.
    pub(super) fn start(
        session: &Session,
        options: &Ros2Options,
        pool: &Pool,
        platform: Option<String>,
    ) -> Result<RosNode, RemoteError> {
        options.check()?;
        let name = NodeName {
            domain: options.domain,
            namespace: options.namespace.clone(),
            name: options.node.clone(),
        };
        let zid = session.zid().to_string();
        let types = idl::types();
        let node_token = session
            .liveliness()
            .declare_token(name.token(&zid, NODE_ID, NODE_ID, Kind::Node, None))
            .wait()?;
        let (to_audio, calls) = mpsc::sync_channel(CALL_BACKLOG);
        let (replies, outgoing) = mpsc::sync_channel::<Reply>(CALL_BACKLOG);
        let unanswered = Arc::new(AtomicUsize::new(0));
        let sent = unanswered.clone();
        let reply_thread = std::thread::Builder::new()
            .name("afe-ros2-replies".into())
            .spawn(move || {
                for r in outgoing {
                    r.send();
                    sent.fetch_sub(1, Ordering::AcqRel);
                }
            })
            .map_err(|e| RemoteError::Zenoh(format!("cannot start the ROS 2 reply thread: {e}")))?;
        let mut node = RosNode {
            session: session.clone(),
            name,
            zid,
            types,
            hashes: HashMap::new(),
            next_entity: NODE_ID + 1,
            _node_token: node_token,
            _services: Vec::new(),
            calls,
            unanswered,
            replies: Some(replies),
            reply_thread: Some(reply_thread),
            client: pool.client_for(MAX_TOPICS),
            audio: None,
            latched: None,
            requests: Vec::new(),
            next_request: 1,
            start_ns: 0,
        };
        for (service, ty) in messages::SERVICES {
            let s = node.service(service, ty, to_audio.clone())?;
            node._services.push(s);
        }
        if let Some(text) = &platform {
            node.latch(text)?;
        }
        Ok(node)
    }

    /// A new entity of `kind` named `full_name` of type `ty`: its data key and its
    /// liveliness token.
    fn entity(&mut self, kind: Kind, full_name: &str, ty: &str, qos: Qos) -> (String, String) {
        let dds = dds_name(ty);
        let types = &self.types;
        let hash = self
            .hashes
            .entry(ty.to_string())
            .or_insert_with(|| hash::rihs01(ty, types));
        let key = self.name.data_key(full_name, &dds, hash);
        let id = self.next_entity;
        self.next_entity += 1;
        let token = self.name.token(
            &self.zid,
            NODE_ID,
            id,
            kind,
            Some((full_name, &dds, hash, qos)),
        );
        (key, token)
    }

    /// Declares service `service` of type `afe_msgs/srv/<ty>`.
    fn service(
        &mut self,
        service: &str,
        ty: &'static str,
        to_audio: SyncSender<Incoming>,
    ) -> Result<(Queryable<()>, LivelinessToken), RemoteError> {
        let full = self.name.resolve(&format!("~/{service}"));
        let (key, token_key) = self.entity(
            Kind::Service,
            &full,
            &format!("{}/srv/{ty}", idl::PACKAGE),
            Qos::DEFAULT,
        );
        let service: &'static str = ty;
        let queryable = self
            .session
            .declare_queryable(key)
            .complete(true)
            .callback(move |query| {
                let payload = query.payload().map(ZBytes::to_bytes).unwrap_or_default();
                let stamp = query
                    .attachment()
                    .and_then(|a| read_attachment(&a.to_bytes()));
                let refused = match (messages::read_call(service, &payload), stamp) {
                    (Ok(call), Some((sequence, gid))) => {
                        let incoming = Incoming {
                            service,
                            call,
                            query,
                            sequence,
                            gid,
                        };
                        // a call that was read is refused as the service answers (a ROS
                        // client takes no error reply for an answer)
                        if let Err(TrySendError::Full(i) | TrySendError::Disconnected(i)) =
                            to_audio.try_send(incoming)
                        {
                            let why =
                                format!("the node has {CALL_BACKLOG} calls waiting: try again");
                            Reply::to(
                                i.query,
                                service,
                                &Response::Refused(why),
                                i.sequence,
                                &i.gid,
                            )
                            .send();
                        }
                        return;
                    }
                    (Err(e), _) => (query, format!("malformed {service} request: {}", e.0)),
                    (Ok(_), None) => (
                        query,
                        "the call has no rmw_zenoh attachment (sequence number, time, GID)".into(),
                    ),
                };
                let (query, why) = refused;
                let _ = query.reply_err(why).wait();
            })
            .wait()?;
        let token = self.session.liveliness().declare_token(token_key).wait()?;
        Ok((queryable, token))
    }

    /// Publishes the platform descriptor latched on `~/platform`, as rmw_zenoh declares
    /// a reliable transient-local publisher.
    fn latch(&mut self, text: &str) -> Result<(), RemoteError> {
        let full = self.name.resolve("~/platform");
        let (key, token_key) =
            self.entity(Kind::Publisher, &full, "std_msgs/msg/String", Qos::LATCHED);
        let gid = names::gid(&token_key);
        let publisher = self
            .session
            .declare_publisher(key)
            .cache(CacheConfig::default().max_samples(1))
            .sample_miss_detection(
                MissDetectionConfig::default().sporadic_heartbeat(LATCHED_HEARTBEAT),
            )
            .publisher_detection()
            .wait()?;
        let mut buf = Vec::new();
        messages::string(&mut buf, text);
        publisher
            .put(buf)
            .attachment(attachment(1, names::now_ns(), &gid).to_vec())
            .wait()?;
        let token = self.session.liveliness().declare_token(token_key).wait()?;
        self.latched = Some((publisher, token));
        Ok(())
    }

    /// Declares topic `~/<short>` of type `ty`, published through the pool, with its
    /// token.
    fn publisher(&mut self, pool: &Pool, short: &str, ty: &str) -> Result<Published, RemoteError> {
        let full_name = self.name.resolve(&format!("~/{short}"));
        let (key, token_key) = self.entity(Kind::Publisher, &full_name, ty, Qos::DEFAULT);
        let end = pool.subscription(
            &self.session,
            key,
            &self.client,
            Some(names::gid(&token_key)),
        )?;
        let token = self.session.liveliness().declare_token(token_key).wait()?;
        Ok(Published {
            full_name,
            end,
            _token: token,
        })
    }

    /// At the stream's start: the audio topic.
    pub(super) fn start_stream(&mut self, timing: &Timing, pool: &Pool) -> Result<(), RemoteError> {
        let frames_ns = (timing.input_end() as f64 * 1e9 / timing.fs()) as i64;
        self.start_ns = timing.block_end_unix_ns() as i64 - frames_ns;
        let audio = self.publisher(pool, "audio", &format!("{}/msg/Audio", idl::PACKAGE))?;
        self.audio = Some(audio);
        Ok(())
    }

    /// Where a block's new frames of `s` sit.
    fn placed(&self, timing: &Timing, first_frame: u64, first_time_s: f64) -> Placed {
        Placed {
            stamp_ns: self.start_ns + (first_time_s * 1e9) as i64,
            first_frame,
            frames_lost: timing.lost_frames(),
            first_time_s,
        }
    }

    /// Publishes the block's input and every request's new frames.
    pub(super) fn publish(
        &mut self,
        timing: &Timing,
        mgr: &Manager,
        pool: &Pool,
        input: &[Vec<f64>],
    ) {
        let frames = timing.last_block_frames();
        let first = timing.input_end() - frames as u64;
        let at = self.placed(timing, first, first as f64 / timing.fs());
        if let Some(audio) = &self.audio {
            if let Some(mut buf) = audio.buffer(pool) {
                messages::audio(&mut buf, at, timing.fs(), input, frames);
                pool.send(&audio.end, buf);
            }
        }
        for r in &self.requests {
            for (k, topic) in r.topics.iter().enumerate() {
                // a block that completed no frame of this output publishes nothing
                let Some(s) = mgr
                    .request_signal(r.handle, k)
                    .filter(|s| s.new.frames() > 0)
                else {
                    continue;
                };
                let Some(mut buf) = topic.published.buffer(pool) else {
                    continue;
                };
                let at = self.placed(timing, s.first_frame, s.first_time_s);
                messages::signal(
                    &mut buf,
                    &topic.described,
                    at,
                    s.new.frames(),
                    s.new.as_slice(),
                );
                pool.send(&topic.published.end, buf);
            }
        }
    }

    /// The calls waiting, at most [`CALLS_PER_BLOCK`], and no more than the replies'
    /// way has room for (the others wait, or are refused as busy on arrival).
    pub(super) fn take_calls(&mut self) -> Vec<Incoming> {
        let room = CALL_BACKLOG.saturating_sub(self.unanswered.load(Ordering::Acquire));
        let taken: Vec<Incoming> = self
            .calls
            .try_iter()
            .take(CALLS_PER_BLOCK.min(room))
            .collect();
        self.unanswered.fetch_add(taken.len(), Ordering::AcqRel);
        taken
    }

    /// Answers a call taken by [`RosNode::take_calls`] (its reply always has room).
    pub(super) fn answer(&self, incoming: Incoming, response: &Response) {
        let reply = Reply::to(
            incoming.query,
            incoming.service,
            response,
            incoming.sequence,
            &incoming.gid,
        );
        if let Some(replies) = &self.replies {
            let _ = replies.try_send(reply);
        }
    }

    /// What to do with a call: answered at once, or (an add or a modify) the request to
    /// measure before it is placed.
    pub(super) fn step(&mut self, mgr: &mut Manager, call: &Call) -> Step {
        let answer = match call {
            Call::Add(name, params) => {
                let given = params.iter().map(|(k, v)| (k.as_str(), v.as_str()));
                return measured(name, ParamMap::new(), given);
            }
            Call::Modify(id, parameter, value) => {
                match self.requests.iter().find(|r| r.id == *id) {
                    Some(r) => {
                        let given = [(parameter.as_str(), value.as_str())];
                        return measured(&r.name, r.params.clone(), given.into_iter());
                    }
                    None => unknown(*id),
                }
            }
            Call::Remove(id) => match self.requests.iter().position(|r| r.id == *id) {
                Some(i) => {
                    let r = self.requests.remove(i);
                    let _ = mgr.remove_request(r.handle);
                    Response::Done
                }
                None => unknown(*id),
            },
            Call::Signals => Response::Signals(
                self.requests
                    .iter()
                    .flat_map(|r| {
                        r.topics.iter().map(|t| Listed {
                            request_id: r.id,
                            topic: t.published.full_name.clone(),
                            described: t.described.clone(),
                        })
                    })
                    .collect(),
            ),
            Call::Parameters(id) => match self.requests.iter().find(|r| r.id == *id) {
                Some(r) => match mgr.request_parameters(r.handle) {
                    Ok(p) => Response::Parameters(
                        p.into_iter().map(|(k, v)| (k, v.to_string())).collect(),
                    ),
                    Err(e) => Response::Refused(e.to_string()),
                },
                None => unknown(*id),
            },
        };
        Step::Answer(answer)
    }

    /// A request placed anew with changed parameters (measured and admitted by the
    /// server), on the same topics; other clients' requests that shared its processors
    /// keep theirs. The outputs must stay the same ones.
    fn replace(&mut self, mgr: &mut Manager, id: u64, spec: &RequestSpec) -> Response {
        let Some(r) = self.requests.iter_mut().find(|r| r.id == id) else {
            return unknown(id);
        };
        let handle = match mgr.add_request(&spec.name, &spec.params) {
            Ok(h) => h,
            Err(e) => return Response::Refused(format!("request {id} ({}): {e}", r.name)),
        };
        let signals = mgr.request_signals(handle).unwrap_or_default();
        let same = signals.len() == r.topics.len()
            && signals
                .iter()
                .zip(&r.topics)
                .all(|(s, t)| output_name(s, r.ordinal) == t.described.output);
        if !same {
            drop(signals);
            let _ = mgr.remove_request(handle);
            return Response::Refused(format!(
                "the change would change request {id}'s outputs: remove it and add it anew"
            ));
        }
        let described: Vec<Described> = signals
            .iter()
            .zip(&r.topics)
            .map(|(s, t)| describe(&r.name, &t.described.output, s))
            .collect();
        drop(signals);
        let _ = mgr.remove_request(std::mem::replace(&mut r.handle, handle));
        r.params = spec.params.clone();
        for (t, d) in r.topics.iter_mut().zip(described) {
            t.described = d;
        }
        Response::Done
    }

    /// Places what an admitted add or modify asked for.
    pub(super) fn settle(
        &mut self,
        mgr: &mut Manager,
        pool: &Pool,
        call: &Call,
        spec: &RequestSpec,
    ) -> Response {
        match call {
            Call::Modify(id, _, _) => self.replace(mgr, *id, spec),
            _ => self.place(mgr, pool, spec),
        }
    }

    /// Places an add (measured and admitted by the server): its topics are declared.
    pub(super) fn place(&mut self, mgr: &mut Manager, pool: &Pool, spec: &RequestSpec) -> Response {
        if self.requests.len() >= MAX_ROS_REQUESTS {
            return Response::Refused(format!(
                "the node holds {MAX_ROS_REQUESTS} requests: remove one first"
            ));
        }
        let handle = match mgr.add_request(&spec.name, &spec.params) {
            Ok(h) => h,
            Err(e) => return Response::Refused(format!("request '{}': {e}", spec.name)),
        };
        let ordinal = (1..)
            .find(|n| {
                !self
                    .requests
                    .iter()
                    .any(|r| r.name == spec.name && r.ordinal == *n)
            })
            .unwrap_or(1);
        let signals: Vec<(String, Described)> = mgr
            .request_signals(handle)
            .unwrap_or_default()
            .iter()
            .map(|s| {
                let output = output_name(s, ordinal);
                (output.clone(), describe(&spec.name, &output, s))
            })
            .collect();
        let in_use: usize = self.requests.iter().map(|r| r.topics.len()).sum();
        if in_use + signals.len() + 1 > MAX_TOPICS {
            let _ = mgr.remove_request(handle);
            return Response::Refused(format!("the node publishes {MAX_TOPICS} topics at most"));
        }
        let mut topics = Vec::new();
        for (output, described) in signals {
            match self.publisher(pool, &output, &format!("{}/msg/Signal", idl::PACKAGE)) {
                Ok(published) => topics.push(Topic {
                    published,
                    described,
                }),
                Err(e) => {
                    let _ = mgr.remove_request(handle);
                    return Response::Refused(e.to_string());
                }
            }
        }
        let id = self.next_request;
        self.next_request += 1;
        let names = topics
            .iter()
            .map(|t| t.published.full_name.clone())
            .collect();
        self.requests.push(RosRequest {
            id,
            name: spec.name.clone(),
            params: spec.params.clone(),
            ordinal,
            handle,
            topics,
        });
        Response::Added(id, names)
    }
}

impl Drop for RosNode {
    fn drop(&mut self) {
        self.replies = None;
        if let Some(t) = self.reply_thread.take() {
            let _ = t.join();
        }
    }
}

/// The name of output `s` of the `ordinal`-th request of its name: `ratemap_left`, then
/// `ratemap_2_left`, ...
fn output_name(s: &Signal<'_>, ordinal: usize) -> String {
    if ordinal > 1 {
        format!("{}_{ordinal}_{}", s.name, s.channel.as_str())
    } else {
        format!("{}_{}", s.name, s.channel.as_str())
    }
}

/// Request `name` with `params` and the `given` values (JSON text) over them, to measure;
/// refused if a value is not JSON.
fn measured<'a>(
    name: &str,
    mut params: ParamMap,
    given: impl Iterator<Item = (&'a str, &'a str)>,
) -> Step {
    for (k, v) in given {
        match serde_json::from_str(v) {
            Ok(value) => {
                params.insert(k.to_string(), value);
            }
            Err(e) => return Step::Answer(Response::Refused(not_json(k, &e))),
        }
    }
    Step::Measure(RequestSpec {
        name: name.to_string(),
        params,
    })
}

fn not_json(parameter: &str, e: &serde_json::Error) -> String {
    format!("the value of {parameter} is not JSON ({e}): give e.g. 0.04, 32 or \"dau\"")
}

fn unknown(id: u64) -> Response {
    Response::Refused(format!(
        "the node holds no request {id} (get_signals lists them)"
    ))
}

/// What output `s` of request `request` says of itself.
fn describe(request: &str, output: &str, s: &Signal<'_>) -> Described {
    let info = s.info;
    Described {
        request: request.to_string(),
        output: output.to_string(),
        kind: afe::metadata::kind_name(info.kind),
        unit: info.unit,
        axes: info.axis_names(),
        sample_rate: info.fs_hz,
        centre_frequencies: info.cf_hz().to_vec(),
        lags: info.lags_s().to_vec(),
        features: info.features().to_vec(),
        frame_shape: info.frame_shape().into_iter().map(|n| n as u32).collect(),
        complex: info.is_complex(),
    }
}
