//! `buslab web`: a bus as web pages, served by axum on a small tokio runtime of its own.
//!
//! - The **CAN WebServer** (the seed's feature): server-rendered pages that work without
//!   JavaScript: nodes with their state and counters, the bus load, the last frames, the
//!   per-ID table.
//! - A **live dashboard** (`/dashboard`, plain JavaScript) on server-sent events (`/api/events`);
//!   each viewer pulls what changed since its own cursor in [`buslab_view::BusView`], so a
//!   slow viewer gets fewer, larger updates and the log lines it had no room for are counted,
//!   never queued without bound.
//! - **Signals** with a DBC database ([`WebConfig::dbc`]): each message seen with its signals'
//!   latest values, live, and a plot of any signal over time.
//! - **Device panels** ([`devices`]) in the lab: the SLIO boards (an LED changes when the
//!   SLIO confirms it), the ZELLE cell (measurements plotted as they come, its RAM), the
//!   CPU196 board (identity, THREAD text, the A/D stream plotted live).
//! - **Writes** (send a frame, inject or repair a fault on a virtual bus) only with the
//!   server's token in the `X-Buslab-Token` header; without a token the server is read-only.
//! - **Guarded** ([`guard`]): only requests naming a host it answers to (no DNS rebinding),
//!   a Content-Security-Policy and no framing on every answer; and **bounded** in time
//!   ([`Timeouts`]): a client that stalls a request or stops reading its answer loses its
//!   connection, so stalled connections cannot keep others out.
//!
//! The bus is owned by a [`buslab_backends::Pump`] thread; the view is the sans-IO model, fed
//! with the time since the server started. [`WebServer::start`] is synchronous so the
//! (thread-based) command-line tool can start it next to anything else.

mod api;
mod app;
mod chart;
mod device_api;
pub mod device_request;
pub mod devices;
mod error;
pub mod guard;
mod html;
mod hub;
mod limits;
mod pages;
pub mod request;
mod routes;
mod server;

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use buslab_dbc::Database;

pub use devices::DeviceConfig;
pub use error::ApiError;
pub use guard::BadHostName;
pub use limits::Timeouts;
pub use server::WebServer;

/// The header that carries the write token.
pub const TOKEN_HEADER: &str = "x-buslab-token";

/// How the server listens and what it allows.
#[derive(Clone, Debug)]
pub struct WebConfig {
    /// Where to listen; loopback unless the user says otherwise.
    pub listen: SocketAddr,
    /// The write token; `None`: read-only.
    pub token: Option<String>,
    /// Connections served at once; more are answered 503 and closed.
    pub max_connections: usize,
    /// How often the nodes' status is asked for.
    pub status_every: Duration,
    /// The bus's bit rate when the bus cannot tell, to estimate the load.
    pub bitrate: Option<u32>,
    /// The bench's devices to show as panels (`buslab lab`); none by default.
    pub devices: DeviceConfig,
    /// Host names the server answers to besides IP addresses and `localhost`
    /// (`--allow-host`): a request naming another host is refused (DNS rebinding).
    pub allowed_hosts: Vec<String>,
    /// How long a client may take to send a request, or stall while it is answered.
    pub timeouts: Timeouts,
    /// A DBC database: the dashboard shows its messages' signals and plots any of them.
    pub dbc: Option<Arc<Database>>,
    /// The bus is joined to remote buses (cannelloni, MQTT): the overview shows its counters
    /// per peer (sent, lost, reordered).
    pub join: Option<buslab_backends::JoinSender>,
}

impl Default for WebConfig {
    fn default() -> Self {
        Self {
            listen: SocketAddr::from(([127, 0, 0, 1], 8080)),
            token: None,
            max_connections: 64,
            status_every: Duration::from_millis(250),
            bitrate: None,
            devices: DeviceConfig::default(),
            allowed_hosts: Vec::new(),
            timeouts: Timeouts::default(),
            dbc: None,
            join: None,
        }
    }
}

/// Why the server did not start.
#[derive(Debug, thiserror::Error)]
pub enum WebError {
    #[error("cannot listen on {addr}: {source}")]
    Listen {
        addr: SocketAddr,
        source: std::io::Error,
    },
    #[error("cannot start the web server's threads: {0}")]
    Threads(std::io::Error),
    #[error("token {0:?}: expected 8 to 128 characters of A-Z, a-z, 0-9, '-', '_' or '.'")]
    BadToken(String),
    #[error("cannot make a random token: {0}")]
    Random(String),
    #[error("--max-connections 0: at least one connection must be allowed")]
    NoConnections,
    #[error(transparent)]
    BadHost(#[from] BadHostName),
    #[error("a request timeout of 0 would refuse every request: give at least 1 ms")]
    NoTime,
}

/// A fresh random token (128 bits, hex).
pub fn generate_token() -> Result<String, WebError> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes).map_err(|e| WebError::Random(e.to_string()))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Checks a user's token: long enough to guess hardly, and safe in a header.
pub fn check_token(token: &str) -> Result<(), WebError> {
    let ok = (8..=128).contains(&token.len())
        && token
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.'));
    if ok {
        Ok(())
    } else {
        Err(WebError::BadToken(token.to_string()))
    }
}
