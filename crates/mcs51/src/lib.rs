//! An MCS-51 (8051) core: every opcode with its flags and cycle count, bit-addressable RAM and
//! SFRs, register banks, timers 0 and 1 (modes 0..3, GATE, counters), the UART (modes 0..3,
//! baud from timer 1 and SMOD), the five interrupt sources with two priority levels, IDLE and
//! power-down. Written from the behaviour Intel's MCS-51 user manual documents.
//!
//! Sans-IO, `no_std`: no clock, no threads, no files. Time is the crystal's clocks
//! ([`Clocks`], 12 to a machine cycle), given and returned explicitly, in the shape of
//! quinn-proto: announce inputs with their times ([`Mcs51::set_pin`], [`Mcs51::send_rxd`]),
//! [`Mcs51::run`] until a time or an event, take the events ([`Mcs51::poll_event`]: frames the
//! UART sent, port writes), repeat. The board supplies memory through [`Bus`] (code fetches
//! and `MOVX`; [`FlatMemory`] is 64 KiB shared by code and data) and can trap calls into an
//! operating system it models ([`Mcs51::set_traps`], [`Stop::Trap`]).
//!
//! ```
//! use buslab_mcs51::{Clocks, FlatMemory, Mcs51, Stop};
//!
//! let mut mem = FlatMemory::new();
//! // MOV A,#5 ; ADD A,#7 ; SJMP $
//! mem.load(0, &[0x74, 0x05, 0x24, 0x07, 0x80, 0xFE]);
//! let mut cpu = Mcs51::new();
//! assert_eq!(cpu.run(&mut mem, Clocks::from_cycles(100)), Stop::Limit);
//! assert_eq!(cpu.a(), 12);
//! ```
//!
//! See `docs/mcs51.md` for the memory model, timing and deviations.
#![no_std]
#![forbid(unsafe_code)]

extern crate alloc;
#[cfg(test)]
extern crate std;

mod bus;
mod core;
mod event;
mod exec;
mod interrupts;
pub mod opcodes;
mod pins;
pub mod sfr;
mod time;
mod timers;
mod uart;

pub use crate::core::{IRAM_SIZE, Mcs51, NO_UPPER_RAM, Registers};
pub use bus::{Bus, FlatMemory};
pub use event::{Event, LineFrame, SerialFrame, SerialMode, Stop};
pub use interrupts::Source;
pub use opcodes::Instruction;
pub use pins::{InputError, MAX_QUEUED_INPUTS, Pin, Port};
pub use time::{CLOCKS_PER_CYCLE, Clocks, Crystal, CrystalError};
