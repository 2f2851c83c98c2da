//! The device control registers (`mtdcr`, `mfdcr`): the interrupt controller's EXISR and
//! EXIER, and, as plain registers (the board decodes its banks itself, there is no DMA
//! engine), the bank registers BR0..BR7, BEAR/BESR (set by a data machine check), IOCR and
//! the DMA channels' registers. Any other number is an illegal instruction.

use crate::core::{Event, Executed, Ppc403};
use crate::decode::{rd, split_field};
use crate::exceptions::{illegal, privileged};

pub mod number {
    pub const EXISR: u32 = 0x40;
    pub const EXIER: u32 = 0x42;
    pub const BR0: u32 = 0x80;
    pub const BR7: u32 = 0x87;
    pub const BEAR: u32 = 0x90;
    pub const BESR: u32 = 0x91;
    pub const IOCR: u32 = 0xA0;
    /// DMACR0 .. DMACC3 (four channels of eight numbers).
    pub const DMA_FIRST: u32 = 0xC0;
    pub const DMA_LAST: u32 = 0xDF;
    pub const DMASR: u32 = 0xE0;
}

#[derive(Clone, Debug, Default)]
pub(crate) struct Dcrs {
    pub br: [u32; 8],
    pub bear: u32,
    pub besr: u32,
    pub iocr: u32,
    pub dma: [u32; (number::DMA_LAST - number::DMA_FIRST + 1) as usize],
    pub dmasr: u32,
}

impl Ppc403 {
    /// The DCR `n`, or `None` when the 403 has none there.
    pub fn dcr(&self, n: u32) -> Option<u32> {
        use number::*;
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
        use number::*;
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
