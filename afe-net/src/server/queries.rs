//! The query loop: one thread answers the catalogue, subscribe and unsubscribe queries
//! and follows the clients' liveliness tokens. It never waits on one query: a
//! subscription whose client's token has not been seen yet, or a catalogue asked for
//! before the stream has started, is parked and answered when it can be (or refused at
//! its deadline), and an edit of the graph is passed to the audio thread and answered
//! when its outcome comes back. It also holds each client's secret token and counts its
//! subscriptions against the server's limits. A client's id is its session's Zenoh id,
//! so that one connection holds one client whatever tokens it declares, and a client
//! leaves when its session does, whatever tokens others declared under its id.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

use afe_core::ParamMap;
use serde::Deserialize;
use serde_json::{json, Value};
use zenoh::query::Query;
use zenoh::{Session, Wait};

use super::{lock, Shared};
use crate::{MAX_QUERY_BYTES, MAX_REQUESTS};

/// How long a query waits for the audio thread to act on it, or for the stream to start.
const EDIT_WAIT: Duration = Duration::from_secs(5);
/// How long a subscription waits for its client's liveliness token to be seen (it is
/// declared just before, and may arrive just after).
const CLIENT_WAIT: Duration = Duration::from_secs(2);
/// How often the loop looks whether its server has gone.
const QUERY_POLL: Duration = Duration::from_millis(50);
/// How often the loop looks which sessions are connected: a client whose session has
/// gone leaves then, whatever liveliness tokens others declared under its id.
const SESSIONS_POLL: Duration = Duration::from_millis(250);
/// Queries on their way to the loop before the next are turned away.
pub(super) const QUERY_BACKLOG: usize = 256;
/// Queries parked (waiting for a client's token or the stream's start) before the next
/// are turned away.
pub(super) const MAX_PARKED: usize = 128;

/// The server's queryables.
#[derive(Debug, Clone, Copy)]
pub(super) enum Op {
    Catalogue,
    Subscribe,
    Unsubscribe,
}

/// A query's outcome: its reply's JSON, or the reason it was refused.
pub(super) type Outcome = Result<Value, String>;

/// What reaches the query loop.
pub(super) enum Event {
    /// A query on one of the server's keys.
    Query(Op, Query),
    /// The audio thread's outcome of the edit with this ticket.
    Outcome(u64, Outcome),
    /// The stream has started: the catalogue is there.
    Started,
    /// A client's liveliness token appeared.
    ClientUp(String),
    /// A client's liveliness token went (the client closed, died or lost its link).
    ClientGone(String),
}

/// What the query loop asks of the audio thread; each edit with a ticket is answered
/// with an [`Event::Outcome`].
pub(super) enum Edit {
    Subscribe {
        ticket: u64,
        client: String,
        requests: Vec<RequestSpec>,
    },
    Unsubscribe {
        ticket: u64,
        client: String,
        subscription: u64,
    },
    /// Removes every subscription of a departed client.
    ClientGone(String),
}

/// One request of a subscription.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RequestSpec {
    pub(super) name: String,
    #[serde(default)]
    pub(super) params: ParamMap,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SubscribeQuery {
    client: String,
    /// The client's secret token, from the reply to its first subscription.
    #[serde(default)]
    token: Option<String>,
    requests: Vec<RequestSpec>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct UnsubscribeQuery {
    client: String,
    subscription: u64,
    #[serde(default)]
    token: Option<String>,
}

/// The server's limits on its clients.
#[derive(Debug, Clone, Copy)]
pub(super) struct Limits {
    pub(super) max_clients: usize,
    pub(super) max_subscriptions: usize,
}

/// A client holding (or placing) subscriptions.
struct ClientState {
    /// Its secret, required for every later subscription or cancellation.
    token: String,
    /// Which state of its id this is (an id may leave and come back).
    epoch: u64,
    subscriptions: HashSet<u64>,
    /// Subscriptions being placed by the audio thread.
    reserved: usize,
}

/// A query that waits for something other than the audio thread.
enum Parked {
    Catalogue(Query, Instant),
    Subscribe(Query, SubscribeQuery, Instant),
}

/// What an edit passed to the audio thread was for.
enum Asked {
    Subscribe { client: String, epoch: u64 },
    Unsubscribe { client: String, subscription: u64 },
}

/// An edit awaiting its outcome; the query is gone once answered at its deadline.
struct Pending {
    query: Option<Query>,
    asked: Asked,
    deadline: Instant,
}

/// The loop's state.
pub(super) struct QueryLoop {
    /// The server's session: which sessions are connected to it.
    session: Session,
    /// When the connected sessions were last looked at.
    sessions_seen: Instant,
    shared: Arc<Shared>,
    edits: Sender<Edit>,
    limits: Limits,
    catalogue_key: String,
    client_key: String,
    alive: HashSet<String>,
    clients: HashMap<String, ClientState>,
    parked: Vec<Parked>,
    pending: HashMap<u64, Pending>,
    next_ticket: u64,
    next_epoch: u64,
}

impl QueryLoop {
    pub(super) fn new(
        session: Session,
        shared: Arc<Shared>,
        edits: Sender<Edit>,
        limits: Limits,
        catalogue_key: String,
        client_key: String,
    ) -> Self {
        QueryLoop {
            session,
            sessions_seen: Instant::now(),
            shared,
            edits,
            limits,
            catalogue_key,
            client_key,
            alive: HashSet::new(),
            clients: HashMap::new(),
            parked: Vec::new(),
            pending: HashMap::new(),
            next_ticket: 0,
            next_epoch: 0,
        }
    }

    /// Handles events until `stop` is set or every sender has gone; `queued` counts the
    /// queries on their way.
    pub(super) fn run(mut self, events: Receiver<Event>, queued: &AtomicUsize, stop: &AtomicBool) {
        while !stop.load(Ordering::Relaxed) {
            let wait = self
                .next_deadline()
                .map_or(QUERY_POLL, |d| d.saturating_duration_since(Instant::now()))
                .min(QUERY_POLL);
            match events.recv_timeout(wait) {
                Ok(Event::Query(op, q)) => {
                    queued.fetch_sub(1, Ordering::AcqRel);
                    self.query(op, q);
                }
                Ok(Event::Outcome(ticket, outcome)) => self.outcome(ticket, outcome),
                Ok(Event::Started) => self.started(),
                Ok(Event::ClientUp(id)) => self.client_up(id),
                Ok(Event::ClientGone(id)) => self.client_gone(id),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            self.expire(Instant::now());
            if self.sessions_seen.elapsed() >= SESSIONS_POLL {
                self.sessions_seen = Instant::now();
                self.drop_disconnected();
            }
        }
    }

    /// The ids of the sessions connected to the server (peers).
    fn connected(&self) -> HashSet<String> {
        self.session
            .info()
            .peers_zid()
            .wait()
            .map(|z| z.to_string())
            .collect()
    }

    /// Every client whose session is no longer connected leaves.
    fn drop_disconnected(&mut self) {
        if self.clients.is_empty() {
            return;
        }
        let connected = self.connected();
        let gone: Vec<String> = self
            .clients
            .keys()
            .filter(|id| !connected.contains(*id))
            .cloned()
            .collect();
        for id in gone {
            self.client_gone(id);
        }
    }

    fn next_deadline(&self) -> Option<Instant> {
        let parked = self.parked.iter().map(|p| match p {
            Parked::Catalogue(_, d) | Parked::Subscribe(_, _, d) => *d,
        });
        let pending = self
            .pending
            .values()
            .filter(|p| p.query.is_some())
            .map(|p| p.deadline);
        parked.chain(pending).min()
    }

    fn query(&mut self, op: Op, q: Query) {
        match op {
            Op::Catalogue => self.catalogue(q),
            Op::Subscribe => match payload::<SubscribeQuery>(&q).and_then(check_requests) {
                Ok(s) => self.subscribe(q, s),
                Err(e) => answer(&q, Err(e)),
            },
            Op::Unsubscribe => match payload::<UnsubscribeQuery>(&q) {
                Ok(u) => self.unsubscribe(q, u),
                Err(e) => answer(&q, Err(e)),
            },
        }
    }

    fn catalogue(&mut self, q: Query) {
        let catalogue = lock(&self.shared.catalogue).clone();
        match catalogue {
            Some(c) => {
                let _ = q.reply(self.catalogue_key.clone(), c).wait();
            }
            None => self.park(Parked::Catalogue(q, Instant::now() + EDIT_WAIT)),
        }
    }

    fn park(&mut self, p: Parked) {
        if self.parked.len() < MAX_PARKED {
            self.parked.push(p);
        } else {
            let q = match &p {
                Parked::Catalogue(q, _) | Parked::Subscribe(q, _, _) => q,
            };
            answer(
                q,
                Err(format!(
                    "the server has {MAX_PARKED} queries waiting for their clients' tokens \
                     or for its stream: try again"
                )),
            );
        }
    }

    fn subscribe(&mut self, q: Query, s: SubscribeQuery) {
        if !self.alive.contains(&s.client) {
            let deadline = Instant::now() + CLIENT_WAIT;
            self.park(Parked::Subscribe(q, s, deadline));
            return;
        }
        let limits = self.limits;
        let state = match self.clients.get_mut(&s.client) {
            Some(state) => match s.token.as_deref() {
                None => {
                    return answer(
                        &q,
                        Err(format!(
                            "the \"token\" is missing: client '{}' already holds \
                                 subscriptions, and a further one under its id must carry the \
                                 \"token\" of its first subscription's reply (the Rust and \
                                 Python clients send it themselves)",
                            s.client
                        )),
                    )
                }
                Some(t) if !same(t, &state.token) => {
                    return answer(
                        &q,
                        Err(format!(
                            "the token is not client '{}''s: it is held by another session, \
                                 and only the session that subscribed first may add to its \
                                 subscriptions (subscribe under an id of your own, e.g. your \
                                 Zenoh session id)",
                            s.client
                        )),
                    )
                }
                Some(_) => state,
            },
            None => {
                if !self.connected().contains(&s.client) {
                    return answer(
                        &q,
                        Err(format!(
                            "client '{}' is not the Zenoh id of a session connected to this \
                             server: subscribe under your own session's id (its zid), from a \
                             session in peer mode (the Rust and Python clients do), so that \
                             each connection holds one client",
                            s.client
                        )),
                    );
                }
                if self.clients.len() >= limits.max_clients {
                    return answer(
                        &q,
                        Err(format!(
                            "the server serves at most {} clients (afe serve --max-clients) \
                             and has as many: try again when one has left",
                            limits.max_clients
                        )),
                    );
                }
                let token = match new_token() {
                    Ok(t) => t,
                    Err(e) => return answer(&q, Err(e)),
                };
                self.next_epoch += 1;
                self.clients.entry(s.client.clone()).or_insert(ClientState {
                    token,
                    epoch: self.next_epoch,
                    subscriptions: HashSet::new(),
                    reserved: 0,
                })
            }
        };
        if state.subscriptions.len() + state.reserved >= limits.max_subscriptions {
            return answer(
                &q,
                Err(format!(
                    "client '{}' already holds {} subscriptions, the most a client may hold \
                     (afe serve --max-subscriptions)",
                    s.client, limits.max_subscriptions
                )),
            );
        }
        state.reserved += 1;
        let epoch = state.epoch;
        let ticket = self.ticket();
        let client = s.client;
        let sent = self.edits.send(Edit::Subscribe {
            ticket,
            client: client.clone(),
            requests: s.requests,
        });
        let asked = Asked::Subscribe { client, epoch };
        if sent.is_err() {
            self.settle(asked, Err("the server's stream has ended".into()), Some(q));
        } else {
            self.wait_for(ticket, q, asked);
        }
    }

    fn unsubscribe(&mut self, q: Query, u: UnsubscribeQuery) {
        let Some(state) = self.clients.get(&u.client) else {
            return answer(
                &q,
                Err(format!("client '{}' has no subscriptions here", u.client)),
            );
        };
        let Some(token) = u.token else {
            return answer(
                &q,
                Err("a cancellation needs the \"token\" of the client's subscription reply".into()),
            );
        };
        if !same(&token, &state.token) {
            return answer(
                &q,
                Err(format!(
                    "the token is not client '{}''s: only the client that subscribed may \
                     cancel its subscriptions",
                    u.client
                )),
            );
        }
        if !state.subscriptions.contains(&u.subscription) {
            return answer(
                &q,
                Err(format!(
                    "client '{}' has no subscription {}",
                    u.client, u.subscription
                )),
            );
        }
        let ticket = self.ticket();
        let sent = self.edits.send(Edit::Unsubscribe {
            ticket,
            client: u.client.clone(),
            subscription: u.subscription,
        });
        let asked = Asked::Unsubscribe {
            client: u.client,
            subscription: u.subscription,
        };
        if sent.is_err() {
            self.settle(asked, Err("the server's stream has ended".into()), Some(q));
        } else {
            self.wait_for(ticket, q, asked);
        }
    }

    fn ticket(&mut self) -> u64 {
        self.next_ticket += 1;
        self.next_ticket
    }

    fn wait_for(&mut self, ticket: u64, q: Query, asked: Asked) {
        self.pending.insert(
            ticket,
            Pending {
                query: Some(q),
                asked,
                deadline: Instant::now() + EDIT_WAIT,
            },
        );
    }

    fn outcome(&mut self, ticket: u64, outcome: Outcome) {
        if let Some(p) = self.pending.remove(&ticket) {
            self.settle(p.asked, outcome, p.query);
        }
    }

    /// Records an edit's outcome and answers its query (if not answered at its deadline).
    fn settle(&mut self, asked: Asked, outcome: Outcome, query: Option<Query>) {
        let outcome = match asked {
            Asked::Subscribe { client, epoch } => {
                let state = self.clients.get_mut(&client).filter(|s| s.epoch == epoch);
                match (outcome, state) {
                    (Ok(mut reply), Some(state)) => {
                        state.reserved -= 1;
                        let id = reply["subscription"].as_u64().unwrap_or(u64::MAX);
                        if query.is_some() {
                            state.subscriptions.insert(id);
                            if let Some(o) = reply.as_object_mut() {
                                o.insert("client".into(), json!(client));
                                o.insert("token".into(), json!(state.token));
                            }
                            Ok(reply)
                        } else {
                            // refused at its deadline: placed too late, so taken back
                            let ticket = self.ticket();
                            let _ = self.edits.send(Edit::Unsubscribe {
                                ticket,
                                client,
                                subscription: id,
                            });
                            return;
                        }
                    }
                    // the client left meanwhile: its departure, sent to the audio thread
                    // after this edit, removes the subscription there
                    (Ok(_), None) => Err(format!("client '{client}' left while subscribing")),
                    (Err(e), state) => {
                        if let Some(state) = state {
                            state.reserved -= 1;
                            if state.subscriptions.is_empty() && state.reserved == 0 {
                                self.clients.remove(&client);
                            }
                        }
                        Err(e)
                    }
                }
            }
            Asked::Unsubscribe {
                client,
                subscription,
            } => {
                if outcome.is_ok() {
                    if let Some(state) = self.clients.get_mut(&client) {
                        state.subscriptions.remove(&subscription);
                    }
                }
                outcome
            }
        };
        if let Some(q) = query {
            answer(&q, outcome);
        }
    }

    fn started(&mut self) {
        let (catalogues, rest) = std::mem::take(&mut self.parked)
            .into_iter()
            .partition(|p| matches!(p, Parked::Catalogue(..)));
        self.parked = rest;
        for p in catalogues {
            if let Parked::Catalogue(q, _) = p {
                self.catalogue(q);
            }
        }
    }

    fn client_up(&mut self, id: String) {
        let (now, rest) = std::mem::take(&mut self.parked)
            .into_iter()
            .partition(|p| matches!(p, Parked::Subscribe(_, s, _) if s.client == id));
        self.parked = rest;
        self.alive.insert(id);
        for p in now {
            if let Parked::Subscribe(q, s, _) = p {
                self.subscribe(q, s);
            }
        }
    }

    fn client_gone(&mut self, id: String) {
        self.alive.remove(&id);
        self.clients.remove(&id);
        let _ = self.edits.send(Edit::ClientGone(id));
    }

    /// Refuses the parked queries and the edits whose deadline has passed.
    fn expire(&mut self, now: Instant) {
        let (due, kept) = std::mem::take(&mut self.parked)
            .into_iter()
            .partition(|p| match p {
                Parked::Catalogue(_, d) | Parked::Subscribe(_, _, d) => *d <= now,
            });
        self.parked = kept;
        for p in due {
            match p {
                Parked::Catalogue(q, _) => {
                    answer(&q, Err("the server's stream has not started".into()));
                }
                Parked::Subscribe(q, s, _) => answer(
                    &q,
                    Err(format!(
                        "client '{}' has no liveliness token on {}{}: declare it first \
                         (waited {} s)",
                        s.client,
                        self.client_key,
                        s.client,
                        CLIENT_WAIT.as_secs_f64()
                    )),
                ),
            }
        }
        for p in self.pending.values_mut() {
            if p.deadline <= now {
                if let Some(q) = p.query.take() {
                    answer(
                        &q,
                        Err("the server's stream did not take the query in time".into()),
                    );
                }
            }
        }
    }
}

/// Replies to `q` on its own key with the JSON of `outcome`, or an error reply
/// `{"error": message}`.
pub(super) fn answer(q: &Query, outcome: Outcome) {
    let _ = match outcome {
        Ok(v) => q.reply(q.key_expr().clone(), v.to_string()).wait(),
        Err(message) => q.reply_err(json!({ "error": message }).to_string()).wait(),
    };
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

fn check_requests(s: SubscribeQuery) -> Result<SubscribeQuery, String> {
    if s.requests.is_empty() || s.requests.len() > MAX_REQUESTS {
        return Err(format!(
            "a subscription holds 1 to {MAX_REQUESTS} requests, not {}",
            s.requests.len()
        ));
    }
    Ok(s)
}

/// A client's secret: 128 bits from the operating system's random source, in hex.
fn new_token() -> Result<String, String> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes)
        .map_err(|e| format!("no random source for the client's token: {e}"))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Whether two tokens are equal, in a time that does not depend on where they differ.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}
