//! The virtual CAN bus server behind `buslab bus serve`.
//!
//! The bit-level bus runs paced to the wall clock; every TCP client gets its own SJA1000
//! (register model) on it, initialised and operated through the host library's driver, and
//! talks socketcand in raw mode, so python-can's `socketcand` interface can join.
//!
//! - [`bus`]: the sans-IO part, [`VirtualBus`]: chips on one wire in virtual time.
//! - [`server`]: listener, client sessions and the pacing loop ([`spawn`]).
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
pub mod server;

pub use bus::{Delivery, NodeCounters, VbusError, VirtualBus};
pub use server::{ServerConfig, ServerError, ServerHandle, spawn};
