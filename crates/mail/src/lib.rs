//! The mail notifier's core (seed 002 §5.4.5, JerryCAN's `MailWatcher`), sans-IO: one look at
//! an IMAP mailbox ([`imap::Poll`], behind a [`imap::Framer`] that bounds what the server may
//! send), a mail as the server hands it over becomes the text MoniCAN shows ([`mail_text`]),
//! and the [`Announcer`] turns the waiting texts into CAN frames. `buslab mail` owns the
//! socket, TLS, the bus and the clock.

mod announcer;
pub mod imap;
mod text;

pub use announcer::{Announcer, MAX_WAITING};
pub use text::{header, mail_text};
