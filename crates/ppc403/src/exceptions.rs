//! Taking exceptions: the vector (EVPR's upper half | the offset), the save registers
//! (SRR0/SRR1, or SRR2/SRR3 for the critical class), the MSR bits the 403 clears, and
//! returning from them (`rfi`, `rfci`).

use crate::Exception;
use crate::core::{Event, Executed, Ppc403, Stop};

/// The MSR's bits (PowerPC numbering in the comments).
pub mod msr {
    /// Auxiliary processor available (bit 12; no APU on the 403GA: kept as written).
    pub const APE: u32 = 0x0008_0000;
    /// Wait state enable (bit 13): the core stops until an interrupt.
    pub const WE: u32 = 0x0004_0000;
    /// Critical interrupt enable (bit 14).
    pub const CE: u32 = 0x0002_0000;
    /// Interrupt little-endian (bit 15; stored, not honoured).
    pub const ILE: u32 = 0x0001_0000;
    /// External interrupt enable (bit 16), also the PIT's and FIT's.
    pub const EE: u32 = 0x0000_8000;
    /// Problem state (bit 17): user mode.
    pub const PR: u32 = 0x0000_4000;
    /// Machine check enable (bit 19).
    pub const ME: u32 = 0x0000_1000;
    /// Debug exception enable (bit 22).
    pub const DE: u32 = 0x0000_0200;
    /// Protection enable and protection exclusive (bits 28, 29).
    pub const PE: u32 = 0x0000_0008;
    pub const PX: u32 = 0x0000_0004;
    /// Little-endian mode (bit 31; stored, not honoured).
    pub const LE: u32 = 0x0000_0001;
    /// The bits the 403GA has: `mtmsr`, `rfi`, `rfci` keep only these (the others read 0).
    pub const IMPLEMENTED: u32 = APE | WE | CE | ILE | EE | PR | ME | DE | PE | PX | LE;
}

/// The Exception Syndrome Register's bits.
pub mod esr {
    /// Instruction machine check: a fetch got a bus error.
    pub const MCI: u32 = 0x8000_0000;
    /// Program: illegal instruction.
    pub const PIL: u32 = 0x0800_0000;
    /// Program: privileged instruction in problem state.
    pub const PPR: u32 = 0x0400_0000;
    /// Program: trap.
    pub const PTR: u32 = 0x0200_0000;
    /// Data storage / alignment: the access was a store.
    pub const DST: u32 = 0x0080_0000;
}

/// The vector offsets (added to EVPR's upper 16 bits).
pub mod vector {
    pub const CRITICAL: u32 = 0x0100;
    pub const MACHINE_CHECK: u32 = 0x0200;
    pub const DATA_STORAGE: u32 = 0x0300;
    pub const INSTRUCTION_STORAGE: u32 = 0x0400;
    pub const EXTERNAL: u32 = 0x0500;
    pub const ALIGNMENT: u32 = 0x0600;
    pub const PROGRAM: u32 = 0x0700;
    pub const SYSTEM_CALL: u32 = 0x0C00;
    pub const PIT: u32 = 0x1000;
    pub const FIT: u32 = 0x1010;
    pub const WATCHDOG: u32 = 0x1020;
    pub const DEBUG: u32 = 0x2000;
}

/// The MSR bits a non-critical exception keeps (it clears WE, EE, PR, PE, PX, LE).
const KEPT_NONCRITICAL: u32 = msr::APE | msr::CE | msr::ILE | msr::ME | msr::DE;
/// The MSR bits a critical exception keeps (it also clears CE and DE; a machine check clears
/// ME as well).
const KEPT_CRITICAL: u32 = msr::APE | msr::ILE | msr::ME;

/// An illegal instruction.
#[cold]
pub(crate) fn illegal(word: u32) -> Executed {
    Err(Event::Exception(Exception::Illegal { word }))
}

/// A supervisor instruction in problem state.
#[cold]
pub(crate) fn privileged(word: u32) -> Executed {
    Err(Event::Exception(Exception::Privileged { word }))
}

impl Exception {
    /// The vector offset.
    pub fn vector(self) -> u32 {
        match self {
            Exception::Critical => vector::CRITICAL,
            Exception::MachineCheck { .. } => vector::MACHINE_CHECK,
            Exception::External => vector::EXTERNAL,
            Exception::Alignment { .. } => vector::ALIGNMENT,
            Exception::Illegal { .. } | Exception::Privileged { .. } | Exception::Trap => {
                vector::PROGRAM
            }
            Exception::SystemCall => vector::SYSTEM_CALL,
            Exception::Pit => vector::PIT,
            Exception::Fit => vector::FIT,
            Exception::Watchdog => vector::WATCHDOG,
        }
    }

    /// Whether it is of the critical class (saved in SRR2/SRR3, returned from with `rfci`).
    pub fn is_critical(self) -> bool {
        matches!(
            self,
            Exception::Critical | Exception::MachineCheck { .. } | Exception::Watchdog
        )
    }
}

impl Ppc403 {
    /// Takes `kind`: saves `srr0` (the instruction to return to) and the MSR, sets ESR for
    /// program exceptions, clears the MSR bits, jumps to the vector. `at` is what
    /// [`Stop::Exception`] reports.
    pub(crate) fn take_exception(&mut self, kind: Exception, srr0: u32, at: u32) -> Stop {
        match kind {
            Exception::Illegal { .. } => self.regs.esr = esr::PIL,
            Exception::Privileged { .. } => self.regs.esr = esr::PPR,
            Exception::Trap => self.regs.esr = esr::PTR,
            _ => {}
        }
        let old = self.regs.msr;
        if kind.is_critical() {
            self.regs.srr2 = srr0;
            self.regs.srr3 = old;
            let mut kept = KEPT_CRITICAL;
            if matches!(kind, Exception::MachineCheck { .. }) {
                kept &= !msr::ME;
            }
            self.regs.msr = old & kept;
        } else {
            self.regs.srr0 = srr0;
            self.regs.srr1 = old;
            self.regs.msr = old & KEPT_NONCRITICAL;
        }
        self.reservation = None;
        self.regs.pc = (self.regs.evpr & 0xFFFF_0000) | kind.vector();
        Stop::Exception { kind, at }
    }

    /// `rfi` (`critical`: `rfci`): PC and MSR back from SRR0/SRR1 (SRR2/SRR3).
    pub(crate) fn return_from_interrupt(&mut self, w: u32, critical: bool) -> Executed {
        if self.problem_state() {
            return privileged(w);
        }
        let (pc, msr) = if critical {
            (self.regs.srr2, self.regs.srr3)
        } else {
            (self.regs.srr0, self.regs.srr1)
        };
        self.regs.pc = pc & !3;
        self.regs.msr = msr & msr::IMPLEMENTED;
        self.reservation = None;
        self.spend(1);
        Err(Event::Sync)
    }
}
