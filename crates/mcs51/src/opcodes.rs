//! The instruction set as a table: length and machine cycles of every opcode (Intel's
//! MCS-51 instruction table), and a disassembler for traces and test reports.

use core::fmt;

use crate::Bus;

/// Bytes of each opcode's instruction.
pub const LENGTH: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut op = 0;
    while op < 256 {
        t[op] = length(op as u8);
        op += 1;
    }
    t
};

/// Machine cycles of each opcode's instruction (1, 2 or 4; taken or not, a branch costs the
/// same).
pub const CYCLES: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut op = 0;
    while op < 256 {
        t[op] = cycles(op as u8);
        op += 1;
    }
    t
};

/// The opcode no instruction has. This core runs it as a one-byte, one-cycle no-op (as SDCC's
/// `s51` does) and reports it ([`Event::ReservedOpcode`](crate::Event::ReservedOpcode)).
pub const RESERVED: u8 = 0xA5;

const fn length(op: u8) -> u8 {
    match op {
        _ if op & 0x1F == 0x01 || op & 0x1F == 0x11 => 2, // AJMP, ACALL
        0x02 | 0x12 | 0x10 | 0x20 | 0x30 | 0x43 | 0x53 | 0x63 | 0x75 | 0x85 | 0x90 => 3,
        0xB4..=0xBF | 0xD5 => 3,
        0x05 | 0x15 | 0x24 | 0x25 | 0x34 | 0x35 | 0x40 | 0x50 | 0x60 | 0x70 => 2,
        0x42 | 0x44 | 0x45 | 0x52 | 0x54 | 0x55 | 0x62 | 0x64 | 0x65 => 2,
        0x72 | 0x74 | 0x76..=0x7F | 0x80 | 0x82 | 0x86..=0x8F | 0x92 | 0x94 | 0x95 => 2,
        0xA0 | 0xA2 | 0xA6..=0xAF | 0xB0 | 0xB2 | 0xC0 | 0xC2 | 0xC5 | 0xD0 | 0xD2 => 2,
        0xD8..=0xDF | 0xE5 | 0xF5 => 2,
        _ => 1,
    }
}

const fn cycles(op: u8) -> u8 {
    match op {
        0x84 | 0xA4 => 4, // DIV, MUL
        _ if op & 0x1F == 0x01 || op & 0x1F == 0x11 => 2,
        0x02 | 0x12 | 0x10 | 0x20 | 0x30 | 0x22 | 0x32 | 0x40 | 0x50 | 0x60 | 0x70 => 2,
        0x43 | 0x53 | 0x63 | 0x72 | 0x73 | 0x75 | 0x80 | 0x82 | 0x83 | 0x85..=0x8F => 2,
        0x90 | 0x92 | 0x93 | 0xA0 | 0xA3 | 0xA6..=0xAF | 0xB0 | 0xB4..=0xBF => 2,
        0xC0 | 0xD0 | 0xD5 | 0xD8..=0xDF | 0xE0 | 0xE2 | 0xE3 | 0xF0 | 0xF2 | 0xF3 => 2,
        _ => 1,
    }
}

/// One instruction as it sits in code memory, for display.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Instruction {
    /// Its address.
    pub pc: u16,
    /// Its bytes (those past its length are not part of it).
    pub bytes: [u8; 3],
}

impl Instruction {
    /// The instruction at `pc`.
    pub fn at(bus: &mut impl Bus, pc: u16) -> Instruction {
        Instruction {
            pc,
            bytes: [
                bus.code(pc),
                bus.code(pc.wrapping_add(1)),
                bus.code(pc.wrapping_add(2)),
            ],
        }
    }

    /// Its length in bytes.
    pub fn length(&self) -> u8 {
        LENGTH[usize::from(self.bytes[0])]
    }

    /// Machine cycles it takes.
    pub fn cycles(&self) -> u8 {
        CYCLES[usize::from(self.bytes[0])]
    }

    /// Its bytes.
    pub fn encoding(&self) -> &[u8] {
        &self.bytes[..usize::from(self.length())]
    }

    fn next(&self) -> u16 {
        self.pc.wrapping_add(u16::from(self.length()))
    }

    fn rel(&self, offset: u8) -> u16 {
        self.next().wrapping_add(offset as i8 as u16)
    }
}

/// An SFR's name, if a register lives at `addr` (80h..FFh).
pub fn sfr_name(addr: u8) -> Option<&'static str> {
    use crate::sfr::*;
    Some(match addr {
        P0 => "P0",
        SP => "SP",
        DPL => "DPL",
        DPH => "DPH",
        PCON => "PCON",
        TCON => "TCON",
        TMOD => "TMOD",
        TL0 => "TL0",
        TL1 => "TL1",
        TH0 => "TH0",
        TH1 => "TH1",
        P1 => "P1",
        SCON => "SCON",
        SBUF => "SBUF",
        P2 => "P2",
        IE => "IE",
        P3 => "P3",
        IP => "IP",
        PSW => "PSW",
        ACC => "ACC",
        B => "B",
        _ => return None,
    })
}

struct Direct(u8);

impl fmt::Display for Direct {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match sfr_name(self.0) {
            Some(name) if self.0 >= 0x80 => f.write_str(name),
            _ => write!(f, "{:02X}h", self.0),
        }
    }
}

struct Bit(u8);

impl fmt::Display for Bit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (byte, bit) = if self.0 < 0x80 {
            (0x20 + self.0 / 8, self.0 % 8)
        } else {
            (self.0 & 0xF8, self.0 % 8)
        };
        match sfr_name(byte) {
            Some(name) if byte >= 0x80 => write!(f, "{name}.{bit}"),
            _ => write!(f, "{byte:02X}h.{bit}"),
        }
    }
}

impl fmt::Display for Instruction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [op, b1, b2] = self.bytes;
        let r = op & 7;
        let i = op & 1;
        // The second operand's name for the ALU columns 4..F of rows 2..9 and C..F.
        let src = |f: &mut fmt::Formatter<'_>| match op & 0x0F {
            0x04 => write!(f, "#{b1:02X}h"),
            0x05 => write!(f, "{}", Direct(b1)),
            0x06 | 0x07 => write!(f, "@R{i}"),
            _ => write!(f, "R{r}"),
        };
        let word = u16::from_be_bytes([b1, b2]);
        match op {
            0x00 => f.write_str("NOP"),
            0x01 | 0x21 | 0x41 | 0x61 | 0x81 | 0xA1 | 0xC1 | 0xE1 => {
                write!(f, "AJMP {:04X}h", self.page_target(op, b1))
            }
            0x11 | 0x31 | 0x51 | 0x71 | 0x91 | 0xB1 | 0xD1 | 0xF1 => {
                write!(f, "ACALL {:04X}h", self.page_target(op, b1))
            }
            0x02 => write!(f, "LJMP {word:04X}h"),
            0x12 => write!(f, "LCALL {word:04X}h"),
            0x03 => f.write_str("RR A"),
            0x13 => f.write_str("RRC A"),
            0x23 => f.write_str("RL A"),
            0x33 => f.write_str("RLC A"),
            0x04 => f.write_str("INC A"),
            0x14 => f.write_str("DEC A"),
            0x05 => write!(f, "INC {}", Direct(b1)),
            0x15 => write!(f, "DEC {}", Direct(b1)),
            0x06..=0x0F => {
                f.write_str("INC ")?;
                src(f)
            }
            0x16..=0x1F => {
                f.write_str("DEC ")?;
                src(f)
            }
            0x10 => write!(f, "JBC {},{:04X}h", Bit(b1), self.rel(b2)),
            0x20 => write!(f, "JB {},{:04X}h", Bit(b1), self.rel(b2)),
            0x30 => write!(f, "JNB {},{:04X}h", Bit(b1), self.rel(b2)),
            0x22 => f.write_str("RET"),
            0x32 => f.write_str("RETI"),
            0x24..=0x2F | 0x34..=0x3F | 0x44..=0x4F | 0x54..=0x5F | 0x64..=0x6F | 0x94..=0x9F => {
                let name = match op >> 4 {
                    2 => "ADD",
                    3 => "ADDC",
                    4 => "ORL",
                    5 => "ANL",
                    6 => "XRL",
                    _ => "SUBB",
                };
                write!(f, "{name} A,")?;
                src(f)
            }
            0x40 => write!(f, "JC {:04X}h", self.rel(b1)),
            0x50 => write!(f, "JNC {:04X}h", self.rel(b1)),
            0x60 => write!(f, "JZ {:04X}h", self.rel(b1)),
            0x70 => write!(f, "JNZ {:04X}h", self.rel(b1)),
            0x80 => write!(f, "SJMP {:04X}h", self.rel(b1)),
            0x42 | 0x52 | 0x62 | 0x43 | 0x53 | 0x63 => {
                let name = ["ORL", "ANL", "XRL"][usize::from((op >> 4) - 4)];
                if op & 1 == 0 {
                    write!(f, "{name} {},A", Direct(b1))
                } else {
                    write!(f, "{name} {},#{b2:02X}h", Direct(b1))
                }
            }
            0x72 => write!(f, "ORL C,{}", Bit(b1)),
            0x82 => write!(f, "ANL C,{}", Bit(b1)),
            0xA0 => write!(f, "ORL C,/{}", Bit(b1)),
            0xB0 => write!(f, "ANL C,/{}", Bit(b1)),
            0x73 => f.write_str("JMP @A+DPTR"),
            0x74 => write!(f, "MOV A,#{b1:02X}h"),
            0x75 => write!(f, "MOV {},#{b2:02X}h", Direct(b1)),
            0x76 | 0x77 => write!(f, "MOV @R{i},#{b1:02X}h"),
            0x78..=0x7F => write!(f, "MOV R{r},#{b1:02X}h"),
            0x83 => f.write_str("MOVC A,@A+PC"),
            0x84 => f.write_str("DIV AB"),
            0x85 => write!(f, "MOV {},{}", Direct(b2), Direct(b1)),
            0x86 | 0x87 => write!(f, "MOV {},@R{i}", Direct(b1)),
            0x88..=0x8F => write!(f, "MOV {},R{r}", Direct(b1)),
            0x90 => write!(f, "MOV DPTR,#{word:04X}h"),
            0x92 => write!(f, "MOV {},C", Bit(b1)),
            0x93 => f.write_str("MOVC A,@A+DPTR"),
            0xA2 => write!(f, "MOV C,{}", Bit(b1)),
            0xA3 => f.write_str("INC DPTR"),
            0xA4 => f.write_str("MUL AB"),
            RESERVED => f.write_str("DB A5h"),
            0xA6 | 0xA7 => write!(f, "MOV @R{i},{}", Direct(b1)),
            0xA8..=0xAF => write!(f, "MOV R{r},{}", Direct(b1)),
            0xB2 => write!(f, "CPL {}", Bit(b1)),
            0xB3 => f.write_str("CPL C"),
            0xB4 => write!(f, "CJNE A,#{b1:02X}h,{:04X}h", self.rel(b2)),
            0xB5 => write!(f, "CJNE A,{},{:04X}h", Direct(b1), self.rel(b2)),
            0xB6 | 0xB7 => write!(f, "CJNE @R{i},#{b1:02X}h,{:04X}h", self.rel(b2)),
            0xB8..=0xBF => write!(f, "CJNE R{r},#{b1:02X}h,{:04X}h", self.rel(b2)),
            0xC0 => write!(f, "PUSH {}", Direct(b1)),
            0xD0 => write!(f, "POP {}", Direct(b1)),
            0xC2 => write!(f, "CLR {}", Bit(b1)),
            0xC3 => f.write_str("CLR C"),
            0xC4 => f.write_str("SWAP A"),
            0xC5..=0xCF => {
                f.write_str("XCH A,")?;
                src(f)
            }
            0xD2 => write!(f, "SETB {}", Bit(b1)),
            0xD3 => f.write_str("SETB C"),
            0xD4 => f.write_str("DA A"),
            0xD5 => write!(f, "DJNZ {},{:04X}h", Direct(b1), self.rel(b2)),
            0xD6 | 0xD7 => write!(f, "XCHD A,@R{i}"),
            0xD8..=0xDF => write!(f, "DJNZ R{r},{:04X}h", self.rel(b1)),
            0xE0 => f.write_str("MOVX A,@DPTR"),
            0xE2 | 0xE3 => write!(f, "MOVX A,@R{i}"),
            0xE4 => f.write_str("CLR A"),
            0xE5..=0xEF => {
                f.write_str("MOV A,")?;
                src(f)
            }
            0xF0 => f.write_str("MOVX @DPTR,A"),
            0xF2 | 0xF3 => write!(f, "MOVX @R{i},A"),
            0xF4 => f.write_str("CPL A"),
            0xF5 => write!(f, "MOV {},A", Direct(b1)),
            0xF6 | 0xF7 => write!(f, "MOV @R{i},A"),
            0xF8..=0xFF => write!(f, "MOV R{r},A"),
        }
    }
}

impl Instruction {
    fn page_target(&self, op: u8, low: u8) -> u16 {
        (self.next() & 0xF800) | (u16::from(op >> 5) << 8) | u16::from(low)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::string::ToString;

    fn show(pc: u16, bytes: [u8; 3]) -> alloc::string::String {
        Instruction { pc, bytes }.to_string()
    }

    #[test]
    fn lengths_and_cycles_follow_the_instruction_table() {
        // One of each shape, from Intel's table.
        for (op, len, cycles) in [
            (0x00, 1, 1),
            (0xE1, 2, 2),
            (0x12, 3, 2),
            (0x85, 3, 2),
            (0x75, 3, 2),
            (0x76, 2, 1),
            (0x88, 2, 2),
            (0xA8, 2, 2),
            (0xA4, 1, 4),
            (0x84, 1, 4),
            (0xD8, 2, 2),
            (0xD5, 3, 2),
            (0xE0, 1, 2),
            (0xF5, 2, 1),
            (0xA2, 2, 1),
            (0x92, 2, 2),
            (0xA3, 1, 2),
            (0xB3, 1, 1),
            (0xA5, 1, 1),
        ] {
            assert_eq!((LENGTH[op], CYCLES[op]), (len, cycles), "opcode {op:02X}h");
        }
    }

    #[test]
    fn disassembles_with_register_names_and_targets() {
        assert_eq!(show(0x0400, [0x85, 0x30, 0xE0]), "MOV ACC,30h");
        assert_eq!(show(0x0400, [0x80, 0xFE, 0]), "SJMP 0400h");
        assert_eq!(show(0x07FE, [0x31, 0x23, 0]), "ACALL 0923h");
        assert_eq!(show(0, [0x10, 0x99, 0x05]), "JBC SCON.1,0008h");
        assert_eq!(show(0, [0xD2, 0x07, 0]), "SETB 20h.7");
        assert_eq!(show(0, [0xB6, 0x12, 0xFD]), "CJNE @R0,#12h,0000h");
        assert_eq!(show(0, [0x9B, 0, 0]), "SUBB A,R3");
        assert_eq!(show(0, [0xA5, 0, 0]), "DB A5h");
    }
}
