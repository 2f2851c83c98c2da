//! A tiny assembler (instruction words from their fields) and a board of flat RAM for the
//! core's tests.
#![allow(dead_code)]

use buslab_ppc403::{Cycles, FlatMemory, Ppc403, Stop};

/// Where test programs are loaded.
pub const ORG: u32 = 0x1000;
/// RAM size of the test board.
pub const RAM: usize = 0x10_0000;

pub fn d_form(op: u32, rt: u32, ra: u32, imm: i32) -> u32 {
    (op << 26) | (rt << 21) | (ra << 16) | (imm as u32 & 0xFFFF)
}

/// X/XO form of primary opcode 31: `xo` is the 10-bit extended opcode (with OE as +512).
pub fn x31(rt: u32, ra: u32, rb: u32, xo: u32, rc: bool) -> u32 {
    (31 << 26) | (rt << 21) | (ra << 16) | (rb << 11) | (xo << 1) | rc as u32
}

pub fn addi(rt: u32, ra: u32, imm: i32) -> u32 {
    d_form(14, rt, ra, imm)
}
pub fn li(rt: u32, imm: i32) -> u32 {
    addi(rt, 0, imm)
}
pub fn addis(rt: u32, ra: u32, imm: i32) -> u32 {
    d_form(15, rt, ra, imm)
}
pub fn lis(rt: u32, imm: i32) -> u32 {
    addis(rt, 0, imm)
}
pub fn ori(ra: u32, rs: u32, imm: u32) -> u32 {
    d_form(24, rs, ra, imm as i32)
}
/// `rt = value` in two instructions.
pub fn load_const(rt: u32, value: u32) -> [u32; 2] {
    [lis(rt, (value >> 16) as i32), ori(rt, rt, value & 0xFFFF)]
}
pub fn add(rt: u32, ra: u32, rb: u32) -> u32 {
    x31(rt, ra, rb, 266, false)
}
pub fn cmpwi(crf: u32, ra: u32, imm: i32) -> u32 {
    d_form(11, crf << 2, ra, imm)
}
pub fn cmplwi(crf: u32, ra: u32, imm: u32) -> u32 {
    d_form(10, crf << 2, ra, imm as i32)
}
pub fn b(offset: i32) -> u32 {
    (18 << 26) | (offset as u32 & 0x03FF_FFFC)
}
pub fn bl(offset: i32) -> u32 {
    b(offset) | 1
}
pub fn bc(bo: u32, bi: u32, offset: i32) -> u32 {
    (16 << 26) | (bo << 21) | (bi << 16) | (offset as u32 & 0xFFFC)
}
pub fn bdnz(offset: i32) -> u32 {
    bc(16, 0, offset)
}
pub fn bclr(bo: u32, bi: u32, link: bool) -> u32 {
    (19 << 26) | (bo << 21) | (bi << 16) | (16 << 1) | link as u32
}
pub fn blr() -> u32 {
    bclr(20, 0, false)
}
pub fn bcctr(bo: u32, bi: u32, link: bool) -> u32 {
    (19 << 26) | (bo << 21) | (bi << 16) | (528 << 1) | link as u32
}
pub fn mtspr(spr: u32, rs: u32) -> u32 {
    x31(rs, spr & 31, spr >> 5, 467, false)
}
pub fn mfspr(rt: u32, spr: u32) -> u32 {
    x31(rt, spr & 31, spr >> 5, 339, false)
}
pub fn mtdcr(dcr: u32, rs: u32) -> u32 {
    x31(rs, dcr & 31, dcr >> 5, 451, false)
}
pub fn mfdcr(rt: u32, dcr: u32) -> u32 {
    x31(rt, dcr & 31, dcr >> 5, 323, false)
}
pub fn mtmsr(rs: u32) -> u32 {
    x31(rs, 0, 0, 146, false)
}
pub fn mfmsr(rt: u32) -> u32 {
    x31(rt, 0, 0, 83, false)
}
pub fn wrteei(on: bool) -> u32 {
    x31(0, 0, 0, 163, false) | if on { 0x8000 } else { 0 }
}
pub fn rlwinm(ra: u32, rs: u32, sh: u32, mb: u32, me: u32) -> u32 {
    (21 << 26) | (rs << 21) | (ra << 16) | (sh << 11) | (mb << 6) | (me << 1)
}
pub fn lwz(rt: u32, ra: u32, d: i32) -> u32 {
    d_form(32, rt, ra, d)
}
pub fn stw(rs: u32, ra: u32, d: i32) -> u32 {
    d_form(36, rs, ra, d)
}
pub const SC: u32 = 0x4400_0002;
pub const RFI: u32 = 0x4C00_0064;
pub const RFCI: u32 = 0x4C00_0066;
pub const NOP: u32 = 0x6000_0000;

/// A core on flat RAM with a program at [`ORG`].
pub struct Board {
    pub cpu: Ppc403,
    pub mem: FlatMemory,
}

impl Board {
    pub fn new(program: &[u32]) -> Board {
        let mut mem = FlatMemory::new(RAM);
        mem.load_words(ORG, program);
        let mut cpu = Ppc403::new();
        cpu.set_pc(ORG);
        Board { cpu, mem }
    }

    pub fn run(&mut self, limit: u64) -> Stop {
        self.cpu.run(&mut self.mem, Cycles(limit))
    }

    /// Runs the program with `sc` trapped until it reaches its `sc` (within a generous
    /// budget of cycles).
    pub fn run_to_sc(&mut self) -> Stop {
        self.cpu.set_trap_sc(true);
        let limit = self.cpu.now().0 + 1_000_000;
        self.run(limit)
    }

    pub fn word(&self, addr: u32) -> u32 {
        let a = addr as usize;
        u32::from_be_bytes(self.mem.as_bytes()[a..a + 4].try_into().unwrap())
    }

    pub fn r(&self, n: usize) -> u32 {
        self.cpu.gpr(n)
    }
}

/// Runs `program` followed by `sc` with registers preset by `setup`, and returns the board.
pub fn exec(setup: &[(usize, u32)], program: &[u32]) -> Board {
    let mut words = program.to_vec();
    words.push(SC);
    let mut board = Board::new(&words);
    for &(r, v) in setup {
        board.cpu.set_gpr(r, v);
    }
    let stop = board.run_to_sc();
    assert_eq!(
        stop,
        Stop::SystemCall {
            at: ORG + 4 * program.len() as u32
        },
        "the program ran to its sc"
    );
    board
}
