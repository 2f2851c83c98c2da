//! What a bus gives and takes, in the spirit of python-can: timestamped messages and error
//! frames, receive filters by ID and mask, the error state, and why an operation failed.

use std::fmt;
use std::time::Duration;

use buslab_can::Frame;

use crate::error_frame::ErrorFrame;
pub use buslab_can::controller::ErrorState;

/// A received (or sent, `is_rx = false`) frame with its time and channel, like `can.Message`.
#[derive(Clone, Debug, PartialEq)]
pub struct Message {
    /// Seconds (Unix epoch for wall-clock sources; virtual seconds for simulations).
    pub timestamp: f64,
    pub channel: String,
    pub frame: Frame,
    /// `true` for a received frame, `false` for one this node sent.
    pub is_rx: bool,
}

impl Message {
    /// A received message.
    pub fn rx(timestamp: f64, channel: impl Into<String>, frame: Frame) -> Self {
        Self {
            timestamp,
            channel: channel.into(),
            frame,
            is_rx: true,
        }
    }
}

/// candump-like: `(1700000000.123456) can0 123#DEADBEEF`, with ` TX` for sent frames.
impl fmt::Display for Message {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "({:.6}) {} {}", self.timestamp, self.channel, self.frame)?;
        if !self.is_rx {
            f.write_str(" TX")?;
        }
        Ok(())
    }
}

/// An error frame with its time and channel (python-can's `Message` with `is_error_frame`).
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorMessage {
    /// Seconds, as [`Message::timestamp`].
    pub timestamp: f64,
    pub channel: String,
    pub error: ErrorFrame,
}

/// What a bus's `recv_event` gives: a frame or an error frame.
#[derive(Clone, Debug, PartialEq)]
pub enum BusEvent {
    Frame(Message),
    Error(ErrorMessage),
}

/// A receive filter with python-can semantics: a frame matches when
/// `(frame_id ^ id) & mask == 0` and, if `extended` is `Some`, the ID format agrees.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Filter {
    pub id: u32,
    pub mask: u32,
    /// `Some(true)`: extended IDs only; `Some(false)`: standard IDs only; `None`: both.
    pub extended: Option<bool>,
}

impl Filter {
    /// Matches no frame (a client that only sends need not keep what it receives): bit 31
    /// is never set in a 29-bit ID.
    pub const NONE: Self = Self {
        id: 1 << 31,
        mask: 1 << 31,
        extended: None,
    };

    /// Matches exactly one standard ID.
    pub const fn standard(id: u16) -> Self {
        Self {
            id: id as u32,
            mask: 0x7FF,
            extended: Some(false),
        }
    }

    /// Matches exactly one extended ID.
    pub const fn extended(id: u32) -> Self {
        Self {
            id,
            mask: 0x1FFF_FFFF,
            extended: Some(true),
        }
    }

    pub fn matches(&self, frame: &Frame) -> bool {
        let id = frame.id();
        (id.as_raw() ^ self.id) & self.mask == 0
            && self.extended.is_none_or(|ext| ext == id.is_extended())
    }
}

/// Software filtering: whether any filter matches (an empty list matches everything).
pub fn matches_any(filters: &[Filter], frame: &Frame) -> bool {
    filters.is_empty() || filters.iter().any(|f| f.matches(frame))
}

/// Why a bus operation failed.
#[derive(Debug, thiserror::Error)]
pub enum BusError {
    #[error("the bus is closed")]
    Closed,
    #[error("transmit queue full: {0}")]
    QueueFull(String),
    /// The controller or the server behind the bus refused: the typed reason (a driver's
    /// error, or the text a socketcand server sent with `< error … >`).
    #[error("the controller refused the frame: {0}")]
    Rejected(Reason),
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// The other side broke its protocol: the codec's typed error.
    #[error("protocol error: {0}")]
    Protocol(Reason),
    /// `what` names what did not come: "answer to < buslab_flush >".
    #[error("no {what} within {}", Human(*after))]
    Timeout { what: String, after: Duration },
    #[error("{backend} cannot deliver {what}")]
    Unsupported { what: &'static str, backend: String },
    /// A limit of the bus refused a fault: too many on the wire, or too many from this client
    /// for now (then with the time until the next is allowed).
    #[error("{0}")]
    FaultRefused(crate::admin::FaultLimit),
    /// What a backend could not fit in the variants above, typed by the backend.
    #[error("{0}")]
    Other(Reason),
}

/// A backend's own error inside a [`BusError`], kept typed (`downcast_ref` finds it again);
/// text (`"…".into()`) where the reason is a peer's words.
pub type Reason = Box<dyn std::error::Error + Send + Sync>;

/// `2.06 s`, `350 ms`: three significant digits and a unit, for messages.
pub use buslab_device::Human;

#[cfg(test)]
mod tests {
    use super::*;

    fn f(s: &str) -> Frame {
        s.parse().unwrap()
    }

    #[test]
    fn filters_match_like_python_can() {
        let range = Filter {
            id: 0x120,
            mask: 0x7F0,
            extended: None,
        };
        assert!(range.matches(&f("123#")));
        assert!(range.matches(&f("12F#R")));
        assert!(!range.matches(&f("130#")));
        assert!(
            range.matches(&f("00000123#")),
            "no format given: both match"
        );
        let sff_only = Filter {
            extended: Some(false),
            ..range
        };
        assert!(!sff_only.matches(&f("00000123#")));
        assert!(Filter::extended(0x123).matches(&f("00000123#")));
        assert!(!Filter::extended(0x123).matches(&f("123#")));
        assert!(!Filter::standard(0x123).matches(&f("00000123#")));
        // Bits above the mask are ignored, also for IDs wider than the filter's.
        let low_byte = Filter {
            id: 0x42,
            mask: 0xFF,
            extended: None,
        };
        assert!(low_byte.matches(&f("1ABCDE42#")));
    }

    #[test]
    fn an_empty_filter_list_accepts_everything_and_filters_are_ored() {
        assert!(matches_any(&[], &f("7FF#")));
        let filters = [Filter::standard(0x100), Filter::standard(0x200)];
        assert!(matches_any(&filters, &f("200#")));
        assert!(!matches_any(&filters, &f("300#")));
        for frame in ["000#", "7FF#R", "00000000#", "1FFFFFFF#11"] {
            assert!(!matches_any(&[Filter::NONE], &f(frame)), "{frame}");
        }
    }

    #[test]
    fn messages_print_like_candump() {
        let mut m = Message::rx(1.5, "vcan0", f("123#DEAD"));
        assert_eq!(m.to_string(), "(1.500000) vcan0 123#DEAD");
        m.is_rx = false;
        assert_eq!(m.to_string(), "(1.500000) vcan0 123#DEAD TX");
        assert_eq!(ErrorState::Passive.to_string(), "error-passive");
    }
}
