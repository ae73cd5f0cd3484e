//! The robot as a server: `afe serve` publishes its live source and the representations
//! its subscribers ask for over [Zenoh](https://zenoh.io); [`Client`] and
//! [`RemoteSource`] are the remote ends, with the interfaces of the local ones.
//!
//! Key expressions, for a server named `N` (`--name`, default `robot`):
//!
//! | key | what |
//! |---|---|
//! | `afe/N/server` | the server's liveliness token |
//! | `afe/N/catalogue` | queryable: JSON of the stream (rate, ears, block) and the requests |
//! | `afe/N/subscribe` | queryable: JSON `{"client", "token"?, "requests": [{"name", "params"}]}` → the subscription and the client's secret `token` |
//! | `afe/N/unsubscribe` | queryable: JSON `{"client", "subscription", "token"}` |
//! | `afe/N/client/ID` | a client's liveliness token: its subscriptions and its state go when it goes |
//!
//! The first subscription under a client id returns a secret token (never published);
//! every later subscription or cancellation under that id must carry it, so another
//! session that learns the id (it is in the report) can neither cancel the client's
//! subscriptions nor add to them. The server holds at most
//! [`ServeOptions::max_clients`] clients of [`ServeOptions::max_subscriptions`]
//! subscriptions each, answers every query without waiting on any one client, and
//! publishes every subscription from a fixed pool of [`PUBLISH_THREADS`] threads.
//! | `afe/N/audio` | raw audio blocks ([`wire`]) |
//! | `afe/N/frames/S` | subscription `S`'s new frames per block ([`wire`]) |
//! | `afe/N/report` | the server's report, JSON, once per second of audio |

#[cfg(feature = "zenoh")]
mod client;
#[cfg(feature = "ros2")]
pub mod ros2;
#[cfg(feature = "zenoh")]
mod server;
#[cfg(feature = "zenoh")]
mod source;
#[cfg(feature = "zenoh")]
mod tally;
pub mod wire;

use thiserror::Error;

pub use afe::frames::{FrameBlock, Frames};
#[cfg(feature = "zenoh")]
pub use client::{Client, Subscription};
#[cfg(feature = "zenoh")]
pub use server::{ServeOptions, ServeTap, Server};
#[cfg(feature = "zenoh")]
pub use source::{run_spec, RemoteSource};
#[cfg(feature = "zenoh")]
pub use tally::Tally;
#[cfg(feature = "zenoh")]
/// The Zenoh crate this one speaks through, for clients that open their own sessions.
pub use zenoh;

/// Where `afe serve` listens unless told otherwise: loopback only.
pub const DEFAULT_LISTEN: &str = "tcp/127.0.0.1:7447";
/// The server's name unless told otherwise.
pub const DEFAULT_NAME: &str = "robot";
/// Requests one subscription may hold.
pub const MAX_REQUESTS: usize = 64;
/// Subscriptions one client may hold unless `afe serve --max-subscriptions` says otherwise.
pub const MAX_SUBSCRIPTIONS: usize = 32;
/// Clients (ids holding subscriptions) a server serves at once unless `afe serve
/// --max-clients` says otherwise.
pub const MAX_CLIENTS: usize = 32;
/// The largest `--max-subscriptions` accepted: each client's queue to the publishing
/// pool is sized for this many subscriptions' messages.
pub const MAX_SUBSCRIPTIONS_LIMIT: usize = 256;
/// The largest `--max-clients` accepted.
pub const MAX_CLIENTS_LIMIT: usize = 1024;
/// Threads publishing every subscription's messages, however many there are.
pub const PUBLISH_THREADS: usize = 4;
/// The share of a block's budget requests may take unless [`ServeOptions::max_load`]
/// says otherwise: a subscription whose measured cost would take the stream beyond it
/// is refused before it runs.
pub const MAX_LOAD: f64 = 0.8;
/// Largest subscription message accepted, bytes.
pub const MAX_QUERY_BYTES: usize = 64 * 1024;

/// What can go wrong on either end.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RemoteError {
    /// Zenoh could not open a session, declare a key or send.
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// A server name that cannot be a key expression chunk.
    #[error("server name '{0}': use letters, digits, '-' and '_' only")]
    Name(String),
    /// No server answered, or several did and none was named.
    #[error("{0}")]
    NoServer(String),
    /// The server refused a query (its message says why).
    #[error("the server refused: {0}")]
    Refused(String),
    /// A reply or message that does not follow the wire format.
    #[error("malformed message from the server: {0}")]
    Malformed(String),
    /// Server options out of their range.
    #[error("{0}")]
    Options(String),
    /// The server has gone (its liveliness token was withdrawn).
    #[error("the server '{0}' has gone")]
    ServerGone(String),
}

#[cfg(feature = "zenoh")]
impl From<zenoh::Error> for RemoteError {
    fn from(e: zenoh::Error) -> Self {
        RemoteError::Zenoh(e.to_string())
    }
}

impl From<wire::WireError> for RemoteError {
    fn from(e: wire::WireError) -> Self {
        RemoteError::Malformed(e.to_string())
    }
}

#[cfg(feature = "zenoh")]
/// Checks that `name` can be one chunk of a key expression.
fn check_name(name: &str) -> Result<(), RemoteError> {
    let ok = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    if ok {
        Ok(())
    } else {
        Err(RemoteError::Name(name.to_string()))
    }
}

#[cfg(feature = "zenoh")]
/// The key `afe/<name>/<what>`.
fn key(name: &str, what: &str) -> String {
    format!("afe/{name}/{what}")
}

#[cfg(feature = "zenoh")]
/// A Zenoh configuration (from `base`, or the defaults) with multicast scouting off and
/// the given mode and endpoints.
fn config(
    base: Option<zenoh::Config>,
    mode: &str,
    listen: &[String],
    connect: &[String],
) -> Result<zenoh::Config, RemoteError> {
    let json = |v: &[String]| serde_json::to_string(v).unwrap_or_else(|_| "[]".into());
    let mut c = base.unwrap_or_default();
    c.insert_json5("mode", &format!("\"{mode}\""))?;
    c.insert_json5("scouting/multicast/enabled", "false")?;
    c.insert_json5("listen/endpoints", &json(listen))?;
    c.insert_json5("connect/endpoints", &json(connect))?;
    Ok(c)
}

/// Whether every endpoint is on a loopback address or a unix socket.
pub fn is_loopback(endpoint: &str) -> bool {
    let Some((proto, addr)) = endpoint.split_once('/') else {
        return false;
    };
    if proto == "unixsock-stream" {
        return true;
    }
    let host = addr.split('#').next().unwrap_or(addr);
    let host = host.rsplit_once(':').map_or(host, |(h, _)| h);
    let host = host.trim_start_matches('[').trim_end_matches(']');
    host == "localhost"
        || host
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

#[cfg(all(test, feature = "zenoh"))]
mod tests {
    use super::*;

    #[test]
    fn loopback_endpoints_are_told_from_open_ones() {
        assert!(is_loopback("tcp/127.0.0.1:7447"));
        assert!(is_loopback("tcp/[::1]:7447"));
        assert!(is_loopback("tcp/localhost:7447"));
        assert!(is_loopback("unixsock-stream//tmp/afe.sock"));
        assert!(!is_loopback("tcp/0.0.0.0:7447"));
        assert!(!is_loopback("tcp/192.168.1.4:7447"));
        assert!(!is_loopback("garbage"));
    }

    #[test]
    fn names_are_single_key_chunks() {
        assert!(check_name("robot-1_a").is_ok());
        for bad in ["", "a/b", "*", "r#", "a b"] {
            assert!(check_name(bad).is_err(), "{bad}");
        }
    }
}
