//! buslab's bus vocabulary: what every bus, log and view speaks, with no model or driver
//! behind it (it depends on `buslab-can` only, and on `buslab-device` for [`Human`]).
//!
//! - [`bus`]: messages and error messages with their time and channel ([`Message`],
//!   [`ErrorMessage`], [`BusEvent`]), receive filters ([`Filter`]), typed errors ([`BusError`]).
//! - [`state`]: a controller's error state, python-can's ([`BusState`]) and Linux's
//!   ([`ControllerState`]).
//! - [`error_frame`]: SocketCAN error frames as typed values ([`ErrorFrame`]), decoded,
//!   encoded, and in can-utils' words.
//! - [`admin`]: typed values of a bus that has more to tell than frames: nodes, counters,
//!   timing, faults on the wire and the limits that refuse them.
//!
//! ```
//! use buslab_bus::{ErrorFrame, Filter, Message, matches_any};
//!
//! let message = Message::rx(1.5, "vcan0", "123#DEAD".parse()?);
//! assert!(matches_any(&[Filter::standard(0x123)], &message.frame));
//! assert_eq!(message.to_string(), "(1.500000) vcan0 123#DEAD");
//! assert_eq!(ErrorFrame::decode(0x040, &[])?.to_string(), "bus-off");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod admin;
pub mod bus;
pub mod error_frame;
pub mod state;

pub use admin::{
    BadProbability, BadSwitch, BoardSwitch, BusSummary, FaultLimit, NodeCounters, NodeInfo,
    NodeRef, NodeTiming, Probability, TxReport, WireFault, switch_bits,
};
pub use bus::{BusError, BusEvent, ErrorMessage, Filter, Human, Message, matches_any};
pub use error_frame::{
    ArbitrationBit, CanError, CapturedBusError, ControllerProblems, ErrorCounters, ErrorFrame,
    ErrorFrameError, ProtocolLocation, ProtocolViolation, TransceiverStatus,
};
pub use state::{BusState, ControllerState};
