//! What can be wrong with a DBC file or with values to encode.

use thiserror::Error;

/// A DBC file refused, with the line (1-based) it is on when it is known.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DbcError {
    /// The file is neither UTF-8 nor Windows-1252 text.
    #[error("the DBC file is not text (neither UTF-8 nor Windows-1252)")]
    NotText,
    /// The grammar failed at a line and column.
    #[error("line {line}, column {column}: {expected}")]
    Syntax {
        line: usize,
        column: usize,
        /// What the grammar expected there.
        expected: String,
    },
    /// The grammar matched but the content does not hold together (a signal out of its
    /// message, a size a value type cannot have, a multiplexor that is not there).
    #[error("{}{what}", line.map(|l| format!("line {l}: ")).unwrap_or_default())]
    Invalid { line: Option<usize>, what: String },
}

/// Values that cannot be put into a message.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EncodeError {
    #[error("message {message} has no signal {signal} (its signals: {known})")]
    UnknownSignal {
        message: String,
        signal: String,
        known: String,
    },
    #[error("{message}.{signal} = {value} is out of range: allowed {min} ..= {max}")]
    OutOfRange {
        message: String,
        signal: String,
        value: f64,
        min: f64,
        max: f64,
    },
    #[error("{message}.{signal} is not sent when {multiplexor} = {selector}")]
    InactiveBranch {
        message: String,
        signal: String,
        multiplexor: String,
        selector: u64,
    },
    #[error("{message}.{signal} = {value}: not a number")]
    NotANumber {
        message: String,
        signal: String,
        value: f64,
    },
}
