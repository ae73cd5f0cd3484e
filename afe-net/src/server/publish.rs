//! The publishing pool: a fixed number of threads put every subscription's messages on
//! the network, however many subscriptions there are. The audio thread hands a filled
//! buffer to its client's queue and never waits; a client is served by one thread at a
//! time (its messages stay in order), and a client whose link is congested is served
//! without waiting on it, so it holds up no other client.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use zenoh::pubsub::Publisher;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::{Session, Wait};

use super::lock;
#[cfg(feature = "ros2")]
use crate::ros2::names;
use crate::RemoteError;

/// Messages a subscription may have on their way to its client before the next are
/// dropped for it alone (at 10-ms blocks, 0.32 s).
pub(super) const SUB_QUEUE: usize = 32;
/// How long a new subscription's messages wait for its client's subscriber.
const MATCH_WAIT: Duration = Duration::from_secs(2);
/// A put that takes longer than this met a full link (a put waits up to 20 ms for room
/// before it drops, see `Server::start`), or its thread lost its core meanwhile.
const CONGESTED_PUT: Duration = Duration::from_millis(18);
/// Slow puts in a row that tell a congested link: a congested link makes every put wait,
/// while a thread that lost its core for a while (a busy or virtual host) makes one slow
/// put and then catches up.
const CONGESTED_PUTS: u32 = 2;
/// How long a congested client's messages are dropped without a put, so that its link
/// holds no publishing thread (a client that reads again gets messages after this).
const CONGESTION_BACKOFF: Duration = Duration::from_millis(100);

/// A message for a subscription: a filled buffer, or an empty one (no allocation) that
/// asks the thread to look again whether the subscription's client has matched.
type Message = (Arc<SubOutlet>, Vec<u8>);

/// One subscription's publisher, its held messages and its counters.
pub(super) struct SubOutlet {
    publisher: Publisher<'static>,
    /// Buffers back to the audio thread's pool for this subscription.
    back: SyncSender<Vec<u8>>,
    /// Messages held until the client's subscriber matches (at most [`MATCH_WAIT`]);
    /// touched only by the thread serving the client.
    held: Mutex<VecDeque<Vec<u8>>>,
    matched: AtomicBool,
    since: Instant,
    /// Messages dropped by the pool for a congested link.
    dropped: AtomicU64,
    /// A ROS 2 topic's GID and next sequence number, for each sample's attachment.
    #[cfg(feature = "ros2")]
    ros: Option<([u8; 16], AtomicU64)>,
}

impl SubOutlet {
    /// Messages the pool dropped for a congested link.
    pub(super) fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Counts a ROS 2 topic's message dropped before it reached the pool: its sequence
    /// number is spent, so that subscribers see the gap.
    #[cfg(feature = "ros2")]
    pub(super) fn skip(&self) {
        if let Some((_, seq)) = &self.ros {
            seq.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// One client's queue to the pool.
pub(super) struct ClientOut {
    queue: SyncSender<Message>,
    inbox: Mutex<Receiver<Message>>,
    /// Messages sent and not yet taken: the client is in the ready queue or held by a
    /// thread exactly while this is above zero.
    pending: AtomicUsize,
    /// Its link's state, for the serving thread.
    link: Mutex<Link>,
}

/// A client's link as its puts tell it.
#[derive(Default)]
struct Link {
    /// Slow puts in a row.
    slow_puts: u32,
    /// Until when its messages are dropped without a put (a congested link).
    congested_until: Option<Instant>,
}

impl Link {
    /// Counts a put that took `took`: the link is congested after [`CONGESTED_PUTS`]
    /// slow ones in a row, and its messages are then dropped for [`CONGESTION_BACKOFF`].
    fn put_took(&mut self, took: Duration) {
        self.slow_puts = if took > CONGESTED_PUT {
            self.slow_puts + 1
        } else {
            0
        };
        self.congested_until = (self.slow_puts >= CONGESTED_PUTS).then(|| {
            self.slow_puts = 0;
            Instant::now() + CONGESTION_BACKOFF
        });
    }
}

/// The audio thread's end of a subscription: its buffers, and where they go.
pub(super) struct SubEnd {
    pool: Receiver<Vec<u8>>,
    outlet: Arc<SubOutlet>,
    client: Arc<ClientOut>,
}

impl SubEnd {
    /// An empty buffer, if one is free.
    pub(super) fn buffer(&self) -> Option<Vec<u8>> {
        let mut b = self.pool.try_recv().ok()?;
        b.clear();
        Some(b)
    }

    /// The subscription's counters and publisher.
    pub(super) fn outlet(&self) -> &SubOutlet {
        &self.outlet
    }
}

/// The pool's threads and the queue of clients with messages.
pub(super) struct Pool {
    ready: Option<SyncSender<Arc<ClientOut>>>,
    threads: Vec<JoinHandle<()>>,
    /// Messages one client's queue holds: every subscription's buffers and a wake-up each.
    client_queue: usize,
}

impl Pool {
    /// Starts `threads` publishing threads for at most `max_clients` clients of
    /// `max_subscriptions` subscriptions each.
    pub(super) fn start(
        threads: usize,
        max_clients: usize,
        max_subscriptions: usize,
    ) -> Result<Pool, RemoteError> {
        // a client is queued once at a time; a departed client's queue may still be
        // queued while its id comes back
        let (ready, clients) = mpsc::sync_channel::<Arc<ClientOut>>(2 * max_clients + 1);
        let clients = Arc::new(Mutex::new(clients));
        let threads = (0..threads)
            .map(|i| {
                let clients = clients.clone();
                std::thread::Builder::new()
                    .name(format!("afe-zenoh-publish-{i}"))
                    .spawn(move || loop {
                        let next = lock(&clients).recv();
                        match next {
                            Ok(client) => serve(&client),
                            Err(_) => break,
                        }
                    })
                    .map_err(|e| {
                        RemoteError::Zenoh(format!("cannot start a publishing thread: {e}"))
                    })
            })
            .collect::<Result<_, _>>()?;
        Ok(Pool {
            ready: Some(ready),
            threads,
            client_queue: max_subscriptions * (SUB_QUEUE + 1),
        })
    }

    /// A new client's queue.
    pub(super) fn client(&self) -> Arc<ClientOut> {
        self.client_with(self.client_queue)
    }

    /// A new client's queue for up to `subscriptions` subscriptions.
    #[cfg(feature = "ros2")]
    pub(super) fn client_for(&self, subscriptions: usize) -> Arc<ClientOut> {
        self.client_with(subscriptions * (SUB_QUEUE + 1))
    }

    fn client_with(&self, capacity: usize) -> Arc<ClientOut> {
        let (queue, inbox) = mpsc::sync_channel(capacity);
        Arc::new(ClientOut {
            queue,
            inbox: Mutex::new(inbox),
            pending: AtomicUsize::new(0),
            link: Mutex::new(Link::default()),
        })
    }

    /// A new subscription of `client` publishing on `key` (dropping messages for a
    /// congested link, never blocking), with its [`SUB_QUEUE`] buffers; with a ROS 2
    /// topic's GID, each sample carries rmw_zenoh's attachment.
    pub(super) fn subscription(
        &self,
        session: &Session,
        key: String,
        client: &Arc<ClientOut>,
        #[cfg(feature = "ros2")] ros_gid: Option<[u8; 16]>,
    ) -> Result<SubEnd, RemoteError> {
        let publisher = session
            .declare_publisher(key)
            .congestion_control(CongestionControl::Drop)
            .priority(Priority::DataHigh)
            .wait()?;
        let (back, pool) = mpsc::sync_channel(SUB_QUEUE);
        for _ in 0..SUB_QUEUE {
            let _ = back.try_send(Vec::new());
        }
        Ok(SubEnd {
            pool,
            outlet: Arc::new(SubOutlet {
                publisher,
                back,
                held: Mutex::new(VecDeque::with_capacity(SUB_QUEUE)),
                matched: AtomicBool::new(false),
                since: Instant::now(),
                dropped: AtomicU64::new(0),
                #[cfg(feature = "ros2")]
                // rmw_zenoh numbers a publisher's samples from 1
                ros: ros_gid.map(|g| (g, AtomicU64::new(1))),
            }),
            client: client.clone(),
        })
    }

    /// Passes a filled buffer on, never waiting.
    pub(super) fn send(&self, sub: &SubEnd, message: Vec<u8>) {
        self.enqueue(sub, message);
    }

    /// Asks the pool to look again at a subscription that has no free buffer and whose
    /// client has not matched yet: its held messages go once it has.
    pub(super) fn nudge(&self, sub: &SubEnd) {
        if !sub.outlet.matched.load(Ordering::Relaxed) {
            self.enqueue(sub, Vec::new());
        }
    }

    fn enqueue(&self, sub: &SubEnd, message: Vec<u8>) {
        let client = &sub.client;
        let before = client.pending.fetch_add(1, Ordering::AcqRel);
        if client
            .queue
            .try_send((sub.outlet.clone(), message))
            .is_err()
        {
            // full (only wake-ups can fill it) or its threads have gone
            client.pending.fetch_sub(1, Ordering::AcqRel);
            return;
        }
        if before == 0 {
            if let Some(ready) = &self.ready {
                let _ = ready.try_send(client.clone());
            }
        }
    }
}

impl Drop for Pool {
    fn drop(&mut self) {
        self.ready = None;
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// Serves a client until its queue is empty: the only thread serving it meanwhile.
fn serve(client: &ClientOut) {
    loop {
        let mut taken = 0;
        loop {
            let next = lock(&client.inbox).try_recv();
            let Ok((sub, message)) = next else { break };
            deliver(client, &sub, message);
            taken += 1;
        }
        if taken == 0 {
            // counted by the audio thread, not yet in the queue
            std::thread::yield_now();
        }
        if client.pending.fetch_sub(taken, Ordering::AcqRel) == taken {
            return;
        }
    }
}

/// Publishes a subscription's message, after those it holds; holds them while its
/// client's subscriber has not matched (the client declares it once it has the reply).
fn deliver(client: &ClientOut, sub: &SubOutlet, message: Vec<u8>) {
    let mut held = lock(&sub.held);
    if !message.is_empty() {
        held.push_back(message);
    }
    if !sub.matched.load(Ordering::Relaxed) {
        let matched = sub
            .publisher
            .matching_status()
            .wait()
            .map_or(true, |m| m.matching());
        if !matched && sub.since.elapsed() < MATCH_WAIT {
            return;
        }
        sub.matched.store(true, Ordering::Relaxed);
    }
    while let Some(m) = held.pop_front() {
        let mut link = lock(&client.link);
        if link
            .congested_until
            .is_some_and(|until| Instant::now() < until)
        {
            sub.dropped.fetch_add(1, Ordering::Relaxed);
            #[cfg(feature = "ros2")]
            sub.skip();
        } else {
            let start = Instant::now();
            let put = sub.publisher.put(m.as_slice());
            #[cfg(feature = "ros2")]
            let put = match &sub.ros {
                Some((gid, seq)) => {
                    let n = seq.fetch_add(1, Ordering::Relaxed) as i64;
                    put.attachment(names::attachment(n, names::now_ns(), gid).to_vec())
                }
                None => put,
            };
            let _ = put.wait();
            link.put_took(start.elapsed());
        }
        let _ = sub.back.try_send(m);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_slow_put_is_a_lost_core_and_two_in_a_row_a_congested_link() {
        let slow = CONGESTED_PUT + Duration::from_millis(80);
        let fast = Duration::from_micros(50);
        let mut link = Link::default();
        link.put_took(slow);
        assert!(link.congested_until.is_none(), "one slow put");
        link.put_took(fast);
        link.put_took(slow);
        assert!(link.congested_until.is_none(), "slow puts apart");
        link.put_took(slow);
        let until = link.congested_until.expect("two slow puts in a row");
        assert!(until > Instant::now() + CONGESTION_BACKOFF / 2);
        link.put_took(fast);
        assert!(link.congested_until.is_none(), "a fast put clears it");
    }
}
