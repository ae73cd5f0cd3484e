//! `afe serve` against hostile Zenoh clients on loopback (issue 44, items 6 and 7): the
//! server runs as its own process, so that its threads are counted alone. Forty queries
//! naming clients without a liveliness token and a thousand subscriptions leave the
//! catalogue answering within 100 ms and the server's threads as many as at its start;
//! a subscription is cancelled, or added to, only with its client's secret token, never
//! with its published id; a departed client's subscriptions are removed and its room
//! given to new clients.
#![cfg(feature = "remote")]

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use afe_net::zenoh::{self, Wait};
use afe_net::Client;
use serde_json::{json, Value};

fn endpoint(port: u16) -> String {
    format!("tcp/127.0.0.1:{port}")
}

/// `afe serve` on `port` over a synthetic source for `seconds`, with `limits` (extra
/// arguments); killed when dropped.
struct ServeProcess(Child);

impl ServeProcess {
    fn start(port: u16, seconds: u32, limits: &[&str]) -> Self {
        let child = Command::new(env!("CARGO_BIN_EXE_afe"))
            .args([
                "serve",
                "--source",
                "synth:fs=44100,tone=440,noise=0.1,seed=4",
            ])
            .args(["--listen", &endpoint(port), "--for", &seconds.to_string()])
            .args(limits)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("afe serve");
        ServeProcess(child)
    }

    /// The server process's threads, from /proc.
    fn threads(&self) -> usize {
        std::fs::read_dir(format!("/proc/{}/task", self.0.id()))
            .map(Iterator::count)
            .unwrap_or(0)
    }
}

impl Drop for ServeProcess {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A plain Zenoh session connected to the server, as a client in any language opens it.
fn raw_session(port: u16) -> zenoh::Session {
    let mut c = zenoh::Config::default();
    // a peer, as the server's clients are: a client's id is its session's zid
    c.insert_json5("mode", "\"peer\"").expect("mode");
    c.insert_json5("listen/endpoints", "[]").expect("listen");
    c.insert_json5("scouting/multicast/enabled", "false")
        .expect("scouting");
    c.insert_json5("connect/endpoints", &format!("[\"{}\"]", endpoint(port)))
        .expect("connect");
    let start = Instant::now();
    loop {
        match zenoh::open(c.clone()).wait() {
            Ok(s) => return s,
            Err(e) if start.elapsed() > Duration::from_secs(10) => panic!("no server: {e}"),
            Err(_) => std::thread::sleep(Duration::from_millis(50)),
        }
    }
}

type Replies = zenoh::handlers::FifoChannelHandler<zenoh::query::Reply>;

/// Sends a query on `afe/robot/<what>` without waiting for its reply.
fn send(session: &zenoh::Session, what: &str, body: Option<Value>) -> Replies {
    let mut get = session
        .get(format!("afe/robot/{what}"))
        .timeout(Duration::from_secs(10));
    if let Some(b) = body {
        get = get.payload(b.to_string());
    }
    get.wait().expect("get")
}

/// A query's reply: its JSON, or the server's reason for refusing.
fn reply(replies: Replies) -> Result<Value, String> {
    let reply = replies.recv().map_err(|_| "no reply".to_string())?;
    match reply.result() {
        Ok(ok) => Ok(serde_json::from_slice(&ok.payload().to_bytes()).expect("json")),
        Err(e) => {
            let bytes = e.payload().to_bytes();
            Err(serde_json::from_slice::<Value>(&bytes).map_or_else(
                |_| String::from_utf8_lossy(&bytes).to_string(),
                |v| v["error"].as_str().unwrap_or_default().to_string(),
            ))
        }
    }
}

fn ask(session: &zenoh::Session, what: &str, body: Value) -> Result<Value, String> {
    reply(send(session, what, Some(body)))
}

/// The catalogue's round trip, once the stream has started.
fn catalogue_time(session: &zenoh::Session) -> Duration {
    let start = Instant::now();
    let c = reply(send(session, "catalogue", None)).expect("the catalogue");
    assert!(c["requests"].is_array(), "{c}");
    start.elapsed()
}

/// Waits for the server's catalogue (its stream has started).
fn wait_for_catalogue(session: &zenoh::Session) {
    let start = Instant::now();
    while reply(send(session, "catalogue", None)).is_err() {
        assert!(start.elapsed() < Duration::from_secs(15), "no catalogue");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Forty subscriptions naming clients that never declared a liveliness token: before
/// the fix each held every query for 2 s, and legitimate ones timed out.
fn stall(session: &zenoh::Session, round: usize) -> Vec<Replies> {
    (0..40)
        .map(|i| {
            let body =
                json!({ "client": format!("ghost-{round}-{i}"), "requests": [{ "name": "ild" }] });
            send(session, "subscribe", Some(body))
        })
        .collect()
}

/// A subscription body for `client` (with its `token`, if it has one).
fn subscription(client: &str, token: Option<&str>) -> Value {
    let mut body = json!({
        "client": client,
        "requests": [{ "name": "ild", "params": { "fb_nChannels": 8 } }],
    });
    if let Some(t) = token {
        body["token"] = json!(t);
    }
    body
}

/// The server's next report.
fn report(session: &zenoh::Session) -> Value {
    let reports = session
        .declare_subscriber("afe/robot/report")
        .wait()
        .expect("subscriber");
    let s = reports
        .recv_timeout(Duration::from_secs(5))
        .expect("recv")
        .expect("a report within 5 s");
    serde_json::from_slice(&s.payload().to_bytes()).expect("report")
}

#[test]
fn forty_stalled_queries_and_a_thousand_subscriptions_keep_the_catalogue_answering() {
    let port = 17631;
    let server = ServeProcess::start(
        port,
        40,
        &["--max-clients", "40", "--max-subscriptions", "25"],
    );
    let session = raw_session(port);
    wait_for_catalogue(&session);
    let threads_at_start = server.threads();

    let stalled = stall(&session, 0);
    let mut worst = Duration::ZERO;
    for _ in 0..5 {
        worst = worst.max(catalogue_time(&session));
    }
    eprintln!("catalogue with 40 stalled queries: {worst:?} at worst of 5");
    assert!(worst < Duration::from_millis(100), "{worst:?}");

    // 40 clients (sessions, a client's id its session's) of 25 subscriptions each: the
    // first of each gives the client's token
    let clients: Vec<zenoh::Session> = (0..40).map(|_| raw_session(port)).collect();
    let ids: Vec<String> = clients.iter().map(|c| c.zid().to_string()).collect();
    let tokens: Vec<_> = clients
        .iter()
        .zip(&ids)
        .map(|(c, id)| {
            c.liveliness()
                .declare_token(format!("afe/robot/client/{id}"))
                .wait()
                .expect("token")
        })
        .collect();
    let firsts: Vec<Replies> = clients
        .iter()
        .zip(&ids)
        .map(|(c, id)| send(c, "subscribe", Some(subscription(id, None))))
        .collect();
    let secrets: Vec<String> = firsts
        .into_iter()
        .map(|r| {
            let v = reply(r).expect("first subscription");
            v["token"].as_str().expect("a token").to_string()
        })
        .collect();
    let mut accepted = 40;
    for batch in 0..4 {
        let replies: Vec<Replies> = (0..40)
            .flat_map(|i| std::iter::repeat_n(i, 6))
            .map(|i| {
                let body = subscription(&ids[i], Some(&secrets[i]));
                send(&clients[i], "subscribe", Some(body))
            })
            .collect();
        for r in replies {
            reply(r).unwrap_or_else(|e| panic!("batch {batch}: {e}"));
            accepted += 1;
        }
    }
    assert_eq!(accepted, 1000);
    // beyond the limits: refused, naming them
    let more = ask(
        &clients[0],
        "subscribe",
        subscription(&ids[0], Some(&secrets[0])),
    );
    assert!(
        more.as_ref()
            .is_err_and(|e| e.contains("already holds 25 subscriptions")
                && e.contains("--max-subscriptions")),
        "{more:?}"
    );
    let late_id = session.zid().to_string();
    let _late = session
        .liveliness()
        .declare_token(format!("afe/robot/client/{late_id}"))
        .wait()
        .expect("token");
    let late = ask(&session, "subscribe", subscription(&late_id, None));
    assert!(
        late.as_ref()
            .is_err_and(|e| e.contains("at most 40 clients") && e.contains("--max-clients")),
        "{late:?}"
    );

    let held = report(&session);
    assert_eq!(held["subscriptions"].as_array().map(Vec::len), Some(1000));
    assert_eq!(held["clients"], 40);
    let threads = server.threads();
    eprintln!("server threads: {threads_at_start} at start, {threads} with 1000 subscriptions");
    assert!(
        threads <= threads_at_start + 4,
        "{threads} threads with 1000 subscriptions, {threads_at_start} at start"
    );

    // the catalogue still answers at once, with 40 more stalled queries and 1000
    // subscriptions published
    let stalled_again = stall(&session, 1);
    let mut worst = Duration::ZERO;
    for _ in 0..5 {
        worst = worst.max(catalogue_time(&session));
    }
    eprintln!("catalogue with 40 stalled queries and 1000 subscriptions: {worst:?} at worst of 5");
    assert!(worst < Duration::from_millis(100), "{worst:?}");
    for r in stalled.into_iter().chain(stalled_again) {
        let refused = reply(r);
        assert!(
            refused
                .as_ref()
                .is_err_and(|e| e.contains("no liveliness token")),
            "{refused:?}"
        );
    }
    drop(tokens);
}

#[test]
fn a_subscription_is_cancelled_or_added_to_only_with_its_clients_token() {
    let port = 17632;
    let _server = ServeProcess::start(port, 30, &[]);
    let attacker = raw_session(port);
    wait_for_catalogue(&attacker);
    let client = Client::connect(&endpoint(port), None).expect("client");
    let mut sub = client
        .subscribe(&[("ild", Default::default())])
        .expect("subscribed");
    let id = sub.id();
    // the client's id is public: the report names it
    let held = report(&attacker);
    let victim = held["subscriptions"][0]["client"]
        .as_str()
        .expect("a client id")
        .to_string();
    assert_eq!(held["subscriptions"][0]["subscription"], id);
    assert!(!held.to_string().contains("token"), "{held}");

    let cancel = |token: Option<&str>| {
        let mut body = json!({ "client": victim, "subscription": id });
        if let Some(t) = token {
            body["token"] = json!(t);
        }
        ask(&attacker, "unsubscribe", body)
    };
    let bare = cancel(None);
    assert!(
        bare.as_ref()
            .is_err_and(|e| e.contains("needs the \"token\"")),
        "{bare:?}"
    );
    let guessed = cancel(Some("00000000000000000000000000000000"));
    assert!(
        guessed
            .as_ref()
            .is_err_and(|e| e.contains("only the client that subscribed")),
        "{guessed:?}"
    );
    let _token = attacker
        .liveliness()
        .declare_token(format!("afe/robot/client/{victim}"))
        .wait()
        .expect("token");
    let under = ask(&attacker, "subscribe", subscription(&victim, None));
    assert!(
        under
            .as_ref()
            .is_err_and(|e| e.starts_with("the \"token\" is missing")),
        "{under:?}"
    );

    // the subscription is there and goes on
    let held = report(&attacker);
    assert_eq!(held["subscriptions"].as_array().map(Vec::len), Some(1));
    let seqs: Vec<u64> = (0..10)
        .map(|_| {
            sub.recv(Duration::from_secs(5))
                .expect("recv")
                .expect("a block")
                .seq
        })
        .collect();
    assert!(seqs.windows(2).all(|w| w[1] == w[0] + 1), "{seqs:?}");
    // its own client cancels it (with the token it was given)
    drop(sub);
    let start = Instant::now();
    while report(&attacker)["subscriptions"]
        .as_array()
        .is_some_and(|s| !s.is_empty())
    {
        assert!(start.elapsed() < Duration::from_secs(5), "not cancelled");
    }
}

#[test]
fn a_departed_clients_subscriptions_are_removed_and_its_room_given_to_others() {
    let port = 17633;
    let _server = ServeProcess::start(
        port,
        30,
        &["--max-clients", "2", "--max-subscriptions", "3"],
    );
    let watcher = raw_session(port);
    wait_for_catalogue(&watcher);
    // two clients fill the server, three subscriptions each
    let fill = || {
        let s = raw_session(port);
        let name = &s.zid().to_string();
        let token = s
            .liveliness()
            .declare_token(format!("afe/robot/client/{name}"))
            .wait()
            .expect("token");
        let first = ask(&s, "subscribe", subscription(name, None)).expect("subscribed");
        let secret = first["token"].as_str().expect("a token").to_string();
        for _ in 0..2 {
            ask(&s, "subscribe", subscription(name, Some(&secret))).expect("subscribed");
        }
        (s, token)
    };
    let a = fill();
    let b = fill();
    assert_eq!(
        report(&watcher)["subscriptions"].as_array().map(Vec::len),
        Some(6)
    );
    let refused = {
        let s = raw_session(port);
        let c = s.zid().to_string();
        let _t = s
            .liveliness()
            .declare_token(format!("afe/robot/client/{c}"))
            .wait()
            .expect("token");
        ask(&s, "subscribe", subscription(&c, None))
    };
    assert!(
        refused
            .as_ref()
            .is_err_and(|e| e.contains("at most 2 clients")),
        "{refused:?}"
    );
    // both leave without cancelling anything (their sessions close, as a killed
    // process's link would)
    for (session, _token) in [a, b] {
        session.close().wait().expect("close");
    }
    until_no_client(
        &watcher,
        Duration::from_secs(10),
        "the departed clients' subscriptions stayed",
    );
    // and two new clients get the whole room
    let _c = fill();
    let _d = fill();
    assert_eq!(
        report(&watcher)["subscriptions"].as_array().map(Vec::len),
        Some(6)
    );
}

/// Issue 57: one connection declaring eight liveliness tokens holds one client, not
/// eight: a client's id is its session's, and an id of no connected session is refused,
/// so `--max-clients` counts connections; the room left is another session's.
#[test]
fn one_connection_with_many_tokens_holds_one_client() {
    let port = 17634;
    let _server = ServeProcess::start(port, 30, &["--max-clients", "2"]);
    let hostile = raw_session(port);
    wait_for_catalogue(&hostile);
    let own = hostile.zid().to_string();
    let names: Vec<String> = (0..8)
        .map(|i| format!("sock-{i}"))
        .chain([own.clone()])
        .collect();
    let _tokens: Vec<_> = names
        .iter()
        .map(|n| {
            hostile
                .liveliness()
                .declare_token(format!("afe/robot/client/{n}"))
                .wait()
                .expect("token")
        })
        .collect();
    for n in &names[..8] {
        let refused = ask(&hostile, "subscribe", subscription(n, None));
        assert!(
            refused.as_ref().is_err_and(|e| e.contains(&format!(
                "client '{n}' is not the Zenoh id of a session connected to this server"
            ))),
            "{refused:?}"
        );
    }
    ask(&hostile, "subscribe", subscription(&own, None)).expect("its own id");
    assert_eq!(report(&hostile)["clients"], 1);
    // another connection still finds room
    let other = Client::connect(&endpoint(port), None).expect("client");
    let mut sub = other
        .subscribe(&[("ild", Default::default())])
        .expect("room for another connection");
    assert!(sub.recv(Duration::from_secs(5)).expect("recv").is_some());
    assert_eq!(report(&hostile)["clients"], 2);
}

/// Issue 57: a liveliness token another session declared under a client's public id
/// does not keep that client's subscriptions once its own session has gone.
#[test]
fn a_foreign_token_under_a_departed_clients_id_keeps_nothing_alive() {
    let port = 17635;
    let _server = ServeProcess::start(port, 30, &[]);
    let watcher = raw_session(port);
    wait_for_catalogue(&watcher);
    let victim = raw_session(port);
    let id = victim.zid().to_string();
    let _own = victim
        .liveliness()
        .declare_token(format!("afe/robot/client/{id}"))
        .wait()
        .expect("token");
    let placed = ask(&victim, "subscribe", subscription(&id, None)).expect("subscribed");
    let key = placed["key"].as_str().expect("frames key").to_string();
    let _foreign = watcher
        .liveliness()
        .declare_token(format!("afe/robot/client/{id}"))
        .wait()
        .expect("token");
    assert_eq!(report(&watcher)["clients"], 1);
    // the victim's session goes (as a killed process's link does)
    victim.close().wait().expect("close");
    until_no_client(
        &watcher,
        Duration::from_secs(5),
        "the departed client's subscription is still published",
    );
    // and its frames stop
    let frames = watcher.declare_subscriber(&key).wait().expect("subscriber");
    std::thread::sleep(Duration::from_millis(300));
    while frames.try_recv().ok().flatten().is_some() {}
    assert!(
        frames
            .recv_timeout(Duration::from_millis(500))
            .ok()
            .flatten()
            .is_none(),
        "frames still published"
    );
}

/// Polls the server's report through `watcher` until it has no client and no
/// subscription, failing with `what` and the last report after `within`.
fn until_no_client(watcher: &zenoh::Session, within: Duration, what: &str) {
    let start = Instant::now();
    loop {
        let r = report(watcher);
        if r["subscriptions"].as_array().is_some_and(Vec::is_empty) && r["clients"] == 0 {
            return;
        }
        assert!(start.elapsed() < within, "{what}: {r}");
    }
}

/// Issue 57, item 11: a subscription whose measured cost would take the stream past
/// its deadline is refused before it runs, with its cost, the budget and what to
/// change; the clients already served keep every frame.
#[test]
fn a_subscription_too_heavy_for_the_deadline_is_refused_before_it_runs() {
    let port = 17636;
    let _server = ServeProcess::start(port, 30, &[]);
    wait_for_catalogue(&raw_session(port));
    let light = Client::connect(&endpoint(port), None).expect("client");
    let mut served = light
        .subscribe(&[("ild", Default::default())])
        .expect("ild");
    let heavy = Client::connect(&endpoint(port), None).expect("client");
    let params: afe::ParamMap = [
        ("fb_nChannels".to_string(), json!(64)),
        ("ac_hSizeSec".to_string(), json!(0.002)),
        ("ac_wSizeSec".to_string(), json!(0.05)),
    ]
    .into_iter()
    .collect();
    let refused = heavy
        .subscribe(&[("autocorrelation", params)])
        .map(|_| ())
        .expect_err("refused");
    let m = refused.to_string();
    assert!(
        m.contains("'autocorrelation' would cost ")
            && m.contains(" of each 10.0-ms block (measured on a trial before placing it)")
            && m.contains("ask for less (fewer channels, a longer hop"),
        "{m}"
    );
    let seqs: Vec<u64> = (0..20)
        .map(|_| {
            served
                .recv(Duration::from_secs(5))
                .expect("recv")
                .expect("a block")
                .seq
        })
        .collect();
    assert!(seqs.windows(2).all(|w| w[1] == w[0] + 1), "{seqs:?}");
    let r = report(&raw_session(port));
    assert_eq!(r["subscriptions"].as_array().map(Vec::len), Some(1), "{r}");
    assert_eq!(r["stream"]["lost_frames"], 0, "{r}");
}

/// Issue 57, item 1: a web page cannot change or remove a Zenoh client's request: its
/// `set` finds no request of its own, its `remove` of the client's handle is refused, and
/// the client keeps getting frames of the width it was announced.
#[test]
fn a_web_page_cannot_edit_a_zenoh_clients_subscription() {
    let (port, http) = (17637, 17638);
    let _server = ServeProcess::start(port, 30, &["--http", &format!("127.0.0.1:{http}")]);
    wait_for_catalogue(&raw_session(port));
    let client = Client::connect(&endpoint(port), None).expect("client");
    let mut sub = client
        .subscribe(&[("ratemap", Default::default())])
        .expect("ratemap");
    let width = |sub: &mut afe_net::Subscription| {
        let f = sub
            .recv(Duration::from_secs(5))
            .expect("recv")
            .expect("a block");
        f.signals[0].frame_shape.iter().product::<usize>()
    };
    assert_eq!(width(&mut sub), 31);
    // a script's WebSocket, no Origin header
    let (mut page, _) = tungstenite::connect(format!("ws://127.0.0.1:{http}/ws")).expect("ws");
    let mut ask = |msg: Value| {
        page.send(tungstenite::Message::text(msg.to_string()))
            .expect("send");
        loop {
            if let tungstenite::Message::Text(t) = page.read().expect("read") {
                let v: Value = serde_json::from_str(t.as_str()).expect("json");
                if v["type"] == "reply" {
                    return v;
                }
            }
        }
    };
    let set = ask(json!({"op": "set", "name": "fb_nChannels", "value": 8}));
    assert_eq!(set["ok"], false, "{set}");
    let removed = ask(json!({"op": "remove", "handle": 0}));
    assert_eq!(removed["ok"], false, "{removed}");
    assert!(
        removed["message"]
            .as_str()
            .is_some_and(|m| m.contains("was not placed by this page")),
        "{removed}"
    );
    for _ in 0..20 {
        assert_eq!(width(&mut sub), 31);
    }
    assert_eq!(
        report(&raw_session(port))["subscriptions"]
            .as_array()
            .map(Vec::len),
        Some(1)
    );
}
