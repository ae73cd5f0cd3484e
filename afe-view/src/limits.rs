//! The bounds that keep one page, or many, from taking the view (and the stream behind
//! it) over: connections, pages, requests, message sizes and rates, waiting edits and
//! the stream's load. Each refusal is told to the page with its reason.

use std::time::{Duration, Instant};

/// The view's bounds; [`Limits::default`] gives the documented ones.
#[derive(Debug, Clone)]
pub struct Limits {
    /// Pages (WebSockets) connected at once; one more is told "too many pages" and
    /// closed (close code 1013, try again later).
    pub pages: usize,
    /// HTTP connections being served at once besides the pages (loading the page,
    /// opening a WebSocket); more wait to be accepted.
    pub connections: usize,
    /// Time a connection may take to send its request's headers; a slower one is
    /// closed.
    pub header_timeout: Duration,
    /// Requests one page may have in place at once (those it added and nobody removed).
    pub requests_per_page: usize,
    /// Requests all pages together may have in place at once (besides those the stream
    /// was started with).
    pub requests: usize,
    /// Largest message a page may send, bytes; a larger one closes its socket (close
    /// code 1009, message too big).
    pub message_bytes: usize,
    /// Messages a page may send per second, on average (as many at once after a quiet
    /// second); the others are dropped and told.
    pub messages_per_s: f64,
    /// Edits (add, remove, set) waiting for the stream, all pages together; more are
    /// refused as busy.
    pub edits_waiting: usize,
    /// Edits applied between two blocks (each may rebuild part of the graph); the others
    /// wait for the next block.
    pub edits_per_block: usize,
    /// Load of the stream (compute time of a block over its duration, averaged over
    /// about a second) above which adding a request is refused.
    pub max_load: f64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            pages: 16,
            connections: 32,
            header_timeout: Duration::from_secs(10),
            requests_per_page: 8,
            requests: 32,
            message_bytes: 16 * 1024,
            messages_per_s: 20.0,
            edits_waiting: 16,
            edits_per_block: 4,
            max_load: 0.8,
        }
    }
}

/// A token bucket: `per_s` tokens a second, at most `per_s` (at least one) held.
pub(crate) struct Rate {
    per_s: f64,
    tokens: f64,
    last: Instant,
}

impl Rate {
    /// A full bucket.
    pub fn new(per_s: f64) -> Self {
        let per_s = per_s.max(0.0);
        Rate {
            per_s,
            tokens: per_s.max(1.0),
            last: Instant::now(),
        }
    }

    /// Takes a token if there is one.
    pub fn take(&mut self) -> bool {
        self.take_at(Instant::now())
    }

    fn take_at(&mut self, now: Instant) -> bool {
        let elapsed = now.saturating_duration_since(self.last).as_secs_f64();
        self.last = now;
        self.tokens = (self.tokens + elapsed * self.per_s).min(self.per_s.max(1.0));
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rate_allows_its_burst_then_its_rate() {
        let start = Instant::now();
        let mut rate = Rate::new(20.0);
        rate.last = start;
        let burst = (0..100).filter(|_| rate.take_at(start)).count();
        assert_eq!(burst, 20);
        // over the next 2 s, taking every millisecond: 40 more
        let later = (1..=2000)
            .filter(|ms| rate.take_at(start + Duration::from_millis(*ms)))
            .count();
        assert!((39..=41).contains(&later), "{later}");
    }
}
