//! MoniCAN (seed 002 §4.3): the PowerPC node's VT100 application that calibrates, finds and
//! drives up to 16 SLIO demo boards, as one sans-IO core.
//!
//! [`MoniCan`] takes keys (bytes from a VT100 terminal) and received frames, with the time in
//! nanoseconds; it gives frames to send ([`MoniCan::poll_transmit`]), the VT100 bytes that
//! update the terminal ([`MoniCan::take_screen`]) and when it next needs the time
//! ([`MoniCan::next_deadline`]). The same core runs inside the PowerPC node on the simulated
//! bus (`buslab-ppc`) and in the user's terminal (`buslab monican --bus URL`).
//!
//! - [`app`]: the application (start-up, the confirmation rule, mail, the loader request).
//! - [`command`]: typing a command; what each pin of the demo board means.
//! - [`layout`]: where everything is on the screen of the seed's Fig. 4.2.
//! - [`screen`]: the 24 × 80 screen and its VT100 rendering (only the cells that change).
//! - [`mail`]: a supervisor's message and its page.
#![forbid(unsafe_code)]

pub mod app;
pub mod command;
pub mod layout;
pub mod mail;
pub mod screen;

pub use app::{Config, ConfigError, DEFAULT_MAIL_ID, DEFAULT_MAIL_LIMIT, Event, MoniCan, SlioView};
pub use buslab_slio::Transmit;
pub use command::{Action, Adc, Command, Dpm};
