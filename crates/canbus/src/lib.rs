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
//! - [`regs`], [`config`], [`driver`], [`decode`]: the SJA1000 driver, its register access
//!   ([`RegisterAccess`]) and configuration ([`Sja1000Config`]); they live in
//!   `buslab-sja1000-driver` (the PowerPC node, a model, runs the same driver) and are
//!   re-exported here under their old paths.
//! - [`error_frame`]: the SJA1000 driver's events as SocketCAN error frames
//!   ([`error_frame::from_driver_event`]), as Linux's driver sends them.
//! - [`manager`]: the single owner of a driver: one thread, listeners and requests
//!   ([`Manager`], [`ManagerHandle`]).
//! - [`node`]: an SJA1000 with the CPU running this driver as a node of the bus engine
//!   ([`node::Sja1000Node`]), for the virtual bus's clients and scenario files.
//! - [`slio`]: SLIOs from any bus ([`slio::SlioHost`], CANAPI's `SlIo` class).
//! - [`file`](mod@file): the file protocol for data longer than 8 bytes (SPEC N5).
//!
//! How two drivers on a wired-AND bus of model chips exchange a frame is shown in
//! `buslab-sja1000-driver`'s documentation.

pub mod admin;
pub mod bus;
pub mod error_frame;
pub mod file;
pub mod manager;
pub mod node;
pub mod slio;

/// The driver and its vocabulary, under the paths they had when they lived here.
pub use buslab_sja1000_driver::{config, decode, driver, regs};

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
