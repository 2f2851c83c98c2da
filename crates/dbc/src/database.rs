//! A DBC file read into messages and signals: can-dbc's syntax tree resolved (comments,
//! value tables, value types, multiplexing, attributes) and checked, once.

use std::collections::HashMap;
use std::time::Duration;

use buslab_can::Id;
use can_dbc::{
    AttributeDefinition, AttributeValue, AttributeValueType, Dbc, MessageId, MultiplexIndicator,
    NumericValue, SignalExtendedValueType,
};

use crate::error::DbcError;
use crate::layout::Layout;
use crate::message::Message;
use crate::signal::{ByteOrder, Multiplexing, Signal, ValueKind};

/// The largest payload a message can declare (CAN FD).
const MAX_LENGTH: u64 = 64;
/// Vector's pseudo-message that holds signals not placed in any message.
const INDEPENDENT_SIGNALS: &str = "VECTOR__INDEPENDENT_SIG_MSG";

/// The messages of a DBC file, found by ID or by name.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Database {
    messages: Vec<Message>,
    by_id: HashMap<Id, usize>,
    nodes: Vec<String>,
}

impl Database {
    /// A DBC file's bytes: UTF-8, or Windows-1252 as Vector's tools write them.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, DbcError> {
        match std::str::from_utf8(bytes) {
            Ok(text) => Self::parse(text),
            Err(_) => {
                let text = can_dbc::decode_cp1252(bytes).ok_or(DbcError::NotText)?;
                Self::parse(&text)
            }
        }
    }

    /// A DBC file's text.
    pub fn parse(text: &str) -> Result<Self, DbcError> {
        let dbc = Dbc::try_from(text).map_err(syntax)?;
        let mut messages = Vec::with_capacity(dbc.messages.len());
        let mut by_id = HashMap::with_capacity(dbc.messages.len());
        for message in &dbc.messages {
            if message.name == INDEPENDENT_SIGNALS {
                continue;
            }
            let message = resolve_message(&dbc, message, text)?;
            if by_id.insert(message.id, messages.len()).is_some() {
                return Err(DbcError::Invalid {
                    line: line_of(text, &format!("BO_ {}", raw_id(message.id))),
                    what: format!("message ID {} is defined twice", message.id),
                });
            }
            messages.push(message);
        }
        Ok(Self {
            messages,
            by_id,
            nodes: dbc.nodes.iter().map(|n| n.0.clone()).collect(),
        })
    }

    /// Its messages, in the file's order.
    pub fn messages(&self) -> &[Message] {
        &self.messages
    }
    /// The message with this ID.
    pub fn message(&self, id: Id) -> Option<&Message> {
        self.by_id.get(&id).map(|&i| &self.messages[i])
    }
    /// The message called `name`.
    pub fn message_by_name(&self, name: &str) -> Option<&Message> {
        self.messages.iter().find(|m| m.name == name)
    }
    /// The nodes (`BU_`).
    pub fn nodes(&self) -> &[String] {
        &self.nodes
    }
}

fn syntax(error: can_dbc::DbcError) -> DbcError {
    match error {
        can_dbc::DbcError::Pest(e) => {
            let (line, column) = match e.line_col {
                pest::error::LineColLocation::Pos(at) => at,
                pest::error::LineColLocation::Span(at, _) => at,
            };
            DbcError::Syntax {
                line,
                column,
                expected: e.variant.message().into_owned(),
            }
        }
        other => DbcError::Invalid {
            line: None,
            what: other.to_string(),
        },
    }
}

/// The DBC spelling of an ID (bit 31 set for extended).
fn raw_id(id: Id) -> u32 {
    match id {
        Id::Standard(_) => id.as_raw(),
        Id::Extended(_) => id.as_raw() | 1 << 31,
    }
}

/// The first line (1-based) holding `needle`, for errors about the resolved model.
fn line_of(text: &str, needle: &str) -> Option<usize> {
    text.lines().position(|l| l.contains(needle)).map(|i| i + 1)
}

fn number(value: &NumericValue) -> f64 {
    match *value {
        NumericValue::Uint(v) => v as f64,
        NumericValue::Int(v) => v as f64,
        NumericValue::Double(v) => v,
    }
}

fn attribute_number(value: &AttributeValue) -> Option<f64> {
    match *value {
        AttributeValue::Uint(v) => Some(v as f64),
        AttributeValue::Int(v) => Some(v as f64),
        AttributeValue::Double(v) => Some(v),
        AttributeValue::String(_) => None,
    }
}

/// An enum attribute's value as its name (DBC stores the index into the definition's list).
fn enum_name<'a>(dbc: &'a Dbc, attribute: &str, value: &'a AttributeValue) -> Option<&'a str> {
    if let AttributeValue::String(s) = value {
        return Some(s);
    }
    let index = attribute_number(value)? as usize;
    dbc.attribute_definitions.iter().find_map(|d| match d {
        AttributeDefinition::Message(name, AttributeValueType::Enum(names))
            if name == attribute =>
        {
            names.get(index).map(String::as_str)
        }
        _ => None,
    })
}

fn resolve_message(dbc: &Dbc, message: &can_dbc::Message, text: &str) -> Result<Message, DbcError> {
    let at = || line_of(text, &format!("BO_ {} {}", message.id.raw(), message.name));
    let id = match message.id {
        MessageId::Standard(raw) => Id::standard(raw),
        MessageId::Extended(raw) => Id::extended(raw),
    }
    .map_err(|e| DbcError::Invalid {
        line: at(),
        what: format!("message {}: {e}", message.name),
    })?;
    if message.size > MAX_LENGTH {
        return Err(DbcError::Invalid {
            line: at(),
            what: format!(
                "message {} is {} bytes long: at most {MAX_LENGTH} (CAN FD)",
                message.name, message.size
            ),
        });
    }
    let cycle_time = dbc
        .resolved_message_attribute(message.id, "GenMsgCycleTime")
        .and_then(attribute_number)
        .filter(|&ms| ms > 0.0 && ms.is_finite())
        .map(|ms| Duration::from_secs_f64(ms / 1000.0));
    let fd = dbc
        .resolved_message_attribute(message.id, "VFrameFormat")
        .and_then(|v| enum_name(dbc, "VFrameFormat", v))
        .is_some_and(|name| name.contains("FD"));
    let mut signals = Vec::with_capacity(message.signals.len());
    for signal in &message.signals {
        signals.push(resolve_signal(dbc, message, signal, text)?);
    }
    resolve_multiplexing(dbc, message, &mut signals, text)?;
    Ok(Message {
        id,
        name: message.name.clone(),
        length: message.size as usize,
        transmitter: message.transmitter.clone(),
        signals,
        cycle_time,
        comment: dbc.message_comment(message.id).map(str::to_string),
        fd,
    })
}

fn resolve_signal(
    dbc: &Dbc,
    message: &can_dbc::Message,
    signal: &can_dbc::Signal,
    text: &str,
) -> Result<Signal, DbcError> {
    let invalid = |what: String| DbcError::Invalid {
        line: line_of(text, &format!("SG_ {} ", signal.name)),
        what: format!("signal {}.{}: {what}", message.name, signal.name),
    };
    let kind = match dbc.extended_value_type_for_signal(message.id, &signal.name) {
        Some(SignalExtendedValueType::IEEEfloat32Bit) => ValueKind::Float32,
        Some(SignalExtendedValueType::IEEEdouble64bit) => ValueKind::Float64,
        _ => match signal.value_type {
            can_dbc::ValueType::Signed => ValueKind::Signed,
            can_dbc::ValueType::Unsigned => ValueKind::Unsigned,
        },
    };
    let size = signal.size;
    if !(1..=64).contains(&size) {
        return Err(invalid(format!("{size} bits: a signal has 1 to 64")));
    }
    match (kind, size) {
        (ValueKind::Float32, 32) | (ValueKind::Float64, 64) => {}
        (ValueKind::Float32, _) => return Err(invalid(format!("a float is 32 bits, not {size}"))),
        (ValueKind::Float64, _) => {
            return Err(invalid(format!("a double is 64 bits, not {size}")));
        }
        _ => {}
    }
    if signal.start_bit >= 8 * MAX_LENGTH {
        return Err(invalid(format!(
            "start bit {} is past {MAX_LENGTH} bytes",
            signal.start_bit
        )));
    }
    let byte_order = match signal.byte_order {
        can_dbc::ByteOrder::LittleEndian => ByteOrder::LittleEndian,
        can_dbc::ByteOrder::BigEndian => ByteOrder::BigEndian,
    };
    let layout = Layout::new(
        signal.start_bit as u32,
        size as u32,
        byte_order == ByteOrder::BigEndian,
    );
    if layout.end() as u64 > MAX_LENGTH {
        return Err(invalid(format!(
            "its bits run past {MAX_LENGTH} bytes (start bit {}, {size} bits)",
            signal.start_bit
        )));
    }
    if !signal.factor.is_finite() || signal.factor == 0.0 || !signal.offset.is_finite() {
        return Err(invalid(format!(
            "factor {} and offset {}: a nonzero finite factor and a finite offset",
            signal.factor, signal.offset
        )));
    }
    let choices = dbc
        .value_descriptions_for_signal(message.id, &signal.name)
        .map(|v| v.iter().map(|d| (d.id, d.description.clone())).collect())
        .unwrap_or_default();
    Ok(Signal {
        name: signal.name.clone(),
        start_bit: signal.start_bit as u32,
        size: size as u32,
        byte_order,
        kind,
        factor: signal.factor,
        offset: signal.offset,
        min: number(&signal.min),
        max: number(&signal.max),
        unit: signal.unit.clone(),
        receivers: signal
            .receivers
            .iter()
            .filter(|r| r.as_str() != "Vector__XXX")
            .cloned()
            .collect(),
        choices,
        comment: dbc
            .signal_comment(message.id, &signal.name)
            .map(str::to_string),
        multiplexing: Multiplexing::Plain,
        layout,
    })
}

/// Simple multiplexing (`M`, `mN`) and extended (`mNM`, `SG_MUL_VAL_`), checked for a
/// multiplexor that is there and for cycles.
fn resolve_multiplexing(
    dbc: &Dbc,
    message: &can_dbc::Message,
    signals: &mut [Signal],
    text: &str,
) -> Result<(), DbcError> {
    let index_of = |name: &str| message.signals.iter().position(|s| s.name == name);
    let at = || line_of(text, &format!("BO_ {} {}", message.id.raw(), message.name));
    let simple: Vec<usize> = message
        .signals
        .iter()
        .enumerate()
        .filter(|(_, s)| s.multiplexer_indicator == MultiplexIndicator::Multiplexor)
        .map(|(i, _)| i)
        .collect();
    let extended: Vec<_> = dbc
        .extended_multiplex
        .iter()
        .filter(|e| e.message_id == message.id)
        .collect();
    for (index, signal) in message.signals.iter().enumerate() {
        let (value, selects) = match signal.multiplexer_indicator {
            MultiplexIndicator::Plain => continue,
            MultiplexIndicator::Multiplexor => {
                signals[index].multiplexing = Multiplexing::Multiplexor;
                continue;
            }
            MultiplexIndicator::MultiplexedSignal(v) => (v, false),
            MultiplexIndicator::MultiplexorAndMultiplexedSignal(v) => (v, true),
        };
        let mapped = extended.iter().find(|e| e.signal_name == signal.name);
        let (multiplexor, values) = match mapped {
            Some(e) => {
                let by = index_of(&e.multiplexor_signal_name).ok_or_else(|| DbcError::Invalid {
                    line: line_of(text, &format!("SG_MUL_VAL_ {}", message.id.raw())),
                    what: format!(
                        "signal {}.{} is multiplexed by {}, which the message does not have",
                        message.name, signal.name, e.multiplexor_signal_name
                    ),
                })?;
                let values = e
                    .mappings
                    .iter()
                    .map(|m| m.min_value..=m.max_value)
                    .collect();
                (by, values)
            }
            None => match simple.as_slice() {
                [by] => (*by, vec![value..=value]),
                [] => {
                    return Err(DbcError::Invalid {
                        line: at(),
                        what: format!(
                            "signal {}.{} is multiplexed (m{value}) but the message has no multiplexor (M)",
                            message.name, signal.name
                        ),
                    });
                }
                _ => {
                    return Err(DbcError::Invalid {
                        line: at(),
                        what: format!(
                            "signal {}.{} is multiplexed (m{value}) and the message has several multiplexors without SG_MUL_VAL_ to say which",
                            message.name, signal.name
                        ),
                    });
                }
            },
        };
        if multiplexor == index {
            return Err(DbcError::Invalid {
                line: at(),
                what: format!(
                    "signal {}.{} is multiplexed by itself",
                    message.name, signal.name
                ),
            });
        }
        signals[index].multiplexing = Multiplexing::Multiplexed {
            multiplexor,
            values,
            selects,
        };
    }
    // A chain of multiplexors must end at one that is always sent.
    for start in 0..signals.len() {
        let mut at_signal = start;
        let mut steps = 0;
        while let Multiplexing::Multiplexed { multiplexor, .. } = signals[at_signal].multiplexing {
            steps += 1;
            if steps > signals.len() {
                return Err(DbcError::Invalid {
                    line: at(),
                    what: format!(
                        "message {}: the multiplexors of {} select each other in a circle",
                        message.name, signals[start].name
                    ),
                });
            }
            at_signal = multiplexor;
        }
    }
    Ok(())
}
