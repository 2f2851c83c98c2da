//! buslab's bus vocabulary: what every bus, log and view speaks, with no model or driver
//! behind it (it depends on `buslab-can`, on `buslab-chips` for the SJA1000 and SLIO facts its
//! values are in terms of, and on `buslab-device` for [`Human`]).
//!
//! - [`bus`]: frames and error frames with their time, channel and direction ([`Message`],
//!   [`Record`], [`Direction`], [`Timestamp`]), receive filters ([`Filter`]), typed errors
//!   ([`BusError`]).
//! - [`state`]: a controller's error state, python-can's ([`ErrorState`]) and Linux's
//!   ([`ControllerState`]).
//! - [`error_frame`]: SocketCAN error frames as typed values ([`ErrorFrame`]), decoded,
//!   encoded, and in can-utils' words.
//! - [`admin`]: typed values of a bus that has more to tell than frames: nodes, their status
//!   and registers, counters, timing, faults on the wire and the limits that refuse them,
//!   demo boards.
//! - [`decode`]: SJA1000 status, error-code and arbitration-lost registers in words
//!   ([`Status`], [`Ecc`], [`Alc`], [`RegisterDump`]).
//! - [`settings`]: what a host asks of its own controller ([`ControllerSettings`]).
//! - [`interface`]: the traits a bus implements, [`CanBus`] and [`BusAdmin`].
//!
//! ```
//! use buslab_bus::{ErrorFrame, Filter, Message, Timestamp, matches_any};
//!
//! let message = Message::rx(Timestamp::from_micros(1_500_000), "vcan0", "123#DEAD".parse()?);
//! assert!(matches_any(&[Filter::standard(0x123)], &message.record));
//! assert_eq!(message.to_string(), "(1.500000) vcan0 123#DEAD");
//! assert_eq!(ErrorFrame::decode(0x040, &[])?.to_string(), "bus-off");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod admin;
pub mod bus;
pub mod decode;
pub mod error_frame;
pub mod interface;
pub mod settings;
pub mod state;

pub use admin::{
    BadProbability, BadSwitch, BadVolts, BoardInput, BoardState, BoardSwitch, BoardVolts,
    BusSummary, FaultLimit, NodeCounters, NodeInfo, NodeRef, NodeRegisters, NodeStatus, NodeTiming,
    Probability, TxReport, WireFault, switch_bits,
};
pub use bus::{
    BusError, Direction, FdSupport, Filter, Human, Message, NoFd, Reason, Record, matches_any,
    matches_any_id, wall_clock,
};
pub use buslab_can::Timestamp;
pub use buslab_can::controller::ErrorState;
pub use decode::{Alc, Ecc, ErrorRegisters, RegisterDump, Status};
pub use error_frame::{
    ArbitrationBit, CanError, CapturedBusError, ControllerProblems, ErrorCounters, ErrorFrame,
    ErrorFrameError, ProtocolLocation, ProtocolViolation, TransceiverStatus,
};
pub use interface::{BusAdmin, CanBus, RecvWaker};
pub use settings::{
    AcceptanceFilter, BusOffRecovery, ClockOut, ControllerMode, ControllerPart, ControllerSettings,
    TimingSetting,
};
pub use state::ControllerState;

/// The chip facts a bus's values are in terms of, so a user of a bus needs no other crate.
pub use buslab_chips::sja1000::{BitTiming, CanMode, FilterMode};
pub use buslab_chips::slio::SlioId;
