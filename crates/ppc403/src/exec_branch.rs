//! Branches: `b`, `bc`, `bclr`, `bcctr` with every BO and BI, the link register, the count
//! register's decrement. A taken branch costs one cycle more than an untaken one.

use crate::core::{Executed, Ppc403};
use crate::decode::{ra, rd};
use crate::exceptions::illegal;

/// Cycles a taken branch costs beyond the first (the 403 refills its fetch).
const TAKEN_EXTRA: u64 = 1;

impl Ppc403 {
    /// `b`, `ba`, `bl`, `bla`.
    pub(crate) fn branch(&mut self, w: u32, pc: u32) -> Executed {
        let offset = ((w & 0x03FF_FFFC) << 6) as i32 >> 6;
        let target = if w & 2 != 0 {
            offset as u32
        } else {
            pc.wrapping_add(offset as u32)
        };
        if w & 1 != 0 {
            self.regs.lr = pc.wrapping_add(4);
        }
        self.regs.pc = target;
        self.spend(TAKEN_EXTRA);
        Ok(())
    }

    /// Whether BO and BI let a conditional branch go, decrementing CTR when BO says so.
    #[inline(always)]
    fn condition(&mut self, w: u32) -> bool {
        let bo = rd(w) as u32;
        let ctr_ok = if bo & 0x04 == 0 {
            self.regs.ctr = self.regs.ctr.wrapping_sub(1);
            (self.regs.ctr != 0) != (bo & 0x02 != 0)
        } else {
            true
        };
        let cond_ok =
            bo & 0x10 != 0 || ((self.regs.cr >> (31 - ra(w))) & 1 == 1) == (bo & 0x08 != 0);
        ctr_ok && cond_ok
    }

    /// `bc`, `bca`, `bcl`, `bcla`.
    pub(crate) fn branch_conditional(&mut self, w: u32, pc: u32) -> Executed {
        let taken = self.condition(w);
        if w & 1 != 0 {
            self.regs.lr = pc.wrapping_add(4);
        }
        if taken {
            let offset = (w & 0xFFFC) as u16 as i16 as i32 as u32;
            self.regs.pc = if w & 2 != 0 {
                offset
            } else {
                pc.wrapping_add(offset)
            };
            self.spend(TAKEN_EXTRA);
        }
        Ok(())
    }

    /// `bclr`, `bclrl`.
    pub(crate) fn branch_to_lr(&mut self, w: u32, pc: u32) -> Executed {
        let taken = self.condition(w);
        let target = self.regs.lr & !3;
        if w & 1 != 0 {
            self.regs.lr = pc.wrapping_add(4);
        }
        if taken {
            self.regs.pc = target;
            self.spend(TAKEN_EXTRA);
        }
        Ok(())
    }

    /// `bcctr`, `bcctrl` (decrementing CTR while branching to it is an invalid form).
    pub(crate) fn branch_to_ctr(&mut self, w: u32, pc: u32) -> Executed {
        if rd(w) & 0x04 == 0 {
            return illegal(w);
        }
        let taken = self.condition(w);
        if w & 1 != 0 {
            self.regs.lr = pc.wrapping_add(4);
        }
        if taken {
            self.regs.pc = self.regs.ctr & !3;
            self.spend(TAKEN_EXTRA);
        }
        Ok(())
    }
}
