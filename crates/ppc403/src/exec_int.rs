//! Integer arithmetic, logic, shifts, rotates, compares and the condition register's own
//! instructions, with XER[SO, OV, CA] and CR0 exactly as Book I defines them.

use crate::core::{Event, Executed, Ppc403, compare_field};
use crate::decode::{mb, me, oe, ra, rb, rc, rd, rotate_mask, simm, uimm};
use crate::exceptions::illegal;

const XER_SO: u32 = 0x8000_0000;
const XER_OV: u32 = 0x4000_0000;
const XER_CA: u32 = 0x2000_0000;

/// `a + b + carry`: the sum, the carry out, and whether it overflowed as signed.
#[inline(always)]
fn add3(a: u32, b: u32, carry: u32) -> (u32, bool, bool) {
    let (s, c1) = a.overflowing_add(b);
    let (r, c2) = s.overflowing_add(carry);
    let ov = ((a ^ r) & (b ^ r)) >> 31 != 0;
    (r, c1 | c2, ov)
}

impl Ppc403 {
    #[inline(always)]
    fn ra_or_zero(&self, w: u32) -> u32 {
        match ra(w) {
            0 => 0,
            n => self.regs.gpr[n],
        }
    }

    #[inline(always)]
    pub(crate) fn xer_ca(&self) -> u32 {
        (self.regs.xer >> 29) & 1
    }

    #[inline(always)]
    pub(crate) fn set_ca(&mut self, ca: bool) {
        self.regs.xer = (self.regs.xer & !XER_CA) | if ca { XER_CA } else { 0 };
    }

    /// XER[OV] = `ov`; SO is sticky.
    #[inline(always)]
    fn set_ov(&mut self, ov: bool) {
        self.regs.xer = (self.regs.xer & !XER_OV) | if ov { XER_OV | XER_SO } else { 0 };
    }

    /// The end of an XO-form instruction: rD, CA when it sets it, OV with OE, CR0 with Rc.
    #[inline(always)]
    fn finish_xo(&mut self, w: u32, result: u32, ca: Option<bool>, ov: bool) -> Executed {
        self.regs.gpr[rd(w)] = result;
        if let Some(ca) = ca {
            self.set_ca(ca);
        }
        if oe(w) {
            self.set_ov(ov);
        }
        if rc(w) {
            self.set_cr0(result);
        }
        Ok(())
    }

    /// The end of an X-form logical instruction: rA, CR0 with Rc.
    #[inline(always)]
    fn finish_logical(&mut self, w: u32, result: u32) -> Executed {
        self.regs.gpr[ra(w)] = result;
        if rc(w) {
            self.set_cr0(result);
        }
        Ok(())
    }

    // D-form immediates.

    pub(crate) fn addi(&mut self, w: u32) -> Executed {
        self.regs.gpr[rd(w)] = self.ra_or_zero(w).wrapping_add(simm(w));
        Ok(())
    }

    pub(crate) fn addis(&mut self, w: u32) -> Executed {
        self.regs.gpr[rd(w)] = self.ra_or_zero(w).wrapping_add(w << 16);
        Ok(())
    }

    /// `addic` and `addic.` (`record`).
    pub(crate) fn addic(&mut self, w: u32, record: bool) -> Executed {
        let (r, ca, _) = add3(self.regs.gpr[ra(w)], simm(w), 0);
        self.regs.gpr[rd(w)] = r;
        self.set_ca(ca);
        if record {
            self.set_cr0(r);
        }
        Ok(())
    }

    pub(crate) fn subfic(&mut self, w: u32) -> Executed {
        let (r, ca, _) = add3(!self.regs.gpr[ra(w)], simm(w), 1);
        self.regs.gpr[rd(w)] = r;
        self.set_ca(ca);
        Ok(())
    }

    pub(crate) fn mulli(&mut self, w: u32) -> Executed {
        let r = (self.regs.gpr[ra(w)] as i32).wrapping_mul(simm(w) as i32);
        self.regs.gpr[rd(w)] = r as u32;
        self.spend(MUL_EXTRA);
        Ok(())
    }

    pub(crate) fn cmpi(&mut self, w: u32) -> Executed {
        if w & 0x0020_0000 != 0 {
            return illegal(w); // L = 1: a 64-bit compare
        }
        let field = compare_field(self.regs.gpr[ra(w)] as i32, simm(w) as i32) | self.xer_so();
        self.set_cr_field(rd(w) >> 2, field);
        Ok(())
    }

    pub(crate) fn cmpli(&mut self, w: u32) -> Executed {
        if w & 0x0020_0000 != 0 {
            return illegal(w);
        }
        let field = compare_field(self.regs.gpr[ra(w)], uimm(w)) | self.xer_so();
        self.set_cr_field(rd(w) >> 2, field);
        Ok(())
    }

    /// `ori`, `oris`, `xori`, `xoris`, `andi.`, `andis.` by primary opcode.
    pub(crate) fn logical_immediate(&mut self, op: u32, w: u32) -> Executed {
        let s = self.regs.gpr[rd(w)];
        let u = uimm(w);
        let r = match op {
            24 => s | u,
            25 => s | (u << 16),
            26 => s ^ u,
            27 => s ^ (u << 16),
            28 => s & u,
            _ => s & (u << 16),
        };
        self.regs.gpr[ra(w)] = r;
        if op >= 28 {
            self.set_cr0(r);
        }
        Ok(())
    }

    // Rotates.

    pub(crate) fn rlwinm(&mut self, w: u32) -> Executed {
        let r = self.regs.gpr[rd(w)].rotate_left(rb(w) as u32) & rotate_mask(mb(w), me(w));
        self.finish_logical(w, r)
    }

    pub(crate) fn rlwnm(&mut self, w: u32) -> Executed {
        let n = self.regs.gpr[rb(w)] & 31;
        let r = self.regs.gpr[rd(w)].rotate_left(n) & rotate_mask(mb(w), me(w));
        self.finish_logical(w, r)
    }

    pub(crate) fn rlwimi(&mut self, w: u32) -> Executed {
        let m = rotate_mask(mb(w), me(w));
        let rot = self.regs.gpr[rd(w)].rotate_left(rb(w) as u32);
        let r = (rot & m) | (self.regs.gpr[ra(w)] & !m);
        self.finish_logical(w, r)
    }

    /// The integer instructions of primary opcode 31 (by extended opcode `x`); `None` when
    /// `x` is not one of them.
    #[inline(always)]
    pub(crate) fn op31_integer(&mut self, w: u32, x: u32) -> Option<Executed> {
        let a = self.regs.gpr[ra(w)];
        let b = self.regs.gpr[rb(w)];
        let s = self.regs.gpr[rd(w)];
        let ca_in = self.xer_ca();
        Some(match x {
            // XO-form arithmetic, without and with OE (+512).
            266 | 778 => {
                let (r, _, ov) = add3(a, b, 0);
                self.finish_xo(w, r, None, ov)
            }
            10 | 522 => {
                let (r, ca, ov) = add3(a, b, 0);
                self.finish_xo(w, r, Some(ca), ov)
            }
            138 | 650 => {
                let (r, ca, ov) = add3(a, b, ca_in);
                self.finish_xo(w, r, Some(ca), ov)
            }
            234 | 746 => {
                let (r, ca, ov) = add3(a, u32::MAX, ca_in);
                self.finish_xo(w, r, Some(ca), ov)
            }
            202 | 714 => {
                let (r, ca, ov) = add3(a, 0, ca_in);
                self.finish_xo(w, r, Some(ca), ov)
            }
            40 | 552 => {
                let (r, _, ov) = add3(!a, b, 1);
                self.finish_xo(w, r, None, ov)
            }
            8 | 520 => {
                let (r, ca, ov) = add3(!a, b, 1);
                self.finish_xo(w, r, Some(ca), ov)
            }
            136 | 648 => {
                let (r, ca, ov) = add3(!a, b, ca_in);
                self.finish_xo(w, r, Some(ca), ov)
            }
            232 | 744 => {
                let (r, ca, ov) = add3(!a, u32::MAX, ca_in);
                self.finish_xo(w, r, Some(ca), ov)
            }
            200 | 712 => {
                let (r, ca, ov) = add3(!a, 0, ca_in);
                self.finish_xo(w, r, Some(ca), ov)
            }
            104 | 616 => {
                let (r, _, ov) = add3(!a, 0, 1);
                self.finish_xo(w, r, None, ov)
            }
            235 | 747 => {
                let p = i64::from(a as i32) * i64::from(b as i32);
                self.spend(MUL_EXTRA);
                self.finish_xo(w, p as u32, None, p != i64::from(p as i32))
            }
            75 => {
                let p = i64::from(a as i32) * i64::from(b as i32);
                self.spend(MUL_EXTRA);
                self.finish_xo(w, (p >> 32) as u32, None, false)
            }
            11 => {
                let p = u64::from(a) * u64::from(b);
                self.spend(MUL_EXTRA);
                self.finish_xo(w, (p >> 32) as u32, None, false)
            }
            491 | 1003 => {
                self.spend(DIV_EXTRA);
                let (n, d) = (a as i32, b as i32);
                if d == 0 || (n == i32::MIN && d == -1) {
                    // Undefined by the architecture: the dividend, as QEMU gives.
                    self.finish_xo(w, a, None, true)
                } else {
                    self.finish_xo(w, (n / d) as u32, None, false)
                }
            }
            459 | 971 => {
                self.spend(DIV_EXTRA);
                match a.checked_div(b) {
                    Some(q) => self.finish_xo(w, q, None, false),
                    None => self.finish_xo(w, a, None, true),
                }
            }
            // Logical, rS → rA.
            28 => self.finish_logical(w, s & b),
            60 => self.finish_logical(w, s & !b),
            444 => self.finish_logical(w, s | b),
            412 => self.finish_logical(w, s | !b),
            316 => self.finish_logical(w, s ^ b),
            476 => self.finish_logical(w, !(s & b)),
            124 => self.finish_logical(w, !(s | b)),
            284 => self.finish_logical(w, !(s ^ b)),
            954 => self.finish_logical(w, s as u8 as i8 as i32 as u32),
            922 => self.finish_logical(w, s as u16 as i16 as i32 as u32),
            26 => self.finish_logical(w, s.leading_zeros()),
            // Shifts (the amount is rB's low 6 bits: 32..63 shift everything out).
            24 => {
                let n = b & 63;
                self.finish_logical(w, if n > 31 { 0 } else { s << n })
            }
            536 => {
                let n = b & 63;
                self.finish_logical(w, if n > 31 { 0 } else { s >> n })
            }
            792 => {
                let n = b & 63;
                self.shift_right_algebraic(w, s, n)
            }
            824 => self.shift_right_algebraic(w, s, rb(w) as u32),
            // Compares.
            0 => {
                if w & 0x0020_0000 != 0 {
                    return Some(illegal(w));
                }
                let field = compare_field(a as i32, b as i32) | self.xer_so();
                self.set_cr_field(rd(w) >> 2, field);
                Ok(())
            }
            32 => {
                if w & 0x0020_0000 != 0 {
                    return Some(illegal(w));
                }
                let field = compare_field(a, b) | self.xer_so();
                self.set_cr_field(rd(w) >> 2, field);
                Ok(())
            }
            // Traps.
            4 => self.trap(w, a, b),
            // CR and XER moves.
            19 => {
                self.regs.gpr[rd(w)] = self.regs.cr;
                Ok(())
            }
            144 => {
                let fxm = (w >> 12) & 0xFF;
                let mut mask = 0;
                for field in 0..8 {
                    if fxm & (0x80 >> field) != 0 {
                        mask |= 0xF000_0000 >> (4 * field);
                    }
                }
                self.regs.cr = (self.regs.cr & !mask) | (s & mask);
                Ok(())
            }
            512 => {
                let field = self.regs.xer >> 28;
                self.set_cr_field(rd(w) >> 2, field);
                self.regs.xer &= 0x0FFF_FFFF;
                Ok(())
            }
            _ => return None,
        })
    }

    /// `sraw`/`srawi` by `n` (0..63): CA when the result is negative and 1 bits were lost.
    fn shift_right_algebraic(&mut self, w: u32, s: u32, n: u32) -> Executed {
        let negative = (s as i32) < 0;
        let (r, lost) = if n > 31 {
            (if negative { u32::MAX } else { 0 }, s != 0)
        } else {
            ((s as i32 >> n) as u32, n > 0 && s << (32 - n) != 0)
        };
        self.set_ca(negative && lost);
        self.finish_logical(w, r)
    }

    pub(crate) fn twi(&mut self, w: u32) -> Executed {
        self.trap(w, self.regs.gpr[ra(w)], simm(w))
    }

    fn trap(&mut self, w: u32, a: u32, b: u32) -> Executed {
        let to = rd(w) as u32;
        let (sa, sb) = (a as i32, b as i32);
        let hit = (to & 0x10 != 0 && sa < sb)
            || (to & 0x08 != 0 && sa > sb)
            || (to & 0x04 != 0 && a == b)
            || (to & 0x02 != 0 && a < b)
            || (to & 0x01 != 0 && a > b);
        if hit {
            Err(Event::Exception(crate::Exception::Trap))
        } else {
            Ok(())
        }
    }

    /// The CR-logical instructions and `mcrf` (primary opcode 19) by extended opcode.
    pub(crate) fn cr_logical(&mut self, w: u32, x: u32) -> Executed {
        if x == 0 {
            let field = self.regs.cr >> (28 - 4 * (ra(w) as u32 >> 2));
            self.set_cr_field(rd(w) >> 2, field);
            return Ok(());
        }
        let bit = |n: usize| (self.regs.cr >> (31 - n)) & 1;
        let (a, b) = (bit(ra(w)), bit(rb(w)));
        let r = match x {
            257 => a & b,
            129 => a & !b,
            289 => !(a ^ b),
            225 => !(a & b),
            33 => !(a | b),
            449 => a | b,
            417 => a | !b,
            193 => a ^ b,
            _ => return illegal(w),
        } & 1;
        let shift = 31 - rd(w) as u32;
        self.regs.cr = (self.regs.cr & !(1 << shift)) | (r << shift);
        Ok(())
    }
}

/// Cycles a multiply takes beyond the first (the 403's multiplier: 4 cycles).
const MUL_EXTRA: u64 = 3;
/// Cycles a divide takes beyond the first (the 403's divider: 33 cycles).
const DIV_EXTRA: u64 = 32;
