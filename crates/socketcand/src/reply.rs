//! buslab's extension replies as typed values, both ways: what a server writes
//! (`status_fields` and friends) and what a client reads back (`parse_status` and friends).
//!
//! The wire stays text, as docs/bus.md lists it: `< buslab_status N NAME key=value … >`,
//! `< buslab_regs N NAME MODE STATE HH … >`, `< buslab_nodes N:NAME … >`,
//! `< buslab_flushed SENT FAILED >`. The values are typed on both sides of it.

use buslab_bus::{
    Alc, BusSummary, CanMode, Ecc, ErrorRegisters, ErrorState, NodeCounters, NodeInfo,
    NodeRegisters, NodeStatus, NodeTiming, RegisterDump, Status, TxReport,
};

use std::time::Duration;

use buslab_bus::SlioId;
use buslab_bus::admin::{BoardState, FaultLimit};

use crate::message::ServerMessage;

/// The reply names.
pub const STATUS: &str = "buslab_status";
pub const REGS: &str = "buslab_regs";
pub const NODES: &str = "buslab_nodes";
pub const FLUSHED: &str = "buslab_flushed";
/// A request a limit refused (`< buslab_refused fault rate max=20 … >`).
pub const REFUSED: &str = "buslab_refused";
/// A SLIO demo board's inputs and outputs (`< buslab_board 3 6 slio3 switches=5 … >`).
pub const BOARD: &str = "buslab_board";

/// Why a reply's tokens are not what its name promises.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReplyError {
    #[error("{reply}: expected {expected}, got {got:?}")]
    Shape {
        reply: &'static str,
        expected: &'static str,
        got: String,
    },
    #[error("{reply}: {key}={value:?} must be {expected}")]
    Value {
        reply: &'static str,
        key: String,
        value: String,
        expected: &'static str,
    },
    #[error("{reply}: {key}= is missing")]
    Missing {
        reply: &'static str,
        key: &'static str,
    },
    #[error("{reply}: {key}= is given twice")]
    Duplicate { reply: &'static str, key: String },
}

// ------------------------------------------------------------------------------ status

/// `[N, NAME, key=value…]`: a node's status as `< buslab_status … >` carries it, keys in this
/// order (absent parts are left out):
/// `state sr txerr rxerr [alc] [ecc] btr0 btr1 bitrate bus_bitrate timing sent received
/// tx_failed bus_errors arbitration_lost overruns bus_off rx_lost tx_queued bus_load
/// bus_frames bus_errors_total`.
pub fn status_fields(st: &NodeStatus) -> Vec<String> {
    let mut out = vec![st.number.to_string(), st.name.clone()];
    let mut put = |k: &str, v: String| out.push(format!("{k}={v}"));
    put("state", st.state.to_string());
    if let Some(sr) = st.sr {
        put("sr", format!("{:02X}", sr.0));
    }
    if let Some(e) = st.errors {
        put("txerr", e.txerr.to_string());
        put("rxerr", e.rxerr.to_string());
        if let Some(alc) = e.alc {
            put("alc", format!("{:02X}", alc.0));
        }
        if let Some(ecc) = e.ecc {
            put("ecc", format!("{:02X}", ecc.0));
        }
    }
    if let Some(t) = st.timing {
        put("btr0", format!("{:02X}", t.btr0));
        put("btr1", format!("{:02X}", t.btr1));
        put("bitrate", t.bitrate.to_string());
    }
    put("bus_bitrate", st.bus.bitrate.to_string());
    if let Some(t) = st.timing {
        put(
            "timing",
            if t.matches_bus { "ok" } else { "mismatch" }.into(),
        );
    }
    let c = st.counters;
    put("sent", c.sent.to_string());
    put("received", c.received.to_string());
    put("tx_failed", c.tx_failed.to_string());
    put("bus_errors", c.bus_errors.to_string());
    put("arbitration_lost", c.arbitration_lost.to_string());
    put("overruns", c.overruns.to_string());
    put("bus_off", c.bus_off.to_string());
    put("rx_lost", c.rx_lost.to_string());
    put("tx_queued", st.tx_queued.to_string());
    put("bus_load", format!("{:.1}%", st.bus.load_percent));
    put("bus_frames", st.bus.frames.to_string());
    put("bus_errors_total", st.bus.errors.to_string());
    out
}

/// `< buslab_status … >` for a node's status.
pub fn status_reply(st: &NodeStatus) -> ServerMessage {
    ServerMessage::Other {
        name: STATUS.into(),
        args: status_fields(st),
    }
}

/// The fields of a status reply, looked up by key.
struct Fields<'a> {
    pairs: Vec<(&'a str, &'a str)>,
}

impl<'a> Fields<'a> {
    fn new(tokens: &'a [impl AsRef<str>]) -> Result<Self, ReplyError> {
        let mut pairs: Vec<(&str, &str)> = Vec::new();
        for t in tokens {
            let t = t.as_ref();
            let (k, v) = t.split_once('=').ok_or_else(|| ReplyError::Shape {
                reply: STATUS,
                expected: "KEY=VALUE fields after the number and name",
                got: t.to_string(),
            })?;
            if pairs.iter().any(|(seen, _)| *seen == k) {
                return Err(ReplyError::Duplicate {
                    reply: STATUS,
                    key: k.to_string(),
                });
            }
            pairs.push((k, v));
        }
        Ok(Self { pairs })
    }

    fn get(&self, key: &str) -> Option<&'a str> {
        self.pairs.iter().find(|(k, _)| *k == key).map(|(_, v)| *v)
    }

    fn require(&self, key: &'static str) -> Result<&'a str, ReplyError> {
        self.get(key)
            .ok_or(ReplyError::Missing { reply: STATUS, key })
    }

    /// An optional value read with `parse`; `expected` names what is allowed.
    fn opt<T>(
        &self,
        key: &'static str,
        expected: &'static str,
        parse: impl Fn(&str) -> Option<T>,
    ) -> Result<Option<T>, ReplyError> {
        self.get(key)
            .map(|v| parse(v).ok_or_else(|| bad(STATUS, key, v, expected)))
            .transpose()
    }

    fn req<T>(
        &self,
        key: &'static str,
        expected: &'static str,
        parse: impl Fn(&str) -> Option<T>,
    ) -> Result<T, ReplyError> {
        let v = self.require(key)?;
        parse(v).ok_or_else(|| bad(STATUS, key, v, expected))
    }

    fn count(&self, key: &'static str) -> Result<u64, ReplyError> {
        self.req(key, "a decimal count", decimal)
    }
}

fn bad(reply: &'static str, key: &str, value: &str, expected: &'static str) -> ReplyError {
    ReplyError::Value {
        reply,
        key: key.to_string(),
        value: value.to_string(),
        expected,
    }
}

/// Digits only (`u64::from_str` would take `+5`).
fn decimal<T: std::str::FromStr>(text: &str) -> Option<T> {
    if text.is_empty() || !text.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    text.parse().ok()
}

/// One or two hex digits.
fn hex_byte(text: &str) -> Option<u8> {
    if !(1..=2).contains(&text.len()) || !text.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    u8::from_str_radix(text, 16).ok()
}

fn bus_state(text: &str) -> Option<ErrorState> {
    match text {
        "error-active" => Some(ErrorState::Active),
        "error-passive" => Some(ErrorState::Passive),
        "bus-off" => Some(ErrorState::BusOff),
        _ => None,
    }
}

/// `12.3%`: a per cent value 0..=100.
fn percent(text: &str) -> Option<f64> {
    let number = text.strip_suffix('%')?;
    if number.is_empty() || !number.bytes().all(|b| b.is_ascii_digit() || b == b'.') {
        return None;
    }
    number
        .parse::<f64>()
        .ok()
        .filter(|p| (0.0..=100.0).contains(p))
}

/// Reads `[N, NAME, key=value…]` back into a [`NodeStatus`]. Keys it does not know are
/// skipped (a newer server may add some); a known key with a bad value, a missing required
/// key or a key given twice is an error naming it.
pub fn parse_status(args: &[impl AsRef<str>]) -> Result<NodeStatus, ReplyError> {
    let [number, name, fields @ ..] = args else {
        return Err(ReplyError::Shape {
            reply: STATUS,
            expected: "N NAME KEY=VALUE…",
            got: join(args),
        });
    };
    let number = decimal(number.as_ref()).ok_or_else(|| ReplyError::Shape {
        reply: STATUS,
        expected: "a node number first",
        got: number.as_ref().to_string(),
    })?;
    let f = Fields::new(fields)?;
    let errors = match (f.get("txerr"), f.get("rxerr")) {
        (None, None) => None,
        _ => Some(ErrorRegisters {
            txerr: f.req("txerr", "a decimal 0..255", decimal)?,
            rxerr: f.req("rxerr", "a decimal 0..255", decimal)?,
            alc: f.opt("alc", "a hex byte", hex_byte)?.map(Alc),
            ecc: f.opt("ecc", "a hex byte", hex_byte)?.map(Ecc),
        }),
    };
    if errors.is_none() {
        for key in ["alc", "ecc"] {
            if f.get(key).is_some() {
                return Err(ReplyError::Missing {
                    reply: STATUS,
                    key: "txerr",
                });
            }
        }
    }
    let timing_keys = ["btr0", "btr1", "bitrate", "timing"];
    let timing = if timing_keys.iter().all(|k| f.get(k).is_none()) {
        None
    } else {
        Some(NodeTiming {
            btr0: f.req("btr0", "a hex byte", hex_byte)?,
            btr1: f.req("btr1", "a hex byte", hex_byte)?,
            bitrate: f.req("bitrate", "a bit rate in bit/s", decimal)?,
            matches_bus: f.req("timing", "ok or mismatch", |v| match v {
                "ok" => Some(true),
                "mismatch" => Some(false),
                _ => None,
            })?,
        })
    };
    Ok(NodeStatus {
        number,
        name: name.as_ref().to_string(),
        state: f.req("state", "error-active, error-passive or bus-off", bus_state)?,
        errors,
        sr: f.opt("sr", "a hex byte", hex_byte)?.map(Status),
        timing,
        counters: NodeCounters {
            sent: f.count("sent")?,
            received: f.count("received")?,
            tx_failed: f.count("tx_failed")?,
            bus_errors: f.count("bus_errors")?,
            arbitration_lost: f.count("arbitration_lost")?,
            overruns: f.count("overruns")?,
            bus_off: f.count("bus_off")?,
            rx_lost: f.count("rx_lost")?,
        },
        tx_queued: f.count("tx_queued")?,
        bus: BusSummary {
            bitrate: f.req("bus_bitrate", "a bit rate in bit/s", decimal)?,
            load_percent: f.req("bus_load", "a per cent value 0..100 with %", percent)?,
            frames: f.count("bus_frames")?,
            errors: f.count("bus_errors_total")?,
        },
    })
}

// ------------------------------------------------------------------------------ registers

/// `[N, NAME, peli|basic, reset|operating, HH|--…]`: a node's register dump.
pub fn regs_fields(regs: &NodeRegisters) -> Vec<String> {
    let dump = &regs.dump;
    let mut out = vec![
        regs.number.to_string(),
        regs.name.clone(),
        match dump.mode {
            CanMode::Peli => "peli",
            CanMode::Basic => "basic",
        }
        .into(),
        if dump.reset_mode {
            "reset"
        } else {
            "operating"
        }
        .into(),
    ];
    out.extend(
        dump.values
            .iter()
            .map(|v| v.map_or("--".to_string(), |v| format!("{v:02X}"))),
    );
    out
}

/// `< buslab_regs … >` for a node's registers.
pub fn regs_reply(regs: &NodeRegisters) -> ServerMessage {
    ServerMessage::Other {
        name: REGS.into(),
        args: regs_fields(regs),
    }
}

/// Reads a register dump back: 128 values in PeliCAN, 32 in BasicCAN.
pub fn parse_regs(args: &[impl AsRef<str>]) -> Result<NodeRegisters, ReplyError> {
    let shape = |expected: &'static str, got: &str| ReplyError::Shape {
        reply: REGS,
        expected,
        got: got.to_string(),
    };
    let [number, name, mode, state, values @ ..] = args else {
        return Err(shape(
            "N NAME peli|basic reset|operating VALUES…",
            &join(args),
        ));
    };
    let number =
        decimal(number.as_ref()).ok_or_else(|| shape("a node number first", number.as_ref()))?;
    let (mode, count) = match mode.as_ref() {
        "peli" => (CanMode::Peli, 128),
        "basic" => (CanMode::Basic, 32),
        other => return Err(shape("peli or basic", other)),
    };
    let reset_mode = match state.as_ref() {
        "reset" => true,
        "operating" => false,
        other => return Err(shape("reset or operating", other)),
    };
    if values.len() != count {
        return Err(ReplyError::Shape {
            reply: REGS,
            expected: if count == 128 {
                "128 register values in PeliCAN"
            } else {
                "32 register values in BasicCAN"
            },
            got: format!("{} values", values.len()),
        });
    }
    let values = values
        .iter()
        .enumerate()
        .map(|(addr, v)| match v.as_ref() {
            "--" => Ok(None),
            v => hex_byte(v)
                .map(Some)
                .ok_or_else(|| bad(REGS, &format!("register {addr}"), v, "two hex digits or --")),
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(NodeRegisters {
        number,
        name: name.as_ref().to_string(),
        dump: RegisterDump {
            mode,
            reset_mode,
            values,
        },
    })
}

// ------------------------------------------------------------------------------ nodes, flush

/// `[N:NAME…]`: the nodes on the bus.
pub fn nodes_fields(nodes: &[NodeInfo]) -> Vec<String> {
    nodes
        .iter()
        .map(|n| format!("{}:{}", n.number, n.name))
        .collect()
}

/// `< buslab_nodes … >`.
pub fn nodes_reply(nodes: &[NodeInfo]) -> ServerMessage {
    ServerMessage::Other {
        name: NODES.into(),
        args: nodes_fields(nodes),
    }
}

pub fn parse_nodes(args: &[impl AsRef<str>]) -> Result<Vec<NodeInfo>, ReplyError> {
    args.iter()
        .map(|a| {
            let a = a.as_ref();
            a.split_once(':')
                .and_then(|(n, name)| {
                    Some(NodeInfo {
                        number: decimal(n)?,
                        name: (!name.is_empty()).then(|| name.to_string())?,
                    })
                })
                .ok_or_else(|| ReplyError::Shape {
                    reply: NODES,
                    expected: "N:NAME for each node",
                    got: a.to_string(),
                })
        })
        .collect()
}

/// `[SENT, FAILED]`: what `< buslab_flushed … >` reports.
pub fn flushed_fields(report: &TxReport) -> Vec<String> {
    vec![report.sent.to_string(), report.failed.to_string()]
}

/// `< buslab_flushed SENT FAILED >`: the answer to `< buslab_flush >`.
pub fn flushed_reply(report: &TxReport) -> ServerMessage {
    ServerMessage::Other {
        name: FLUSHED.into(),
        args: flushed_fields(report),
    }
}

pub fn parse_flushed(args: &[impl AsRef<str>]) -> Result<TxReport, ReplyError> {
    let shape = || ReplyError::Shape {
        reply: FLUSHED,
        expected: "SENT FAILED (two decimal counts)",
        got: join(args),
    };
    let [sent, failed] = args else {
        return Err(shape());
    };
    Ok(TxReport {
        sent: decimal(sent.as_ref()).ok_or_else(shape)?,
        failed: decimal(failed.as_ref()).ok_or_else(shape)?,
    })
}

// ----------------------------------------------------------------------------- refused

/// `[fault, active, max=N]` or `[fault, rate, max=N, per_ms=MS, retry_ms=MS]`: a fault a limit
/// refused, as `< buslab_refused … >` carries it (the retry rounded up to whole milliseconds,
/// so a client that waits that long is let through).
pub fn refused_fields(limit: &FaultLimit) -> Vec<String> {
    let ms = |d: Duration| d.as_nanos().div_ceil(1_000_000).to_string();
    let mut out = vec!["fault".to_string()];
    match limit {
        FaultLimit::Active { max } => {
            out.push("active".into());
            out.push(format!("max={max}"));
        }
        FaultLimit::Rate {
            max,
            per,
            retry_after,
        } => {
            out.push("rate".into());
            out.push(format!("max={max}"));
            out.push(format!("per_ms={}", ms(*per)));
            out.push(format!("retry_ms={}", ms(*retry_after)));
        }
    }
    out
}

pub fn refused_reply(limit: &FaultLimit) -> ServerMessage {
    ServerMessage::Other {
        name: REFUSED.into(),
        args: refused_fields(limit),
    }
}

pub fn parse_refused(args: &[impl AsRef<str>]) -> Result<FaultLimit, ReplyError> {
    let shape = || ReplyError::Shape {
        reply: REFUSED,
        expected: "fault active max=N, or fault rate max=N per_ms=MS retry_ms=MS",
        got: join(args),
    };
    let args: Vec<&str> = args.iter().map(|a| a.as_ref()).collect();
    let value = |token: &str, key: &'static str| -> Result<u64, ReplyError> {
        let text = token
            .strip_prefix(key)
            .and_then(|t| t.strip_prefix('='))
            .ok_or_else(shape)?;
        decimal(text).ok_or_else(|| ReplyError::Value {
            reply: REFUSED,
            key: key.to_string(),
            value: text.to_string(),
            expected: "a decimal count",
        })
    };
    let max = |token: &str| -> Result<u32, ReplyError> {
        u32::try_from(value(token, "max")?).map_err(|_| ReplyError::Value {
            reply: REFUSED,
            key: "max".into(),
            value: token.to_string(),
            expected: "a count up to 4294967295",
        })
    };
    match args.as_slice() {
        ["fault", "active", m] => Ok(FaultLimit::Active { max: max(m)? }),
        ["fault", "rate", m, per, retry] => Ok(FaultLimit::Rate {
            max: max(m)?,
            per: Duration::from_millis(value(per, "per_ms")?),
            retry_after: Duration::from_millis(value(retry, "retry_ms")?),
        }),
        _ => Err(shape()),
    }
}

// ------------------------------------------------------------------------------ board

/// `[SLIO, N, NAME, switches=H, pot=V, adc1=V, leds=HHHH, dpm1=V|floating, dpm2=V|floating]`:
/// a demo board as `< buslab_board … >` carries it (volts as Rust's shortest text that reads
/// back as the same number).
pub fn board_fields(board: &BoardState) -> Vec<String> {
    let dpm = |v: Option<f64>| v.map_or("floating".to_string(), |v| v.to_string());
    vec![
        board.slio.to_string(),
        board.node.number.to_string(),
        board.node.name.clone(),
        format!("switches={:X}", board.switches & 0xF),
        format!("pot={}", board.potentiometer),
        format!("adc1={}", board.adc1),
        format!("leds={:04X}", board.leds),
        format!("dpm1={}", dpm(board.dpm[0])),
        format!("dpm2={}", dpm(board.dpm[1])),
    ]
}

/// `< buslab_board … >`: the answer to `< buslab_board SLIO [CHANGE] >`.
pub fn board_reply(board: &BoardState) -> ServerMessage {
    ServerMessage::Other {
        name: BOARD.into(),
        args: board_fields(board),
    }
}

/// Volts 0..=5 as a plain decimal (no sign, exponent, `inf` or `NaN`).
fn volts(text: &str) -> Option<f64> {
    let plain = !text.is_empty()
        && text.len() <= 32
        && text.bytes().all(|b| b.is_ascii_digit() || b == b'.')
        && text.bytes().filter(|&b| b == b'.').count() <= 1;
    plain
        .then(|| text.parse::<f64>().ok())
        .flatten()
        .filter(|v| (0.0..=buslab_chips::slio::VDD).contains(v))
}

/// Reads a demo board back from `< buslab_board … >`.
pub fn parse_board(args: &[impl AsRef<str>]) -> Result<BoardState, ReplyError> {
    let args: Vec<&str> = args.iter().map(|a| a.as_ref()).collect();
    let shape = |expected: &'static str, got: &str| ReplyError::Shape {
        reply: BOARD,
        expected,
        got: got.to_string(),
    };
    let [slio, number, name, fields @ ..] = args.as_slice() else {
        return Err(shape("SLIO N NAME KEY=VALUE…", &join(&args)));
    };
    let slio = (slio.len() == 1)
        .then(|| slio.parse::<SlioId>().ok())
        .flatten()
        .ok_or_else(|| shape("a SLIO number 0..F first", slio))?;
    let number = decimal(number).ok_or_else(|| shape("a node number after the SLIO", number))?;
    let field = |key: &'static str| -> Result<&str, ReplyError> {
        let mut found = fields
            .iter()
            .filter_map(|f| f.split_once('=').filter(|(k, _)| *k == key).map(|(_, v)| v));
        let value = found
            .next()
            .ok_or(ReplyError::Missing { reply: BOARD, key })?;
        if found.next().is_some() {
            return Err(ReplyError::Duplicate {
                reply: BOARD,
                key: key.to_string(),
            });
        }
        Ok(value)
    };
    let value = |key: &'static str, expected: &'static str, parse: &dyn Fn(&str) -> Option<f64>| {
        let v = field(key)?;
        parse(v).ok_or_else(|| bad(BOARD, key, v, expected))
    };
    let dpm = |key: &'static str| -> Result<Option<f64>, ReplyError> {
        match field(key)? {
            "floating" => Ok(None),
            v => volts(v)
                .map(Some)
                .ok_or_else(|| bad(BOARD, key, v, "volts 0..5 or floating")),
        }
    };
    let switches = field("switches")?;
    let leds = field("leds")?;
    Ok(BoardState {
        slio,
        node: NodeInfo {
            number,
            name: name.to_string(),
        },
        switches: (switches.len() == 1)
            .then(|| u8::from_str_radix(switches, 16).ok())
            .flatten()
            .ok_or_else(|| bad(BOARD, "switches", switches, "one hex digit"))?,
        potentiometer: value("pot", "volts 0..5", &volts)?,
        adc1: value("adc1", "volts 0..5", &volts)?,
        leds: (leds.len() == 4 && leds.bytes().all(|b| b.is_ascii_hexdigit()))
            .then(|| u16::from_str_radix(leds, 16).ok())
            .flatten()
            .ok_or_else(|| bad(BOARD, "leds", leds, "four hex digits (a pin mask)"))?,
        dpm: [dpm("dpm1")?, dpm("dpm2")?],
    })
}

/// The tokens for an error message (the first few: garbage can be long).
fn join(args: &[impl AsRef<str>]) -> String {
    let mut text: Vec<&str> = args.iter().take(8).map(|a| a.as_ref()).collect();
    if args.len() > 8 {
        text.push("…");
    }
    text.join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn board() -> BoardState {
        BoardState {
            slio: SlioId::new(3).unwrap(),
            node: NodeInfo {
                number: 6,
                name: "slio3".into(),
            },
            switches: 0x5,
            potentiometer: 1.0 / 3.0,
            adc1: 1.25,
            leds: 0x0880,
            dpm: [Some(2.5), None],
        }
    }

    #[test]
    fn a_board_reads_back_as_it_was_written() {
        let fields = board_fields(&board());
        assert_eq!(
            fields.join(" "),
            "3 6 slio3 switches=5 pot=0.3333333333333333 adc1=1.25 leds=0880 dpm1=2.5 dpm2=floating"
        );
        assert_eq!(parse_board(&fields).unwrap(), board());
    }

    #[test]
    fn a_bad_board_reply_names_the_field() {
        let with = |key: &str, value: &str| {
            let mut fields = board_fields(&board());
            for f in &mut fields {
                if f.starts_with(&format!("{key}=")) {
                    *f = format!("{key}={value}");
                }
            }
            parse_board(&fields).unwrap_err().to_string()
        };
        assert_eq!(
            with("pot", "7"),
            "buslab_board: pot=\"7\" must be volts 0..5"
        );
        assert!(with("switches", "10").contains("one hex digit"));
        assert!(with("leds", "88").contains("four hex digits"));
        assert!(with("dpm2", "off").contains("volts 0..5 or floating"));
        assert!(with("adc1", "NaN").contains("adc1"));
        let mut twice = board_fields(&board());
        twice.push("pot=1".into());
        assert_eq!(
            parse_board(&twice).unwrap_err(),
            ReplyError::Duplicate {
                reply: BOARD,
                key: "pot".into()
            }
        );
        let short = ["3", "6"];
        assert!(parse_board(&short).is_err());
        let mut missing = board_fields(&board());
        missing.retain(|f| !f.starts_with("leds="));
        assert_eq!(
            parse_board(&missing).unwrap_err(),
            ReplyError::Missing {
                reply: BOARD,
                key: "leds"
            }
        );
    }
}
