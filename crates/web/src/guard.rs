//! Who may ask, and what every answer says about itself.
//!
//! - **Host**: a page of another site can point its own name at 127.0.0.1 (DNS rebinding)
//!   and then read this server as its own origin; its requests still name that site in the
//!   `Host` header. So the server answers only requests naming a host it knows: an IP
//!   address (a rebinding needs a name), `localhost` and its subdomains (never sent to DNS),
//!   and the names given with `--allow-host`. Anything else: 403 with the reason.
//! - **Origin**: a write (anything but GET and HEAD) that comes from a page must come from a
//!   page of an allowed host (the token header already keeps other sites' pages out; this
//!   says so plainly before the token is looked at).
//! - **Headers on every answer**: a Content-Security-Policy that allows the server's own
//!   files only (no inline script or style anywhere in the pages), no framing, no MIME
//!   sniffing, no referrer.
//!
//! The checks are plain functions of the header bytes (the fuzz target `web_hosts` feeds
//! them garbage); [`HostGuard`] holds the allow-list.

use std::net::{Ipv4Addr, Ipv6Addr};

use axum::http::header::HeaderName;
use axum::http::{HeaderMap, HeaderValue, StatusCode};

use crate::error::ApiError;

/// What every page may load: its own scripts, styles and images, its own API; nothing
/// inline, no plug-ins, no framing, forms only to itself.
pub const CONTENT_SECURITY_POLICY: &str = "default-src 'none'; script-src 'self'; \
     style-src 'self'; img-src 'self'; connect-src 'self'; form-action 'self'; \
     frame-ancestors 'none'; base-uri 'none'";

/// The headers every answer carries (the 503 of a refused connection included).
pub const SECURITY_HEADERS: [(&str, &str); 5] = [
    ("content-security-policy", CONTENT_SECURITY_POLICY),
    ("x-frame-options", "DENY"),
    ("x-content-type-options", "nosniff"),
    ("referrer-policy", "no-referrer"),
    ("cross-origin-resource-policy", "same-origin"),
];

/// Adds [`SECURITY_HEADERS`] to an answer's headers.
pub fn add_security_headers(headers: &mut HeaderMap) {
    for (name, value) in SECURITY_HEADERS {
        headers.insert(
            HeaderName::from_static(name),
            HeaderValue::from_static(value),
        );
    }
}

/// Why a `--allow-host` name was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "--allow-host {0:?}: expected a host name (letters, digits, '-' and '.', at most 253 \
     characters) or an IP address, without a port or a scheme"
)]
pub struct BadHostName(pub String);

/// The hosts this server answers to besides IP addresses and `localhost`.
#[derive(Clone, Debug, Default)]
pub struct HostGuard {
    /// Lower case, checked by [`HostGuard::new`].
    names: Vec<String>,
}

impl HostGuard {
    /// The default list (IP addresses, `localhost`, `*.localhost`) plus `extra` names.
    pub fn new(extra: &[String]) -> Result<Self, BadHostName> {
        let names = extra
            .iter()
            .map(|name| {
                let lower = name.to_ascii_lowercase();
                let ok =
                    ip_literal(&lower) || ip_literal(&format!("[{lower}]")) || dns_name(&lower);
                if ok {
                    Ok(lower)
                } else {
                    Err(BadHostName(name.clone()))
                }
            })
            .collect::<Result<_, _>>()?;
        Ok(Self { names })
    }

    /// Whether `host` (no port, any case; an IPv6 address in brackets) is one this server
    /// answers to.
    pub fn allows(&self, host: &str) -> bool {
        let host = host.to_ascii_lowercase();
        ip_literal(&host)
            || (host == "localhost" || host.ends_with(".localhost")) && dns_name(&host)
            || self.names.contains(&host)
    }

    /// The `Host` header: required by HTTP/1.1 (`http11`), and naming an allowed host.
    pub fn check_host(&self, value: Option<&[u8]>, http11: bool) -> Result<(), ApiError> {
        let Some(value) = value else {
            return if http11 {
                Err(ApiError::bad_request(
                    "an HTTP/1.1 request needs a Host header",
                ))
            } else {
                Ok(())
            };
        };
        let shown = String::from_utf8_lossy(value);
        match split_authority(value) {
            Some(host) if self.allows(host) => Ok(()),
            _ => Err(ApiError::new(
                StatusCode::FORBIDDEN,
                format!(
                    "Host {shown:?} is not a name this server answers to: it answers to IP \
                     addresses, localhost{} (a page that names another host may be another \
                     site's, reaching this one through DNS rebinding); start it with \
                     --allow-host NAME to allow a name",
                    self.listed()
                ),
            )),
        }
    }

    /// The `Origin` header of a write, when there is one: a page of an allowed host.
    pub fn check_origin(&self, value: &[u8]) -> Result<(), ApiError> {
        let shown = String::from_utf8_lossy(value);
        let host = std::str::from_utf8(value)
            .ok()
            .and_then(|v| {
                v.strip_prefix("http://")
                    .or_else(|| v.strip_prefix("https://"))
            })
            .and_then(|authority| split_authority(authority.as_bytes()));
        match host {
            Some(host) if self.allows(host) => Ok(()),
            _ => Err(ApiError::new(
                StatusCode::FORBIDDEN,
                format!(
                    "a write from a page of origin {shown:?} is refused: writes come from \
                     this server's own pages (IP addresses, localhost{}); start it with \
                     --allow-host NAME to allow a name",
                    self.listed()
                ),
            )),
        }
    }

    fn listed(&self) -> String {
        self.names.iter().map(|n| format!(", {n}")).collect()
    }
}

/// The host of `host[:port]` (an IPv6 address in brackets), `None` for anything else
/// (user info, a path, an empty host, a port that is not a number).
fn split_authority(value: &[u8]) -> Option<&str> {
    let text = std::str::from_utf8(value).ok()?;
    let (host, port) = if text.starts_with('[') {
        let end = text.find(']')?;
        let (host, rest) = text.split_at(end + 1);
        match rest {
            "" => (host, None),
            _ => (host, Some(rest.strip_prefix(':')?)),
        }
    } else {
        match text.rsplit_once(':') {
            Some((host, port)) => (host, Some(port)),
            None => (text, None),
        }
    };
    if let Some(port) = port
        && (port.is_empty() || port.len() > 5 || !port.bytes().all(|b| b.is_ascii_digit()))
    {
        return None;
    }
    (ip_literal(host) || dns_name(host)).then_some(host)
}

/// An IPv4 address, or an IPv6 address in brackets.
fn ip_literal(host: &str) -> bool {
    match host.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
        Some(v6) => v6.parse::<Ipv6Addr>().is_ok(),
        None => host.parse::<Ipv4Addr>().is_ok(),
    }
}

/// A DNS name: dot-separated labels of 1..63 letters, digits and '-' (not at a label's ends),
/// 253 characters at most.
fn dns_name(host: &str) -> bool {
    !host.is_empty()
        && host.len() <= 253
        && host.split('.').all(|label| {
            (1..=63).contains(&label.len())
                && label
                    .bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b == b'-')
                && !label.starts_with('-')
                && !label.ends_with('-')
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn guard(extra: &[&str]) -> HostGuard {
        HostGuard::new(&extra.iter().map(|s| s.to_string()).collect::<Vec<_>>()).unwrap()
    }

    #[test]
    fn loopback_names_and_addresses_are_allowed_by_default() {
        let g = guard(&[]);
        for host in [
            "localhost",
            "LOCALHOST:8080",
            "127.0.0.1:8080",
            "127.0.0.1",
            "[::1]:8080",
            "[::1]",
            "dash.localhost:80",
            "192.168.1.20:8080",
        ] {
            assert!(g.check_host(Some(host.as_bytes()), true).is_ok(), "{host}");
        }
    }

    #[test]
    fn a_foreign_host_is_refused_with_403_and_the_way_to_allow_it() {
        let g = guard(&[]);
        for host in [
            &b"evil.example"[..],
            b"evil.example:8080",
            b"localhost.evil.example",
            b"127.0.0.1.evil.example",
            b"localhost.",
            b"user@localhost",
            b"localhost:80/x",
            b"localhost:http",
            b"localhost:",
            b"[::1",
            b"::1",
            b"",
            b"\xff\xfe",
            b"local host",
        ] {
            let e = g.check_host(Some(host), true).unwrap_err();
            assert_eq!(e.status, StatusCode::FORBIDDEN, "{host:?}");
            assert!(e.reason.contains("--allow-host"), "{}", e.reason);
        }
        let e = g.check_host(None, true).unwrap_err();
        assert_eq!(e.status, StatusCode::BAD_REQUEST);
        assert!(
            g.check_host(None, false).is_ok(),
            "HTTP/1.0 may leave it out"
        );
    }

    #[test]
    fn allowed_names_are_added_and_bad_ones_refused() {
        // Addresses are allowed anyway; naming one is not an error.
        let g = guard(&["Bench.Lab", "10.1.2.3", "fe80::1"]);
        assert!(g.check_host(Some(b"bench.lab:8080"), true).is_ok());
        assert!(g.check_host(Some(b"BENCH.LAB"), true).is_ok());
        assert!(g.check_host(Some(b"other.lab"), true).is_err());
        let e = g.check_host(Some(b"other.lab"), true).unwrap_err();
        assert!(e.reason.contains("bench.lab"), "{}", e.reason);
        for bad in [
            "",
            "a b",
            "x:8080",
            "http://x",
            "-x",
            "x..y",
            &"a".repeat(64),
        ] {
            assert_eq!(
                HostGuard::new(&[bad.to_string()]).unwrap_err(),
                BadHostName(bad.to_string())
            );
        }
    }

    #[test]
    fn writes_from_pages_of_other_origins_are_refused() {
        let g = guard(&["bench.lab"]);
        for ok in [
            "http://127.0.0.1:8080",
            "http://localhost:8080",
            "https://bench.lab",
            "http://[::1]:8080",
        ] {
            assert!(g.check_origin(ok.as_bytes()).is_ok(), "{ok}");
        }
        for bad in [
            &b"null"[..],
            b"http://evil.example",
            b"http://evil.example:8080",
            b"file://",
            b"ftp://localhost",
            b"http://localhost:8080/path",
            b"localhost",
            b"\xff",
        ] {
            let e = g.check_origin(bad).unwrap_err();
            assert_eq!(e.status, StatusCode::FORBIDDEN, "{bad:?}");
        }
    }
}
