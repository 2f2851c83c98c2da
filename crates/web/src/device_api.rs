//! The device panels' API: `GET /api/devices` and the writes `POST /api/slio`,
//! `/api/zelle`, `/api/cpu196`, each behind the token like every other write.

use axum::Json;
use axum::body::Bytes;
use axum::extract::State;
use axum::http::{HeaderMap, StatusCode};
use axum::response::IntoResponse;
use buslab_backends::TrySendError;
use buslab_slio::SlioId;
use buslab_zelle::client::SeriesParams;
use serde::Deserialize;

use crate::devices::cpu196::Cpu196Job;
use crate::devices::zelle::{self, JobRefused, MAX_CHUNKS, ZelleJob};
use crate::routes::{ApiError, App, authorize};

/// `GET /api/devices`: every panel.
pub async fn devices(State(app): State<App>) -> impl IntoResponse {
    Json(app.hub.devices.view())
}

fn body<T: for<'de> Deserialize<'de>>(body: &Bytes, example: &str) -> Result<T, ApiError> {
    serde_json::from_slice(body)
        .map_err(|e| ApiError::bad_request(format!("body: {e} (expected JSON like {example})")))
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

#[derive(Debug, Deserialize)]
#[serde(tag = "action", rename_all = "lowercase", deny_unknown_fields)]
enum SlioAction {
    /// Turn an LED on or off (DATA_OUTPUT).
    Output { slio: String, pin: u8, on: bool },
    /// A DPM duty, 0..1023.
    Dpm { slio: String, output: u8, duty: u16 },
    /// Convert ADC1 or ADC2.
    Convert { slio: String, input: u8 },
    /// Read the board's registers again (inputs, outputs, DPMs).
    Read { slio: String },
}

const SLIO_EXAMPLE: &str = r#"{"action":"output","slio":"3","pin":7,"on":true}"#;

/// `POST /api/slio`: a request frame to a SLIO; its answer, seen on the bus, changes the
/// panel (202: queued, not yet confirmed).
pub async fn slio(
    State(app): State<App>,
    headers: HeaderMap,
    bytes: Bytes,
) -> Result<impl IntoResponse, ApiError> {
    authorize(&app, &headers)?;
    let action: SlioAction = body(&bytes, SLIO_EXAMPLE)?;
    if app.hub.devices.slio().is_empty() {
        return Err(absent("SLIO boards"));
    }
    let id = |text: &str| -> Result<SlioId, ApiError> {
        text.parse()
            .map_err(|_| ApiError::bad_request(format!("slio {text:?}: a SLIO number 0..F")))
    };
    let frames = {
        let mut panels = app.hub.devices.slio();
        let bad = |e: crate::devices::slio::SlioRequestError| {
            let status = match e {
                crate::devices::slio::SlioRequestError::OutputsUnknown(_) => StatusCode::CONFLICT,
                _ => StatusCode::BAD_REQUEST,
            };
            ApiError::new(status, e.to_string())
        };
        match &action {
            SlioAction::Output { slio, pin, on } => {
                vec![panels.output_request(id(slio)?, *pin, *on).map_err(bad)?]
            }
            SlioAction::Dpm { slio, output, duty } => {
                vec![panels.dpm_request(id(slio)?, *output, *duty).map_err(bad)?]
            }
            SlioAction::Convert { slio, input } => {
                vec![panels.convert_request(id(slio)?, *input).map_err(bad)?]
            }
            SlioAction::Read { slio } => {
                let id = id(slio)?;
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
    Ok((
        StatusCode::ACCEPTED,
        Json(serde_json::json!({ "queued": queued })),
    ))
}

#[derive(Debug, Deserialize)]
#[serde(tag = "action", rename_all = "lowercase", deny_unknown_fields)]
enum ZelleAction {
    /// `chunks` blocks of `cycles` scan cycles of `channels` every `interval_ms`.
    Measure {
        channels: Vec<u8>,
        interval_ms: u32,
        cycles: u16,
        chunks: u32,
    },
    /// End a measurement after the block under way.
    Stop,
    /// The data area from 0800h.
    Ram { len: usize },
}

const ZELLE_EXAMPLE: &str =
    r#"{"action":"measure","channels":[1,2],"interval_ms":10,"cycles":50,"chunks":10}"#;

/// `POST /api/zelle`: a measurement (plotted block by block), its stop, a RAM read.
pub async fn zelle(
    State(app): State<App>,
    headers: HeaderMap,
    bytes: Bytes,
) -> Result<impl IntoResponse, ApiError> {
    authorize(&app, &headers)?;
    let action: ZelleAction = body(&bytes, ZELLE_EXAMPLE)?;
    let cell = app
        .hub
        .devices
        .zelle
        .as_ref()
        .ok_or_else(|| absent("ZELLE cell"))?;
    let job = match action {
        ZelleAction::Stop => {
            cell.stop_run();
            return Ok(Json(serde_json::json!({ "stopping": true })));
        }
        ZelleAction::Ram { len } => {
            if !(1..=zelle::MAX_RAM_VIEW).contains(&len) {
                return Err(ApiError::bad_request(format!(
                    "len {len}: 1..{} bytes from 0800h",
                    zelle::MAX_RAM_VIEW
                )));
            }
            ZelleJob::ReadRam { len }
        }
        ZelleAction::Measure {
            channels,
            interval_ms,
            cycles,
            chunks,
        } => {
            let params = SeriesParams::new(&channels, cycles, interval_ms)
                .map_err(|e| ApiError::bad_request(e.to_string()))?;
            if channels.is_empty() || cycles == 0 {
                return Err(ApiError::bad_request(
                    "a measurement needs one to four channels and at least one cycle",
                ));
            }
            if !(1..=MAX_CHUNKS).contains(&chunks) {
                return Err(ApiError::bad_request(format!(
                    "chunks {chunks}: 1..{MAX_CHUNKS} blocks"
                )));
            }
            let lasts = zelle::run_time(&params, chunks);
            if lasts > std::time::Duration::from_secs(600) {
                return Err(ApiError::bad_request(format!(
                    "this measurement would last {} s: 10 minutes at most from the dashboard",
                    lasts.as_secs()
                )));
            }
            ZelleJob::Measure { params, chunks }
        }
    };
    cell.submit(job).map_err(refused)?;
    Ok(Json(serde_json::json!({ "started": true })))
}

#[derive(Debug, Deserialize)]
#[serde(tag = "action", rename_all = "lowercase", deny_unknown_fields)]
enum Cpu196Action {
    Identify,
    Start {
        #[serde(default)]
        bank: u8,
        #[serde(default)]
        config: u8,
    },
    Stop,
}

/// `POST /api/cpu196`: identify, start streaming a configuration set, stop.
pub async fn cpu196(
    State(app): State<App>,
    headers: HeaderMap,
    bytes: Bytes,
) -> Result<impl IntoResponse, ApiError> {
    authorize(&app, &headers)?;
    let action: Cpu196Action = body(&bytes, r#"{"action":"start","bank":0,"config":0}"#)?;
    let board = app
        .hub
        .devices
        .cpu196
        .as_ref()
        .ok_or_else(|| absent("CPU196 board"))?;
    let job = match action {
        Cpu196Action::Identify => Cpu196Job::Identify,
        Cpu196Action::Stop => Cpu196Job::Stop,
        Cpu196Action::Start { bank, config } => {
            if bank > 7 || config > 7 {
                return Err(ApiError::bad_request(format!(
                    "bank {bank}, config {config}: each 0..7"
                )));
            }
            Cpu196Job::Start { bank, config }
        }
    };
    board.submit(job).map_err(refused)?;
    Ok(Json(serde_json::json!({ "accepted": true })))
}
