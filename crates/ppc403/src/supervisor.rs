//! The supervisor's registers as a program reaches them: `mfspr`/`mtspr`/`mftb`, the MSR's
//! instructions (`mfmsr`, `mtmsr`, `wrtee`, `wrteei`), `mfdcr`/`mtdcr`, and the same registers
//! for the board ([`Ppc403::spr`], [`Ppc403::dcr`] and their setters). The registers
//! themselves and their numbers are in `spr` and `dcr`.

use crate::core::{Event, Executed, Ppc403, illegal, privileged};
use crate::decode::{rd, split_field};
use crate::spr::PVR_403GA;

impl Ppc403 {
    /// The SPR `n`, or `None` when the 403GA has none there.
    pub fn spr(&self, n: u32) -> Option<u32> {
        use crate::spr::number::*;
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
        use crate::spr::number::*;
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
        if matches!(n, crate::spr::number::TSR | crate::spr::number::PIT) {
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
            crate::spr::number::TBL_READ => self.time_base() as u32,
            crate::spr::number::TBU_READ => (self.time_base() >> 32) as u32,
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

impl Ppc403 {
    /// The DCR `n`, or `None` when the 403 has none there.
    pub fn dcr(&self, n: u32) -> Option<u32> {
        use crate::dcr::number::*;
        Some(match n {
            EXISR => self.irq.status,
            EXIER => self.irq.enable,
            BR0..=BR7 => self.dcrs.br[(n - BR0) as usize],
            BEAR => self.dcrs.bear,
            BESR => self.dcrs.besr,
            IOCR => self.dcrs.iocr,
            DMA_FIRST..=DMA_LAST => self.dcrs.dma[(n - DMA_FIRST) as usize],
            DMASR => self.dcrs.dmasr,
            _ => return None,
        })
    }

    /// Writes the DCR `n`; `false` when the 403 has none there.
    pub fn set_dcr(&mut self, n: u32, value: u32) -> bool {
        use crate::dcr::number::*;
        match n {
            EXISR => self.irq.write_status(value),
            EXIER => self.irq.enable = value,
            BR0..=BR7 => self.dcrs.br[(n - BR0) as usize] = value,
            BEAR => self.dcrs.bear = value,
            BESR => self.dcrs.besr = value,
            IOCR => self.dcrs.iocr = value,
            DMA_FIRST..=DMA_LAST => self.dcrs.dma[(n - DMA_FIRST) as usize] = value,
            DMASR => self.dcrs.dmasr &= !value,
            _ => return false,
        }
        true
    }

    /// `mfdcr` (`to_dcr` false) and `mtdcr`.
    pub(crate) fn move_dcr(&mut self, w: u32, to_dcr: bool) -> Executed {
        if self.problem_state() {
            return privileged(w);
        }
        let n = split_field(w);
        if to_dcr {
            if !self.set_dcr(n, self.regs.gpr[rd(w)]) {
                return illegal(w);
            }
            Err(Event::Sync)
        } else {
            match self.dcr(n) {
                Some(v) => {
                    self.regs.gpr[rd(w)] = v;
                    Ok(())
                }
                None => illegal(w),
            }
        }
    }
}
