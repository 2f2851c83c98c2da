//! ZELLE measurement cell: a sans-IO model of the cell and a host client for it.
//!
//! The cell is an 8051 board with a 1 KB EPROM operating system, a 4-channel 8-bit A/D
//! converter, digital port lines, a START key and battery-backed RAM. A host drives it over a
//! 9600 baud 8N2 line with one-byte commands (1..19), some followed by a small exchange.
//!
//! - [`Cell`]: the device model. Bytes go in with their arrival time (virtual nanoseconds),
//!   bytes come out with the time their stop bits end on TxD; [`Cell::next_deadline`] says when
//!   to look again. No threads, clocks or files inside.
//! - [`chip`], [`rom`]: user programs on the cell's 8051 (the `buslab-mcs51` core), one
//!   character time behind the line, with the OS's routines `Sende` and `Empf` at the entry
//!   points of [`rom`].
//! - [`analog`]: the sources that feed the A/D inputs (constant, waveforms, ramp, CSV replay).
//! - [`BatteryRam`]: the battery-backed RAM as a serialisable snapshot (the state file).
//! - [`client`]: the host side over any [`Port`] (a serial port or PTY through
//!   `buslab_link::SerialLine`, or the model itself in virtual time through [`SimPort`], see
//!   [`Cell::into_sim_port`]). No clock, sleep or file inside: the port keeps the time.

pub mod analog;
mod board;
mod cell;
pub mod chip;
pub mod client;
mod command;
pub mod control;
mod converter;
mod device;
mod memory;
mod number;
pub mod program;
pub mod rom;
pub mod sfr;
pub mod timing;
pub mod view;

pub use board::BUS_BASE;
pub use buslab_device::{ByteDevice, Changes, Persistent, Port, SimPort};
pub use cell::{
    Activity, COUNT_HIGH_REGISTER, COUNT_LOW_REGISTER, Cell, InputError, Mode, SetupRule, Stats,
};
pub use chip::{CpuSnapshot, ProgramEnd, ProgramStop, SfrSnapshot, TraceEvent};
pub use command::Command;
pub use memory::{BatteryRam, StateFileError, hex_listing};
pub use memory::{
    DATA_AREA, EXT_RAM_SIZE, INTERNAL_RAM_SIZE, PARAMS_LEN, PROGRAM_AREA, START_BYTE,
};
