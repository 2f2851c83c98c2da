//! A PowerPC 403 core (the PPC403GA's processor: 32-bit, big-endian, integer only, no MMU):
//! the user-level integer instruction set with the condition register, link and count
//! registers and XER; the supervisor state a bare-metal program needs (`mtmsr`/`mfmsr`,
//! `mtspr`/`mfspr`, `rfi`/`rfci`, `sc`, `wrtee`/`wrteei`, `mtdcr`/`mfdcr`); the 403's
//! exception vectors relative to EVPR, its interrupt controller (EXISR/EXIER), and its
//! timers (time base, PIT, FIT, watchdog). Written from the PowerPC architecture (Book I) and
//! the 403GA's register numbers and bit layouts as public sources give them (where they did
//! not say, `docs/decisions.md` says what was decided).
//!
//! ```
//! use buslab_ppc403::{Cycles, FlatMemory, Ppc403, Stop};
//!
//! let mut mem = FlatMemory::new(0x1_0000);
//! // li r3,5 ; addi r3,r3,7 ; sc
//! mem.load_words(0x100, &[0x3860_0005, 0x3863_0007, 0x4400_0002]);
//! let mut cpu = Ppc403::new();
//! cpu.set_pc(0x100);
//! cpu.set_trap_sc(true);
//! assert_eq!(cpu.run(&mut mem, Cycles(100)), Stop::SystemCall { at: 0x108 });
//! assert_eq!(cpu.gpr(3), 12);
//! assert_eq!(cpu.now(), Cycles(3));
//! assert_eq!(buslab_ppc403::disassemble(0x3863_0007, 0x104).to_string(), "addi r3,r3,7");
//! ```
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
pub mod disasm;
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
pub use disasm::{Disassembly, disassemble};
pub use time::Cycles;
pub use timers::WatchdogReset;
