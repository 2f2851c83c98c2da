//! Open a CAN bus by URL, whatever is behind it (python-can's `can.Bus(interface=…)` idea):
//! a registry of backends keyed by the URL's scheme.
//!
//! | URL | backend |
//! |---|---|
//! | `socketcand://HOST[:PORT][/CHANNEL]` | socketcand raw mode over TCP (port 29536, channel vcan0 by default) |
//! | `socketcan:IFACE` | a Linux SocketCAN interface (raw socket, kernel timestamps and filters, error frames) |
//! | `slcan:DEVICE[@BAUD][?bitrate=N&listen_only=1&fd=1&data_bitrate=N]` | an SLCAN (Lawicel) serial adapter |
//! | `cannelloni://PEER:PORT[?listen=HOST:PORT]` | cannelloni over UDP, point to point |
//! | `cannelloni+tcp://HOST:PORT[?role=server]` | cannelloni over TCP, connecting or listening |
//! | `mqtt://BROKER[:PORT]/PREFIX` (`mqtts://` with TLS) | buses joined through an MQTT broker |
//!
//! [`resolve`] turns names as can-utils users type them (`vcan0`, `can0`, `/dev/ttyACM0`)
//! into URLs; [`Pump`] drives a bus from a thread of its own so a program can send to it while
//! it waits for frames (bridges, the SLCAN adapter model); [`BusSpec`] reads candump's
//! interface arguments with their filters (`can0,123:7FF,~200:700,#FFFFFFFF`);
//! [`confirm_sent`] waits until the frames a client handed over were sent.
//!
//! ```no_run
//! use buslab_bus::CanBus;
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

pub mod cannelloni;
pub mod confirm;
pub mod controller;
pub mod gateway;
pub mod join;
pub mod mqtt;
pub mod pump;
pub mod registry;
#[cfg(target_os = "linux")]
pub mod socketcan;
pub mod spec;
pub mod url;

pub use confirm::{ConfirmError, Confirmation, confirm_sent};
pub use controller::{Accepting, ControllerReport, Outcome};
pub use gateway::Gateway;
pub use join::{JoinBus, JoinSender};
pub use pump::{BusJob, JOB_LATENCY, Pump, PumpEvent, PumpSender, PumpStopped, TrySendError};
pub use registry::{
    BACKENDS, Backend, OpenError, OpenFn, OpenOptions, Opened, backend, open, open_configured,
    open_join, open_url, resolve,
};
pub use spec::{BusSpec, FilterItem, FilterSet, IdFilter, SpecError, filter_set};
pub use url::{
    BusUrl, CANNELLONI_PORT, CannelloniTransport, DEFAULT_CHANNEL, DEFAULT_NAME, MQTT_PORT,
    SOCKETCAND_PORT, UrlError, UrlProblem,
};

/// An open bus, of whichever backend.
pub type DynBus = Box<dyn buslab_bus::CanBus + Send>;

/// The bus the command-line tools use by default: `buslab bus serve` on this machine.
pub const DEFAULT_URL: &str = "socketcand://127.0.0.1:29536/vcan0";
