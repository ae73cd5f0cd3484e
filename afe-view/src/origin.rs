//! Which web pages may open the view's WebSocket, judged from the `Origin` and `Host`
//! headers of the upgrade request.
//!
//! A browser sends the `Origin` of the page that opens a WebSocket, and any page may
//! open one to any address, loopback included: without this check a page of another
//! site in the robot's browser could edit the graph and listen to the microphone. The
//! rule:
//! - no `Origin` header: not a browser page (a script, a test client), accepted;
//! - the page's own origin (the `Origin`'s host and port equal the `Host` header) when
//!   that host is an IP address or `localhost`: accepted. A host *name* is not enough,
//!   because another site can point its own name at this address (DNS rebinding) and
//!   then be "same origin"; such names are accepted only when allowed by name;
//! - an origin in the allowed list (`scheme://host[:port]`, as the browser sends it),
//!   or any origin when the list holds `*`: accepted;
//! - anything else, `null` included (sandboxed frames, `file:` pages): refused.

use std::net::IpAddr;

use thiserror::Error;

/// An allowed origin given by the user that is not one.
#[derive(Debug, Error)]
#[error(
    "'{given}' is not an origin: give scheme://host[:port] as a browser sends it \
     (e.g. http://robot.local:8080, no path), or * for any"
)]
pub struct OriginError {
    /// What was given.
    pub given: String,
}

/// The origins allowed besides the page's own.
#[derive(Debug, Clone, Default)]
pub struct AllowedOrigins {
    any: bool,
    /// `scheme://host[:port]`, lower case, without the scheme's default port.
    listed: Vec<String>,
}

impl AllowedOrigins {
    /// Only the page's own origin (the default).
    pub fn same_origin() -> Self {
        Self::default()
    }

    /// The page's own origin and each of `origins` (`scheme://host[:port]`, or `*` for
    /// any origin).
    pub fn parse<S: AsRef<str>>(origins: &[S]) -> Result<Self, OriginError> {
        let mut allowed = Self::default();
        for given in origins {
            let given = given.as_ref().trim();
            if given == "*" {
                allowed.any = true;
                continue;
            }
            let error = || OriginError {
                given: given.to_string(),
            };
            let (scheme, authority) = split_origin(given).ok_or_else(error)?;
            if authority.is_empty() || authority.contains(['/', '?', '#', '@']) {
                return Err(error());
            }
            allowed
                .listed
                .push(format!("{scheme}://{}", authority_of(scheme, authority)));
        }
        Ok(allowed)
    }

    /// Whether a WebSocket upgrade with these `Origin` and `Host` headers is accepted;
    /// the refusal says why and what would allow it.
    pub(crate) fn check(&self, origin: Option<&str>, host: Option<&str>) -> Result<(), String> {
        let Some(origin) = origin.map(str::trim) else {
            return Ok(());
        };
        if self.any {
            return Ok(());
        }
        let allow = format!(
            "start the server allowing it (afe serve --http-allow-origin {origin}, \
             afe stream --view-allow-origin {origin}, or * for any)"
        );
        let Some((scheme, authority)) = split_origin(origin) else {
            return Err(format!(
                "origin '{origin}' is not a web page's own address; {allow}"
            ));
        };
        let authority = authority_of(scheme, authority);
        if self.listed.contains(&format!("{scheme}://{authority}")) {
            return Ok(());
        }
        let host = host.map(|h| authority_of(scheme, h.trim()));
        if host.as_deref() != Some(authority.as_str()) {
            return Err(format!(
                "origin {origin} is not this server's page (Host {}); {allow}",
                host.as_deref().unwrap_or("missing")
            ));
        }
        let name = host_name(&authority);
        if is_address(name) {
            return Ok(());
        }
        Err(format!(
            "the page's host name '{name}' is not an IP address or localhost, and another \
             site could give its own name this address; {allow}"
        ))
    }
}

/// `scheme://authority` split at `://`, for the schemes of web pages.
fn split_origin(origin: &str) -> Option<(&'static str, &str)> {
    let (scheme, authority) = origin.split_once("://")?;
    let scheme = match scheme.to_ascii_lowercase().as_str() {
        "http" => "http",
        "https" => "https",
        _ => return None,
    };
    Some((scheme, authority.strip_suffix('/').unwrap_or(authority)))
}

/// `host[:port]` in lower case, without the scheme's default port (browsers leave it
/// out of `Origin`, and may or may not out of `Host`).
fn authority_of(scheme: &str, authority: &str) -> String {
    let lower = authority.to_ascii_lowercase();
    let default = if scheme == "https" { ":443" } else { ":80" };
    lower.strip_suffix(default).unwrap_or(&lower).to_string()
}

/// The host of `host[:port]` (an IPv6 address keeps its brackets).
fn host_name(authority: &str) -> &str {
    match authority.find(']') {
        Some(end) if authority.starts_with('[') => &authority[..=end],
        _ => authority.split(':').next().unwrap_or(authority),
    }
}

/// An IP address literal, `localhost` or a name under `.localhost` (which browsers
/// resolve to loopback themselves).
fn is_address(host: &str) -> bool {
    let bare = host.trim_start_matches('[').trim_end_matches(']');
    bare.parse::<IpAddr>().is_ok() || host == "localhost" || host.ends_with(".localhost")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pages_own_origin_is_accepted_on_an_address() {
        let same = AllowedOrigins::same_origin();
        assert!(same.check(None, Some("127.0.0.1:8080")).is_ok());
        assert!(same
            .check(Some("http://127.0.0.1:8080"), Some("127.0.0.1:8080"))
            .is_ok());
        assert!(same
            .check(Some("http://LOCALHOST:8080"), Some("localhost:8080"))
            .is_ok());
        assert!(same
            .check(Some("http://[::1]:9000"), Some("[::1]:9000"))
            .is_ok());
        assert!(same
            .check(Some("http://10.0.0.2"), Some("10.0.0.2:80"))
            .is_ok());
    }

    #[test]
    fn other_origins_are_refused_with_the_flag_that_allows_them() {
        let same = AllowedOrigins::same_origin();
        let refused = |o: &str, h: &str| same.check(Some(o), Some(h)).expect_err(o);
        let e = refused("http://evil.example", "127.0.0.1:8080");
        assert!(e.contains("--http-allow-origin http://evil.example"), "{e}");
        assert!(e.contains("Host 127.0.0.1:8080"), "{e}");
        // another port of the same machine is another origin
        refused("http://127.0.0.1:8081", "127.0.0.1:8080");
        refused("null", "127.0.0.1:8080");
        refused("file://", "127.0.0.1:8080");
        // a name that equals Host may be a rebound name: it must be allowed by name
        let e = refused("http://evil.example:8080", "evil.example:8080");
        assert!(e.contains("'evil.example' is not an IP address"), "{e}");
        assert!(same.check(Some("http://x"), None).is_err());
    }

    #[test]
    fn listed_origins_and_any_are_accepted() {
        let listed = AllowedOrigins::parse(&["http://Robot.local:8080/", "https://lab.example"])
            .expect("origins");
        assert!(listed
            .check(Some("http://robot.local:8080"), Some("x:1"))
            .is_ok());
        assert!(listed
            .check(Some("https://lab.example:443"), Some("x:1"))
            .is_ok());
        assert!(listed
            .check(Some("http://lab.example"), Some("x:1"))
            .is_err());
        let any = AllowedOrigins::parse(&["*"]).expect("any");
        assert!(any.check(Some("null"), Some("x:1")).is_ok());
        for bad in [
            "robot.local",
            "http://",
            "http://x/page",
            "ftp://x",
            "http://u@x",
        ] {
            let e = AllowedOrigins::parse(&[bad]).expect_err(bad);
            assert!(e.to_string().contains("scheme://host[:port]"), "{e}");
        }
    }
}
