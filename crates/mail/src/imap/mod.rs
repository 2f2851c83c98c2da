//! The IMAP side of the notifier, sans-IO: a [`Framer`] that bounds what the server may send
//! before anything parses it, and a [`Poll`]: one look at the mailbox (log in, find the new
//! mails, fetch the first bytes of each) driven by bytes and time. imap-codec parses the
//! responses; the adapter in `buslab mail` owns the socket, TLS and the clock.

mod command;
mod framer;
mod session;

pub use command::Unsendable;
pub use framer::{FrameError, Framer, Limits};
pub use session::{Event, Outcome, Poll, PollConfig, PollError, Security, Step, Watermark};

/// Bytes of a message's header read at most to find `From:` and `Subject:` (a mail's header
/// with its `Received:` lines is a few kilobytes; 64 KiB is generous).
pub const HEADER_ALLOWANCE: u32 = 64 * 1024;

/// The bytes of a mail fetched (`BODY.PEEK[]<0.N>`) to make a text of `text_limit` bytes: the
/// header allowance and twice the limit (CRLF line ends become LF: the text of N bytes of body
/// is at least N/2 bytes).
pub fn fetch_bytes(text_limit: usize) -> u32 {
    let text_limit = u32::try_from(text_limit).unwrap_or(u32::MAX);
    HEADER_ALLOWANCE.saturating_add(text_limit.saturating_mul(2))
}

/// The largest fetch for the largest `--limit` (65 536): what [`Limits::DEFAULT`]'s literal
/// cap must allow.
pub const FETCH_MAX: u32 = HEADER_ALLOWANCE + 2 * 65536;

const _: () = assert!(FETCH_MAX as u64 <= Limits::DEFAULT.literal);
