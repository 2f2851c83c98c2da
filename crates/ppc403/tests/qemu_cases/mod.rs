//! The cases of the differential test against `qemu-ppc`, shared by the generator
//! (`examples/qemu_vectors.rs`) and the replay test (`tests/qemu_vectors.rs`).
//!
//! A case is a machine state (every GPR, CR, XER, LR, CTR and a 256-byte scratch area of
//! memory), 1–8 user-level integer instructions at a code address below 0x8000, and the state
//! after them. The state before is `fill(seed)` changed by the case's `in` overrides (the
//! registers the generator set so that addresses fall in the scratch area, divisors are
//! defined, branch targets lie ahead); the state after is the state before changed by the
//! case's `out` changes, as `qemu-ppc` computed them.
//!
//! A vector is one line:
//! `SEED ADDR WORD... | in NAME=VALUE... | out NAME=VALUE...` where NAME is `r0`..`r31`,
//! `cr`, `xer`, `lr`, `ctr` (8 hex digits) or `mAAAA` (changed scratch bytes from address
//! AAAA, hex). XER holds only its defined bits (SO, OV, CA, the string byte count).
#![allow(dead_code)] // each includer uses its part

use std::fmt::Write as _;

use buslab_ppc403::{Cycles, FlatMemory, Ppc403, Stop};

/// The scratch area every load and store of a case addresses: below 0x8000, so that a D-form
/// with rA = 0 reaches it with its displacement alone.
pub const SCRATCH: u32 = 0x7000;
pub const SCRATCH_LEN: usize = 256;
/// The memory a case runs in (code, scratch).
pub const MEMORY: usize = 0x8000;
pub const MAX_INSNS: usize = 8;
/// XER's defined bits: SO, OV, CA and the byte count of `lswx`/`stswx`.
pub const XER_DEFINED: u32 = 0xE000_007F;
/// `sc`: the core's run stops here (trapped system call) at the end of a case.
const SC: u32 = 0x4400_0002;
/// Far more than 8 instructions (or the string and multiple ones) need.
const CYCLE_LIMIT: u64 = 10_000;

/// xorshift64*: small, seeded, reproducible on every machine.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        // splitmix64 of the seed: neighbouring seeds give unrelated streams, never zero.
        let mut z = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        Rng((z ^ (z >> 31)) | 1)
    }

    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    pub fn word(&mut self) -> u32 {
        (self.next() >> 32) as u32
    }

    /// 0..n (n > 0).
    pub fn below(&mut self, n: u32) -> u32 {
        (((self.next() >> 32) * u64::from(n)) >> 32) as u32
    }

    /// True `num` times in `den`.
    pub fn chance(&mut self, num: u32, den: u32) -> bool {
        self.below(den) < num
    }

    pub fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[self.below(items.len() as u32) as usize]
    }
}

/// The operand values arithmetic goes wrong on, and plain random ones.
pub fn interesting(rng: &mut Rng) -> u32 {
    const EDGES: [u32; 14] = [
        0,
        1,
        2,
        0xFFFF_FFFF,
        0xFFFF_FFFE,
        0x7FFF_FFFF,
        0x8000_0000,
        0x8000_0001,
        0x0000_FFFF,
        0x0000_8000,
        0x0000_7FFF,
        0x0001_0000,
        0xFFFF_0000,
        0xFFFF_8000,
    ];
    match rng.below(8) {
        0 | 1 => rng.pick(&EDGES),
        2 => rng.below(32),
        3 => rng.below(32).wrapping_neg(),
        4 => 1 << rng.below(32),
        5 => (1u32 << rng.below(32)).wrapping_sub(1),
        _ => rng.word(),
    }
}

/// Everything a case reads and writes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct State {
    pub gpr: [u32; 32],
    pub cr: u32,
    pub xer: u32,
    pub lr: u32,
    pub ctr: u32,
    pub scratch: [u8; SCRATCH_LEN],
}

/// The state a case starts from before its overrides. FROZEN: the committed vectors rebuild
/// their states with it; changing it means generating them again.
pub fn fill(seed: u64) -> State {
    let mut rng = Rng::new(seed);
    let mut gpr = [0; 32];
    for g in &mut gpr {
        *g = interesting(&mut rng);
    }
    let cr = rng.word();
    let xer = rng.word() & XER_DEFINED;
    let lr = rng.word();
    let ctr = match rng.below(4) {
        0 => rng.below(4),
        1 => interesting(&mut rng),
        _ => rng.word(),
    };
    let mut scratch = [0; SCRATCH_LEN];
    for b in &mut scratch {
        *b = rng.word() as u8;
    }
    State {
        gpr,
        cr,
        xer,
        lr,
        ctr,
        scratch,
    }
}

impl State {
    /// `NAME=VALUE` tokens for what differs from `base`.
    pub fn changes_from(&self, base: &State) -> Vec<String> {
        let mut out = Vec::new();
        for (i, (a, b)) in base.gpr.iter().zip(&self.gpr).enumerate() {
            if a != b {
                out.push(format!("r{i}={b:08x}"));
            }
        }
        for (name, a, b) in [
            ("cr", base.cr, self.cr),
            ("xer", base.xer, self.xer),
            ("lr", base.lr, self.lr),
            ("ctr", base.ctr, self.ctr),
        ] {
            if a != b {
                out.push(format!("{name}={b:08x}"));
            }
        }
        let mut i = 0;
        while i < SCRATCH_LEN {
            if base.scratch[i] == self.scratch[i] {
                i += 1;
                continue;
            }
            let start = i;
            let mut run = format!("m{:04x}=", SCRATCH as usize + i);
            while i < SCRATCH_LEN && base.scratch[i] != self.scratch[i] {
                write!(run, "{:02x}", self.scratch[i]).unwrap();
                i += 1;
            }
            debug_assert!(i > start);
            out.push(run);
        }
        out
    }

    /// Applies `NAME=VALUE` tokens.
    pub fn apply(&mut self, token: &str) -> Result<(), String> {
        let (name, value) = token
            .split_once('=')
            .ok_or_else(|| format!("{token:?} is not NAME=VALUE"))?;
        let word = || {
            u32::from_str_radix(value, 16)
                .map_err(|_| format!("{token:?}: {value:?} is not a hex word"))
        };
        match name {
            "cr" => self.cr = word()?,
            "xer" => self.xer = word()?,
            "lr" => self.lr = word()?,
            "ctr" => self.ctr = word()?,
            _ if name.starts_with('r') => {
                let n: usize = name[1..]
                    .parse()
                    .ok()
                    .filter(|&n| n < 32)
                    .ok_or_else(|| format!("{token:?}: no register {name}"))?;
                self.gpr[n] = word()?;
            }
            _ if name.starts_with('m') => {
                let addr = usize::from_str_radix(&name[1..], 16)
                    .map_err(|_| format!("{token:?}: {name:?} is not mADDR"))?;
                if value.len() % 2 != 0 || value.is_empty() {
                    return Err(format!("{token:?}: odd or empty byte string"));
                }
                let n = value.len() / 2;
                let at = addr
                    .checked_sub(SCRATCH as usize)
                    .filter(|&at| at + n <= SCRATCH_LEN)
                    .ok_or_else(|| format!("{token:?}: outside the scratch area"))?;
                for k in 0..n {
                    self.scratch[at + k] = u8::from_str_radix(&value[2 * k..2 * k + 2], 16)
                        .map_err(|_| format!("{token:?}: not hex bytes"))?;
                }
            }
            _ => return Err(format!("{token:?}: unknown name {name:?}")),
        }
        Ok(())
    }

    /// Every field that differs, `name: expected X, core Y`.
    pub fn differences(&self, core: &State) -> Vec<String> {
        let mut out = Vec::new();
        for i in 0..32 {
            if self.gpr[i] != core.gpr[i] {
                out.push(format!(
                    "r{i}: qemu {:08x}, core {:08x}",
                    self.gpr[i], core.gpr[i]
                ));
            }
        }
        for (name, a, b) in [
            ("cr", self.cr, core.cr),
            ("xer", self.xer, core.xer),
            ("lr", self.lr, core.lr),
            ("ctr", self.ctr, core.ctr),
        ] {
            if a != b {
                out.push(format!("{name}: qemu {a:08x}, core {b:08x}"));
            }
        }
        for i in 0..SCRATCH_LEN {
            if self.scratch[i] != core.scratch[i] {
                out.push(format!(
                    "mem {:04x}: qemu {:02x}, core {:02x}",
                    SCRATCH as usize + i,
                    self.scratch[i],
                    core.scratch[i]
                ));
            }
        }
        out
    }
}

/// A case: where its code runs, the code, and the state before it.
#[derive(Clone, Debug)]
pub struct Case {
    pub seed: u64,
    pub addr: u32,
    pub code: Vec<u32>,
    pub before: State,
}

/// A case with `qemu-ppc`'s state after it.
#[derive(Clone, Debug)]
pub struct Vector {
    pub case: Case,
    pub after: State,
}

impl Vector {
    pub fn line(&self) -> String {
        let c = &self.case;
        let mut s = format!("{:016x} {:08x}", c.seed, c.addr);
        for w in &c.code {
            write!(s, " {w:08x}").unwrap();
        }
        s.push_str(" | in");
        for t in c.before.changes_from(&fill(c.seed)) {
            write!(s, " {t}").unwrap();
        }
        s.push_str(" | out");
        for t in self.after.changes_from(&c.before) {
            write!(s, " {t}").unwrap();
        }
        s
    }

    pub fn parse(line: &str) -> Result<Vector, String> {
        let err = |what: &str| format!("vector {line:?}: {what}");
        let mut parts = line.split(" | ");
        let (head, ins, outs) = match (parts.next(), parts.next(), parts.next(), parts.next()) {
            (Some(h), Some(i), Some(o), None) => (h, i, o),
            _ => return Err(err("not SEED ADDR WORDS | in ... | out ...")),
        };
        let mut head = head.split_whitespace();
        let seed = head
            .next()
            .and_then(|s| u64::from_str_radix(s, 16).ok())
            .ok_or_else(|| err("no hex seed"))?;
        let addr = head
            .next()
            .and_then(|s| u32::from_str_radix(s, 16).ok())
            .ok_or_else(|| err("no hex address"))?;
        let code: Vec<u32> = head
            .map(|w| u32::from_str_radix(w, 16).map_err(|_| err("a code word is not hex")))
            .collect::<Result<_, _>>()?;
        if code.is_empty() || code.len() > MAX_INSNS {
            return Err(err("1 to 8 code words expected"));
        }
        if addr % 4 != 0 || addr as usize + 4 * (code.len() + 1) > SCRATCH as usize {
            return Err(err(
                "the code must be word-aligned and end below the scratch area",
            ));
        }
        let mut before = fill(seed);
        let ins = ins.strip_prefix("in").ok_or_else(|| err("no `in`"))?;
        for t in ins.split_whitespace() {
            before.apply(t).map_err(|e| err(&e))?;
        }
        let mut after = before.clone();
        let outs = outs.strip_prefix("out").ok_or_else(|| err("no `out`"))?;
        for t in outs.split_whitespace() {
            after.apply(t).map_err(|e| err(&e))?;
        }
        Ok(Vector {
            case: Case {
                seed,
                addr,
                code,
                before,
            },
            after,
        })
    }
}

impl Case {
    /// The code as assembly, one instruction a line.
    pub fn listing(&self) -> String {
        let mut s = String::new();
        for (i, &w) in self.code.iter().enumerate() {
            let at = self.addr + 4 * i as u32;
            writeln!(s, "    {at:08x}: {w:08x}  {}", disassemble(w, at).1).unwrap();
        }
        s
    }

    /// The address just past the code, where every case leaves its block.
    pub fn end(&self) -> u32 {
        self.addr + 4 * self.code.len() as u32
    }
}

/// Runs a case on buslab's core in a flat memory; the state after it, or why it did not end
/// at its end (an exception, a run away).
pub fn run_core(case: &Case) -> Result<State, String> {
    let mut mem = FlatMemory::new(MEMORY);
    mem.load(SCRATCH, &case.before.scratch);
    mem.load_words(case.addr, &case.code);
    mem.load_words(case.end(), &[SC]);
    let image = mem.clone();
    let mut cpu = Ppc403::new();
    cpu.set_trap_sc(true);
    {
        let r = cpu.registers_mut();
        r.pc = case.addr;
        r.gpr = case.before.gpr;
        r.cr = case.before.cr;
        r.xer = case.before.xer;
        r.lr = case.before.lr;
        r.ctr = case.before.ctr;
    }
    match cpu.run(&mut mem, Cycles(CYCLE_LIMIT)) {
        Stop::SystemCall { at } if at == case.end() => {}
        other => {
            return Err(format!(
                "the core stopped with {other:?} (pc {:08x}), not at the end {:08x}",
                cpu.pc(),
                case.end()
            ));
        }
    }
    let bytes = mem.as_bytes();
    let s = SCRATCH as usize;
    if let Some(at) = (0..MEMORY)
        .filter(|&a| !(s..s + SCRATCH_LEN).contains(&a))
        .find(|&a| bytes[a] != image.as_bytes()[a])
    {
        return Err(format!(
            "the core wrote {:02x} at {at:04x}, outside the scratch area",
            bytes[at]
        ));
    }
    let r = cpu.registers();
    Ok(State {
        gpr: r.gpr,
        cr: r.cr,
        xer: r.xer & XER_DEFINED,
        lr: r.lr,
        ctr: r.ctr,
        scratch: bytes[s..s + SCRATCH_LEN].try_into().unwrap(),
    })
}

/// Checks a vector on the core: Ok, or the report of what differs.
pub fn check(v: &Vector) -> Result<(), String> {
    let report = |what: String| {
        format!(
            "seed {:016x} at {:08x}:\n{}  {what}",
            v.case.seed,
            v.case.addr,
            v.case.listing()
        )
    };
    let core = run_core(&v.case).map_err(report)?;
    let diff = v.after.differences(&core);
    if diff.is_empty() {
        Ok(())
    } else {
        let before: Vec<String> = v
            .case
            .before
            .changes_from(&State {
                gpr: [0; 32],
                cr: 0,
                xer: 0,
                lr: 0,
                ctr: 0,
                scratch: v.case.before.scratch,
            })
            .into_iter()
            .collect();
        Err(report(format!(
            "{}\n  before: {}",
            diff.join("\n  "),
            before.join(" ")
        )))
    }
}

// ---- the instruction forms: encoding for the generator, names and disassembly for both ----

/// Register-register arithmetic (primary opcode 31, XO form): name, extended opcode, whether
/// it has an OE (overflow) form, whether it takes rB.
pub const XO_ARITH: [(&str, u32, bool, bool); 16] = [
    ("add", 266, true, true),
    ("addc", 10, true, true),
    ("adde", 138, true, true),
    ("subf", 40, true, true),
    ("subfc", 8, true, true),
    ("subfe", 136, true, true),
    ("mullw", 235, true, true),
    ("mulhw", 75, false, true),
    ("mulhwu", 11, false, true),
    ("divw", 491, true, true),
    ("divwu", 459, true, true),
    ("addme", 234, true, false),
    ("addze", 202, true, false),
    ("subfme", 232, true, false),
    ("subfze", 200, true, false),
    ("neg", 104, true, false),
];

/// D-form arithmetic: name, primary opcode (`addic.` records into CR0 by its opcode).
pub const D_ARITH: [(&str, u32); 6] = [
    ("addi", 14),
    ("addis", 15),
    ("addic", 12),
    ("addic.", 13),
    ("subfic", 8),
    ("mulli", 7),
];

/// D-form logic with an unsigned immediate (rA, rS, UIMM).
pub const D_LOGIC: [(&str, u32); 6] = [
    ("andi.", 28),
    ("andis.", 29),
    ("ori", 24),
    ("oris", 25),
    ("xori", 26),
    ("xoris", 27),
];

/// X-form logic and shifts (rA, rS, rB), with a `.` form.
pub const X_LOGIC: [(&str, u32); 11] = [
    ("and", 28),
    ("andc", 60),
    ("or", 444),
    ("orc", 412),
    ("xor", 316),
    ("nand", 476),
    ("nor", 124),
    ("eqv", 284),
    ("slw", 24),
    ("srw", 536),
    ("sraw", 792),
];

/// X-form with one source (rA, rS), with a `.` form.
pub const X_UNARY: [(&str, u32); 3] = [("extsb", 954), ("extsh", 922), ("cntlzw", 26)];

/// Condition register logic (primary opcode 19).
pub const CR_LOGIC: [(&str, u32); 8] = [
    ("crand", 257),
    ("crandc", 129),
    ("creqv", 289),
    ("crnand", 225),
    ("crnor", 33),
    ("cror", 449),
    ("crorc", 417),
    ("crxor", 193),
];

/// D-form loads and stores: name, primary opcode, bytes, update, store.
pub const D_MEM: [(&str, u32, u32, bool, bool); 14] = [
    ("lwz", 32, 4, false, false),
    ("lwzu", 33, 4, true, false),
    ("lbz", 34, 1, false, false),
    ("lbzu", 35, 1, true, false),
    ("stw", 36, 4, false, true),
    ("stwu", 37, 4, true, true),
    ("stb", 38, 1, false, true),
    ("stbu", 39, 1, true, true),
    ("lhz", 40, 2, false, false),
    ("lhzu", 41, 2, true, false),
    ("lha", 42, 2, false, false),
    ("lhau", 43, 2, true, false),
    ("sth", 44, 2, false, true),
    ("sthu", 45, 2, true, true),
];

/// X-form loads and stores (primary opcode 31): name, extended opcode, bytes, update, store.
pub const X_MEM: [(&str, u32, u32, bool, bool); 18] = [
    ("lwzx", 23, 4, false, false),
    ("lwzux", 55, 4, true, false),
    ("lbzx", 87, 1, false, false),
    ("lbzux", 119, 1, true, false),
    ("stwx", 151, 4, false, true),
    ("stwux", 183, 4, true, true),
    ("stbx", 215, 1, false, true),
    ("stbux", 247, 1, true, true),
    ("lhzx", 279, 2, false, false),
    ("lhzux", 311, 2, true, false),
    ("lhax", 343, 2, false, false),
    ("lhaux", 375, 2, true, false),
    ("sthx", 407, 2, false, true),
    ("sthux", 439, 2, true, true),
    ("lwbrx", 534, 4, false, false),
    ("stwbrx", 662, 4, false, true),
    ("lhbrx", 790, 2, false, false),
    ("sthbrx", 918, 2, false, true),
];

/// Cache management a user program may run (no-ops for the results), X-form (rA|0, rB).
/// `dcbz` is left out: it zeroes a cache line, 16 bytes on the 403 and 32 in qemu's CPUs.
pub const CACHE_OPS: [(&str, u32); 5] = [
    ("dcbt", 278),
    ("dcbtst", 246),
    ("dcbst", 54),
    ("dcbf", 86),
    ("icbi", 982),
];

/// The special registers a user program reaches with `mfspr`/`mtspr`.
pub const USER_SPRS: [(&str, u32); 3] = [("xer", 1), ("lr", 8), ("ctr", 9)];

/// The BO values with a defined meaning (z bits 0; the y hint bit both ways).
pub const BO_ALL: [u32; 17] = [0, 1, 2, 3, 4, 5, 8, 9, 10, 11, 12, 13, 16, 17, 18, 19, 20];

pub const fn op(primary: u32) -> u32 {
    primary << 26
}
pub const fn x(xo: u32) -> u32 {
    op(31) | xo << 1
}
pub const fn d(r: u32) -> u32 {
    r << 21
}
pub const fn a(r: u32) -> u32 {
    r << 16
}
pub const fn b(r: u32) -> u32 {
    r << 11
}
pub const fn spr(n: u32) -> u32 {
    ((n & 0x1F) << 16) | ((n >> 5) << 11)
}
pub const OE: u32 = 1 << 10;
pub const RC: u32 = 1;
pub const LK: u32 = 1;
pub const AA: u32 = 2;

/// Every mnemonic the generator makes (with its `o`, `.`, `l`, `a` forms).
pub fn all_mnemonics() -> Vec<String> {
    let mut v = Vec::new();
    for (name, _, oe, _) in XO_ARITH {
        for o in if oe { &["", "o"][..] } else { &[""][..] } {
            for dot in ["", "."] {
                v.push(format!("{name}{o}{dot}"));
            }
        }
    }
    v.extend(D_ARITH.iter().map(|f| f.0.to_string()));
    v.extend(D_LOGIC.iter().map(|f| f.0.to_string()));
    for (name, _) in X_LOGIC.iter().chain(&X_UNARY).chain(&[("srawi", 824)]) {
        v.push(name.to_string());
        v.push(format!("{name}."));
    }
    for name in ["rlwinm", "rlwimi", "rlwnm"] {
        v.push(name.to_string());
        v.push(format!("{name}."));
    }
    for name in [
        "cmp", "cmpl", "cmpi", "cmpli", "mcrf", "mcrxr", "mtcrf", "mfcr",
    ] {
        v.push(name.to_string());
    }
    v.extend(CR_LOGIC.iter().map(|f| f.0.to_string()));
    for (name, _) in USER_SPRS {
        v.push(format!("mf{name}"));
        v.push(format!("mt{name}"));
    }
    v.extend(D_MEM.iter().map(|f| f.0.to_string()));
    v.extend(X_MEM.iter().map(|f| f.0.to_string()));
    v.extend(CACHE_OPS.iter().map(|f| f.0.to_string()));
    for name in [
        "tw", "twi", "lmw", "stmw", "lswi", "lswx", "stswi", "stswx", "lwarx", "stwcx.", "b", "ba",
        "bl", "bla", "bc", "bca", "bcl", "bcla", "bclr", "bclrl", "bcctr", "bcctrl", "sync",
        "isync", "eieio",
    ] {
        v.push(name.to_string());
    }
    v
}

fn sext16(v: u32) -> i32 {
    v as u16 as i16 as i32
}

/// The mnemonic (as in [`all_mnemonics`]) and the assembly text of `w` at `at`; `.long` for
/// a word outside the generated set.
pub fn disassemble(w: u32, at: u32) -> (String, String) {
    let rd = (w >> 21) & 31;
    let ra = (w >> 16) & 31;
    let rb = (w >> 11) & 31;
    let rc = if w & 1 != 0 { "." } else { "" };
    let imm = w & 0xFFFF;
    let unknown = || (".long".to_string(), format!(".long 0x{w:08x}"));
    let named = |m: String, ops: String| (m.clone(), format!("{m} {ops}"));
    match w >> 26 {
        7 | 8 | 12 | 13 | 14 | 15 => {
            let name = D_ARITH.iter().find(|f| f.1 == w >> 26).unwrap().0;
            named(name.into(), format!("r{rd},r{ra},{}", sext16(imm)))
        }
        24..=29 => {
            let name = D_LOGIC.iter().find(|f| f.1 == w >> 26).unwrap().0;
            named(name.into(), format!("r{ra},r{rd},0x{imm:x}"))
        }
        10 | 11 if w & (1 << 22 | 1 << 21) == 0 => {
            let (name, v) = if w >> 26 == 11 {
                ("cmpi", sext16(imm).to_string())
            } else {
                ("cmpli", format!("0x{imm:x}"))
            };
            named(name.into(), format!("cr{},r{ra},{v}", rd >> 2))
        }
        20 | 21 | 23 => {
            let name = match w >> 26 {
                20 => "rlwimi",
                21 => "rlwinm",
                _ => "rlwnm",
            };
            let sh = if w >> 26 == 23 {
                format!("r{rb}")
            } else {
                rb.to_string()
            };
            named(
                format!("{name}{rc}"),
                format!("r{ra},r{rd},{sh},{},{}", (w >> 6) & 31, (w >> 1) & 31),
            )
        }
        32..=45 => {
            let f = D_MEM.iter().find(|f| f.1 == w >> 26).unwrap();
            named(f.0.into(), format!("r{rd},{}(r{ra})", sext16(imm)))
        }
        3 => named("twi".into(), format!("{rd},r{ra},{}", sext16(imm))),
        46 | 47 => named(
            if w >> 26 == 46 { "lmw" } else { "stmw" }.into(),
            format!("r{rd},{}(r{ra})", sext16(imm)),
        ),
        18 => {
            let li = ((w & 0x03FF_FFFC) << 6) as i32 >> 6;
            let target = if w & AA != 0 {
                li as u32
            } else {
                at.wrapping_add(li as u32)
            };
            let suffix = format!(
                "{}{}",
                if w & LK != 0 { "l" } else { "" },
                if w & AA != 0 { "a" } else { "" }
            );
            named(format!("b{suffix}"), format!("0x{target:x}"))
        }
        16 => {
            let bd = sext16(w & 0xFFFC) as u32;
            let target = if w & AA != 0 { bd } else { at.wrapping_add(bd) };
            let suffix = format!(
                "{}{}",
                if w & LK != 0 { "l" } else { "" },
                if w & AA != 0 { "a" } else { "" }
            );
            named(format!("bc{suffix}"), format!("{rd},{ra},0x{target:x}"))
        }
        19 => match (w >> 1) & 0x3FF {
            0 if w & 0x0063_F801 == 0 => {
                named("mcrf".into(), format!("cr{},cr{}", rd >> 2, ra >> 2))
            }
            16 if rb == 0 => named(
                format!("bclr{}", if w & LK != 0 { "l" } else { "" }),
                format!("{rd},{ra}"),
            ),
            528 if rb == 0 => named(
                format!("bcctr{}", if w & LK != 0 { "l" } else { "" }),
                format!("{rd},{ra}"),
            ),
            150 if w & 0x03FF_F801 == 0 => named("isync".into(), String::new()),
            xo => match CR_LOGIC.iter().find(|f| f.1 == xo) {
                Some(f) if w & 1 == 0 => named(f.0.into(), format!("{rd},{ra},{rb}")),
                _ => unknown(),
            },
        },
        31 => decode_31(w, rd, ra, rb, rc).unwrap_or_else(unknown),
        _ => unknown(),
    }
}

fn decode_31(w: u32, rd: u32, ra: u32, rb: u32, rc: &str) -> Option<(String, String)> {
    let named = |m: String, ops: String| Some((m.clone(), format!("{m} {ops}")));
    let xo10 = (w >> 1) & 0x3FF;
    let no_rc = w & 1 == 0;
    if let Some(f) = X_MEM.iter().find(|f| f.1 == xo10).filter(|_| no_rc) {
        return named(f.0.into(), format!("r{rd},r{ra},r{rb}"));
    }
    if let Some(f) = CACHE_OPS
        .iter()
        .find(|f| f.1 == xo10)
        .filter(|_| no_rc && rd == 0)
    {
        return named(f.0.into(), format!("r{ra},r{rb}"));
    }
    if let Some(f) = X_LOGIC.iter().find(|f| f.1 == xo10) {
        return named(format!("{}{rc}", f.0), format!("r{ra},r{rd},r{rb}"));
    }
    if let Some(f) = X_UNARY.iter().find(|f| f.1 == xo10).filter(|_| rb == 0) {
        return named(format!("{}{rc}", f.0), format!("r{ra},r{rd}"));
    }
    match xo10 {
        4 if no_rc => return named("tw".into(), format!("{rd},r{ra},r{rb}")),
        824 => return named(format!("srawi{rc}"), format!("r{ra},r{rd},{rb}")),
        0 | 32 if no_rc && w & (1 << 22 | 1 << 21) == 0 => {
            let name = if xo10 == 0 { "cmp" } else { "cmpl" };
            return named(name.into(), format!("cr{},r{ra},r{rb}", rd >> 2));
        }
        512 if no_rc && w & 0x007F_F800 == 0 => {
            return named("mcrxr".into(), format!("cr{}", rd >> 2));
        }
        144 if no_rc && w & 0x0010_0800 == 0 => {
            return named("mtcrf".into(), format!("0x{:02x},r{rd}", (w >> 12) & 0xFF));
        }
        19 if no_rc && ra == 0 && rb == 0 => return named("mfcr".into(), format!("r{rd}")),
        339 | 467 if no_rc => {
            let n = ra | rb << 5;
            let (name, _) = USER_SPRS.iter().find(|s| s.1 == n)?;
            return if xo10 == 339 {
                named(format!("mf{name}"), format!("r{rd}"))
            } else {
                named(format!("mt{name}"), format!("r{rd}"))
            };
        }
        597 | 725 if no_rc => {
            let name = if xo10 == 597 { "lswi" } else { "stswi" };
            return named(name.into(), format!("r{rd},r{ra},{rb}"));
        }
        533 | 661 if no_rc => {
            let name = if xo10 == 533 { "lswx" } else { "stswx" };
            return named(name.into(), format!("r{rd},r{ra},r{rb}"));
        }
        20 if no_rc => return named("lwarx".into(), format!("r{rd},r{ra},r{rb}")),
        150 if !no_rc => return named("stwcx.".into(), format!("r{rd},r{ra},r{rb}")),
        598 if w == x(598) => return named("sync".into(), String::new()),
        854 if w == x(854) => return named("eieio".into(), String::new()),
        _ => {}
    }
    let xo9 = xo10 & 0x1FF;
    let oe = w & OE != 0;
    let (name, _, has_oe, has_rb) = XO_ARITH.iter().find(|f| f.1 == xo9)?;
    if oe && !has_oe || !has_rb && rb != 0 {
        return None;
    }
    let o = if oe { "o" } else { "" };
    let ops = if *has_rb {
        format!("r{rd},r{ra},r{rb}")
    } else {
        format!("r{rd},r{ra}")
    };
    named(format!("{name}{o}{rc}"), ops)
}
