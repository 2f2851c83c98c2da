//! The JSON side: the whole view, live updates over server-sent events, and the writes (send
//! a frame, inject or repair a fault), each write behind the token and answered with what was
//! done in words (`done`), a refusal with its reason.

use std::convert::Infallible;
use std::time::Duration;

use axum::Json;
use axum::body::Bytes;
use axum::extract::{Query, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::IntoResponse;
use axum::response::sse::{Event, KeepAlive, Sse};
use buslab_backends::TrySendError;
use buslab_bus::admin::FaultLimit;
use buslab_bus::bus::Human;
use buslab_bus::{BusAdmin, BusError, CanBus, NodeRef, WireFault};
use buslab_view::{BusView, Cursor, Delta, LogFilter, Series, SignalKey};
use futures_util::Stream;
use serde::Serialize;
use tokio::time::MissedTickBehavior;

use crate::app::{App, authorize};
use crate::error::ApiError;
use crate::request::{FaultOrder, ViewQuery, ViewRequest, fault_request, send_request};

/// Updates per second a viewer gets at most (the issue allows 20).
const UPDATE_EVERY: Duration = Duration::from_millis(100);
/// Log frames in one update at most; further ones are counted as lost for that viewer.
const MAX_LOG: usize = 200;

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
    /// The signal the viewer plots (`plot=`): its new values, or all of the window in the
    /// first update.
    #[serde(skip_serializing_if = "Option::is_none")]
    plot: Option<Series>,
}

/// The signal a request names with `plot=`, found in the view's database.
fn plot_key(view: &BusView, plot: Option<&str>) -> Result<Option<SignalKey>, ApiError> {
    plot.map(|name| view.signal(name))
        .transpose()
        .map_err(|e| ApiError::bad_request(format!("plot: {e}")))
}

/// `GET /api/state?filter=F&n=N&window=S&plot=M.S`: the whole view now.
pub async fn state(
    State(app): State<App>,
    Query(q): Query<ViewQuery>,
) -> Result<impl IntoResponse, ApiError> {
    let ViewRequest {
        filter,
        frames: n,
        window,
        plot,
    } = q.checked()?;
    let now = app.hub.now();
    let (delta, plot, signals) = {
        let view = app.hub.view();
        let key = plot_key(&view, plot.as_deref())?;
        let start = Cursor::start();
        (
            view.delta_within(&start, now, &filter, n, window),
            key.map(|k| view.series(&k, &start, now, window)),
            view.database().map(|db| db.messages().len()),
        )
    };
    Ok(Json(serde_json::json!({
        "delta": delta,
        "plot": plot,
        "bus_failure": app.hub.failure(),
        "channel": app.hub.channel,
        "writable": app.token.is_some(),
        "dbc_messages": signals,
    })))
}

struct Viewer {
    app: App,
    cursor: Cursor,
    filter: LogFilter,
    /// How far back the first (whole) update's charts go.
    window: Duration,
    lost: u64,
    ticker: tokio::time::Interval,
    /// The device panels' version this viewer has (`None`: none sent yet).
    devices_seen: Option<u64>,
    /// The signal it plots.
    plot: Option<SignalKey>,
}

/// `GET /api/events?filter=F&window=S&plot=M.S`: server-sent events, one `update` at most
/// every 100 ms, with the values of the signal `plot` names. The
/// stream is pulled only when the connection has room, so a slow viewer gets larger updates
/// less often; the frames it missed are counted in its `lost`.
pub async fn events(
    State(app): State<App>,
    Query(q): Query<ViewQuery>,
) -> Result<Sse<impl Stream<Item = Result<Event, Infallible>>>, ApiError> {
    let ViewRequest {
        filter,
        window,
        plot,
        ..
    } = q.checked()?;
    let plot = plot_key(&app.hub.view(), plot.as_deref())?;
    let mut ticker = tokio::time::interval(UPDATE_EVERY);
    ticker.set_missed_tick_behavior(MissedTickBehavior::Delay);
    let viewer = Viewer {
        app,
        cursor: Cursor::start(),
        filter,
        window,
        lost: 0,
        ticker,
        devices_seen: None,
        plot,
    };
    let stream = futures_util::stream::unfold(viewer, |mut v| async move {
        v.ticker.tick().await;
        let now = v.app.hub.now();
        let (delta, plot) = {
            let view = v.app.hub.view();
            let delta = view.delta_within(&v.cursor, now, &v.filter, MAX_LOG, v.window);
            let plot = v
                .plot
                .as_ref()
                .map(|key| view.series(key, &v.cursor, now, v.window))
                .filter(|s| s.full || !s.points.is_empty());
            v.cursor = view.advance(now);
            (delta, plot)
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
            plot,
        };
        let event = match serde_json::to_string(&update) {
            Ok(json) => Event::default().event("update").data(json),
            Err(e) => Event::default().event("problem").data(e.to_string()),
        };
        Some((Ok(event), v))
    });
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}

/// `POST /api/send {"frame":"123#1122"}`: queues a frame for the bus.
pub async fn send(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<impl IntoResponse, ApiError> {
    authorize(&app, &headers)?;
    let frame = send_request(&body)?;
    match app.sender.try_send(frame) {
        Ok(()) => Ok((
            StatusCode::ACCEPTED,
            Json(serde_json::json!({
                "queued": frame.to_string(),
                "done": format!("{frame} is queued for the bus"),
            })),
        )),
        Err(TrySendError::Full) => Err(ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "the bus takes no more frames now (its queue is full): try again",
        )),
        Err(TrySendError::Stopped(_)) => Err(stopped()),
    }
}

/// `POST /api/fault {"kind":"cut","nodes":["sender"],"rate":0.05,"for_ms":2000}`.
pub async fn fault(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<impl IntoResponse, ApiError> {
    authorize(&app, &headers)?;
    let FaultOrder { fault, lasting } = fault_request(&body)?;
    let for_ms = lasting.map(|d| d.as_millis() as u64);
    let name = fault.name();
    let (label, what) = (fault_label(&fault), fault_words(&fault));
    on_bus(&app, move |admin| admin.inject_fault(&fault, lasting)).await?;
    // Marked on the time charts, from when the bus took it.
    let now = app.hub.now();
    app.hub.view().fault(now, label, what.clone(), lasting);
    let until = match lasting {
        Some(d) => format!("for {}", Human(d)),
        None => "until repaired".to_string(),
    };
    Ok(Json(serde_json::json!({
        "injected": name,
        "for_ms": for_ms,
        "done": format!("{what}, {until}"),
    })))
}

/// `POST /api/repair`: ends every fault on the wire.
pub async fn repair(
    State(app): State<App>,
    headers: HeaderMap,
) -> Result<impl IntoResponse, ApiError> {
    authorize(&app, &headers)?;
    on_bus(&app, |admin| admin.repair()).await?;
    let now = app.hub.now();
    app.hub.view().repaired(now);
    Ok(Json(serde_json::json!({
        "repaired": true,
        "done": "the wire is repaired: every fault on it ended",
    })))
}

/// A fault in a few words, for its band on the time charts.
pub fn fault_label(fault: &WireFault) -> String {
    match fault {
        WireFault::Cut { far_side, .. } => format!("cut at {}", node_list(far_side)),
        WireFault::Disconnect { node } => format!("{} disconnected", node_words(node)),
        WireFault::Flip { node: Some(node) } => format!("flip at {}", node_words(node)),
        WireFault::Flip { node: None } => "flip".to_string(),
        WireFault::Noise { rate, .. } => format!("noise {}", percent(rate.get())),
        WireFault::StuckDominant => "stuck dominant".to_string(),
    }
}

/// `5 %`, `0.1 %`: a probability as a person says it.
fn percent(p: f64) -> String {
    let p = (p * 100.0 * 1000.0).round() / 1000.0;
    format!("{p} %")
}

/// A fault in words, as the dashboard's result line and the charts' marks say it.
pub fn fault_words(fault: &WireFault) -> String {
    match fault {
        WireFault::Cut {
            far_side,
            error_rate,
        } => format!(
            "the wire cut: {} on the far side, {} of the bits read there wrong",
            node_list(far_side),
            percent(error_rate.get())
        ),
        WireFault::Disconnect { node } => format!("{} disconnected", node_words(node)),
        WireFault::Flip { node: Some(node) } => {
            format!("every bit {} reads inverted", node_words(node))
        }
        WireFault::Flip { node: None } => "every bit read inverted, by every node".to_string(),
        WireFault::Noise { nodes, rate } if nodes.is_empty() => format!(
            "noise on the whole bus: {} of the bits read wrong",
            percent(rate.get())
        ),
        WireFault::Noise { nodes, rate } => format!(
            "noise at {}: {} of the bits read wrong",
            node_list(nodes),
            percent(rate.get())
        ),
        WireFault::StuckDominant => "the bus held dominant".to_string(),
    }
}

fn node_words(node: &NodeRef) -> String {
    match node {
        NodeRef::Number(n) => format!("node {n}"),
        NodeRef::Name(name) => name.clone(),
    }
}

fn node_list(nodes: &[NodeRef]) -> String {
    nodes.iter().map(node_words).collect::<Vec<_>>().join(", ")
}

fn stopped() -> ApiError {
    ApiError::new(
        StatusCode::SERVICE_UNAVAILABLE,
        "the bus is no longer served (it failed: see the overview page)",
    )
}

/// Runs `work` on the bus's administration side, on the bus's own thread: the bus's answer,
/// or `Unsupported` naming `what` for a bus without one. A bus no longer served is 503.
pub(crate) async fn on_admin<T: Send + 'static>(
    app: &App,
    what: &'static str,
    work: impl FnOnce(&mut dyn BusAdmin) -> Result<T, BusError> + Send + 'static,
) -> Result<Result<T, BusError>, ApiError> {
    let (tx, rx) = tokio::sync::oneshot::channel();
    let job = Box::new(move |bus: &mut dyn CanBus| {
        let result = match bus.admin() {
            Some(admin) => work(admin),
            None => Err(BusError::Unsupported {
                what,
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
    rx.await.map_err(|_| stopped())
}

/// Runs `work` (a fault, a repair) on the bus's administration side.
async fn on_bus(
    app: &App,
    work: impl FnOnce(&mut dyn BusAdmin) -> Result<(), BusError> + Send + 'static,
) -> Result<(), ApiError> {
    match on_admin(app, "fault injection", work).await? {
        Ok(()) => Ok(()),
        Err(e @ BusError::Unsupported { .. }) => Err(ApiError::new(
            StatusCode::CONFLICT,
            format!("{e} (only a buslab virtual bus has a wire to break)"),
        )),
        Err(BusError::FaultRefused(limit @ FaultLimit::Rate { retry_after, .. })) => Err(
            ApiError::too_many(format!("the bus refused the fault: {limit}"), retry_after),
        ),
        Err(BusError::FaultRefused(limit @ FaultLimit::Active { .. })) => Err(
            ApiError::bad_request(format!("the bus refused the fault: {limit}")),
        ),
        Err(e @ (BusError::Other(_) | BusError::Rejected(_))) => {
            Err(ApiError::bad_request(format!("the bus refused it: {e}")))
        }
        Err(e) => Err(ApiError::new(StatusCode::BAD_GATEWAY, e.to_string())),
    }
}
