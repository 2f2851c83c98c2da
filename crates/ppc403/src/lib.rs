//! A PowerPC 403 core (the PPC403GA's processor: 32-bit, big-endian, integer only, no MMU):
//! the user-level integer instruction set with the condition register, link and count
//! registers and XER; the supervisor state a bare-metal program needs (`mtmsr`/`mfmsr`,
//! `mtspr`/`mfspr`, `rfi`/`rfci`, `sc`, `wrtee`/`wrteei`, `mtdcr`/`mfdcr`); the 403's
//! exception vectors relative to EVPR, its interrupt controller (EXISR/EXIER), and its
//! timers (time base, PIT, FIT, watchdog). Written from the PowerPC architecture books and
//! IBM's PPC403GA user's manual.
//!
//! Sans-IO, `no_std`: no clock, no threads, no files. Time is the CPU clock's cycles
//! ([`Cycles`]), given and returned explicitly: the board raises and lowers interrupt lines
//! ([`Ppc403::set_irq`]), [`Ppc403::run`]s the core until a time or an event ([`Stop`]), and
//! supplies everything outside the chip through [`Bus`] (memory, the chip-select banks).
//!
//! See `docs/ppc403.md` for the instruction set covered, the cycle model and deviations.
#![no_std]
#![forbid(unsafe_code)]

extern crate alloc;
#[cfg(test)]
extern crate std;

mod bus;
mod core;
pub mod dcr;
mod decode;
pub mod exceptions;
mod exec;
mod exec_branch;
mod exec_int;
mod exec_mem;
pub mod interrupts;
pub mod spr;
mod time;
pub mod timers;

pub use crate::core::{Exception, Irq, Ppc403, Registers, Stop};
pub use bus::{Bus, BusError, FlatMemory, Size};
pub use time::Cycles;
pub use timers::WatchdogReset;
