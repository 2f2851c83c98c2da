//! Open a CAN bus by URL, whatever is behind it (python-can's `can.Bus(interface=…)` idea):
//! a registry of backends keyed by the URL's scheme.
//!
//! | URL | backend |
//! |---|---|
//! | `socketcand://HOST[:PORT][/CHANNEL]` | socketcand raw mode over TCP (port 29536, channel vcan0 by default) |
//! | `socketcan:IFACE` | Linux SocketCAN (a slot: "not available yet") |
//! | `slcan:DEVICE[@BAUD][?bitrate=N]` | an SLCAN serial adapter (a slot: "not available yet") |
//!
//! ```no_run
//! use buslab_canbus::CanBus;
//!
//! let mut bus = buslab_backends::open("socketcand://127.0.0.1:29536/vcan0")?;
//! bus.send(&"123#DEADBEEF".parse()?)?;
//! if let Some(admin) = bus.admin() {
//!     // A buslab bus: wait until the frame was sent.
//!     let report = admin.flush(std::time::Duration::from_secs(10))?;
//!     assert_eq!(report.failed, 0);
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod registry;
pub mod url;

pub use registry::{
    BACKENDS, Backend, DynBus, OpenError, OpenFn, OpenOptions, backend, open, open_url,
};
pub use url::{BusUrl, DEFAULT_CHANNEL, SOCKETCAND_PORT, UrlError, UrlProblem};

/// The bus the command-line tools use by default: `buslab bus serve` on this machine.
pub const DEFAULT_URL: &str = "socketcand://127.0.0.1:29536/vcan0";
