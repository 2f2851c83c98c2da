//! The device panels' API: `GET /api/devices` and the writes `POST /api/slio`,
//! `/api/zelle`, `/api/cpu196`, each behind the token like every other write. Their bodies are
//! read and checked by [`crate::device_request`].

use axum::Json;
use axum::body::Bytes;
use axum::extract::State;
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use buslab_backends::TrySendError;
use buslab_bus::BusError;
use buslab_bus::admin::{BoardInput, BoardState};
use buslab_chips::slio::SlioId;

use crate::app::{App, authorize};
use crate::device_request::{
    Cpu196Order, SlioOrder, ZelleOrder, cpu196_request, slio_request, zelle_request,
};
use crate::devices::cpu196::Cpu196Job;
use crate::devices::zelle::{JobRefused, ZelleJob};
use crate::error::ApiError;

/// `GET /api/devices`: every panel.
pub async fn devices(State(app): State<App>) -> impl IntoResponse {
    Json(app.hub.devices.view())
}

fn refused(e: JobRefused) -> ApiError {
    let status = match e {
        JobRefused::Busy(..) => StatusCode::CONFLICT,
        JobRefused::Stopped(_) => StatusCode::SERVICE_UNAVAILABLE,
    };
    ApiError::new(status, e.to_string())
}

fn absent(what: &str) -> ApiError {
    ApiError::new(
        StatusCode::NOT_FOUND,
        format!("this server shows no {what} (`buslab lab` does)"),
    )
}

/// `POST /api/slio`: a request frame to a SLIO; its answer, seen on the bus, changes the
/// panel (202: queued, not yet confirmed). A switch or the potentiometer is the board's, on
/// the bench: changed at once (200, the board's inputs as the bench then has them), and the
/// SLIO's pins are read again so that the panel shows what the SLIO sees.
pub async fn slio(
    State(app): State<App>,
    headers: HeaderMap,
    bytes: Bytes,
) -> Result<Response, ApiError> {
    authorize(&app, &headers)?;
    let order = slio_request(&bytes)?;
    if app.hub.devices.slio().is_empty() {
        return Err(absent("SLIO boards"));
    }
    if let Some(change) = order.bench() {
        return bench(&app, order.slio(), change).await;
    }
    let frames = {
        let mut panels = app.hub.devices.slio();
        let bad = |e: crate::devices::slio::SlioRequestError| {
            let status = match e {
                crate::devices::slio::SlioRequestError::OutputsUnknown(_) => StatusCode::CONFLICT,
                _ => StatusCode::BAD_REQUEST,
            };
            ApiError::new(status, e.to_string())
        };
        match order {
            SlioOrder::Output { slio, pin, on } => {
                vec![panels.output_request(slio, pin, on).map_err(bad)?]
            }
            SlioOrder::Dpm { slio, output, duty } => {
                vec![panels.dpm_request(slio, output, duty).map_err(bad)?]
            }
            SlioOrder::Convert { slio, input } => {
                vec![panels.convert_request(slio, input).map_err(bad)?]
            }
            // Answered above: the board's, not its SLIO's.
            SlioOrder::Switch { .. } | SlioOrder::Pot { .. } | SlioOrder::Board { .. } => {
                Vec::new()
            }
            SlioOrder::Read { slio: id } => {
                let want = format!("{:03X}", id.command_id().as_raw());
                let frames: Vec<_> = panels
                    .read_requests(true)
                    .into_iter()
                    .filter(|f| format!("{:03X}", f.id().as_raw()) == want)
                    .collect();
                if frames.is_empty() {
                    return Err(bad(crate::devices::slio::SlioRequestError::UnknownBoard(
                        id,
                    )));
                }
                frames
            }
        }
    };
    app.hub.devices.changed();
    let queued = queue(&app, frames)?;
    Ok((
        StatusCode::ACCEPTED,
        Json(serde_json::json!({ "queued": queued })),
    )
        .into_response())
}

/// Hands frames to the bus; their text.
fn queue(app: &App, frames: Vec<buslab_can::Frame>) -> Result<Vec<String>, ApiError> {
    let mut queued = Vec::new();
    for frame in frames {
        match app.sender.try_send(frame) {
            Ok(()) => queued.push(frame.to_string()),
            Err(TrySendError::Full) => {
                return Err(ApiError::new(
                    StatusCode::SERVICE_UNAVAILABLE,
                    "the bus takes no more frames now (its queue is full): try again",
                ));
            }
            Err(TrySendError::Stopped(_)) => {
                return Err(ApiError::new(
                    StatusCode::SERVICE_UNAVAILABLE,
                    "the bus is no longer served",
                ));
            }
        }
    }
    Ok(queued)
}

/// A demo board's inputs on the bench: changed (or only looked at) on the bus's own thread
/// through the virtual bus's extension; a changed switch is then read back through the SLIO.
async fn bench(app: &App, slio: SlioId, change: Option<BoardInput>) -> Result<Response, ApiError> {
    let unknown = |id| {
        ApiError::bad_request(crate::devices::slio::SlioRequestError::UnknownBoard(id).to_string())
    };
    if !app.hub.devices.slio().has(slio) {
        return Err(unknown(slio));
    }
    let board = demo_board(app, slio, change).await?;
    let read = {
        let mut panels = app.hub.devices.slio();
        panels.bench(board.clone()).map_err(|_| unknown(slio))?;
        match change {
            Some(BoardInput::Switch { .. } | BoardInput::Switches(_)) => {
                vec![panels.pins_request(slio).map_err(|_| unknown(slio))?]
            }
            _ => Vec::new(),
        }
    };
    app.hub.devices.changed();
    let queued = queue(app, read)?;
    Ok(Json(serde_json::json!({
        "board": {
            "slio": board.slio.to_string(),
            "switches": buslab_bus::admin::switch_bits(board.switches),
            "potentiometer": board.potentiometer,
        },
        "queued": queued,
    }))
    .into_response())
}

/// `BusAdmin::demo_board` on the bus's thread.
async fn demo_board(
    app: &App,
    slio: SlioId,
    change: Option<BoardInput>,
) -> Result<BoardState, ApiError> {
    match crate::api::on_admin(app, "demo boards", move |admin| {
        admin.demo_board(slio, change)
    })
    .await?
    {
        Ok(board) => Ok(board),
        Err(e @ BusError::Unsupported { .. }) => Err(ApiError::new(
            StatusCode::CONFLICT,
            format!("{e} (only a buslab virtual bus has demo boards to reach)"),
        )),
        Err(e @ (BusError::Other(_) | BusError::Rejected(_))) => {
            Err(ApiError::bad_request(format!("the bus refused it: {e}")))
        }
        Err(e) => Err(ApiError::new(StatusCode::BAD_GATEWAY, e.to_string())),
    }
}

/// `POST /api/zelle`: a measurement (plotted block by block), its stop, a RAM read.
pub async fn zelle(
    State(app): State<App>,
    headers: HeaderMap,
    bytes: Bytes,
) -> Result<impl IntoResponse, ApiError> {
    authorize(&app, &headers)?;
    let order = zelle_request(&bytes)?;
    let cell = app
        .hub
        .devices
        .zelle
        .as_ref()
        .ok_or_else(|| absent("ZELLE cell"))?;
    let job = match order {
        ZelleOrder::Stop => {
            cell.stop_run();
            return Ok(Json(serde_json::json!({ "stopping": true })));
        }
        ZelleOrder::Ram { len } => ZelleJob::ReadRam { len },
        ZelleOrder::Measure { params, chunks } => ZelleJob::Measure { params, chunks },
    };
    cell.submit(job).map_err(refused)?;
    Ok(Json(serde_json::json!({ "started": true })))
}

/// `POST /api/cpu196`: identify, start streaming a configuration set, stop.
pub async fn cpu196(
    State(app): State<App>,
    headers: HeaderMap,
    bytes: Bytes,
) -> Result<impl IntoResponse, ApiError> {
    authorize(&app, &headers)?;
    let order = cpu196_request(&bytes)?;
    let board = app
        .hub
        .devices
        .cpu196
        .as_ref()
        .ok_or_else(|| absent("CPU196 board"))?;
    let job = match order {
        Cpu196Order::Identify => Cpu196Job::Identify,
        Cpu196Order::Stop => Cpu196Job::Stop,
        Cpu196Order::Start { bank, config } => Cpu196Job::Start { bank, config },
    };
    board.submit(job).map_err(refused)?;
    Ok(Json(serde_json::json!({ "accepted": true })))
}
