//! The special purpose registers (`mfspr`, `mtspr`, `mftb`) and the MSR's instructions
//! (`mfmsr`, `mtmsr`, `wrtee`, `wrteei`).
//!
//! An SPR number with bit 0x10 set is a supervisor register: problem state gets the
//! privileged-instruction exception. A number the 403GA does not have, or a write to a
//! read-only one (PVR, ICDBDR, TBHU/TBLU), is an illegal instruction.

use crate::core::{Event, Executed, Ppc403};
use crate::decode::{rd, split_field};
use crate::exceptions::{illegal, privileged};

/// The PPC403GA's processor version (as QEMU's CPU table gives it).
pub const PVR_403GA: u32 = 0x0020_0011;

pub mod number {
    pub const XER: u32 = 1;
    pub const LR: u32 = 8;
    pub const CTR: u32 = 9;
    pub const SRR0: u32 = 26;
    pub const SRR1: u32 = 27;
    /// `mftb`'s time base numbers (TBL, TBU).
    pub const TBL_READ: u32 = 268;
    pub const TBU_READ: u32 = 269;
    pub const SPRG0: u32 = 272;
    pub const SPRG3: u32 = 275;
    pub const PVR: u32 = 287;
    /// The user-mode, read-only view of the time base (403GC and later; harmless here).
    pub const TBHU: u32 = 0x3CC;
    pub const TBLU: u32 = 0x3CD;
    pub const ICDBDR: u32 = 0x3D3;
    pub const ESR: u32 = 0x3D4;
    pub const DEAR: u32 = 0x3D5;
    pub const EVPR: u32 = 0x3D6;
    pub const CDBCR: u32 = 0x3D7;
    pub const TSR: u32 = 0x3D8;
    pub const TCR: u32 = 0x3DA;
    pub const PIT: u32 = 0x3DB;
    pub const TBHI: u32 = 0x3DC;
    pub const TBLO: u32 = 0x3DD;
    pub const SRR2: u32 = 0x3DE;
    pub const SRR3: u32 = 0x3DF;
    pub const DBSR: u32 = 0x3F0;
    pub const DBCR: u32 = 0x3F2;
    pub const IAC1: u32 = 0x3F4;
    pub const IAC2: u32 = 0x3F5;
    pub const DAC1: u32 = 0x3F6;
    pub const DAC2: u32 = 0x3F7;
    pub const DCCR: u32 = 0x3FA;
    pub const ICCR: u32 = 0x3FB;
    pub const PBL1: u32 = 0x3FC;
    pub const PBU2: u32 = 0x3FF;
}

/// The supervisor registers kept as written (caches, debug and protection are not
/// modelled).
#[derive(Clone, Debug, Default)]
pub(crate) struct Sprs {
    pub icdbdr: u32,
    pub cdbcr: u32,
    pub dbsr: u32,
    pub dbcr: u32,
    pub iac: [u32; 2],
    pub dac: [u32; 2],
    pub dccr: u32,
    pub iccr: u32,
    /// PBL1, PBU1, PBL2, PBU2.
    pub protection: [u32; 4],
}

impl Ppc403 {
    /// The SPR `n`, or `None` when the 403GA has none there.
    pub fn spr(&self, n: u32) -> Option<u32> {
        use number::*;
        let r = &self.regs;
        Some(match n {
            XER => r.xer,
            LR => r.lr,
            CTR => r.ctr,
            SRR0 => r.srr0,
            SRR1 => r.srr1,
            SPRG0..=SPRG3 => r.sprg[(n - SPRG0) as usize],
            PVR => PVR_403GA,
            TBHU | TBHI => (self.time_base() >> 32) as u32,
            TBLU | TBLO => self.time_base() as u32,
            ICDBDR => self.sprs.icdbdr,
            ESR => r.esr,
            DEAR => r.dear,
            EVPR => r.evpr,
            CDBCR => self.sprs.cdbcr,
            TSR => self.timers.tsr,
            TCR => self.timers.tcr,
            PIT => self.pit(),
            SRR2 => r.srr2,
            SRR3 => r.srr3,
            DBSR => self.sprs.dbsr,
            DBCR => self.sprs.dbcr,
            IAC1 | IAC2 => self.sprs.iac[(n - IAC1) as usize],
            DAC1 | DAC2 => self.sprs.dac[(n - DAC1) as usize],
            DCCR => self.sprs.dccr,
            ICCR => self.sprs.iccr,
            PBL1..=PBU2 => self.sprs.protection[(n - PBL1) as usize],
            _ => return None,
        })
    }

    /// Writes the SPR `n` as `mtspr` does; `None` when the 403GA has no writable SPR there,
    /// `Some(true)` when the write can change what interrupts (the run loop looks again).
    pub fn set_spr(&mut self, n: u32, value: u32) -> Option<bool> {
        use number::*;
        let r = &mut self.regs;
        match n {
            XER => r.xer = value,
            LR => r.lr = value,
            CTR => r.ctr = value,
            SRR0 => r.srr0 = value,
            SRR1 => r.srr1 = value,
            SPRG0..=SPRG3 => r.sprg[(n - SPRG0) as usize] = value,
            ESR => r.esr = value,
            DEAR => r.dear = value,
            EVPR => r.evpr = value & 0xFFFF_0000,
            CDBCR => self.sprs.cdbcr = value,
            SRR2 => r.srr2 = value,
            SRR3 => r.srr3 = value,
            DBSR => self.sprs.dbsr &= !value,
            DBCR => self.sprs.dbcr = value,
            IAC1 | IAC2 => self.sprs.iac[(n - IAC1) as usize] = value,
            DAC1 | DAC2 => self.sprs.dac[(n - DAC1) as usize] = value,
            DCCR => self.sprs.dccr = value,
            ICCR => self.sprs.iccr = value,
            PBL1..=PBU2 => self.sprs.protection[(n - PBL1) as usize] = value,
            TSR => {
                self.clear_tsr(value);
                return Some(true);
            }
            TCR => {
                self.write_tcr(value);
                return Some(true);
            }
            PIT => {
                self.write_pit(value);
                return Some(true);
            }
            TBHI | TBLO => {
                self.write_time_base(value, n == TBHI);
                return Some(true);
            }
            _ => return None,
        }
        Some(false)
    }

    /// `mfspr`.
    pub(crate) fn mfspr(&mut self, w: u32) -> Executed {
        let n = split_field(w);
        if n & 0x10 != 0 && self.problem_state() {
            return privileged(w);
        }
        if matches!(n, number::TSR | number::PIT) {
            self.catch_up_timers();
        }
        match self.spr(n) {
            Some(v) => {
                self.regs.gpr[rd(w)] = v;
                Ok(())
            }
            None => illegal(w),
        }
    }

    /// `mtspr`.
    pub(crate) fn mtspr(&mut self, w: u32) -> Executed {
        let n = split_field(w);
        if n & 0x10 != 0 && self.problem_state() {
            return privileged(w);
        }
        match self.set_spr(n, self.regs.gpr[rd(w)]) {
            Some(false) => Ok(()),
            Some(true) => Err(Event::Sync),
            None => illegal(w),
        }
    }

    /// `mftb` (the architecture's time base read; the 403GA reads TBHI/TBLO with `mfspr`,
    /// later 40x cores have `mftb`: accepted).
    pub(crate) fn mftb(&mut self, w: u32) -> Executed {
        let v = match split_field(w) {
            number::TBL_READ => self.time_base() as u32,
            number::TBU_READ => (self.time_base() >> 32) as u32,
            _ => return illegal(w),
        };
        self.regs.gpr[rd(w)] = v;
        Ok(())
    }

    /// `mfmsr`, `mtmsr`, `wrtee`, `wrteei` by extended opcode.
    pub(crate) fn msr_instruction(&mut self, w: u32, x: u32) -> Executed {
        if self.problem_state() {
            return privileged(w);
        }
        let ee = crate::exceptions::msr::EE;
        match x {
            83 => {
                self.regs.gpr[rd(w)] = self.regs.msr;
                return Ok(());
            }
            146 => self.regs.msr = self.regs.gpr[rd(w)] & crate::exceptions::msr::IMPLEMENTED,
            131 => self.regs.msr = (self.regs.msr & !ee) | (self.regs.gpr[rd(w)] & ee),
            _ => self.regs.msr = (self.regs.msr & !ee) | (w & ee),
        }
        Err(Event::Sync)
    }
}
