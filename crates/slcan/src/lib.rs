//! SLCAN (Lawicel) serial CAN adapters, both ways.
//!
//! - [`codec`]: the ASCII protocol, sans-IO: commands ([`Command`]) and adapter replies
//!   ([`Reply`]) parsed from a line and formatted into bytes; [`LineSplitter`] cuts a byte
//!   stream into lines, bounded. Any bytes give a value or an error, never a panic.
//! - [`adapter`]: an adapter as a sans-IO model ([`Adapter`]): host bytes in, answers and
//!   received frames out, [`AdapterEvent`]s for the bus side (`buslab slcan serve`).
//! - [`handshake`]: opening an adapter, sans-IO ([`Handshake`]): every command closed by `V`,
//!   so replies left from an earlier session cannot shift the answers; Lawicel, CANable and
//!   buslab's own answers.
//! - [`client`]: a [`CanBus`](buslab_bus::CanBus) over an adapter on a serial port
//!   ([`SlcanBus`]), the `slcan:` backend.
//! - [`clock`]: the adapter's wrapping millisecond timestamps mapped onto the host clock.
//! - [`serve`](mod@serve): the adapter model served on a pseudo-terminal's master side.
//!
//! ```
//! use buslab_slcan::{Adapter, AdapterEvent};
//!
//! let mut adapter = Adapter::default();
//! adapter.receive(b"S6\rO\rt1232AABB\r");
//! assert_eq!(adapter.take_output(), b"\r\rz\r");
//! let events: Vec<_> = std::iter::from_fn(|| adapter.poll_event()).collect();
//! assert_eq!(events[1], AdapterEvent::Transmit("123#AABB".parse()?));
//! adapter.deliver(&"7FF#01".parse()?, buslab_can::Nanos::ZERO);
//! assert_eq!(adapter.take_output(), b"t7FF101\r");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod adapter;
pub mod client;
pub mod clock;
pub mod codec;
pub mod handshake;
pub mod serve;

pub use adapter::{Adapter, AdapterEvent, ErrorLevel, Identity, MAX_OUTPUT, Mode, Timing};
pub use client::{BTR_CLOCK_HZ, SlcanBus, SlcanError, SlcanOptions, bitrate_command};
pub use clock::DeviceClock;
pub use codec::{
    BEL, CR, CodecError, Command, DATA_BITRATES, Line, LineSplitter, MAX_LINE, MAX_REPLY_LINE,
    Reply, STANDARD_BITRATES, StatusFlags, data_bitrate, format_command, format_fd_frame,
    format_frame, format_reply, parse_command, parse_reply,
};
pub use handshake::{AcceptanceAnswer, Firmware, Handshake, HandshakeError, Plan};
pub use serve::{INPUT_QUEUE, Input, serve};
