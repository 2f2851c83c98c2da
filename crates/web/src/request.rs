//! What a request says, read and checked without a server: the query of `/api/state` and
//! `/api/events`, the JSON bodies of `/api/send` and `/api/fault`, the token header. The
//! handlers call these; the fuzz target `web_requests` feeds them arbitrary bytes. (axum and
//! hyper read HTTP itself, the query string into [`ViewQuery`] with `serde_urlencoded`.)

use std::time::Duration;

use axum::http::StatusCode;
use buslab_bus::{NodeRef, Probability, WireFault};
use buslab_can::Frame;
use buslab_view::LogFilter;
use serde::Deserialize;

use crate::error::ApiError;

/// Frames `/api/state` gives at most.
pub const MAX_STATE_LOG: usize = 1000;
/// A fault lasts an hour at most (longer: leave `for_ms` out and repair it).
pub const MAX_FAULT_MS: u64 = 3_600_000;
/// Nodes one fault names at most.
pub const MAX_FAULT_NODES: usize = 64;
/// The time charts' window unless a request gives `window` (seconds).
pub const DEFAULT_WINDOW: Duration = Duration::from_secs(60);
/// The longest window a request may ask for: what the view keeps.
pub const MAX_WINDOW: Duration = Duration::from_secs(600);
/// The longest `plot` (`MESSAGE.SIGNAL`) a request may name, in bytes.
pub const MAX_SIGNAL_NAME: usize = 256;

/// The query of `/api/state?filter=F&n=N&window=S&plot=M.S` and
/// `/api/events?filter=F&window=S&plot=M.S`, as axum's `Query` reads it;
/// [`ViewQuery::checked`] gives what it means.
#[derive(Debug, Default, Deserialize)]
pub struct ViewQuery {
    filter: Option<String>,
    n: Option<usize>,
    /// Seconds of load and TEC/REC history a whole view carries.
    window: Option<u64>,
    /// A signal of the DBC database, `MESSAGE.SIGNAL`, whose values over time the answer
    /// carries.
    plot: Option<String>,
}

/// A view request: which frames, how many at most, and how far back the charts go.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ViewRequest {
    pub filter: LogFilter,
    /// `n`, 100 unless given; at most [`MAX_STATE_LOG`].
    pub frames: usize,
    /// `window`, [`DEFAULT_WINDOW`] unless given; 1 s to [`MAX_WINDOW`].
    pub window: Duration,
    /// `plot`: `MESSAGE.SIGNAL` (checked against the database by the handler), at most
    /// [`MAX_SIGNAL_NAME`] bytes; none if empty or absent.
    pub plot: Option<String>,
}

impl ViewQuery {
    pub fn checked(&self) -> Result<ViewRequest, ApiError> {
        let filter = self
            .filter
            .as_deref()
            .unwrap_or("")
            .parse()
            .map_err(|e: buslab_view::FilterError| ApiError::bad_request(e.to_string()))?;
        let frames = self.n.unwrap_or(100);
        if frames > MAX_STATE_LOG {
            return Err(ApiError::bad_request(format!(
                "n={frames}: at most {MAX_STATE_LOG} frames"
            )));
        }
        let window = match self.window {
            None => DEFAULT_WINDOW,
            Some(s) if (1..=MAX_WINDOW.as_secs()).contains(&s) => Duration::from_secs(s),
            Some(s) => {
                return Err(ApiError::bad_request(format!(
                    "window={s}: the charts show from 1 to {} seconds",
                    MAX_WINDOW.as_secs()
                )));
            }
        };
        let plot = plot_name(self.plot.as_deref())?;
        Ok(ViewRequest {
            filter,
            frames,
            window,
            plot,
        })
    }
}

/// A `plot=MESSAGE.SIGNAL` of a query: none if empty or absent; at most [`MAX_SIGNAL_NAME`]
/// bytes, with a dot and no control character (the database's names are checked by the view).
pub fn plot_name(plot: Option<&str>) -> Result<Option<String>, ApiError> {
    match plot.map(str::trim) {
        None | Some("") => Ok(None),
        Some(name) if name.len() > MAX_SIGNAL_NAME => Err(ApiError::bad_request(format!(
            "plot: {} bytes, at most {MAX_SIGNAL_NAME} (MESSAGE.SIGNAL)",
            name.len()
        ))),
        Some(name) if !name.contains('.') || name.chars().any(char::is_control) => {
            Err(ApiError::bad_request(format!(
                "plot={name:?}: expected MESSAGE.SIGNAL, as the DBC database names them"
            )))
        }
        Some(name) => Ok(Some(name.to_string())),
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SendRequest {
    /// cansend syntax: `123#1122`, `18FF0010#`, `123#R`.
    frame: String,
}

fn json_body<T: for<'de> Deserialize<'de>>(body: &[u8], example: &str) -> Result<T, ApiError> {
    serde_json::from_slice(body)
        .map_err(|e| ApiError::bad_request(format!("body: {e} (expected JSON like {example})")))
}

/// The body of `POST /api/send`, `{"frame":"123#1122"}`: the frame to queue.
pub fn send_request(body: &[u8]) -> Result<Frame, ApiError> {
    let req: SendRequest = json_body(body, r#"{"frame":"123#1122"}"#)?;
    req.frame
        .parse()
        .map_err(|e| ApiError::bad_request(format!("frame {:?}: {e}", req.frame)))
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FaultRequest {
    /// cut, noise, flip, disconnect, stuck.
    kind: String,
    /// Node numbers or names: the far side of a cut, the nodes hit by noise, the node a flip
    /// or a disconnect hits.
    #[serde(default)]
    nodes: Vec<String>,
    /// Per-bit error probability: a cut's far side (default 0.05, the seed's experiment),
    /// noise (required).
    rate: Option<f64>,
    /// How long the fault lasts; until repaired if absent.
    for_ms: Option<u64>,
}

/// What `POST /api/fault` asks for.
#[derive(Clone, Debug, PartialEq)]
pub struct FaultOrder {
    pub fault: WireFault,
    /// `None`: until repaired.
    pub lasting: Option<Duration>,
}

/// The body of `POST /api/fault`,
/// `{"kind":"cut","nodes":["sender"],"rate":0.05,"for_ms":2000}`.
pub fn fault_request(body: &[u8]) -> Result<FaultOrder, ApiError> {
    let req: FaultRequest = json_body(body, r#"{"kind":"cut","nodes":["sender"]}"#)?;
    let fault = fault_of(&req)?;
    let lasting = match req.for_ms {
        None => None,
        Some(ms) if (1..=MAX_FAULT_MS).contains(&ms) => Some(Duration::from_millis(ms)),
        Some(ms) => {
            return Err(ApiError::bad_request(format!(
                "for_ms {ms}: from 1 to {MAX_FAULT_MS}, or leave it out for a fault that lasts \
                 until repaired"
            )));
        }
    };
    Ok(FaultOrder { fault, lasting })
}

fn probability(rate: f64) -> Result<Probability, ApiError> {
    Probability::new(rate).map_err(|e| ApiError::bad_request(format!("rate: {e}")))
}

fn fault_of(req: &FaultRequest) -> Result<WireFault, ApiError> {
    if req.nodes.len() > MAX_FAULT_NODES {
        return Err(ApiError::bad_request(format!(
            "nodes: at most {MAX_FAULT_NODES}"
        )));
    }
    let nodes: Vec<NodeRef> = req.nodes.iter().map(|n| NodeRef::parse(n)).collect();
    let at_most_one = |what: &str| -> Result<Option<NodeRef>, ApiError> {
        match nodes.as_slice() {
            [] => Ok(None),
            [one] => Ok(Some(one.clone())),
            _ => Err(ApiError::bad_request(format!("{what}: one node at most"))),
        }
    };
    Ok(match req.kind.as_str() {
        "cut" => {
            if nodes.is_empty() {
                return Err(ApiError::bad_request(
                    "cut: name the nodes left on the far side of the cut, e.g. \"nodes\":[\"sender\"]",
                ));
            }
            WireFault::Cut {
                far_side: nodes,
                error_rate: probability(req.rate.unwrap_or(0.05))?,
            }
        }
        "noise" => {
            let Some(rate) = req.rate else {
                return Err(ApiError::bad_request(
                    "noise: give \"rate\", the probability that a bit is read wrong (e.g. 0.01)",
                ));
            };
            WireFault::Noise {
                nodes,
                rate: probability(rate)?,
            }
        }
        "flip" => WireFault::Flip {
            node: at_most_one("flip")?,
        },
        "disconnect" => match at_most_one("disconnect")? {
            Some(node) => WireFault::Disconnect { node },
            None => return Err(ApiError::bad_request("disconnect: name the node")),
        },
        "stuck" => WireFault::StuckDominant,
        other => {
            return Err(ApiError::bad_request(format!(
                "kind {other:?}: expected cut, noise, flip, disconnect or stuck"
            )));
        }
    })
}

/// The token rule: writes need the server's token (`expected`; `None`: the server is
/// read-only) in the `X-Buslab-Token` header (`given`, its bytes). A header (not a cookie) is
/// what a page of another site cannot make a browser send, so no cross-site request writes.
pub fn check_token(expected: Option<&str>, given: Option<&[u8]>) -> Result<(), ApiError> {
    let Some(token) = expected else {
        return Err(ApiError::new(
            StatusCode::FORBIDDEN,
            "this server is read-only: start it with --token to allow writes",
        ));
    };
    let Some(given) = given else {
        return Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            "a write needs the server's token in the X-Buslab-Token header",
        ));
    };
    if same(given, token.as_bytes()) {
        Ok(())
    } else {
        Err(ApiError::new(
            StatusCode::FORBIDDEN,
            "wrong token in the X-Buslab-Token header",
        ))
    }
}

/// Compares in time independent of where the first difference is.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn query(text: &str) -> Result<ViewRequest, ApiError> {
        serde_urlencoded::from_str::<ViewQuery>(text)
            .map_err(|e| ApiError::bad_request(e.to_string()))?
            .checked()
    }

    #[test]
    fn view_queries_say_which_frames_and_how_many() {
        let r = query("filter=120%3A7F0&n=5").unwrap();
        assert_eq!((r.filter.to_string().as_str(), r.frames), ("120:7F0", 5));
        assert_eq!(query("").unwrap().frames, 100);
        for bad in ["n=1001", "filter=XYZ", "n=-1", "n=1e3", "filter=800"] {
            let e = query(bad).unwrap_err();
            assert_eq!(e.status, StatusCode::BAD_REQUEST, "{bad}");
        }
    }

    #[test]
    fn a_plot_names_one_signal_in_few_bytes() {
        assert_eq!(
            query("plot=Engine.EngineSpeed").unwrap().plot.as_deref(),
            Some("Engine.EngineSpeed")
        );
        assert_eq!(query("plot=").unwrap().plot, None);
        let long = format!("plot=M.{}", "S".repeat(MAX_SIGNAL_NAME));
        for bad in ["plot=EngineSpeed", "plot=Engine.%0ASpeed", long.as_str()] {
            let e = query(bad).unwrap_err();
            assert_eq!(e.status, StatusCode::BAD_REQUEST, "{bad}");
            assert!(e.reason.contains("plot"), "{bad}: {}", e.reason);
        }
    }

    #[test]
    fn garbage_bodies_are_refused_with_a_reason() {
        assert_eq!(
            send_request(br#"{"frame":"123#1122"}"#).unwrap(),
            "123#1122".parse().unwrap()
        );
        for body in [
            &b""[..],
            b"\xff\xfe",
            b"{",
            br#"{"frame":1}"#,
            br#"{"frame":"123#1122","x":1}"#,
            br#"{"frame":"800#"}"#,
            b"[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[",
        ] {
            let e = send_request(body).unwrap_err();
            assert_eq!(e.status, StatusCode::BAD_REQUEST);
            assert!(!e.reason.is_empty());
        }
        let cut = fault_request(br#"{"kind":"cut","nodes":["sender"],"for_ms":2000}"#).unwrap();
        assert_eq!(cut.fault.name(), "cut");
        assert_eq!(cut.lasting, Some(Duration::from_secs(2)));
        let many = format!(
            r#"{{"kind":"noise","rate":0.1,"nodes":[{}]}}"#,
            ["\"a\""; 65].join(",")
        );
        for body in [
            br#"{"kind":"noise"}"#.as_slice(),
            br#"{"kind":"noise","rate":1.5}"#,
            br#"{"kind":"noise","rate":-0.0001}"#,
            br#"{"kind":"cut"}"#,
            br#"{"kind":"flip","nodes":["a","b"]}"#,
            br#"{"kind":"disconnect"}"#,
            br#"{"kind":"melt"}"#,
            br#"{"kind":"stuck","for_ms":0}"#,
            br#"{"kind":"stuck","for_ms":3600001}"#,
            br#"{"kind":"stuck","for_ms":18446744073709551616}"#,
            many.as_bytes(),
        ] {
            let e = fault_request(body).unwrap_err();
            assert_eq!(
                e.status,
                StatusCode::BAD_REQUEST,
                "{}",
                String::from_utf8_lossy(body)
            );
        }
    }

    #[test]
    fn the_token_must_match_exactly() {
        assert!(check_token(Some("s3cret"), Some(b"s3cret")).is_ok());
        let status = |expected, given| check_token(expected, given).unwrap_err().status;
        assert_eq!(status(None, Some(b"x".as_slice())), StatusCode::FORBIDDEN);
        assert_eq!(status(Some("s3cret"), None), StatusCode::UNAUTHORIZED);
        for wrong in [&b""[..], b"s3cre", b"s3cret ", b"S3CRET", b"s3cre\xff"] {
            assert_eq!(status(Some("s3cret"), Some(wrong)), StatusCode::FORBIDDEN);
        }
    }
}
