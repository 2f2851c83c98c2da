//! CPU196 controller board (SPEC C1–C6): the PC ↔ board protocol codec, a sans-IO model of the
//! 80C196 kernel and its PIC slave, and the host client.
//!
//! Layers, bottom up: [`wire`] (byte layout), [`message`] (typed messages), [`decoder`]
//! (streaming, with the kernel's error handling), then the board model and the host client.
#![forbid(unsafe_code)]

pub mod adconfig;
pub mod codes;
pub mod decoder;
pub mod message;
pub mod wire;

pub use codes::{Alert, MsgCode};
pub use decoder::{Decoder, Event, FrameError};
pub use message::Message;
