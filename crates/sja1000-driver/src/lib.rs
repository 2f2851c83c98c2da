//! The SJA1000 driver: the software a CPU runs to drive its SJA1000 (the seed's CANAPI and
//! PowerPC init, the recipes of Linux's `sja1000.c`), apart from any host or transport.
//!
//! It touches the chip only through register reads and writes ([`RegisterAccess`]), so the
//! same driver runs against the register model of `buslab-sja1000` (which implements the
//! trait), a chip shared with the thread that steps the bus ([`SharedChip`]), or a data bus
//! with nothing on it ([`NoChip`]). Nodes of both layers use it: the PowerPC node
//! (`buslab-ppc`) and the host library's bus node and manager (`buslab-canbus`, which
//! re-exports this crate under its old paths).
//!
//! - [`regs`]: register access ([`RegisterAccess`]), the seam between a driver and a chip.
//! - [`config`]: SJA1000 configuration with defaults and validation ([`Sja1000Config`]).
//! - [`driver`]: the driver, BasicCAN and PeliCAN behind one interface ([`Sja1000Driver`]).
//! - [`decode`]: status, error-code and arbitration-lost registers decoded into words.
//!
//! Two drivers on a wired-AND bus of two model chips, stepped bit by bit:
//!
//! ```
//! use buslab_can::Level;
//! use buslab_sja1000_driver::{DriverEvent, Sja1000Config, Sja1000Driver, shared_chip};
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
#![forbid(unsafe_code)]

pub mod config;
pub mod decode;
pub mod driver;
pub mod regs;

pub use config::{
    AcceptanceFilter, BusOffRecovery, ClockOut, ConfigError, ControllerMode, ControllerPart,
    ControllerSettings, InterruptEnables, Sja1000Config, Timing, TimingSetting,
};
pub use decode::{Alc, Ecc, ErrorRegisters, RegisterDump, Status};
pub use driver::{ControllerState, DriverError, DriverEvent, Sja1000Driver, TxFailure, TxMode};
pub use regs::{NoChip, RegisterAccess, SharedChip, shared_chip};

/// The chip's own types a configuration names, so a user needs no further crate for them.
pub use buslab_sja1000::{BitTiming, CanMode, FilterMode};
