//! The core: registers, time, and the loop that runs instructions and takes exceptions.
//!
//! SKELETON: the API the board and the tests are written against; the instruction set, the
//! exceptions, the timers and the interrupt controller are being filled in.

use crate::{Bus, Cycles};

/// The registers a program sees (and a debugger shows).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Registers {
    pub pc: u32,
    pub gpr: [u32; 32],
    pub cr: u32,
    pub lr: u32,
    pub ctr: u32,
    pub xer: u32,
    pub msr: u32,
    pub srr0: u32,
    pub srr1: u32,
    /// The 403's critical-interrupt save registers.
    pub srr2: u32,
    pub srr3: u32,
    pub sprg: [u32; 4],
    /// Exception vector prefix (the upper 16 bits of every vector address).
    pub evpr: u32,
    pub esr: u32,
    pub dear: u32,
}

/// An interrupt input of the 403's interrupt controller (EXISR/EXIER). Level-sensitive: the
/// board sets the line's level, the controller latches it in EXISR while it is high.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Irq {
    /// The critical interrupt pin (vector 0x0100, saved in SRR2/SRR3).
    Critical,
    /// The on-chip serial port's receiver (a byte is ready or a receive error).
    SerialReceive,
    /// The on-chip serial port's transmitter (ready for the next byte).
    SerialTransmit,
    /// External interrupt pin INT0..INT4.
    External(u8),
}

/// Why an exception was taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exception {
    /// A load, store or fetch where nothing answered (vector 0x0200).
    MachineCheck { addr: u32 },
    /// An external or on-chip interrupt through EXISR/EXIER (vector 0x0500).
    External,
    /// A misaligned load or store (vector 0x0600).
    Alignment { addr: u32 },
    /// An illegal instruction word (vector 0x0700, ESR[PIL]).
    Illegal { word: u32 },
    /// A supervisor instruction in problem state (vector 0x0700, ESR[PPR]).
    Privileged { word: u32 },
    /// `tw`/`twi` whose condition held (vector 0x0700, ESR[PTR]).
    Trap,
    /// `sc` (vector 0x0C00).
    SystemCall,
    /// The programmable interval timer reached zero (vector 0x1000).
    Pit,
    /// The fixed interval timer (vector 0x1010).
    Fit,
    /// The watchdog's first time-out (vector 0x1020, critical).
    Watchdog,
    /// The critical interrupt pin (vector 0x0100, critical).
    Critical,
}

/// Why [`Ppc403::run`] returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// The limit was reached.
    Limit,
    /// An exception was just taken: the PC is at its vector, SRR0/SRR1 (SRR2/SRR3) saved.
    /// The board decides whether a program handles it (its vector holds code) or whether
    /// the program crashed.
    Exception { kind: Exception, at: u32 },
    /// `sc` ran while [`Ppc403::set_trap_sc`] is on: nothing was saved or vectored, the PC is
    /// past the `sc`; the board serves the call (registers as the program left them).
    SystemCall { at: u32 },
    /// MSR[WE] is set: the core waits for an interrupt; time was advanced to the limit or to
    /// the next timer event.
    Wait,
}

/// A PowerPC 403 core.
#[derive(Clone, Debug)]
pub struct Ppc403 {
    regs: Registers,
    now: Cycles,
    instructions: u64,
    trap_sc: bool,
}

impl Default for Ppc403 {
    fn default() -> Self {
        Ppc403::new()
    }
}

impl Ppc403 {
    /// A core after reset: PC at 0xFFFF_FFFC, MSR 0 (supervisor, interrupts off).
    pub fn new() -> Ppc403 {
        Ppc403 {
            regs: Registers {
                pc: 0xFFFF_FFFC,
                ..Registers::default()
            },
            now: Cycles::ZERO,
            instructions: 0,
            trap_sc: false,
        }
    }

    /// Runs instructions until `limit` (the cycle count, not a duration) or an event.
    pub fn run(&mut self, _bus: &mut impl Bus, limit: Cycles) -> Stop {
        self.now = self.now.max(limit);
        Stop::Limit
    }

    /// Sets an interrupt line's level.
    pub fn set_irq(&mut self, _irq: Irq, _level: bool) {}

    /// `sc` stops [`run`](Self::run) with [`Stop::SystemCall`] instead of vectoring.
    pub fn set_trap_sc(&mut self, on: bool) {
        self.trap_sc = on;
    }

    pub fn registers(&self) -> &Registers {
        &self.regs
    }

    pub fn registers_mut(&mut self) -> &mut Registers {
        &mut self.regs
    }

    pub fn pc(&self) -> u32 {
        self.regs.pc
    }

    pub fn set_pc(&mut self, pc: u32) {
        self.regs.pc = pc;
    }

    pub fn gpr(&self, n: usize) -> u32 {
        self.regs.gpr[n]
    }

    pub fn set_gpr(&mut self, n: usize, value: u32) {
        self.regs.gpr[n] = value;
    }

    /// The current cycle.
    pub fn now(&self) -> Cycles {
        self.now
    }

    /// Instructions completed since the core was made.
    pub fn instructions(&self) -> u64 {
        self.instructions
    }
}
