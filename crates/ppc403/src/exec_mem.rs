//! Loads and stores: D-form and indexed, with update, algebraic, byte-reversed, multiple,
//! string, `lwarx`/`stwcx.`, and the cache instructions (only `dcbz` changes memory).
//!
//! Accesses are aligned to their size or they are the alignment exception (DEAR = the
//! address). A bus error is the data machine check (BEAR = the address). A load costs one
//! cycle more than other instructions; `lmw`/`stmw` and the strings one cycle per word.

use crate::core::{Event, Executed, Ppc403};
use crate::decode::{ra, rb, rd, simm};
use crate::exceptions::{esr, illegal, privileged};
use crate::{Bus, Cycles, Exception, Size};

/// Cycles a load costs beyond the first.
const LOAD_EXTRA: u64 = 1;
/// The data cache's line size (dcbz zeroes one line).
const CACHE_LINE: u32 = 16;

/// What a data-side bus error leaves in BESR: "a data-side error", plus "a write" for a
/// store (a simplification of the 403's syndrome; documented in docs/ppc403.md).
const BESR_DATA_ERROR: u32 = 0x8000_0000;
const BESR_WRITE: u32 = 0x0800_0000;

impl Ppc403 {
    #[inline(always)]
    fn ea_base(&self, w: u32) -> u32 {
        match ra(w) {
            0 => 0,
            n => self.regs.gpr[n],
        }
    }

    /// A load of `size` at `addr`: aligned, or the alignment exception.
    #[inline(always)]
    pub(crate) fn load(&mut self, bus: &mut impl Bus, addr: u32, size: Size) -> Result<u32, Event> {
        if addr & (size.bytes() - 1) != 0 {
            return Err(self.misaligned(addr, false));
        }
        bus.read(addr, size, Cycles(self.now))
            .map_err(|e| self.bus_error(e.addr, false))
    }

    /// A store of `size` at `addr`: aligned, or the alignment exception.
    #[inline(always)]
    pub(crate) fn store(
        &mut self,
        bus: &mut impl Bus,
        addr: u32,
        size: Size,
        value: u32,
    ) -> Result<(), Event> {
        if addr & (size.bytes() - 1) != 0 {
            return Err(self.misaligned(addr, true));
        }
        bus.write(addr, size, value, Cycles(self.now))
            .map_err(|e| self.bus_error(e.addr, true))
    }

    #[cold]
    fn misaligned(&mut self, addr: u32, store: bool) -> Event {
        self.regs.dear = addr;
        self.regs.esr = if store { esr::DST } else { 0 };
        Event::Exception(Exception::Alignment { addr })
    }

    #[cold]
    fn bus_error(&mut self, addr: u32, store: bool) -> Event {
        self.dcrs.bear = addr;
        self.dcrs.besr = BESR_DATA_ERROR | if store { BESR_WRITE } else { 0 };
        Event::Exception(Exception::MachineCheck { addr })
    }

    /// Primary opcodes 32..47: the D-form loads and stores, `lmw`, `stmw`.
    #[inline(always)]
    pub(crate) fn load_store_d(&mut self, bus: &mut impl Bus, op: u32, w: u32) -> Executed {
        match op {
            46 => return self.load_multiple(bus, w),
            47 => return self.store_multiple(bus, w),
            _ => {}
        }
        let update = op & 1 == 1;
        let ea = if update {
            self.regs.gpr[ra(w)].wrapping_add(simm(w))
        } else {
            self.ea_base(w).wrapping_add(simm(w))
        };
        self.access(bus, w, op & !1, ea, update)
    }

    /// The access of a load or store given by its non-update primary opcode (32 lwz, 34 lbz,
    /// 36 stw, 38 stb, 40 lhz, 42 lha, 44 sth) at `ea`; with `update`, rA = `ea` after.
    #[inline(always)]
    fn access(
        &mut self,
        bus: &mut impl Bus,
        w: u32,
        base_op: u32,
        ea: u32,
        update: bool,
    ) -> Executed {
        let is_store = matches!(base_op, 36 | 38 | 44);
        if update && (ra(w) == 0 || (!is_store && ra(w) == rd(w))) {
            return illegal(w);
        }
        match base_op {
            32 => self.regs.gpr[rd(w)] = self.load(bus, ea, Size::Word)?,
            34 => self.regs.gpr[rd(w)] = self.load(bus, ea, Size::Byte)?,
            40 => self.regs.gpr[rd(w)] = self.load(bus, ea, Size::Half)?,
            42 => {
                self.regs.gpr[rd(w)] = self.load(bus, ea, Size::Half)? as u16 as i16 as i32 as u32
            }
            36 => self.store(bus, ea, Size::Word, self.regs.gpr[rd(w)])?,
            38 => self.store(bus, ea, Size::Byte, self.regs.gpr[rd(w)])?,
            _ => self.store(bus, ea, Size::Half, self.regs.gpr[rd(w)])?,
        }
        if !is_store {
            self.spend(LOAD_EXTRA);
        }
        if update {
            self.regs.gpr[ra(w)] = ea;
        }
        Ok(())
    }

    fn load_multiple(&mut self, bus: &mut impl Bus, w: u32) -> Executed {
        let ea = self.ea_base(w).wrapping_add(simm(w));
        if ea & 3 != 0 {
            return Err(self.misaligned(ea, false));
        }
        for (i, r) in (rd(w)..32).enumerate() {
            self.regs.gpr[r] = self.load(bus, ea.wrapping_add(4 * i as u32), Size::Word)?;
            self.spend(1);
        }
        Ok(())
    }

    fn store_multiple(&mut self, bus: &mut impl Bus, w: u32) -> Executed {
        let ea = self.ea_base(w).wrapping_add(simm(w));
        if ea & 3 != 0 {
            return Err(self.misaligned(ea, true));
        }
        for (i, r) in (rd(w)..32).enumerate() {
            self.store(
                bus,
                ea.wrapping_add(4 * i as u32),
                Size::Word,
                self.regs.gpr[r],
            )?;
            self.spend(1);
        }
        Ok(())
    }

    /// The loads, stores and cache instructions of primary opcode 31; `None` when `x` is not
    /// one of them.
    #[inline(always)]
    pub(crate) fn op31_memory(&mut self, bus: &mut impl Bus, w: u32, x: u32) -> Option<Executed> {
        let indexed = || self.ea_base(w).wrapping_add(self.regs.gpr[rb(w)]);
        let ea = indexed();
        let update_ea = self.regs.gpr[ra(w)].wrapping_add(self.regs.gpr[rb(w)]);
        Some(match x {
            23 => self.access(bus, w, 32, ea, false),
            55 => self.access(bus, w, 32, update_ea, true),
            87 => self.access(bus, w, 34, ea, false),
            119 => self.access(bus, w, 34, update_ea, true),
            279 => self.access(bus, w, 40, ea, false),
            311 => self.access(bus, w, 40, update_ea, true),
            343 => self.access(bus, w, 42, ea, false),
            375 => self.access(bus, w, 42, update_ea, true),
            151 => self.access(bus, w, 36, ea, false),
            183 => self.access(bus, w, 36, update_ea, true),
            215 => self.access(bus, w, 38, ea, false),
            247 => self.access(bus, w, 38, update_ea, true),
            407 => self.access(bus, w, 44, ea, false),
            439 => self.access(bus, w, 44, update_ea, true),
            534 => self.load(bus, ea, Size::Word).map(|v| {
                self.regs.gpr[rd(w)] = v.swap_bytes();
                self.spend(LOAD_EXTRA);
            }),
            790 => self.load(bus, ea, Size::Half).map(|v| {
                self.regs.gpr[rd(w)] = u32::from((v as u16).swap_bytes());
                self.spend(LOAD_EXTRA);
            }),
            662 => self.store(bus, ea, Size::Word, self.regs.gpr[rd(w)].swap_bytes()),
            918 => {
                let v = u32::from((self.regs.gpr[rd(w)] as u16).swap_bytes());
                self.store(bus, ea, Size::Half, v)
            }
            20 => self.load(bus, ea, Size::Word).map(|v| {
                self.regs.gpr[rd(w)] = v;
                self.reservation = Some(ea);
                self.spend(LOAD_EXTRA);
            }),
            150 if w & 1 == 1 => self.store_conditional(bus, w, ea),
            597 => {
                let n = match rb(w) {
                    0 => 32,
                    n => n as u32,
                };
                self.load_string(bus, w, self.ea_base(w), n, false)
            }
            533 => self.load_string(bus, w, ea, self.regs.xer & 0x7F, true),
            725 => {
                let n = match rb(w) {
                    0 => 32,
                    n => n as u32,
                };
                self.store_string(bus, w, self.ea_base(w), n)
            }
            661 => self.store_string(bus, w, ea, self.regs.xer & 0x7F),
            1014 => self.zero_line(bus, ea),
            // dcbf, dcbst, dcbt, dcbtst, icbi: the caches are not modelled.
            86 | 54 | 278 | 246 | 982 => Ok(()),
            // dcbi, dccci, iccci: supervisor, not modelled.
            470 | 454 | 966 => self.supervisor(w),
            // dcread: the cache's data is not modelled, rD = 0.
            486 => self.supervisor(w).map(|()| self.regs.gpr[rd(w)] = 0),
            // icread: into ICDBDR, which reads 0.
            998 => self.supervisor(w).map(|()| self.sprs.icdbdr = 0),
            // sync, eieio: the 403 has one bus, nothing is reordered.
            598 | 854 => Ok(()),
            _ => return None,
        })
    }

    fn supervisor(&self, w: u32) -> Executed {
        if self.problem_state() {
            privileged(w)
        } else {
            Ok(())
        }
    }

    fn store_conditional(&mut self, bus: &mut impl Bus, w: u32, ea: u32) -> Executed {
        let stored = self.reservation == Some(ea);
        if stored {
            self.store(bus, ea, Size::Word, self.regs.gpr[rd(w)])?;
        } else if ea & 3 != 0 {
            return Err(self.misaligned(ea, true));
        }
        self.reservation = None;
        let field = if stored { 0b0010 } else { 0 } | self.xer_so();
        self.set_cr_field(0, field);
        Ok(())
    }

    /// `lswi`/`lswx` of `n` bytes; a form that would load rA (`lswi`: even r0; `lswx`: a
    /// nonzero rA) or rB (`lswx`) is invalid: illegal, as QEMU has it.
    fn load_string(
        &mut self,
        bus: &mut impl Bus,
        w: u32,
        ea: u32,
        n: u32,
        indexed: bool,
    ) -> Executed {
        let loads = |reg: usize| {
            let count = n.div_ceil(4) as usize;
            (reg + 32 - rd(w)) % 32 < count
        };
        let clobbers = if indexed {
            (ra(w) != 0 && loads(ra(w))) || loads(rb(w))
        } else {
            loads(ra(w))
        };
        if clobbers {
            return illegal(w);
        }
        let mut r = rd(w);
        for i in 0..n {
            if i > 0 && i % 4 == 0 {
                r = (r + 1) % 32;
            }
            if i % 4 == 0 {
                self.regs.gpr[r] = 0;
            }
            let byte = self.load(bus, ea.wrapping_add(i), Size::Byte)?;
            self.regs.gpr[r] |= byte << (24 - 8 * (i % 4));
        }
        self.spend(u64::from(n.div_ceil(4)));
        Ok(())
    }

    fn store_string(&mut self, bus: &mut impl Bus, w: u32, ea: u32, n: u32) -> Executed {
        let mut r = rd(w);
        for i in 0..n {
            if i > 0 && i % 4 == 0 {
                r = (r + 1) % 32;
            }
            let byte = self.regs.gpr[r] >> (24 - 8 * (i % 4));
            self.store(bus, ea.wrapping_add(i), Size::Byte, byte & 0xFF)?;
        }
        self.spend(u64::from(n.div_ceil(4)));
        Ok(())
    }

    /// `dcbz`: the 16-byte line holding `ea` becomes zeros.
    fn zero_line(&mut self, bus: &mut impl Bus, ea: u32) -> Executed {
        let line = ea & !(CACHE_LINE - 1);
        for i in 0..CACHE_LINE / 4 {
            self.store(bus, line + 4 * i, Size::Word, 0)?;
        }
        Ok(())
    }
}
