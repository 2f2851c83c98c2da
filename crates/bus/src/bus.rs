//! What a bus gives and takes, in the spirit of python-can: timestamped messages and error
//! frames, receive filters by ID and mask, the error state, and why an operation failed.

use std::fmt;
use std::time::Duration;

use buslab_can::{FdFrame, Frame, Id, Timestamp};

use crate::error_frame::ErrorFrame;
pub use buslab_can::controller::ErrorState;

/// Now on the wall clock, since the Unix epoch (the epoch itself if the clock is set before it).
pub fn wall_clock() -> Timestamp {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(Timestamp::EPOCH, Timestamp::since_epoch)
}

/// Received by this interface, or sent by it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    Rx,
    Tx,
}

/// What happened on a bus: a frame (classic or FD), or an error frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Record {
    Frame(Frame),
    /// A CAN FD frame: from a log, or an adapter that speaks FD. Never on buslab's
    /// bit-level bus, which is classic CAN.
    Fd(FdFrame),
    Error(ErrorFrame),
}

/// A frame or an error frame with its time, channel and direction: what a bus gives, a log
/// holds and a screen shows (python-can's `can.Message`). `R` is [`Record`] (a frame or an
/// error frame: [`CanBus::recv_event`](crate::CanBus::recv_event), logs) or [`Frame`]
/// ([`CanBus::recv`](crate::CanBus::recv), which gives frames only).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Message<R = Record> {
    /// When it happened: since the Unix epoch for wall-clock sources, since the start for
    /// simulations and relative logs.
    pub at: Timestamp,
    /// The interface or channel name (`vcan0`, `can1`).
    pub channel: String,
    /// Received or sent; `None` when a log does not say (candump without `-x`).
    pub direction: Option<Direction>,
    pub record: R,
}

impl Message<Frame> {
    /// A received frame.
    pub fn rx(at: Timestamp, channel: impl Into<String>, frame: Frame) -> Self {
        Self {
            at,
            channel: channel.into(),
            direction: Some(Direction::Rx),
            record: frame,
        }
    }

    /// The same, as a frame or an error frame.
    pub fn into_record(self) -> Message {
        Message {
            at: self.at,
            channel: self.channel,
            direction: self.direction,
            record: Record::Frame(self.record),
        }
    }
}

impl From<Message<Frame>> for Message {
    fn from(m: Message<Frame>) -> Self {
        m.into_record()
    }
}

impl Message {
    /// A CAN FD frame, received.
    pub fn fd(at: Timestamp, channel: impl Into<String>, frame: FdFrame) -> Self {
        Self {
            at,
            channel: channel.into(),
            direction: Some(Direction::Rx),
            record: Record::Fd(frame),
        }
    }

    /// An error frame, received.
    pub fn error(at: Timestamp, channel: impl Into<String>, error: ErrorFrame) -> Self {
        Self {
            at,
            channel: channel.into(),
            direction: Some(Direction::Rx),
            record: Record::Error(error),
        }
    }

    /// The frame, if this is one (not an error frame).
    pub fn frame(&self) -> Option<&Frame> {
        match &self.record {
            Record::Frame(f) => Some(f),
            Record::Fd(_) | Record::Error(_) => None,
        }
    }

    /// The FD frame, if this is one.
    pub fn fd_frame(&self) -> Option<&FdFrame> {
        match &self.record {
            Record::Fd(f) => Some(f),
            Record::Frame(_) | Record::Error(_) => None,
        }
    }

    /// The error frame, if this is one.
    pub fn error_frame(&self) -> Option<&ErrorFrame> {
        match &self.record {
            Record::Frame(_) | Record::Fd(_) => None,
            Record::Error(e) => Some(e),
        }
    }

    /// The frame with its time, channel and direction, if this is one.
    pub fn into_frame(self) -> Option<Message<Frame>> {
        match self.record {
            Record::Frame(frame) => Some(Message {
                at: self.at,
                channel: self.channel,
                direction: self.direction,
                record: frame,
            }),
            Record::Fd(_) | Record::Error(_) => None,
        }
    }
}

impl Default for Message {
    /// An empty error frame at the epoch on no channel: a buffer for a log reader's
    /// `read_into`.
    fn default() -> Self {
        Self {
            at: Timestamp::EPOCH,
            channel: String::new(),
            direction: None,
            record: Record::Error(ErrorFrame::default()),
        }
    }
}

impl<R> Message<R> {
    /// Received, or not said (python-can's `is_rx` defaults to true).
    pub fn is_rx(&self) -> bool {
        self.direction != Some(Direction::Tx)
    }
}

impl fmt::Display for Record {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Record::Frame(frame) => frame.fmt(f),
            Record::Fd(frame) => frame.fmt(f),
            Record::Error(error) => error.fmt(f),
        }
    }
}

impl Record {
    /// The ID of a frame, classic or FD (an error frame has none).
    pub fn id(&self) -> Option<Id> {
        match self {
            Record::Frame(f) => Some(f.id()),
            Record::Fd(f) => Some(f.id()),
            Record::Error(_) => None,
        }
    }

    /// The data of a frame, classic or FD (empty for a remote frame; none for an error frame).
    pub fn payload(&self) -> Option<&[u8]> {
        match self {
            Record::Frame(f) => Some(f.payload()),
            Record::Fd(f) => Some(f.payload()),
            Record::Error(_) => None,
        }
    }
}

/// candump-like: `(1700000000.123456) can0 123#DEADBEEF`, with ` TX` for sent frames.
impl<R: fmt::Display> fmt::Display for Message<R> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "({}) {} {}", self.at, self.channel, self.record)?;
        if self.direction == Some(Direction::Tx) {
            f.write_str(" TX")?;
        }
        Ok(())
    }
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
        self.matches_id(frame.id())
    }

    /// Whether a frame with this ID (classic or FD) passes.
    pub fn matches_id(&self, id: Id) -> bool {
        (id.as_raw() ^ self.id) & self.mask == 0
            && self.extended.is_none_or(|ext| ext == id.is_extended())
    }
}

/// Software filtering: whether any filter matches (an empty list matches everything).
pub fn matches_any(filters: &[Filter], frame: &Frame) -> bool {
    filters.is_empty() || filters.iter().any(|f| f.matches(frame))
}

/// Software filtering of an ID (a classic or an FD frame's): whether any filter matches.
pub fn matches_any_id(filters: &[Filter], id: Id) -> bool {
    filters.is_empty() || filters.iter().any(|f| f.matches_id(id))
}

/// Whether a bus carries CAN FD frames ([`CanBus::fd_support`](crate::CanBus::fd_support)).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FdSupport {
    /// FD frames go both ways.
    Carried,
    /// Classic CAN only, for this reason.
    Classic(NoFd),
}

impl FdSupport {
    pub fn carried(&self) -> bool {
        *self == FdSupport::Carried
    }

    /// Why the bus carries no FD frames (`None` when it carries them).
    pub fn classic_reason(&self) -> Option<&NoFd> {
        match self {
            FdSupport::Carried => None,
            FdSupport::Classic(why) => Some(why),
        }
    }
}

/// Why a bus carries no CAN FD frames.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum NoFd {
    /// buslab's virtual bus, its engine and its nodes (SJA1000, SLIO) are classic CAN, as the
    /// seed's bench is.
    #[error(
        "buslab's bit-level bus carries no FD frames (its engine, SJA1000 and SLIO nodes are classic CAN)"
    )]
    BitLevelBus,
    /// socketcand's protocol (its master branch, and python-can's client) has no FD frames.
    #[error("socketcand's protocol has no CAN FD frames")]
    Socketcand,
    /// A SocketCAN interface whose MTU is a classic frame's.
    #[error(
        "interface {interface} has MTU {mtu}, classic CAN only (as root, `ip link set {interface} mtu 72` lets an FD-capable interface carry FD frames)"
    )]
    ClassicInterface { interface: String, mtu: u32 },
    /// An SLCAN adapter opened for classic CAN.
    #[error(
        "the adapter was opened for classic CAN (for an FD adapter such as a CANable 2.0 add fd=1 or data_bitrate=N to the slcan: URL)"
    )]
    ClassicAdapter,
    /// An SLCAN adapter served on a classic bus.
    #[error("the adapter's bus is classic CAN")]
    ClassicAdapterBus,
    /// A backend that has not said it carries FD.
    #[error("this backend sends classic CAN frames only")]
    Backend,
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
    /// A CAN FD frame offered to a bus that carries classic frames only: the bus and why.
    #[error("{bus} is classic CAN: {why}")]
    ClassicOnly { bus: String, why: NoFd },
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
        let mut m = Message::rx(Timestamp::from_micros(1_500_000), "vcan0", f("123#DEAD"));
        assert_eq!(m.to_string(), "(1.500000) vcan0 123#DEAD");
        m.direction = Some(Direction::Tx);
        assert_eq!(m.to_string(), "(1.500000) vcan0 123#DEAD TX");
        let error = Message::error(m.at, "vcan0", ErrorFrame::decode(0x040, &[]).unwrap());
        assert_eq!(error.to_string(), "(1.500000) vcan0 bus-off");
        assert_eq!(ErrorState::Passive.to_string(), "error-passive");
    }
}
