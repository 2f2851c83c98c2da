//! CPU196 controller board (SPEC C1–C6): the PC ↔ board protocol codec, a sans-IO model of the
//! 80C196 kernel and its PIC slave, and the host client. Std only: no clock, thread or file;
//! the host side (serial ports, served boards, image files, the monitor's file service) lives
//! in `buslab-link` and `buslab-served`.
//!
//! Layers, bottom up: [`wire`] (byte layout), [`message`] (typed messages), [`decoder`]
//! (streaming, with the kernel's error handling); the model: [`board`] (kernel loops and
//! commands) over [`flash`], [`prginf`], [`acquisition`], [`pic`], [`program`] (user hooks)
//! and [`image`] (persistent state, as TOML text); the host: [`host`] (client over any
//! [`Port`], monitor session, recorder) and [`values`] (what host tools
//! accept, checked).
#![forbid(unsafe_code)]

pub mod acquisition;
pub mod adconfig;
pub mod board;
pub mod codes;
pub mod decoder;
pub mod flash;
pub mod host;
pub mod image;
pub mod message;
pub mod pic;
pub mod prginf;
pub mod program;
pub mod source;
pub mod values;
pub mod wire;

pub use board::{Board, ImageChange, Mode, Stats};
pub use buslab_device::{ByteDevice, Changes, Persistent, Port, SimPort};
pub use codes::{Alert, MsgCode};
pub use decoder::{Decoder, Event, FrameError};
pub use image::Image;
pub use message::Message;
