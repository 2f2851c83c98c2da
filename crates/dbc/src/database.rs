//! A DBC file read into messages and signals: the file's items (see `source`) resolved
//! (comments, value tables, value types, multiplexing, attributes) and checked, once.

use std::borrow::Cow;
use std::collections::HashMap;
use std::ops::RangeInclusive;
use std::time::Duration;

use buslab_can::Id;
use can_dbc::{
    AttributeValue, AttributeValueType, MultiplexIndicator, NumericValue, SignalExtendedValueType,
};

use crate::error::DbcError;
use crate::layout::Layout;
use crate::message::Message;
use crate::signal::{ByteOrder, Codec, Multiplexing, Signal, ValueKind};
use crate::source::{RawId, Source, SourceMessage};

/// The largest payload a message can declare (CAN FD).
const MAX_LENGTH: u64 = 64;
/// Vector's pseudo-message that holds signals not placed in any message.
const INDEPENDENT_SIGNALS: &str = "VECTOR__INDEPENDENT_SIG_MSG";

/// The messages of a DBC file, found by ID or by name.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Database {
    messages: Vec<Message>,
    /// Message index by standard ID (`NONE` where there is none): one load per frame.
    standard: Vec<u32>,
    /// (extended ID, message index), sorted by ID.
    extended: Vec<(u32, u32)>,
    nodes: Vec<String>,
}

const NONE: u32 = u32::MAX;

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

    /// A DBC file's text. Line ends are `\n`, `\r\n` or `\r` (comments keep `\n`).
    pub fn parse(text: &str) -> Result<Self, DbcError> {
        let text = if text.contains('\r') {
            Cow::Owned(text.replace("\r\n", "\n").replace('\r', "\n"))
        } else {
            Cow::Borrowed(text)
        };
        let source = Source::parse(&text)?;
        let mut messages = Vec::with_capacity(source.messages.len());
        let mut by_id = HashMap::with_capacity(source.messages.len());
        for message in &source.messages {
            if message.message.name == INDEPENDENT_SIGNALS {
                continue;
            }
            let line = message.line;
            let message = resolve_message(&source, message)?;
            if let Some(&first) = by_id.get(&message.id) {
                let first: &Message = &messages[first];
                return Err(DbcError::Invalid {
                    line: Some(line),
                    what: format!(
                        "message {}: ID {} ({}) is {}'s already",
                        message.name,
                        message.id.as_raw(),
                        message.id,
                        first.name
                    ),
                });
            }
            by_id.insert(message.id, messages.len());
            messages.push(message);
        }
        let mut standard = Vec::new();
        let mut extended = Vec::new();
        for (index, message) in messages.iter().enumerate() {
            match message.id {
                Id::Standard(_) => {
                    standard.resize(0x800, NONE);
                    standard[message.id.as_raw() as usize] = index as u32;
                }
                Id::Extended(_) => extended.push((message.id.as_raw(), index as u32)),
            }
        }
        extended.sort_unstable();
        Ok(Self {
            messages,
            standard,
            extended,
            nodes: source.nodes.iter().map(|n| source.node_name(n)).collect(),
        })
    }

    /// Its messages, in the file's order.
    pub fn messages(&self) -> &[Message] {
        &self.messages
    }
    /// The message with this ID.
    #[inline]
    pub fn message(&self, id: Id) -> Option<&Message> {
        let index = match id {
            Id::Standard(_) => *self.standard.get(id.as_raw() as usize)?,
            Id::Extended(_) => {
                let raw = id.as_raw();
                let at = self.extended.binary_search_by_key(&raw, |e| e.0).ok()?;
                self.extended[at].1
            }
        };
        self.messages.get(index as usize)
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

/// The message ID a file's number stands for. Bit 31 flags an extended ID; a number above
/// 0x7FF without it can only be an extended ID written without the flag (opendbc writes its
/// 29-bit IDs so), and is taken as one.
fn message_id(raw: RawId) -> Option<Id> {
    const EXTENDED_FLAG: RawId = 1 << 31;
    if raw & EXTENDED_FLAG != 0 {
        Id::extended(u32::try_from(raw & !EXTENDED_FLAG).ok()?).ok()
    } else if raw <= 0x7FF {
        Id::standard(raw as u16).ok()
    } else {
        Id::extended(u32::try_from(raw).ok()?).ok()
    }
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

/// A message attribute: its value for the message, else the default, when the file defines
/// the attribute (`BA_DEF_ BO_`), as cantools reads GenMsgCycleTime and VFrameFormat.
fn message_attribute<'a>(source: &'a Source, id: RawId, name: &str) -> Option<&'a AttributeValue> {
    source.message_attribute_types.get(name)?;
    source
        .message_attributes
        .get(&(id, name.to_string()))
        .or_else(|| source.defaults.get(name))
}

/// Whether the message is sent as CAN FD: `VFrameFormat` (its value, else its default) names
/// a `…CAN_FD` format. An INT `VFrameFormat` indexes Vector's list of formats, as in cantools.
fn frame_format_is_fd(source: &Source, id: RawId) -> bool {
    const VECTOR_FORMATS: [&str; 16] = [
        "StandardCAN",
        "ExtendedCAN",
        "reserved",
        "J1939PG",
        "reserved",
        "reserved",
        "reserved",
        "reserved",
        "reserved",
        "reserved",
        "reserved",
        "reserved",
        "reserved",
        "reserved",
        "StandardCAN_FD",
        "ExtendedCAN_FD",
    ];
    let Some(kind) = source.message_attribute_types.get("VFrameFormat") else {
        return false;
    };
    let Some(value) = message_attribute(source, id, "VFrameFormat") else {
        return false;
    };
    let name = match (kind, value) {
        (_, AttributeValue::String(name)) => Some(name.as_str()),
        (AttributeValueType::Enum(names), v) => attribute_number(v)
            .and_then(|i| names.get(i as usize))
            .map(String::as_str),
        (_, v) => attribute_number(v)
            .and_then(|i| VECTOR_FORMATS.get(i as usize))
            .copied(),
    };
    name.is_some_and(|n| n.ends_with("CAN_FD"))
}

fn resolve_message(source: &Source, at: &SourceMessage) -> Result<Message, DbcError> {
    let message = &at.message;
    let invalid = |what: String| DbcError::Invalid {
        line: Some(at.line),
        what: format!("message {}: {what}", message.name),
    };
    let id = message_id(at.raw_id).ok_or_else(|| {
        invalid(format!(
            "ID {} is neither a standard (up to 0x7FF) nor an extended ID (bit 31 and up to 0x1FFFFFFF)",
            at.raw_id
        ))
    })?;
    if message.size > MAX_LENGTH {
        return Err(invalid(format!(
            "{} bytes long: at most {MAX_LENGTH} (CAN FD)",
            message.size
        )));
    }
    // A cycle time of 0 is no cycle time.
    let cycle_time = message_attribute(source, at.raw_id, "GenMsgCycleTime")
        .and_then(attribute_number)
        .filter(|&ms| ms > 0.0 && ms.is_finite())
        .map(|ms| Duration::from_secs_f64(ms / 1000.0));
    let mut senders: Vec<String> = message
        .transmitter
        .iter()
        .map(|n| source.node_name(n))
        .collect();
    for node in source.senders.get(&at.raw_id).into_iter().flatten() {
        let node = source.node_name(node);
        if !senders.contains(&node) && node != "Vector__XXX" {
            senders.push(node);
        }
    }
    let mut signals = Vec::with_capacity(message.signals.len());
    for (signal, &line) in message.signals.iter().zip(&at.signal_lines) {
        signals.push(resolve_signal(source, at, signal, line)?);
    }
    resolve_multiplexing(source, at, &mut signals)?;
    let multiplexed = signals
        .iter()
        .any(|s| matches!(s.multiplexing, Multiplexing::Multiplexed { .. }));
    let name = match source
        .message_attributes
        .get(&(at.raw_id, "SystemMessageLongSymbol".to_string()))
    {
        Some(AttributeValue::String(long)) => long.clone(),
        _ => message.name.clone(),
    };
    Ok(Message {
        id,
        name,
        length: message.size as usize,
        senders,
        cycle_time,
        comment: source.message_comments.get(&at.raw_id).cloned(),
        fd: frame_format_is_fd(source, at.raw_id),
        multiplexed,
        codecs: signals.iter().map(|s| s.codec).collect(),
        signals,
    })
}

fn resolve_signal(
    source: &Source,
    at: &SourceMessage,
    signal: &can_dbc::Signal,
    line: usize,
) -> Result<Signal, DbcError> {
    let message = &at.message;
    let invalid = |what: String| DbcError::Invalid {
        line: Some(line),
        what: format!("signal {}.{}: {what}", message.name, signal.name),
    };
    let key = (at.raw_id, signal.name.clone());
    let kind = match source.value_types.get(&key) {
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
    let byte_order = match signal.byte_order {
        can_dbc::ByteOrder::LittleEndian => ByteOrder::LittleEndian,
        can_dbc::ByteOrder::BigEndian => ByteOrder::BigEndian,
    };
    if signal.start_bit >= 8 * MAX_LENGTH {
        return Err(invalid(format!(
            "start bit {} is past {MAX_LENGTH} bytes",
            signal.start_bit
        )));
    }
    let layout = Layout::new(
        signal.start_bit as u32,
        size as u32,
        byte_order == ByteOrder::BigEndian,
    );
    // As cantools' strict loading: a signal must fit in its message.
    if layout.end() as u64 > message.size {
        return Err(invalid(format!(
            "its bits run past the message's {} bytes (start bit {}, {size} bits, {})",
            message.size,
            signal.start_bit,
            if byte_order == ByteOrder::BigEndian {
                "Motorola"
            } else {
                "Intel"
            }
        )));
    }
    if !signal.factor.is_finite() || signal.factor == 0.0 || !signal.offset.is_finite() {
        return Err(invalid(format!(
            "factor {} and offset {}: a nonzero finite factor and a finite offset",
            signal.factor, signal.offset
        )));
    }
    let attribute = |name: &str| {
        source
            .signal_attributes
            .get(&(at.raw_id, signal.name.clone(), name.to_string()))
    };
    let start_value = match attribute("GenSigStartValue") {
        None => None,
        Some(value) => Some(
            attribute_number(value)
                .ok_or_else(|| invalid(format!("GenSigStartValue {value:?}: a number")))?,
        ),
    };
    let name = match attribute("SystemSignalLongSymbol") {
        Some(AttributeValue::String(long)) => long.clone(),
        _ => signal.name.clone(),
    };
    Ok(Signal {
        name,
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
            .map(|r| source.node_name(r))
            .collect(),
        choices: source.value_tables.get(&key).cloned().unwrap_or_default(),
        comment: source.signal_comments.get(&key).cloned(),
        start_value,
        multiplexing: Multiplexing::Plain,
        codec: Codec {
            layout,
            kind,
            size: size as u32,
            factor: signal.factor,
            offset: signal.offset,
        },
    })
}

/// Simple multiplexing (`M`, `mN`) and extended (`mNM`, `SG_MUL_VAL_`), as cantools reads
/// them. With one multiplexor in the message (one `M` or `mNM`), every other `mN` signal is
/// selected by it, for `N` and for the values `SG_MUL_VAL_` lines give it under that
/// multiplexor. With none or several, the signal's (last) `SG_MUL_VAL_` line says which
/// multiplexor selects it and for which values (an `M` signal too, which makes it a
/// multiplexor selected by another). Checked: the multiplexor is there, no circles.
fn resolve_multiplexing(
    source: &Source,
    at: &SourceMessage,
    signals: &mut [Signal],
) -> Result<(), DbcError> {
    let message = &at.message;
    let index_of = |name: &str| message.signals.iter().position(|s| s.name == name);
    let invalid = |line: usize, what: String| DbcError::Invalid {
        line: Some(line),
        what: format!("message {}: {what}", message.name),
    };
    let multiplexors: Vec<usize> = message
        .signals
        .iter()
        .enumerate()
        .filter(|(_, s)| {
            matches!(
                s.multiplexer_indicator,
                MultiplexIndicator::Multiplexor
                    | MultiplexIndicator::MultiplexorAndMultiplexedSignal(_)
            )
        })
        .map(|(i, _)| i)
        .collect();
    let single = match multiplexors.as_slice() {
        [only] => Some(*only),
        _ => None,
    };
    for index in &multiplexors {
        signals[*index].multiplexing = Multiplexing::Multiplexor;
    }
    for (index, signal) in message.signals.iter().enumerate() {
        let line = at.signal_lines[index];
        let (marked, selects) = match signal.multiplexer_indicator {
            MultiplexIndicator::Plain => continue,
            MultiplexIndicator::Multiplexor => (None, true),
            MultiplexIndicator::MultiplexedSignal(v) => (Some(v), false),
            MultiplexIndicator::MultiplexorAndMultiplexedSignal(_) => (None, true),
        };
        let mapped = source
            .multiplex
            .get(&(at.raw_id, signal.name.clone()))
            .map(Vec::as_slice)
            .unwrap_or_default();
        let ranges_under = |multiplexor: &str| -> Vec<RangeInclusive<u64>> {
            mapped
                .iter()
                .filter(|m| m.multiplex.multiplexor_signal_name == multiplexor)
                .flat_map(|m| m.multiplex.mappings.iter())
                .map(|r| r.min_value..=r.max_value)
                .collect()
        };
        let (multiplexor, mut values) = match single {
            Some(only) if only == index => continue,
            Some(only) => (only, ranges_under(&message.signals[only].name)),
            None => {
                // The last SG_MUL_VAL_ line of the signal names its multiplexor.
                let Some(last) = mapped.last() else {
                    if marked.is_none() {
                        continue; // a multiplexor at the top of the tree
                    }
                    return Err(invalid(
                        line,
                        format!(
                            "signal {} is multiplexed (m{}) but no multiplexor (M) or SG_MUL_VAL_ line says by what",
                            signal.name,
                            marked.unwrap_or_default()
                        ),
                    ));
                };
                let name = &last.multiplex.multiplexor_signal_name;
                let by = index_of(name).ok_or_else(|| {
                    invalid(
                        last.line,
                        format!(
                            "signal {} is multiplexed by {name}, which the message does not have",
                            signal.name
                        ),
                    )
                })?;
                if by == index {
                    return Err(invalid(
                        last.line,
                        format!("signal {} is multiplexed by itself", signal.name),
                    ));
                }
                (by, ranges_under(name))
            }
        };
        if single.is_some()
            && let Some(v) = marked
        {
            values.insert(0, v..=v);
        }
        if values.is_empty() {
            return Err(invalid(
                line,
                format!(
                    "signal {} is multiplexed by {} for no value",
                    signal.name, message.signals[multiplexor].name
                ),
            ));
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
                return Err(invalid(
                    at.line,
                    format!(
                        "the multiplexors of {} select each other in a circle",
                        signals[start].name
                    ),
                ));
            }
            at_signal = multiplexor;
        }
    }
    Ok(())
}
