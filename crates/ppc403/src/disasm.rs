//! A disassembler for reports and traces: `disassemble(word, pc)` shows an instruction the
//! way the GNU assembler writes it, with the common simplified mnemonics (`li`, `mr`, `nop`,
//! `blr`, `beq`, `bdnz`, `mtlr`, ...) and the 403's register names. A word the core would
//! refuse shows as `.long 0x...`.

use core::fmt;

use crate::dcr::number as dcr;
use crate::decode::{mb, me, opcd, ra, rb, rd, simm, split_field, uimm, xo};
use crate::spr::number as spr;

/// An instruction word at an address, shown by its `Display`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Disassembly {
    pub word: u32,
    pub pc: u32,
}

/// `word`, fetched from `pc` (for branch targets), as assembly text.
pub fn disassemble(word: u32, pc: u32) -> Disassembly {
    Disassembly { word, pc }
}

fn spr_name(n: u32) -> Option<&'static str> {
    Some(match n {
        spr::XER => "XER",
        spr::LR => "LR",
        spr::CTR => "CTR",
        spr::SRR0 => "SRR0",
        spr::SRR1 => "SRR1",
        272 => "SPRG0",
        273 => "SPRG1",
        274 => "SPRG2",
        275 => "SPRG3",
        spr::PVR => "PVR",
        spr::TBHU => "TBHU",
        spr::TBLU => "TBLU",
        spr::ICDBDR => "ICDBDR",
        spr::ESR => "ESR",
        spr::DEAR => "DEAR",
        spr::EVPR => "EVPR",
        spr::CDBCR => "CDBCR",
        spr::TSR => "TSR",
        spr::TCR => "TCR",
        spr::PIT => "PIT",
        spr::TBHI => "TBHI",
        spr::TBLO => "TBLO",
        spr::SRR2 => "SRR2",
        spr::SRR3 => "SRR3",
        spr::DBSR => "DBSR",
        spr::DBCR => "DBCR",
        spr::IAC1 => "IAC1",
        spr::IAC2 => "IAC2",
        spr::DAC1 => "DAC1",
        spr::DAC2 => "DAC2",
        spr::DCCR => "DCCR",
        spr::ICCR => "ICCR",
        0x3FC => "PBL1",
        0x3FD => "PBU1",
        0x3FE => "PBL2",
        0x3FF => "PBU2",
        _ => return None,
    })
}

fn dcr_name(n: u32) -> Option<&'static str> {
    Some(match n {
        dcr::EXISR => "EXISR",
        dcr::EXIER => "EXIER",
        dcr::BEAR => "BEAR",
        dcr::BESR => "BESR",
        dcr::IOCR => "IOCR",
        _ => return None,
    })
}

/// A register number that may have a name.
struct Named(u32, Option<&'static str>);

impl fmt::Display for Named {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.1 {
            Some(name) => f.write_str(name),
            None => write!(f, "{}", self.0),
        }
    }
}

/// The condition of `bc` with BO "branch if true/false" (001zy, 011zy: CTR untouched) as a
/// mnemonic suffix.
fn condition(bo: u32, bi: u32) -> Option<&'static str> {
    let set = match bo & 0x1C {
        0x0C => true,
        0x04 => false,
        _ => return None,
    };
    Some(match (bi % 4, set) {
        (0, true) => "lt",
        (0, false) => "ge",
        (1, true) => "gt",
        (1, false) => "le",
        (2, true) => "eq",
        (2, false) => "ne",
        (3, true) => "so",
        _ => "ns",
    })
}

impl fmt::Display for Disassembly {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (w, pc) = (self.word, self.pc);
        let (d, a, b) = (rd(w), ra(w), rb(w));
        let dot = if w & 1 != 0 { "." } else { "" };
        let si = simm(w) as i32;
        match opcd(w) {
            3 => write!(f, "twi {d},r{a},{si}"),
            7 => write!(f, "mulli r{d},r{a},{si}"),
            8 => write!(f, "subfic r{d},r{a},{si}"),
            10 => write!(f, "cmplwi cr{},r{a},{}", d >> 2, uimm(w)),
            11 => write!(f, "cmpwi cr{},r{a},{si}", d >> 2),
            12 => write!(f, "addic r{d},r{a},{si}"),
            13 => write!(f, "addic. r{d},r{a},{si}"),
            14 if a == 0 => write!(f, "li r{d},{si}"),
            14 => write!(f, "addi r{d},r{a},{si}"),
            15 if a == 0 => write!(f, "lis r{d},{:#x}", uimm(w)),
            15 => write!(f, "addis r{d},r{a},{:#x}", uimm(w)),
            16 => self.branch_conditional(f),
            17 => f.write_str("sc"),
            18 => {
                let offset = (((w & 0x03FF_FFFC) << 6) as i32 >> 6) as u32;
                let target = if w & 2 != 0 {
                    offset
                } else {
                    pc.wrapping_add(offset)
                };
                let link = if w & 1 != 0 { "l" } else { "" };
                let abs = if w & 2 != 0 { "a" } else { "" };
                write!(f, "b{link}{abs} {target:#010x}")
            }
            19 => self.op19(f),
            20 => write!(f, "rlwimi{dot} r{a},r{d},{b},{},{}", mb(w), me(w)),
            21 => write!(f, "rlwinm{dot} r{a},r{d},{b},{},{}", mb(w), me(w)),
            23 => write!(f, "rlwnm{dot} r{a},r{d},r{b},{},{}", mb(w), me(w)),
            24 if w == 0x6000_0000 => f.write_str("nop"),
            op @ 24..=29 => {
                let name = ["ori", "oris", "xori", "xoris", "andi.", "andis."][(op - 24) as usize];
                write!(f, "{name} r{a},r{d},{:#x}", uimm(w))
            }
            31 => self.op31(f),
            op @ 32..=47 => {
                let name = [
                    "lwz", "lwzu", "lbz", "lbzu", "stw", "stwu", "stb", "stbu", "lhz", "lhzu",
                    "lha", "lhau", "sth", "sthu", "lmw", "stmw",
                ][(op - 32) as usize];
                write!(f, "{name} r{d},{si}(r{a})")
            }
            _ => write!(f, ".long {w:#010x}"),
        }
    }
}

impl Disassembly {
    fn branch_conditional(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (w, pc) = (self.word, self.pc);
        let (bo, bi) = (rd(w) as u32, ra(w) as u32);
        let offset = (w & 0xFFFC) as u16 as i16 as i32 as u32;
        let target = if w & 2 != 0 {
            offset
        } else {
            pc.wrapping_add(offset)
        };
        let suffix = match (w & 1 != 0, w & 2 != 0) {
            (false, false) => "",
            (true, false) => "l",
            (false, true) => "a",
            (true, true) => "la",
        };
        if let Some(cond) = condition(bo, bi) {
            let cr = bi / 4;
            if cr == 0 {
                return write!(f, "b{cond}{suffix} {target:#010x}");
            }
            return write!(f, "b{cond}{suffix} cr{cr},{target:#010x}");
        }
        if bo & 0x14 == 0x14 {
            return write!(f, "b{suffix} {target:#010x}");
        }
        match bo & 0x16 {
            0x10 => write!(f, "bdnz{suffix} {target:#010x}"),
            0x12 => write!(f, "bdz{suffix} {target:#010x}"),
            _ => write!(f, "bc{suffix} {bo},{bi},{target:#010x}"),
        }
    }

    fn op19(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let w = self.word;
        let (d, a, b) = (rd(w), ra(w), rb(w));
        let link = if w & 1 != 0 { "l" } else { "" };
        let (bo, bi) = (d as u32, a as u32);
        let to = |f: &mut fmt::Formatter<'_>, reg: &str| {
            if bo & 0x14 == 0x14 {
                return write!(f, "b{reg}{link}");
            }
            if let Some(cond) = condition(bo, bi) {
                return match bi / 4 {
                    0 => write!(f, "b{cond}{reg}{link}"),
                    cr => write!(f, "b{cond}{reg}{link} cr{cr}"),
                };
            }
            match (reg, bo & 0x16) {
                ("lr", 0x10) => write!(f, "bdnzlr{link}"),
                ("lr", 0x12) => write!(f, "bdzlr{link}"),
                _ => write!(f, "bc{reg}{link} {bo},{bi}"),
            }
        };
        let cr_op = |name: &str, f: &mut fmt::Formatter<'_>| write!(f, "{name} {d},{a},{b}");
        match xo(w) {
            0 => write!(f, "mcrf cr{},cr{}", d >> 2, a >> 2),
            16 => to(f, "lr"),
            528 => to(f, "ctr"),
            50 => f.write_str("rfi"),
            51 => f.write_str("rfci"),
            150 => f.write_str("isync"),
            257 => cr_op("crand", f),
            129 => cr_op("crandc", f),
            289 => cr_op("creqv", f),
            225 => cr_op("crnand", f),
            33 => cr_op("crnor", f),
            449 => cr_op("cror", f),
            417 => cr_op("crorc", f),
            193 => cr_op("crxor", f),
            _ => write!(f, ".long {w:#010x}"),
        }
    }

    fn op31(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let w = self.word;
        let (d, a, b) = (rd(w), ra(w), rb(w));
        let dot = if w & 1 != 0 { "." } else { "" };
        let x = xo(w);
        // XO-form arithmetic: rD, rA, rB (or rD, rA), OE as "o".
        let arith = match x & 0x1FF {
            266 => Some(("add", true)),
            10 => Some(("addc", true)),
            138 => Some(("adde", true)),
            234 => Some(("addme", false)),
            202 => Some(("addze", false)),
            40 => Some(("subf", true)),
            8 => Some(("subfc", true)),
            136 => Some(("subfe", true)),
            232 => Some(("subfme", false)),
            200 => Some(("subfze", false)),
            104 => Some(("neg", false)),
            235 => Some(("mullw", true)),
            491 => Some(("divw", true)),
            459 => Some(("divwu", true)),
            75 if x == 75 => Some(("mulhw", true)),
            11 if x == 11 => Some(("mulhwu", true)),
            _ => None,
        };
        if let Some((name, two)) = arith {
            let o = if x & 0x200 != 0 { "o" } else { "" };
            return if two {
                write!(f, "{name}{o}{dot} r{d},r{a},r{b}")
            } else {
                write!(f, "{name}{o}{dot} r{d},r{a}")
            };
        }
        let logical = match x {
            28 => Some("and"),
            60 => Some("andc"),
            444 if d == b => return write!(f, "mr{dot} r{a},r{d}"),
            444 => Some("or"),
            412 => Some("orc"),
            316 => Some("xor"),
            476 => Some("nand"),
            124 => Some("nor"),
            284 => Some("eqv"),
            24 => Some("slw"),
            536 => Some("srw"),
            792 => Some("sraw"),
            _ => None,
        };
        if let Some(name) = logical {
            return write!(f, "{name}{dot} r{a},r{d},r{b}");
        }
        let indexed = match x {
            23 => Some("lwzx"),
            55 => Some("lwzux"),
            87 => Some("lbzx"),
            119 => Some("lbzux"),
            279 => Some("lhzx"),
            311 => Some("lhzux"),
            343 => Some("lhax"),
            375 => Some("lhaux"),
            151 => Some("stwx"),
            183 => Some("stwux"),
            215 => Some("stbx"),
            247 => Some("stbux"),
            407 => Some("sthx"),
            439 => Some("sthux"),
            534 => Some("lwbrx"),
            790 => Some("lhbrx"),
            662 => Some("stwbrx"),
            918 => Some("sthbrx"),
            20 => Some("lwarx"),
            150 if w & 1 == 1 => Some("stwcx."),
            533 => Some("lswx"),
            661 => Some("stswx"),
            _ => None,
        };
        if let Some(name) = indexed {
            return write!(f, "{name} r{d},r{a},r{b}");
        }
        let cache = match x {
            1014 => Some("dcbz"),
            86 => Some("dcbf"),
            54 => Some("dcbst"),
            278 => Some("dcbt"),
            246 => Some("dcbtst"),
            982 => Some("icbi"),
            470 => Some("dcbi"),
            454 => Some("dccci"),
            966 => Some("iccci"),
            998 => Some("icread"),
            _ => None,
        };
        if let Some(name) = cache {
            return write!(f, "{name} r{a},r{b}");
        }
        let n = split_field(w);
        match x {
            0 | 32 => {
                let name = if x == 0 { "cmpw" } else { "cmplw" };
                write!(f, "{name} cr{},r{a},r{b}", d >> 2)
            }
            4 if d == 31 && a == 0 && b == 0 => f.write_str("trap"),
            4 => write!(f, "tw {d},r{a},r{b}"),
            954 => write!(f, "extsb{dot} r{a},r{d}"),
            922 => write!(f, "extsh{dot} r{a},r{d}"),
            26 => write!(f, "cntlzw{dot} r{a},r{d}"),
            824 => write!(f, "srawi{dot} r{a},r{d},{b}"),
            19 => write!(f, "mfcr r{d}"),
            144 if (w >> 12) & 0xFF == 0xFF => write!(f, "mtcr r{d}"),
            144 => write!(f, "mtcrf {:#x},r{d}", (w >> 12) & 0xFF),
            512 => write!(f, "mcrxr cr{}", d >> 2),
            597 => write!(f, "lswi r{d},r{a},{b}"),
            725 => write!(f, "stswi r{d},r{a},{b}"),
            486 => write!(f, "dcread r{d},r{a},r{b}"),
            598 => f.write_str("sync"),
            854 => f.write_str("eieio"),
            83 => write!(f, "mfmsr r{d}"),
            146 => write!(f, "mtmsr r{d}"),
            131 => write!(f, "wrtee r{d}"),
            163 => write!(f, "wrteei {}", (w >> 15) & 1),
            339 => match n {
                spr::LR => write!(f, "mflr r{d}"),
                spr::CTR => write!(f, "mfctr r{d}"),
                spr::XER => write!(f, "mfxer r{d}"),
                _ => write!(f, "mfspr r{d},{}", Named(n, spr_name(n))),
            },
            467 => match n {
                spr::LR => write!(f, "mtlr r{d}"),
                spr::CTR => write!(f, "mtctr r{d}"),
                spr::XER => write!(f, "mtxer r{d}"),
                _ => write!(f, "mtspr {},r{d}", Named(n, spr_name(n))),
            },
            371 => write!(f, "mftb r{d},{n}"),
            323 => write!(f, "mfdcr r{d},{}", Named(n, dcr_name(n))),
            451 => write!(f, "mtdcr {},r{d}", Named(n, dcr_name(n))),
            _ => write!(f, ".long {w:#010x}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::disassemble;
    use alloc::string::ToString;

    fn show(word: u32) -> alloc::string::String {
        disassemble(word, 0x1000).to_string()
    }

    #[test]
    fn common_forms() {
        assert_eq!(show(0x3860_0001), "li r3,1");
        assert_eq!(show(0x3C60_1234), "lis r3,0x1234");
        assert_eq!(show(0x6000_0000), "nop");
        assert_eq!(show(0x7C83_2378), "mr r3,r4");
        assert_eq!(show(0x4E80_0020), "blr");
        assert_eq!(show(0x4E80_0421), "bctrl");
        assert_eq!(show(0x4800_0011), "bl 0x00001010");
        assert_eq!(show(0x4182_FFF8), "beq 0x00000ff8");
        assert_eq!(show(0x4086_0008), "bne cr1,0x00001008");
        assert_eq!(show(0x4200_FFFC), "bdnz 0x00000ffc");
        assert_eq!(show(0x41E6_0008), "beq cr1,0x00001008"); // BO 15: with a hint
        assert_eq!(show(0x4E60_0020), "bdzlr"); // BO 19
        assert_eq!(show(0x4E80_0020 | (8 << 16)), "blr"); // BI ignored
        assert_eq!(show(0x7C08_02A6), "mflr r0");
        assert_eq!(show(0x7C7D_F3A6), "mtspr TBLO,r3");
        assert_eq!(show(0x7C60_0106), "wrtee r3");
        assert_eq!(show(0x7C65_25D7), "mullwo. r3,r5,r4");
        assert_eq!(show(0x9421_FFF0), "stwu r1,-16(r1)");
        assert_eq!(show(0x4400_0002), "sc");
        assert_eq!(show(0x4C00_0064), "rfi");
        assert_eq!(show(0x0000_0000), ".long 0x00000000");
        assert_eq!(show(0x7C60_0286), "mfdcr r3,0");
        assert_eq!(show(0x7C62_1286), "mfdcr r3,EXIER");
    }
}
