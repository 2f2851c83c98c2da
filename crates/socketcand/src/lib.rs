//! The socketcand protocol (TCP, ASCII elements `< … >`), as socketcand and python-can speak it.
//!
//! - [`element`]: splitting a byte stream into elements ([`Deframer`]).
//! - [`command`]: what a client sends ([`Command`]), parsed and formatted.
//! - [`message`]: what a server sends ([`ServerMessage`]), parsed and formatted.
//! - [`server`]: one client connection of a server, sans-IO ([`server::Session`]).
//! - [`reply`]: buslab's extension replies (status, registers, nodes, flush, refusals) typed
//!   both ways.
//! - [`client::inbound`]: the client's receive path, sans-IO ([`Inbound`]).
//! - [`client`]: a [`CanBus`](buslab_bus::CanBus) over a TCP connection ([`SocketcandBus`]),
//!   and a [`BusAdmin`](buslab_bus::BusAdmin) when the server has buslab's extensions.
//!
//! The codec is sans-IO: strings in, values out, and back. buslab's own extensions are
//! commands and replies whose name starts with `buslab_`; a real socketcand answers them with
//! `< error unknown command >`.

pub mod client;
pub mod command;
pub mod controller;
pub mod element;
mod hex;
pub mod message;
pub mod reply;
pub mod server;

pub use client::inbound::Inbound;
pub use client::{ClientError, ClientOptions, SocketcandBus};
pub use command::{Command, NodeRef};
pub use element::{Deframer, ElementError, MAX_ELEMENT};
pub use message::{FormattedFrame, ServerMessage, Timestamp, parse_timestamp};
pub use reply::{
    ReplyError, flushed_reply, nodes_reply, parse_flushed, parse_nodes, parse_refused, parse_regs,
    parse_status, refused_reply, regs_reply, status_fields, status_reply,
};

/// The error from parsing one element.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ProtocolError {
    #[error("empty element: expected a command between < and >")]
    Empty,
    #[error("unknown command {0:?}")]
    UnknownCommand(String),
    #[error("{command}: expected {expected}, got {got:?}")]
    Arguments {
        command: &'static str,
        expected: &'static str,
        got: String,
    },
    #[error("{what} {text:?} is not hexadecimal")]
    BadHex { what: &'static str, text: String },
    #[error("ID {text:?}: {reason}")]
    BadId { text: String, reason: String },
    #[error("DLC {text:?} must be a decimal 0..8")]
    BadDlc { text: String },
    #[error("{count} data bytes given but DLC is {dlc}")]
    DataLength { count: usize, dlc: u8 },
    #[error("byte {text:?} must be 1 or 2 hex digits")]
    BadByte { text: String },
    #[error("timestamp {text:?} must be SECONDS.MICROSECONDS")]
    BadTimestamp { text: String },
}

/// Splits an element's inside into tokens (runs of spaces separate them).
pub(crate) fn tokens(inner: &str) -> Vec<&str> {
    // Room for the longest common element (`send` with 8 data bytes: 11 tokens) at once: a
    // collected iterator of unknown length grew 4 → 8 → 16, two reallocations per frame
    // a sender sends (about 1 000 instructions each frame at `--speed max`).
    let mut tokens = Vec::with_capacity(TOKENS_EXPECTED);
    tokens.extend(inner.split_ascii_whitespace());
    tokens
}

/// Tokens of the longest frame element (`send ID DLC` and 8 data bytes, `frame ID TIME` and
/// 8), rounded up.
const TOKENS_EXPECTED: usize = 16;

/// Replaces the characters an element cannot carry (`<`, `>`, control characters, and
/// anything not ASCII: python-can decodes every read as ASCII and fails on the rest) so a
/// free text fits in `< error … >`.
pub fn sanitize(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '<' => out.push('('),
            '>' => out.push(')'),
            '…' => out.push_str("..."),
            c if c.is_ascii_control() => out.push(' '),
            c if !c.is_ascii() => out.push('?'),
            c => out.push(c),
        }
    }
    out
}
