//! Executing one instruction: fetch, decode by opcode, the addressing modes and the ALU with
//! its flags (Intel's MCS-51 instruction set).

use crate::core::Mcs51;
use crate::event::Event;
use crate::opcodes::{CYCLES, RESERVED};
use crate::sfr::psw::{AC, CY, OV};
use crate::{Bus, Clocks};

impl Mcs51 {
    /// Runs the instruction at PC. `now` moves to its end first: during it, `now - 12` is the
    /// start of its last machine cycle, when its SFR and external accesses happen.
    #[inline(always)]
    pub(crate) fn execute<B: Bus>(&mut self, bus: &mut B) {
        let op = bus.code(self.pc);
        self.pc = self.pc.wrapping_add(1);
        self.instructions += 1;
        self.now = self.now.plus_cycles(CYCLES[usize::from(op)]);
        match op {
            0x00 => {}
            // AJMP addr11
            0x01 | 0x21 | 0x41 | 0x61 | 0x81 | 0xA1 | 0xC1 | 0xE1 => {
                let lo = self.imm(bus);
                self.pc = page_target(self.pc, op, lo);
            }
            // ACALL addr11
            0x11 | 0x31 | 0x51 | 0x71 | 0x91 | 0xB1 | 0xD1 | 0xF1 => {
                let lo = self.imm(bus);
                self.call(page_target(self.pc, op, lo));
            }
            0x02 => self.pc = self.imm16(bus),
            0x12 => {
                let target = self.imm16(bus);
                self.call(target);
            }
            0x03 => self.a = self.a.rotate_right(1),
            0x13 => {
                let c = self.a & 1;
                self.a = (self.a >> 1) | (self.psw & CY);
                self.set_cy(c != 0);
            }
            0x23 => self.a = self.a.rotate_left(1),
            0x33 => {
                let c = self.a & 0x80;
                self.a = (self.a << 1) | (self.psw >> 7);
                self.set_cy(c != 0);
            }
            // INC
            0x04 => self.a = self.a.wrapping_add(1),
            0x05 => {
                let d = self.imm(bus);
                let v = self.direct_latch(d).wrapping_add(1);
                self.set_direct(d, v);
            }
            0x06 | 0x07 => {
                let addr = self.r(op & 1);
                self.set_indirect(addr, self.indirect(addr).wrapping_add(1));
            }
            0x08..=0x0F => self.set_r(op & 7, self.r(op & 7).wrapping_add(1)),
            // DEC
            0x14 => self.a = self.a.wrapping_sub(1),
            0x15 => {
                let d = self.imm(bus);
                let v = self.direct_latch(d).wrapping_sub(1);
                self.set_direct(d, v);
            }
            0x16 | 0x17 => {
                let addr = self.r(op & 1);
                self.set_indirect(addr, self.indirect(addr).wrapping_sub(1));
            }
            0x18..=0x1F => self.set_r(op & 7, self.r(op & 7).wrapping_sub(1)),
            // JBC, JB, JNB bit,rel
            0x10 => {
                let bit = self.imm(bus);
                let rel = self.imm(bus);
                if self.bit_latch(bit) {
                    self.set_bit(bit, false);
                    self.jump(rel);
                }
            }
            0x20 | 0x30 => {
                let bit = self.imm(bus);
                let rel = self.imm(bus);
                if self.bit(bit) == (op == 0x20) {
                    self.jump(rel);
                }
            }
            0x22 => self.ret(),
            0x32 => {
                self.ret();
                self.irq.reti();
                self.irq_block = true;
                self.next_event = Clocks::ZERO;
            }
            // ADD, ADDC, ORL, ANL, XRL, SUBB A,src
            0x24..=0x2F => {
                let v = self.source(bus, op);
                self.add(v, false);
            }
            0x34..=0x3F => {
                let v = self.source(bus, op);
                self.add(v, self.psw & CY != 0);
            }
            0x44..=0x4F => self.a |= self.source(bus, op),
            0x54..=0x5F => self.a &= self.source(bus, op),
            0x64..=0x6F => self.a ^= self.source(bus, op),
            0x94..=0x9F => {
                let v = self.source(bus, op);
                self.subb(v);
            }
            // Conditional jumps on C and A
            0x40 | 0x50 | 0x60 | 0x70 => {
                let rel = self.imm(bus);
                let taken = match op {
                    0x40 => self.psw & CY != 0,
                    0x50 => self.psw & CY == 0,
                    0x60 => self.a == 0,
                    _ => self.a != 0,
                };
                if taken {
                    self.jump(rel);
                }
            }
            // ORL, ANL, XRL direct,A / direct,#data (read-modify-write: ports give the latch)
            0x42 | 0x43 | 0x52 | 0x53 | 0x62 | 0x63 => {
                let d = self.imm(bus);
                let v = if op & 1 == 0 { self.a } else { self.imm(bus) };
                let old = self.direct_latch(d);
                let new = match op >> 4 {
                    4 => old | v,
                    5 => old & v,
                    _ => old ^ v,
                };
                self.set_direct(d, new);
            }
            // Boolean operations on C
            0x72 | 0x82 | 0xA0 | 0xB0 => {
                let bit = self.imm(bus);
                let v = self.bit(bit);
                let c = self.psw & CY != 0;
                let c = match op {
                    0x72 => c | v,
                    0x82 => c & v,
                    0xA0 => c | !v,
                    _ => c & !v,
                };
                self.set_cy(c);
            }
            0x73 => self.pc = self.dptr.wrapping_add(u16::from(self.a)),
            0x74 => self.a = self.imm(bus),
            0x75 => {
                let d = self.imm(bus);
                let v = self.imm(bus);
                self.set_direct(d, v);
            }
            0x76 | 0x77 => {
                let v = self.imm(bus);
                self.set_indirect(self.r(op & 1), v);
            }
            0x78..=0x7F => {
                let v = self.imm(bus);
                self.set_r(op & 7, v);
            }
            0x80 => {
                let rel = self.imm(bus);
                self.jump(rel);
            }
            0x83 => self.a = bus.code(self.pc.wrapping_add(u16::from(self.a))),
            0x84 => {
                self.psw &= !(CY | OV);
                match (self.a.checked_div(self.b), self.a.checked_rem(self.b)) {
                    (Some(q), Some(r)) => {
                        self.a = q;
                        self.b = r;
                    }
                    // Quotient and remainder are undefined; A and B are left alone (as s51).
                    _ => self.psw |= OV,
                }
            }
            0x85 => {
                let src = self.imm(bus);
                let dst = self.imm(bus);
                let v = self.direct(src);
                self.set_direct(dst, v);
            }
            0x86 | 0x87 => {
                let d = self.imm(bus);
                let v = self.indirect(self.r(op & 1));
                self.set_direct(d, v);
            }
            0x88..=0x8F => {
                let d = self.imm(bus);
                self.set_direct(d, self.r(op & 7));
            }
            0x90 => self.dptr = self.imm16(bus),
            0x92 => {
                let bit = self.imm(bus);
                self.set_bit(bit, self.psw & CY != 0);
            }
            0x93 => {
                let addr = self.dptr.wrapping_add(u16::from(self.a));
                self.a = bus.code(addr);
            }
            0xA2 => {
                let bit = self.imm(bus);
                let v = self.bit(bit);
                self.set_cy(v);
            }
            0xA3 => self.dptr = self.dptr.wrapping_add(1),
            0xA4 => {
                let product = u16::from(self.a) * u16::from(self.b);
                [self.b, self.a] = product.to_be_bytes();
                self.psw &= !(CY | OV);
                if product > 0xFF {
                    self.psw |= OV;
                }
            }
            RESERVED => self.push_event(Event::ReservedOpcode {
                pc: self.pc.wrapping_sub(1),
                at: self.access_at(),
            }),
            0xA6 | 0xA7 => {
                let d = self.imm(bus);
                let v = self.direct(d);
                self.set_indirect(self.r(op & 1), v);
            }
            0xA8..=0xAF => {
                let d = self.imm(bus);
                let v = self.direct(d);
                self.set_r(op & 7, v);
            }
            0xB2 => {
                let bit = self.imm(bus);
                let v = self.bit_latch(bit);
                self.set_bit(bit, !v);
            }
            0xB3 => self.psw ^= CY,
            // CJNE
            0xB4..=0xBF => {
                let (left, right) = match op {
                    0xB4 => (self.a, self.imm(bus)),
                    0xB5 => {
                        let d = self.imm(bus);
                        (self.a, self.direct(d))
                    }
                    0xB6 | 0xB7 => (self.indirect(self.r(op & 1)), self.imm(bus)),
                    _ => (self.r(op & 7), self.imm(bus)),
                };
                let rel = self.imm(bus);
                self.set_cy(left < right);
                if left != right {
                    self.jump(rel);
                }
            }
            0xC0 => {
                let d = self.imm(bus);
                self.sp = self.sp.wrapping_add(1);
                let v = self.direct(d);
                self.set_indirect(self.sp, v);
            }
            0xC2 | 0xD2 => {
                let bit = self.imm(bus);
                self.set_bit(bit, op == 0xD2);
            }
            0xC3 => self.psw &= !CY,
            0xD3 => self.psw |= CY,
            0xC4 => self.a = self.a.rotate_left(4),
            // XCH A,src
            0xC5 => {
                let d = self.imm(bus);
                let v = self.direct(d);
                self.set_direct(d, self.a);
                self.a = v;
            }
            0xC6 | 0xC7 => {
                let addr = self.r(op & 1);
                let v = self.indirect(addr);
                self.set_indirect(addr, self.a);
                self.a = v;
            }
            0xC8..=0xCF => {
                let v = self.r(op & 7);
                self.set_r(op & 7, self.a);
                self.a = v;
            }
            0xD0 => {
                let d = self.imm(bus);
                let v = self.pop();
                self.set_direct(d, v);
            }
            0xD4 => self.decimal_adjust(),
            0xD5 => {
                let d = self.imm(bus);
                let rel = self.imm(bus);
                let v = self.direct_latch(d).wrapping_sub(1);
                self.set_direct(d, v);
                if v != 0 {
                    self.jump(rel);
                }
            }
            0xD6 | 0xD7 => {
                let addr = self.r(op & 1);
                let m = self.indirect(addr);
                self.set_indirect(addr, (m & 0xF0) | (self.a & 0x0F));
                self.a = (self.a & 0xF0) | (m & 0x0F);
            }
            0xD8..=0xDF => {
                let rel = self.imm(bus);
                let v = self.r(op & 7).wrapping_sub(1);
                self.set_r(op & 7, v);
                if v != 0 {
                    self.jump(rel);
                }
            }
            // MOVX
            0xE0 => {
                let at = self.access_at();
                self.a = bus.read_xdata(self.dptr, at);
                self.external_access(at);
            }
            0xE2 | 0xE3 => {
                let at = self.access_at();
                let addr = self.paged(op);
                self.a = bus.read_xdata(addr, at);
                self.external_access(at);
            }
            0xF0 => {
                let at = self.access_at();
                bus.write_xdata(self.dptr, self.a, at);
                self.external_access(at);
            }
            0xF2 | 0xF3 => {
                let at = self.access_at();
                let addr = self.paged(op);
                bus.write_xdata(addr, self.a, at);
                self.external_access(at);
            }
            0xE4 => self.a = 0,
            0xE5 => {
                let d = self.imm(bus);
                self.a = self.direct(d);
            }
            0xE6 | 0xE7 => self.a = self.indirect(self.r(op & 1)),
            0xE8..=0xEF => self.a = self.r(op & 7),
            0xF4 => self.a = !self.a,
            0xF5 => {
                let d = self.imm(bus);
                self.set_direct(d, self.a);
            }
            0xF6 | 0xF7 => self.set_indirect(self.r(op & 1), self.a),
            0xF8..=0xFF => self.set_r(op & 7, self.a),
        }
    }

    // ----- operands ------------------------------------------------------------------------

    #[inline(always)]
    fn imm<B: Bus>(&mut self, bus: &mut B) -> u8 {
        let v = bus.code(self.pc);
        self.pc = self.pc.wrapping_add(1);
        v
    }

    #[inline(always)]
    fn imm16<B: Bus>(&mut self, bus: &mut B) -> u16 {
        let hi = self.imm(bus);
        let lo = self.imm(bus);
        u16::from_be_bytes([hi, lo])
    }

    /// The second operand of the ALU columns: #data, direct, @Ri or Rn by the low nibble.
    #[inline(always)]
    fn source<B: Bus>(&mut self, bus: &mut B, op: u8) -> u8 {
        match op & 0x0F {
            0x04 => self.imm(bus),
            0x05 => {
                let d = self.imm(bus);
                self.direct(d)
            }
            0x06 | 0x07 => self.indirect(self.r(op & 1)),
            _ => self.r(op & 7),
        }
    }

    #[inline(always)]
    fn set_r(&mut self, n: u8, v: u8) {
        self.iram[usize::from((self.psw & 0x18) | n)] = v;
    }

    /// The start of the current instruction's last machine cycle.
    #[inline(always)]
    fn access_at(&self) -> Clocks {
        self.now - Clocks::CYCLE
    }

    #[inline(always)]
    fn direct(&mut self, addr: u8) -> u8 {
        if addr < 0x80 {
            self.iram[usize::from(addr)]
        } else {
            self.sfr_read(addr, false, self.access_at())
        }
    }

    /// A read-modify-write instruction's read: ports give their latch.
    #[inline(always)]
    fn direct_latch(&mut self, addr: u8) -> u8 {
        if addr < 0x80 {
            self.iram[usize::from(addr)]
        } else {
            self.sfr_read(addr, true, self.access_at())
        }
    }

    #[inline(always)]
    fn set_direct(&mut self, addr: u8, v: u8) {
        if addr < 0x80 {
            self.iram[usize::from(addr)] = v;
        } else {
            self.sfr_write(addr, v, self.access_at());
        }
    }

    /// Bit `bit`: 00h..7Fh in RAM 20h..2Fh, 80h..FFh in the SFRs at multiples of 8.
    #[inline(always)]
    fn bit(&mut self, bit: u8) -> bool {
        let (addr, mask) = bit_place(bit);
        self.direct(addr) & mask != 0
    }

    #[inline(always)]
    fn bit_latch(&mut self, bit: u8) -> bool {
        let (addr, mask) = bit_place(bit);
        self.direct_latch(addr) & mask != 0
    }

    /// Writes one bit: the whole byte is read (ports: the latch), changed and written back.
    #[inline(always)]
    fn set_bit(&mut self, bit: u8, v: bool) {
        let (addr, mask) = bit_place(bit);
        let old = self.direct_latch(addr);
        let new = if v { old | mask } else { old & !mask };
        self.set_direct(addr, new);
    }

    /// `MOVX @Ri`: P2's latch gives the high address byte.
    #[inline(always)]
    fn paged(&self, op: u8) -> u16 {
        u16::from_be_bytes([self.ports.latch[2], self.r(op & 1)])
    }

    // ----- flow ----------------------------------------------------------------------------

    #[inline(always)]
    fn jump(&mut self, rel: u8) {
        self.pc = self.pc.wrapping_add(rel as i8 as u16);
    }

    #[inline(always)]
    fn call(&mut self, target: u16) {
        let [hi, lo] = self.pc.to_be_bytes();
        self.push(lo);
        self.push(hi);
        self.pc = target;
    }

    // ----- ALU -----------------------------------------------------------------------------

    #[inline(always)]
    fn set_cy(&mut self, c: bool) {
        self.psw = (self.psw & !CY) | if c { CY } else { 0 };
    }

    /// A + v + carry_in: CY out of bit 7, AC out of bit 3, OV when the carries out of bits 6
    /// and 7 differ.
    #[inline(always)]
    fn add(&mut self, v: u8, carry_in: bool) {
        let (a, v, c) = (u16::from(self.a), u16::from(v), u16::from(carry_in));
        let sum = a + v + c;
        let cy = sum > 0xFF;
        let ac = (a & 0x0F) + (v & 0x0F) + c > 0x0F;
        let c6 = (a & 0x7F) + (v & 0x7F) + c > 0x7F;
        self.a = sum as u8;
        self.set_arith_flags(cy, ac, c6 != cy);
    }

    /// A − v − CY: CY is the borrow into bit 7, AC the borrow into bit 3, OV when the borrows
    /// into bits 6 and 7 differ.
    #[inline(always)]
    fn subb(&mut self, v: u8) {
        let c = u16::from(self.psw & CY != 0);
        let (a, v) = (u16::from(self.a), u16::from(v));
        let cy = a < v + c;
        let ac = (a & 0x0F) < (v & 0x0F) + c;
        let b6 = (a & 0x7F) < (v & 0x7F) + c;
        self.a = a.wrapping_sub(v + c) as u8;
        self.set_arith_flags(cy, ac, b6 != cy);
    }

    #[inline(always)]
    fn set_arith_flags(&mut self, cy: bool, ac: bool, ov: bool) {
        self.psw = (self.psw & !(CY | AC | OV))
            | if cy { CY } else { 0 }
            | if ac { AC } else { 0 }
            | if ov { OV } else { 0 };
    }

    /// `DA A`: adds 06h if the low digit is above 9 or AC is set, then 60h if the high digit
    /// is now above 9 or CY is set; a carry out of either addition sets CY, nothing clears it.
    fn decimal_adjust(&mut self) {
        let mut a = u16::from(self.a);
        let mut cy = self.psw & CY != 0;
        if a & 0x0F > 9 || self.psw & AC != 0 {
            a += 0x06;
            cy |= a > 0xFF;
            a &= 0xFF;
        }
        if a >> 4 > 9 || cy {
            a += 0x60;
            cy |= a > 0xFF;
            a &= 0xFF;
        }
        self.a = a as u8;
        self.set_cy(cy);
    }
}

#[inline(always)]
fn bit_place(bit: u8) -> (u8, u8) {
    let addr = if bit < 0x80 {
        0x20 + (bit >> 3)
    } else {
        bit & 0xF8
    };
    (addr, 1 << (bit & 7))
}

/// AJMP/ACALL: the 11-bit target within the 2 KiB page of the next instruction.
#[inline(always)]
fn page_target(next: u16, op: u8, lo: u8) -> u16 {
    (next & 0xF800) | u16::from(op >> 5) << 8 | u16::from(lo)
}
