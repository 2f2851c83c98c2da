//! The virtual CAN bus server behind `buslab bus serve`.
//!
//! The one bus engine (`buslab-sim`) runs paced to the wall clock; every TCP client gets its own
//! SJA1000 (register model) on it, initialised and operated through the host library's driver,
//! and talks socketcand in raw mode, so python-can's `socketcand` interface can join.
//!
//! - [`node`]: a client's chip and driver as a node of the engine ([`ClientNode`]).
//! - [`bus`]: the sans-IO part, [`VirtualBus`]: the engine with its client nodes.
//! - [`departure`]: a client that left, while its node sends what it handed over.
//! - [`device`]: a bench's simulated node ([`Device`]), reached through the typed notices it
//!   reports and the demo board it offers, never by its type.
//! - [`speed`]: how fast the bus runs ([`Speed`]: N times real time, or `max`).
//! - [`server`]: one event loop (listener, client sessions, pacing) around [`VirtualBus`] and
//!   the socketcand crate's sans-IO sessions ([`spawn`]).
//!
//! Start one in-process (e.g. from `buslab lab`):
//!
//! ```no_run
//! let config = buslab_vbus::ServerConfig::new("127.0.0.1:0".parse().unwrap(), 500_000);
//! let server = buslab_vbus::spawn(config).unwrap();
//! println!("socketcand://{}/vcan0", server.local_addr());
//! server.shutdown();
//! ```

pub mod bus;
pub mod departure;
pub mod device;
pub mod node;
pub mod server;
pub mod speed;

pub use bus::{BusEvent, MAX_NODES, VbusError, VirtualBus};
pub use departure::{DEPARTURE_STALL, DropReason};
pub use device::{Board, Device, DeviceNode, DeviceNotice};
pub use node::{ClientNode, Delivery, NodeNotice, TimedErrorFrame};
pub use server::{Poster, ServerConfig, ServerError, ServerHandle, spawn};
pub use speed::{Speed, SpeedError};
