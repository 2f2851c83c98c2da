//! What the device panels' writes ask for, read and checked without a server: the JSON bodies
//! of `POST /api/slio`, `/api/zelle` and `/api/cpu196`. The handlers in `device_api` call these
//! and then check what depends on the bench (which boards exist, what they told); the fuzz
//! target `web_device_api` feeds them arbitrary bytes.
//!
//! An accepted body gives an order whose [`to_json`](SlioOrder::to_json) is a body that reads
//! back as the same order.

use std::time::Duration;

use axum::http::StatusCode;
use buslab_bus::admin::{BadSwitch, BoardInput, BoardSwitch, BoardVolts};
use buslab_chips::slio::SlioId;
use buslab_zelle::client::{SeriesError, SeriesParams};
use serde::Deserialize;

use crate::devices::zelle::{MAX_CHUNKS, MAX_RAM_VIEW, run_time};
use crate::error::ApiError;

/// A measurement from the dashboard lasts this long at most.
pub const MAX_MEASUREMENT: Duration = Duration::from_secs(600);

/// Example bodies, shown in the refusal of a body that is not the expected JSON.
pub const SLIO_EXAMPLE: &str = r#"{"action":"output","slio":"3","pin":7,"on":true}"#;
pub const ZELLE_EXAMPLE: &str =
    r#"{"action":"measure","channels":[1,2],"interval_ms":10,"cycles":50,"chunks":10}"#;
pub const CPU196_EXAMPLE: &str = r#"{"action":"start","bank":0,"config":0}"#;

/// Why a device panel's body was refused; each names the value it refuses and what is allowed.
/// All are the client's fault: [`DeviceRequestError::status`] is 400.
#[derive(Debug, thiserror::Error)]
pub enum DeviceRequestError {
    #[error("body: {reason} (expected JSON like {example})")]
    Json {
        reason: String,
        example: &'static str,
    },
    #[error("slio {0:?}: a SLIO number 0..F")]
    SlioNumber(String),
    #[error("{0}")]
    Switch(BadSwitch),
    #[error("volts {0}: the potentiometer turns from 0 to 5 V")]
    Volts(f64),
    #[error("len {0}: 1..{MAX_RAM_VIEW} bytes from 0800h")]
    RamLength(usize),
    #[error("channels {channels:?}, interval_ms {interval_ms}: {source}")]
    Series {
        channels: Vec<u8>,
        interval_ms: u32,
        source: SeriesError,
    },
    #[error(
        "channels {channels:?}, cycles {cycles}: a measurement needs one to four channels and \
         at least one cycle"
    )]
    EmptyMeasurement { channels: Vec<u8>, cycles: u16 },
    #[error("chunks {0}: 1..{MAX_CHUNKS} blocks")]
    Chunks(u32),
    #[error(
        "this measurement would last {} s: {} minutes at most from the dashboard",
        .0.as_secs(),
        MAX_MEASUREMENT.as_secs() / 60
    )]
    TooLong(Duration),
    #[error("bank {bank}, config {config}: each 0..7")]
    BankOrConfig { bank: u8, config: u8 },
}

impl DeviceRequestError {
    /// The HTTP status of the refusal: always a client error.
    pub fn status(&self) -> StatusCode {
        StatusCode::BAD_REQUEST
    }
}

impl From<DeviceRequestError> for ApiError {
    fn from(e: DeviceRequestError) -> Self {
        ApiError::new(e.status(), e.to_string())
    }
}

fn json_body<T: for<'de> Deserialize<'de>>(
    body: &[u8],
    example: &'static str,
) -> Result<T, DeviceRequestError> {
    serde_json::from_slice(body).map_err(|e| DeviceRequestError::Json {
        reason: e.to_string(),
        example,
    })
}

#[derive(Debug, Deserialize)]
#[serde(tag = "action", rename_all = "lowercase", deny_unknown_fields)]
enum SlioBody {
    Output { slio: String, pin: u8, on: bool },
    Dpm { slio: String, output: u8, duty: u16 },
    Convert { slio: String, input: u8 },
    Read { slio: String },
    Switch { slio: String, switch: u8, on: bool },
    Pot { slio: String, volts: f64 },
    Board { slio: String },
}

/// What `POST /api/slio` asks of a SLIO. Whether the pin, DPM or ADC exists on the demo board
/// and whether the board is on the bench is the panel's to check.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlioOrder {
    /// Turn an LED on or off (DATA_OUTPUT).
    Output { slio: SlioId, pin: u8, on: bool },
    /// A DPM duty, 0..1023.
    Dpm { slio: SlioId, output: u8, duty: u16 },
    /// Convert ADC1 or ADC2.
    Convert { slio: SlioId, input: u8 },
    /// Read the board's pins again (DATA_INPUT: the switches, the outputs read back).
    Read { slio: SlioId },
    /// Flip an input switch of the board (the bench's, not the SLIO's).
    Switch {
        slio: SlioId,
        switch: BoardSwitch,
        on: bool,
    },
    /// Turn the board's potentiometer to a level.
    Pot { slio: SlioId, volts: BoardVolts },
    /// The board's switches and potentiometer as the bench has them.
    Board { slio: SlioId },
}

impl SlioOrder {
    /// The board it is for.
    pub fn slio(&self) -> SlioId {
        match *self {
            Self::Output { slio, .. }
            | Self::Dpm { slio, .. }
            | Self::Convert { slio, .. }
            | Self::Read { slio }
            | Self::Switch { slio, .. }
            | Self::Pot { slio, .. }
            | Self::Board { slio } => slio,
        }
    }

    /// What it does to the board's inputs on the bench, for the orders that go to the board
    /// rather than its SLIO (`Some(None)`: only look).
    pub fn bench(&self) -> Option<Option<BoardInput>> {
        match *self {
            Self::Switch { switch, on, .. } => Some(Some(BoardInput::Switch { switch, on })),
            Self::Pot { volts, .. } => Some(Some(BoardInput::Potentiometer(volts))),
            Self::Board { .. } => Some(None),
            _ => None,
        }
    }

    /// A body that asks for this order.
    pub fn to_json(&self) -> String {
        let slio = self.slio().to_string();
        let value = match *self {
            Self::Output { pin, on, .. } => {
                serde_json::json!({ "action": "output", "slio": slio, "pin": pin, "on": on })
            }
            Self::Dpm { output, duty, .. } => {
                serde_json::json!({ "action": "dpm", "slio": slio, "output": output, "duty": duty })
            }
            Self::Convert { input, .. } => {
                serde_json::json!({ "action": "convert", "slio": slio, "input": input })
            }
            Self::Read { .. } => serde_json::json!({ "action": "read", "slio": slio }),
            Self::Switch { switch, on, .. } => serde_json::json!({
                "action": "switch", "slio": slio, "switch": switch.number(), "on": on
            }),
            Self::Pot { volts, .. } => {
                serde_json::json!({ "action": "pot", "slio": slio, "volts": volts.get() })
            }
            Self::Board { .. } => serde_json::json!({ "action": "board", "slio": slio }),
        };
        value.to_string()
    }
}

/// The body of `POST /api/slio`, e.g. `{"action":"output","slio":"3","pin":7,"on":true}`.
pub fn slio_request(body: &[u8]) -> Result<SlioOrder, DeviceRequestError> {
    let id = |text: &str| -> Result<SlioId, DeviceRequestError> {
        text.parse()
            .map_err(|_| DeviceRequestError::SlioNumber(text.to_string()))
    };
    Ok(match json_body(body, SLIO_EXAMPLE)? {
        SlioBody::Output { slio, pin, on } => SlioOrder::Output {
            slio: id(&slio)?,
            pin,
            on,
        },
        SlioBody::Dpm { slio, output, duty } => SlioOrder::Dpm {
            slio: id(&slio)?,
            output,
            duty,
        },
        SlioBody::Convert { slio, input } => SlioOrder::Convert {
            slio: id(&slio)?,
            input,
        },
        SlioBody::Read { slio } => SlioOrder::Read { slio: id(&slio)? },
        SlioBody::Switch { slio, switch, on } => SlioOrder::Switch {
            slio: id(&slio)?,
            switch: BoardSwitch::new(switch).map_err(DeviceRequestError::Switch)?,
            on,
        },
        SlioBody::Pot { slio, volts } => SlioOrder::Pot {
            slio: id(&slio)?,
            volts: BoardVolts::new(volts).map_err(|_| DeviceRequestError::Volts(volts))?,
        },
        SlioBody::Board { slio } => SlioOrder::Board { slio: id(&slio)? },
    })
}

#[derive(Debug, Deserialize)]
#[serde(tag = "action", rename_all = "lowercase", deny_unknown_fields)]
enum ZelleBody {
    Measure {
        channels: Vec<u8>,
        interval_ms: u32,
        cycles: u16,
        chunks: u32,
    },
    // Struct variants, so that `deny_unknown_fields` refuses extra fields here too.
    Stop {},
    Ram {
        len: usize,
    },
}

/// What `POST /api/zelle` asks of the cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ZelleOrder {
    /// `chunks` blocks of the series, plotted as each is read back; at most
    /// [`MAX_MEASUREMENT`] in all.
    Measure { params: SeriesParams, chunks: u32 },
    /// End a measurement after the block under way.
    Stop,
    /// The data area from 0800h, 1..[`MAX_RAM_VIEW`] bytes.
    Ram { len: usize },
}

impl ZelleOrder {
    /// A body that asks for this order.
    pub fn to_json(&self) -> String {
        let value = match *self {
            Self::Measure { params, chunks } => {
                // The slots as given, a slot left off (0) between two channels included.
                let used = params
                    .slots
                    .iter()
                    .rposition(|&c| c != 0)
                    .map_or(0, |i| i + 1);
                serde_json::json!({
                    "action": "measure",
                    "channels": params.slots[..used],
                    "interval_ms": params.interval_ms,
                    "cycles": params.cycles,
                    "chunks": chunks,
                })
            }
            Self::Stop => serde_json::json!({ "action": "stop" }),
            Self::Ram { len } => serde_json::json!({ "action": "ram", "len": len }),
        };
        value.to_string()
    }
}

/// The body of `POST /api/zelle`, e.g.
/// `{"action":"measure","channels":[1,2],"interval_ms":10,"cycles":50,"chunks":10}`.
pub fn zelle_request(body: &[u8]) -> Result<ZelleOrder, DeviceRequestError> {
    Ok(match json_body(body, ZELLE_EXAMPLE)? {
        ZelleBody::Stop {} => ZelleOrder::Stop,
        ZelleBody::Ram { len } => {
            if !(1..=MAX_RAM_VIEW).contains(&len) {
                return Err(DeviceRequestError::RamLength(len));
            }
            ZelleOrder::Ram { len }
        }
        ZelleBody::Measure {
            channels,
            interval_ms,
            cycles,
            chunks,
        } => {
            let params = match SeriesParams::new(&channels, cycles, interval_ms) {
                Ok(params) => params,
                Err(source) => {
                    return Err(DeviceRequestError::Series {
                        channels,
                        interval_ms,
                        source,
                    });
                }
            };
            if channels.is_empty() || cycles == 0 {
                return Err(DeviceRequestError::EmptyMeasurement { channels, cycles });
            }
            if !(1..=MAX_CHUNKS).contains(&chunks) {
                return Err(DeviceRequestError::Chunks(chunks));
            }
            let lasts = run_time(&params, chunks);
            if lasts > MAX_MEASUREMENT {
                return Err(DeviceRequestError::TooLong(lasts));
            }
            ZelleOrder::Measure { params, chunks }
        }
    })
}

#[derive(Debug, Deserialize)]
#[serde(tag = "action", rename_all = "lowercase", deny_unknown_fields)]
enum Cpu196Body {
    // Struct variants, so that `deny_unknown_fields` refuses extra fields here too.
    Identify {},
    Start {
        #[serde(default)]
        bank: u8,
        #[serde(default)]
        config: u8,
    },
    Stop {},
}

/// What `POST /api/cpu196` asks of the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cpu196Order {
    Identify,
    /// Stream configuration set `config` (0..7) of flash bank `bank` (0..7).
    Start {
        bank: u8,
        config: u8,
    },
    Stop,
}

impl Cpu196Order {
    /// A body that asks for this order.
    pub fn to_json(&self) -> String {
        let value = match *self {
            Self::Identify => serde_json::json!({ "action": "identify" }),
            Self::Start { bank, config } => {
                serde_json::json!({ "action": "start", "bank": bank, "config": config })
            }
            Self::Stop => serde_json::json!({ "action": "stop" }),
        };
        value.to_string()
    }
}

/// The body of `POST /api/cpu196`, e.g. `{"action":"start","bank":0,"config":0}`.
pub fn cpu196_request(body: &[u8]) -> Result<Cpu196Order, DeviceRequestError> {
    Ok(match json_body(body, CPU196_EXAMPLE)? {
        Cpu196Body::Identify {} => Cpu196Order::Identify,
        Cpu196Body::Stop {} => Cpu196Order::Stop,
        Cpu196Body::Start { bank, config } => {
            if bank > 7 || config > 7 {
                return Err(DeviceRequestError::BankOrConfig { bank, config });
            }
            Cpu196Order::Start { bank, config }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refused<T: std::fmt::Debug>(result: Result<T, DeviceRequestError>, names: &str) {
        let e = result.expect_err("refused");
        let api = ApiError::from(e);
        assert_eq!(api.status, StatusCode::BAD_REQUEST);
        assert!(
            api.reason.contains(names),
            "{:?} does not name {names:?}",
            api.reason
        );
    }

    /// Bodies that are not JSON, or not an object of the expected kind.
    const GARBAGE: &[&[u8]] = &[
        b"",
        b"\x00\xff\xfe",
        b"{",
        b"[]",
        b"null",
        b"\"output\"",
        b"{}",
        b"{\"action\":\"explode\"}",
        b"{\"action\":17}",
        b"{\"action\":\"stop\",\"extra\":1}",
        b"{\"action\":\"output\",\"slio\":\"3\",\"pin\":7,\"on\":true}trailing",
    ];

    #[test]
    fn garbage_bodies_are_refused_with_the_expected_json_shown() {
        for body in GARBAGE {
            refused(slio_request(body), SLIO_EXAMPLE);
            refused(zelle_request(body), ZELLE_EXAMPLE);
            refused(cpu196_request(body), CPU196_EXAMPLE);
        }
    }

    #[test]
    fn out_of_range_numbers_are_refused_naming_them() {
        refused(
            slio_request(br#"{"action":"output","slio":"3","pin":700,"on":true}"#),
            "700",
        );
        refused(
            slio_request(br#"{"action":"dpm","slio":"3","output":1,"duty":-1}"#),
            "-1",
        );
        refused(slio_request(br#"{"action":"read","slio":"16"}"#), "\"16\"");
        refused(
            slio_request(br#"{"action":"switch","slio":"3","switch":4,"on":true}"#),
            "switch 4: a demo board has input switches 0..=3",
        );
        refused(
            slio_request(br#"{"action":"pot","slio":"3","volts":5.5}"#),
            "volts 5.5: the potentiometer turns from 0 to 5 V",
        );
        refused(
            slio_request(br#"{"action":"pot","slio":"3","volts":-0.5}"#),
            "volts -0.5",
        );
        refused(
            slio_request(br#"{"action":"pot","slio":"3","volts":"2.5V"}"#),
            SLIO_EXAMPLE,
        );
        refused(slio_request(br#"{"action":"read","slio":"G"}"#), "\"G\"");
        refused(zelle_request(br#"{"action":"ram","len":0}"#), "len 0");
        refused(zelle_request(br#"{"action":"ram","len":513}"#), "len 513");
        let measure = |channels: &str, interval: u32, cycles: u16, chunks: u32| {
            zelle_request(
                format!(
                    r#"{{"action":"measure","channels":{channels},"interval_ms":{interval},"cycles":{cycles},"chunks":{chunks}}}"#
                )
                .as_bytes(),
            )
        };
        refused(measure("[5]", 10, 5, 1), "channel 5");
        refused(measure("[1,2,3,4,1]", 10, 5, 1), "[1, 2, 3, 4, 1]");
        refused(measure("[1,2]", 1, 5, 1), "interval_ms 1");
        refused(measure("[]", 10, 5, 1), "[]");
        refused(measure("[1]", 10, 0, 1), "cycles 0");
        refused(measure("[1]", 10, 5, 0), "chunks 0");
        refused(measure("[1]", 10, 5, 101), "chunks 101");
        let params = SeriesParams::new(&[1], 100, 60_000).unwrap();
        let lasts = run_time(&params, 100).as_secs();
        assert!(lasts > MAX_MEASUREMENT.as_secs());
        refused(measure("[1]", 60_000, 100, 100), &format!("last {lasts} s"));
        refused(
            cpu196_request(br#"{"action":"start","bank":8,"config":0}"#),
            "bank 8",
        );
        refused(
            cpu196_request(br#"{"action":"start","bank":0,"config":255}"#),
            "config 255",
        );
    }

    #[test]
    fn accepted_bodies_give_orders_that_read_back_the_same() {
        let slio = slio_request(SLIO_EXAMPLE.as_bytes()).unwrap();
        assert_eq!(
            slio,
            SlioOrder::Output {
                slio: SlioId::new(3).unwrap(),
                pin: 7,
                on: true
            }
        );
        for body in [
            SLIO_EXAMPLE,
            r#"{"action":"dpm","slio":"12","output":2,"duty":1023}"#,
            r#"{"action":"convert","slio":"a","input":2}"#,
            r#"{"action":"read","slio":" F "}"#,
            r#"{"action":"switch","slio":"3","switch":2,"on":true}"#,
            r#"{"action":"switch","slio":"A","switch":0,"on":false}"#,
            r#"{"action":"pot","slio":"3","volts":2.5}"#,
            r#"{"action":"pot","slio":"3","volts":0.1}"#,
            r#"{"action":"pot","slio":"3","volts":0}"#,
            r#"{"action":"board","slio":"0"}"#,
        ] {
            let order = slio_request(body.as_bytes()).unwrap();
            assert_eq!(slio_request(order.to_json().as_bytes()).unwrap(), order);
        }
        for body in [
            ZELLE_EXAMPLE,
            r#"{"action":"measure","channels":[1,0,2],"interval_ms":2,"cycles":1,"chunks":1}"#,
            r#"{"action":"stop"}"#,
            r#"{"action":"ram","len":512}"#,
        ] {
            let order = zelle_request(body.as_bytes()).unwrap();
            assert_eq!(zelle_request(order.to_json().as_bytes()).unwrap(), order);
        }
        assert_eq!(
            cpu196_request(br#"{"action":"start"}"#).unwrap(),
            Cpu196Order::Start { bank: 0, config: 0 }
        );
        for body in [
            CPU196_EXAMPLE,
            r#"{"action":"start","bank":7,"config":7}"#,
            r#"{"action":"identify"}"#,
            r#"{"action":"stop"}"#,
        ] {
            let order = cpu196_request(body.as_bytes()).unwrap();
            assert_eq!(cpu196_request(order.to_json().as_bytes()).unwrap(), order);
        }
    }
}
