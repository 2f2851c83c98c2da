//! The JSON side: the whole view, live updates over server-sent events, and the writes (send
//! a frame, inject or repair a fault), each write behind the token.

use std::convert::Infallible;
use std::time::Duration;

use axum::Json;
use axum::body::Bytes;
use axum::extract::{Query, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::IntoResponse;
use axum::response::sse::{Event, KeepAlive, Sse};
use buslab_backends::TrySendError;
use buslab_can::Frame;
use buslab_canbus::{BusAdmin, BusError, CanBus, NodeRef, Probability, WireFault};
use buslab_view::{Cursor, Delta, LogFilter};
use futures_util::Stream;
use serde::{Deserialize, Serialize};
use tokio::time::MissedTickBehavior;

use crate::routes::{ApiError, App, authorize};

/// Updates per second a viewer gets at most (the issue allows 20).
const UPDATE_EVERY: Duration = Duration::from_millis(100);
/// Log frames in one update at most; further ones are counted as lost for that viewer.
const MAX_LOG: usize = 200;
/// Frames `/api/state` gives at most.
const MAX_STATE_LOG: usize = 1000;
/// A fault lasts an hour at most (longer: leave `for_ms` out and repair it).
const MAX_FAULT_MS: u64 = 3_600_000;

#[derive(Debug, Deserialize)]
pub struct ViewQuery {
    filter: Option<String>,
    n: Option<usize>,
}

fn parse_filter(text: Option<&str>) -> Result<LogFilter, ApiError> {
    text.unwrap_or("")
        .parse()
        .map_err(|e: buslab_view::FilterError| ApiError::bad_request(e.to_string()))
}

/// One live update: what changed since the viewer's last one.
#[derive(Serialize)]
struct Update<'a> {
    #[serde(flatten)]
    delta: &'a Delta,
    /// Log frames this viewer did not get (it fell behind, or more came than one update
    /// holds), since it connected.
    lost: u64,
    /// Why the bus stopped, once it did.
    bus_failure: Option<String>,
    /// Connections refused for the connection limit, since the server started.
    refused: u64,
    /// The device panels, when they changed since this viewer's last update.
    #[serde(skip_serializing_if = "Option::is_none")]
    devices: Option<crate::devices::DevicesView>,
}

/// `GET /api/state?filter=F&n=N`: the whole view now.
pub async fn state(
    State(app): State<App>,
    Query(q): Query<ViewQuery>,
) -> Result<impl IntoResponse, ApiError> {
    let filter = parse_filter(q.filter.as_deref())?;
    let n = q.n.unwrap_or(100);
    if n > MAX_STATE_LOG {
        return Err(ApiError::bad_request(format!(
            "n={n}: at most {MAX_STATE_LOG} frames"
        )));
    }
    let now = app.hub.now();
    let delta = app.hub.view().delta(&Cursor::start(), now, &filter, n);
    Ok(Json(serde_json::json!({
        "delta": delta,
        "bus_failure": app.hub.failure(),
        "channel": app.hub.channel,
        "writable": app.token.is_some(),
    })))
}

struct Viewer {
    app: App,
    cursor: Cursor,
    filter: LogFilter,
    lost: u64,
    ticker: tokio::time::Interval,
    /// The device panels' version this viewer has (`None`: none sent yet).
    devices_seen: Option<u64>,
}

/// `GET /api/events?filter=F`: server-sent events, one `update` at most every 100 ms. The
/// stream is pulled only when the connection has room, so a slow viewer gets larger updates
/// less often; the frames it missed are counted in its `lost`.
pub async fn events(
    State(app): State<App>,
    Query(q): Query<ViewQuery>,
) -> Result<Sse<impl Stream<Item = Result<Event, Infallible>>>, ApiError> {
    let filter = parse_filter(q.filter.as_deref())?;
    let mut ticker = tokio::time::interval(UPDATE_EVERY);
    ticker.set_missed_tick_behavior(MissedTickBehavior::Delay);
    let viewer = Viewer {
        app,
        cursor: Cursor::start(),
        filter,
        lost: 0,
        ticker,
        devices_seen: None,
    };
    let stream = futures_util::stream::unfold(viewer, |mut v| async move {
        v.ticker.tick().await;
        let now = v.app.hub.now();
        let delta = {
            let view = v.app.hub.view();
            let delta = view.delta(&v.cursor, now, &v.filter, MAX_LOG);
            v.cursor = view.advance(now);
            delta
        };
        // A whole view holds the frames from before the viewer came: those it was never sent
        // are history, not updates it lost.
        if !delta.full {
            v.lost += delta.log_skipped;
        }
        let devices = &v.app.hub.devices;
        let devices = if devices.is_empty() || v.devices_seen == Some(devices.version()) {
            None
        } else {
            let view = devices.view();
            v.devices_seen = Some(view.version);
            Some(view)
        };
        let update = Update {
            delta: &delta,
            lost: v.lost,
            bus_failure: v.app.hub.failure(),
            refused: v.app.hub.refused.load(std::sync::atomic::Ordering::Relaxed),
            devices,
        };
        let event = match serde_json::to_string(&update) {
            Ok(json) => Event::default().event("update").data(json),
            Err(e) => Event::default().event("problem").data(e.to_string()),
        };
        Some((Ok(event), v))
    });
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SendRequest {
    /// cansend syntax: `123#1122`, `18FF0010#`, `123#R`.
    frame: String,
}

fn json_body<T: for<'de> Deserialize<'de>>(body: &Bytes, example: &str) -> Result<T, ApiError> {
    serde_json::from_slice(body)
        .map_err(|e| ApiError::bad_request(format!("body: {e} (expected JSON like {example})")))
}

/// `POST /api/send {"frame":"123#1122"}`: queues a frame for the bus.
pub async fn send(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<impl IntoResponse, ApiError> {
    authorize(&app, &headers)?;
    let req: SendRequest = json_body(&body, r#"{"frame":"123#1122"}"#)?;
    let frame: Frame = req
        .frame
        .parse()
        .map_err(|e| ApiError::bad_request(format!("frame {:?}: {e}", req.frame)))?;
    match app.sender.try_send(frame) {
        Ok(()) => Ok((
            StatusCode::ACCEPTED,
            Json(serde_json::json!({ "queued": frame.to_string() })),
        )),
        Err(TrySendError::Full) => Err(ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "the bus takes no more frames now (its queue is full): try again",
        )),
        Err(TrySendError::Stopped(_)) => Err(stopped()),
    }
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

fn probability(rate: f64) -> Result<Probability, ApiError> {
    Probability::new(rate).map_err(|e| ApiError::bad_request(format!("rate: {e}")))
}

fn fault_of(req: &FaultRequest) -> Result<WireFault, ApiError> {
    let nodes: Vec<NodeRef> = req.nodes.iter().map(|n| NodeRef::parse(n)).collect();
    if nodes.len() > 64 {
        return Err(ApiError::bad_request("nodes: at most 64"));
    }
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

/// `POST /api/fault {"kind":"cut","nodes":["sender"],"rate":0.05,"for_ms":2000}`.
pub async fn fault(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<impl IntoResponse, ApiError> {
    authorize(&app, &headers)?;
    let req: FaultRequest = json_body(&body, r#"{"kind":"cut","nodes":["sender"]}"#)?;
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
    let name = fault.name();
    on_bus(&app, move |admin| admin.inject_fault(&fault, lasting)).await?;
    Ok(Json(
        serde_json::json!({ "injected": name, "for_ms": req.for_ms }),
    ))
}

/// `POST /api/repair`: ends every fault on the wire.
pub async fn repair(
    State(app): State<App>,
    headers: HeaderMap,
) -> Result<impl IntoResponse, ApiError> {
    authorize(&app, &headers)?;
    on_bus(&app, |admin| admin.repair()).await?;
    Ok(Json(serde_json::json!({ "repaired": true })))
}

fn stopped() -> ApiError {
    ApiError::new(
        StatusCode::SERVICE_UNAVAILABLE,
        "the bus is no longer served (it failed: see the overview page)",
    )
}

/// Runs `work` on the bus's administration side, on the bus's own thread.
async fn on_bus(
    app: &App,
    work: impl FnOnce(&mut dyn BusAdmin) -> Result<(), BusError> + Send + 'static,
) -> Result<(), ApiError> {
    let (tx, rx) = tokio::sync::oneshot::channel();
    let job = Box::new(move |bus: &mut dyn CanBus| {
        let result = match bus.admin() {
            Some(admin) => work(admin),
            None => Err(BusError::Unsupported {
                what: "fault injection",
                backend: bus.channel_info(),
            }),
        };
        let _ = tx.send(result);
    });
    let sender = app.sender.clone();
    // The pump's queue is bounded: queuing may wait, so not on the async workers.
    tokio::task::spawn_blocking(move || sender.run(job))
        .await
        .map_err(|_| stopped())?
        .map_err(|_| stopped())?;
    match rx.await.map_err(|_| stopped())? {
        Ok(()) => Ok(()),
        Err(e @ BusError::Unsupported { .. }) => Err(ApiError::new(
            StatusCode::CONFLICT,
            format!("{e} (only a buslab virtual bus has a wire to break)"),
        )),
        Err(e @ (BusError::Other(_) | BusError::Rejected(_))) => {
            Err(ApiError::bad_request(format!("the bus refused it: {e}")))
        }
        Err(e) => Err(ApiError::new(StatusCode::BAD_GATEWAY, e.to_string())),
    }
}
