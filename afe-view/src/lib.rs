//! The live web view: a page that shows a running stream's representations as they
//! are computed, lets its user add and remove requests and change parameters, and plays
//! the input. [`View::start`] serves it; its [`Tap`] is the stream's observer.
//!
//! The page talks to the server over one WebSocket (`/ws`):
//! - server → page, text: `{"type":"layout", "version", "fs_hz", "ears", "block_ms",
//!   "catalogue": [request names], "order": [keys], "signals": {key: description},
//!   "requests": [{"handle", "outputs"}]}` on connection (the stream sends one on its
//!   first block, even with no request in place) and whenever the graph changes (the
//!   description is [`afe::metadata::describe`]'s); `{"type":"reply", "op", "ok",
//!   "message"}` to the page that asked, after its edit or a refusal;
//!   `{"type":"refused", "message"}` before closing a page there is no room for;
//!   `{"type":"lagged", "batches"}` when this page fell behind and lost batches;
//! - server → page, binary: a batch of blocks (see `server::encode`): the new frames of
//!   every signal (complex values as magnitudes), each ear's min/max per block, the
//!   input samples while this page listens, and the stream's counters (frames, frames
//!   lost by the stream, frames dropped for slow pages, compute time against budget);
//! - page → server, text: `{"op":"add","request":"itd","params":{...}}`,
//!   `{"op":"remove","handle":2}`, `{"op":"set","name":"rm_wSizeSec","value":0.05}`,
//!   `{"op":"audio","on":true}`.
//!
//! The audio path never waits for the web side: batches come from a small pool and are
//! dropped (counted) when none is free; edits wait in a bounded channel until the next
//! block. Only pages of allowed origins connect ([`AllowedOrigins`]), and what pages may
//! ask is bounded ([`Limits`]): a page edits only the requests it placed, they go when
//! it closes, and each request is measured before it is placed ([`afe::trial`]) and
//! refused if it would take the stream past its deadline.

mod csp;
mod limits;
mod origin;
mod server;
mod tap;

use std::net::{SocketAddr, TcpListener};
use std::sync::atomic::{AtomicU64, AtomicUsize};
use std::sync::{mpsc, Arc, Mutex};
use std::thread::JoinHandle;

use thiserror::Error;

pub use limits::Limits;
pub use origin::{AllowedOrigins, OriginError};
pub use tap::Tap;

/// Who may connect to the view and how much they may ask.
#[derive(Debug, Clone, Default)]
pub struct ViewOptions {
    /// Origins whose pages may open the WebSocket besides the page's own.
    pub origins: AllowedOrigins,
    /// Bounds on connections, pages, requests, messages and edits.
    pub limits: Limits,
    /// The robot's platform descriptor (its JSON form, docs/platform.md), shown on the
    /// page: what the robot is, its microphones and its head.
    pub platform: Option<serde_json::Value>,
}

/// Batches in flight between the audio path and the pages.
const POOL: usize = 4;

/// Problems starting the view.
#[derive(Debug, Error)]
pub enum ViewError {
    /// The address cannot be listened on.
    #[error("cannot serve the live view on {addr}: {source}")]
    Listen {
        /// The address asked for.
        addr: SocketAddr,
        /// What the system said.
        source: std::io::Error,
    },
    /// A thread of the view cannot be started.
    #[error("cannot start the live view's request trials: {0}")]
    Thread(std::io::Error),
    /// An allowed origin given is not one.
    #[error(transparent)]
    Origin(#[from] OriginError),
}

/// A running view server; it stops when dropped.
pub struct View {
    addr: SocketAddr,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    server: Option<JoinHandle<std::io::Result<()>>>,
    shared: Arc<server::Shared>,
}

impl View {
    /// Serves the view on `addr` for a stream in blocks of `block_ms`; returns the server
    /// and the stream's observer. Batches hold about 50 ms of blocks.
    pub fn start(
        addr: SocketAddr,
        block_ms: f64,
        options: &ViewOptions,
    ) -> Result<(View, Tap), ViewError> {
        let listen_error = |source| ViewError::Listen { addr, source };
        let listener = TcpListener::bind(addr).map_err(listen_error)?;
        listener.set_nonblocking(true).map_err(listen_error)?;
        let addr = listener.local_addr().map_err(listen_error)?;
        let (to_server, from_tap) = mpsc::sync_channel(POOL);
        let (pool_tx, pool_rx) = mpsc::channel();
        for _ in 0..POOL {
            let _ = pool_tx.send(tap::Batch::new());
        }
        let (edits_tx, edits_rx) = mpsc::sync_channel(options.limits.edits_waiting);
        // one departure per page: bounded by the pages, never refused
        let (departed_tx, departed_rx) = mpsc::channel();
        let trials =
            afe::trial::Trials::start(options.limits.edits_waiting).map_err(ViewError::Thread)?;
        let listeners = Arc::new(AtomicUsize::new(0));
        let shared = Arc::new(server::Shared {
            out: tokio::sync::broadcast::channel(server::PAGE_BACKLOG).0,
            layout: Mutex::new(String::new()),
            edits: edits_tx,
            departed: departed_tx,
            listeners: listeners.clone(),
            pages: AtomicUsize::new(0),
            next_page: AtomicU64::new(1),
            options: options.clone(),
            log: Mutex::new(server::Throttle::default()),
        });
        let bridge_shared = shared.clone();
        std::thread::Builder::new()
            .name("afe-view-bridge".into())
            .spawn(move || server::bridge(from_tap, pool_tx, bridge_shared))
            .map_err(listen_error)?;
        let (stop, stopped) = tokio::sync::oneshot::channel();
        let serve_shared = shared.clone();
        let server = std::thread::Builder::new()
            .name("afe-view-http".into())
            .spawn(move || server::serve(listener, serve_shared, stopped))
            .map_err(listen_error)?;
        let batch_blocks = (50.0 / block_ms).ceil().clamp(1.0, 100.0) as u32;
        let tap = Tap::new(
            to_server,
            pool_rx,
            edits_rx,
            departed_rx,
            listeners,
            batch_blocks,
            options.limits.clone(),
            trials,
            options.platform.clone(),
        );
        Ok((
            View {
                addr,
                stop: Some(stop),
                server: Some(server),
                shared,
            },
            tap,
        ))
    }

    /// The address served (with the port the system chose for port 0).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Pages connected now.
    pub fn pages(&self) -> usize {
        self.shared.pages.load(std::sync::atomic::Ordering::Relaxed)
    }
}

impl Drop for View {
    fn drop(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(server) = self.server.take() {
            let _ = server.join();
        }
    }
}
