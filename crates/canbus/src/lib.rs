//! buslab's CAN host library (the successor of the seed's CANAPI).
//!
//! The bus vocabulary ([`Message`], [`Filter`], [`ErrorState`], [`BusError`], [`ErrorFrame`],
//! node status, counters and faults, decoded registers, controller settings, and the
//! [`CanBus`] and [`BusAdmin`] traits) lives in `buslab-bus`, which needs no model; it is
//! re-exported here under the same paths.
//!
//! - [`bus`]: a bus interface in the spirit of python-can's `BusABC` ([`CanBus`]).
//! - [`admin`]: typed node status and registers of buslab's virtual bus, demo boards
//!   ([`BusAdmin`]).
//! - [`regs`]: register access ([`RegisterAccess`]), the seam between a driver and a chip.
//! - [`config`]: SJA1000 configuration with defaults and validation ([`Sja1000Config`]).
//! - [`driver`]: the SJA1000 driver, BasicCAN and PeliCAN behind one interface
//!   ([`Sja1000Driver`]); it touches the chip only through register reads and writes.
//! - [`decode`]: status, error-code and arbitration-lost registers decoded into words.
//! - [`error_frame`]: the SJA1000 driver's events as SocketCAN error frames
//!   ([`error_frame::from_driver_event`]), as Linux's driver sends them.
//! - [`manager`]: the single owner of a driver: one thread, listeners and requests
//!   ([`Manager`], [`ManagerHandle`]).
//! - [`node`]: an SJA1000 with the CPU running this driver as a node of the bus engine
//!   ([`node::Sja1000Node`]), for the virtual bus's clients and scenario files.
//! - [`slio`]: SLIOs from any bus ([`slio::SlioHost`], CANAPI's `SlIo` class).
//! - [`file`](mod@file): the file protocol for data longer than 8 bytes (SPEC N5).
//!
//! Two drivers on a wired-AND bus of two model chips, stepped bit by bit:
//!
//! ```
//! use buslab_can::Level;
//! use buslab_canbus::{DriverEvent, Sja1000Config, Sja1000Driver, shared_chip};
//!
//! let chips = [shared_chip(), shared_chip()];
//! let mut a = Sja1000Driver::new(chips[0].clone());
//! let mut b = Sja1000Driver::new(chips[1].clone());
//! a.init(&Sja1000Config::default())?;
//! b.init(&Sja1000Config::basic_can())?;
//! a.send(&"123#CAFE".parse()?)?;
//! let mut received = Vec::new();
//! while received.is_empty() {
//!     let wire = chips.iter().fold(Level::Recessive, |bus, chip| {
//!         bus.and(chip.lock().unwrap().output())
//!     });
//!     chips.iter().for_each(|chip| chip.lock().unwrap().sample(wire));
//!     for event in b.poll() {
//!         if let DriverEvent::Received(frame) = event {
//!             received.push(frame.to_string());
//!         }
//!     }
//! }
//! assert_eq!(received, ["123#CAFE"]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod admin;
pub mod bus;
pub mod config;
pub mod decode;
pub mod driver;
pub mod error_frame;
pub mod file;
pub mod manager;
pub mod node;
pub mod regs;
pub mod slio;

pub use admin::{
    BadProbability, BusAdmin, BusSummary, NodeCounters, NodeInfo, NodeRef, NodeRegisters,
    NodeStatus, NodeTiming, Probability, TxReport, WireFault,
};
pub use bus::{
    BusError, CanBus, Direction, ErrorState, Filter, Message, Record, Timestamp, wall_clock,
};
pub use config::{
    AcceptanceFilter, BusOffRecovery, ClockOut, ConfigError, ControllerMode, ControllerPart,
    ControllerSettings, InterruptEnables, Sja1000Config, Timing, TimingSetting,
};
pub use decode::{Alc, Ecc, ErrorRegisters, RegisterDump, Status};
pub use driver::{ControllerState, DriverError, DriverEvent, Sja1000Driver, TxFailure, TxMode};
pub use error_frame::{
    CanError, ControllerProblems, ErrorCounters, ErrorFrame, ErrorFrameError, ProtocolLocation,
    ProtocolViolation, TransceiverStatus,
};
pub use file::{FileAssembler, FileError, FileFrames, FileReadError, FileReceiver, Received};
pub use manager::{
    Confirmation, Manager, ManagerBus, ManagerConfig, ManagerError, ManagerHandle, SendError,
    Snapshot,
};
pub use regs::{NoChip, RegisterAccess, SharedChip, shared_chip};

/// Re-exported so users need not depend on the model crates for the basic types.
pub use buslab_can::{Frame, Id};
pub use buslab_sja1000::{BitTiming, CanMode, FilterMode};
