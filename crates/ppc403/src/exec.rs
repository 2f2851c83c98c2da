//! Decoding and dispatch: one `match` on the primary opcode, then on the extended opcode for
//! primary opcodes 19 and 31. The floating-point opcodes (the 403 has no FPU), the 64-bit
//! ones and anything unassigned are illegal instructions.

use crate::Bus;
use crate::core::{Event, Executed, Ppc403};
use crate::decode::{opcd, xo};
use crate::exceptions::illegal;

impl Ppc403 {
    /// Executes `w`, fetched from `pc`; the PC already points past it.
    #[inline(always)]
    pub(crate) fn execute(&mut self, bus: &mut impl Bus, w: u32, pc: u32) -> Executed {
        match opcd(w) {
            3 => self.twi(w),
            7 => self.mulli(w),
            8 => self.subfic(w),
            10 => self.cmpli(w),
            11 => self.cmpi(w),
            12 => self.addic(w, false),
            13 => self.addic(w, true),
            14 => self.addi(w),
            15 => self.addis(w),
            16 => self.branch_conditional(w, pc),
            17 => Err(Event::SystemCall),
            18 => self.branch(w, pc),
            19 => self.op19(w, pc),
            20 => self.rlwimi(w),
            21 => self.rlwinm(w),
            23 => self.rlwnm(w),
            op @ 24..=29 => self.logical_immediate(op, w),
            31 => self.op31(bus, w),
            op @ 32..=47 => self.load_store_d(bus, op, w),
            _ => illegal(w),
        }
    }

    fn op19(&mut self, w: u32, pc: u32) -> Executed {
        match xo(w) {
            16 => self.branch_to_lr(w, pc),
            528 => self.branch_to_ctr(w, pc),
            50 => self.return_from_interrupt(w, false),
            51 => self.return_from_interrupt(w, true),
            // isync: nothing is prefetched ahead of the model.
            150 => Ok(()),
            x => self.cr_logical(w, x),
        }
    }

    #[inline(always)]
    fn op31(&mut self, bus: &mut impl Bus, w: u32) -> Executed {
        let x = xo(w);
        if let Some(done) = self.op31_integer(w, x) {
            return done;
        }
        if let Some(done) = self.op31_memory(bus, w, x) {
            return done;
        }
        match x {
            339 => self.mfspr(w),
            467 => self.mtspr(w),
            371 => self.mftb(w),
            83 | 146 | 131 | 163 => self.msr_instruction(w, x),
            323 => self.move_dcr(w, false),
            451 => self.move_dcr(w, true),
            _ => illegal(w),
        }
    }
}
