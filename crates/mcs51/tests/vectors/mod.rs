//! Per-opcode test vectors: a random but reproducible machine state for an opcode and a seed,
//! the state after one instruction as a list of changes, and the vector file's line format.
//! Shared by the test that replays the committed vectors (`tests/s51_vectors.rs`) and the
//! program that makes them with SDCC's `s51` (`examples/s51_vectors.rs`).
//!
//! The state is kept inside what this core and `s51` model alike (see `docs/mcs51.md`,
//! "Deviations"): indirect addresses and the stack stay below 80h, direct addresses are RAM or
//! registers without side effects at the instant of one instruction (A, B, PSW, SP, DPTR, P1,
//! P2, the stopped timers' registers), timers and UART and interrupts are off. TMOD never puts
//! timer 0 in mode 3 with timer 1 out of it: timer 1 then runs without TR1 (the manual's
//! reading this core follows; `s51` keeps it stopped).

#![allow(dead_code)] // each user needs a different part

use std::fmt::Write as _;

use buslab_mcs51::opcodes::LENGTH;
use buslab_mcs51::{Bus, Clocks, Mcs51, Registers, Stop, sfr};

/// SplitMix64: small, and the same everywhere.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }

    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    pub fn byte(&mut self) -> u8 {
        self.next() as u8
    }

    pub fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }

    /// True one time in `n`.
    pub fn one_in(&mut self, n: u64) -> bool {
        self.below(n) == 0
    }
}

/// The SFRs compared after each instruction (every register of the 8051 but SBUF).
pub const WATCHED_SFRS: [u8; 20] = [
    sfr::P0,
    sfr::SP,
    sfr::DPL,
    sfr::DPH,
    sfr::PCON,
    sfr::TCON,
    sfr::TMOD,
    sfr::TL0,
    sfr::TL1,
    sfr::TH0,
    sfr::TH1,
    sfr::P1,
    sfr::SCON,
    sfr::P2,
    sfr::IE,
    sfr::P3,
    sfr::IP,
    sfr::PSW,
    sfr::ACC,
    sfr::B,
];

/// Registers a random direct operand may name besides RAM.
const DIRECT_SFRS: [u8; 12] = [
    sfr::ACC,
    sfr::B,
    sfr::PSW,
    sfr::SP,
    sfr::DPL,
    sfr::DPH,
    sfr::P1,
    sfr::P2,
    sfr::TL0,
    sfr::TH0,
    sfr::TL1,
    sfr::TH1,
];

/// Bit-addressable registers a random bit operand may name besides RAM 20h..2Fh.
const BIT_SFRS: [u8; 5] = [sfr::P1, sfr::P2, sfr::PSW, sfr::ACC, sfr::B];

/// A machine state before one instruction.
#[derive(Clone, Debug)]
pub struct Setup {
    pub op: u8,
    pub seed: u32,
    pub pc: u16,
    pub iram: [u8; 128],
    /// SFR values as written, in this order (A before PSW, so P can follow A).
    pub sfrs: Vec<(u8, u8)>,
    /// Code bytes (later entries win).
    pub code: Vec<(u16, u8)>,
    /// External data bytes (later entries win).
    pub xdata: Vec<(u16, u8)>,
}

#[derive(Clone, Copy, PartialEq)]
enum Operand {
    Direct,
    Bit,
    Other,
}

fn operands(op: u8) -> [Operand; 2] {
    use Operand::*;
    match op {
        0x05 | 0x15 | 0x25 | 0x35 | 0x42 | 0x45 | 0x52 | 0x55 | 0x62 | 0x65 | 0x95 => {
            [Direct, Other]
        }
        0x43 | 0x53 | 0x63 | 0x75 | 0x86..=0x8F | 0xA6..=0xAF | 0xB5 | 0xC0 | 0xC5 | 0xD0 => {
            [Direct, Other]
        }
        0xD5 | 0xE5 | 0xF5 => [Direct, Other],
        0x85 => [Direct, Direct],
        0x10 | 0x20 | 0x30 | 0x72 | 0x82 | 0x92 | 0xA0 | 0xA2 | 0xB0 | 0xB2 | 0xC2 | 0xD2 => {
            [Bit, Other]
        }
        _ => [Other, Other],
    }
}

fn random_direct(rng: &mut Rng) -> u8 {
    if rng.one_in(2) {
        rng.byte() & 0x7F
    } else {
        DIRECT_SFRS[rng.below(DIRECT_SFRS.len() as u64) as usize]
    }
}

fn random_bit(rng: &mut Rng) -> u8 {
    if rng.one_in(2) {
        rng.byte() & 0x7F
    } else {
        BIT_SFRS[rng.below(BIT_SFRS.len() as u64) as usize] + rng.below(8) as u8
    }
}

fn parity(a: u8) -> u8 {
    (a.count_ones() & 1) as u8
}

/// The state for vector `seed` of opcode `op`.
pub fn setup(op: u8, seed: u32) -> Setup {
    let mut rng = Rng::new(u64::from(op) << 32 | u64::from(seed));
    let pc = 0x0100 + rng.below(0xFE00) as u16;
    let mut a = rng.byte();
    let mut b = rng.byte();
    let mut psw = rng.byte();
    let sp = 2 + rng.below(0x7C) as u8;
    let dptr = rng.next() as u16;
    let p1 = rng.byte();
    let p2 = rng.byte();
    let mut timers: Vec<u8> = (0..5).map(|_| rng.byte()).collect();
    if timers[0] & 0x03 == 0x03 {
        timers[0] |= 0x30;
    }
    let mut iram = [0u8; 128];
    iram.iter_mut().for_each(|x| *x = rng.byte());
    let bank = usize::from(psw & 0x18);
    if matches!(op & 0x0F, 6 | 7) {
        iram[bank | usize::from(op & 1)] &= 0x7F;
    }
    let mut bytes = [op, rng.byte(), rng.byte()];
    for (k, kind) in operands(op).into_iter().enumerate() {
        match kind {
            Operand::Direct => bytes[1 + k] = random_direct(&mut rng),
            Operand::Bit => bytes[1 + k] = random_bit(&mut rng),
            Operand::Other => {}
        }
    }
    // Make the other side of each branch likely too.
    let rn = bank | usize::from(op & 7);
    let ri = bank | usize::from(op & 1);
    match op {
        0xB4 if rng.one_in(4) => bytes[1] = a,
        0xB5 if rng.one_in(4) => {
            if bytes[1] < 0x80 {
                iram[usize::from(bytes[1])] = a;
            } else {
                bytes[1] = sfr::ACC;
            }
        }
        0xB6 | 0xB7 if rng.one_in(4) => bytes[1] = iram[usize::from(iram[ri])],
        0xB8..=0xBF if rng.one_in(4) => bytes[1] = iram[rn],
        0xD8..=0xDF if rng.one_in(4) => iram[rn] = 1,
        0xD5 if rng.one_in(4) && bytes[1] < 0x80 => iram[usize::from(bytes[1])] = 1,
        0x60 | 0x70 if rng.one_in(4) => a = 0,
        0x84 if rng.one_in(8) => b = 0,
        _ => {}
    }
    psw = (psw & !1) | parity(a);
    let [dph, dpl] = dptr.to_be_bytes();
    let sfrs = vec![
        (sfr::ACC, a),
        (sfr::B, b),
        (sfr::PSW, psw),
        (sfr::SP, sp),
        (sfr::DPL, dpl),
        (sfr::DPH, dph),
        (sfr::P0, 0xFF),
        (sfr::P1, p1),
        (sfr::P2, p2),
        (sfr::P3, 0xFF),
        (sfr::TMOD, timers[0]),
        (sfr::TL0, timers[1]),
        (sfr::TH0, timers[2]),
        (sfr::TL1, timers[3]),
        (sfr::TH1, timers[4]),
        (sfr::TCON, 0),
        (sfr::SCON, 0),
        (sfr::IE, 0),
        (sfr::IP, 0),
        (sfr::PCON, 0),
    ];
    let mut code = Vec::new();
    match op {
        0x83 => code.push((pc.wrapping_add(1).wrapping_add(u16::from(a)), rng.byte())),
        0x93 => code.push((dptr.wrapping_add(u16::from(a)), rng.byte())),
        _ => {}
    }
    for (i, &byte) in bytes
        .iter()
        .enumerate()
        .take(usize::from(LENGTH[usize::from(op)]))
    {
        code.push((pc.wrapping_add(i as u16), byte));
    }
    let mut xdata = Vec::new();
    match op {
        0xE0 | 0xF0 => xdata.push((dptr, rng.byte())),
        0xE2 | 0xE3 | 0xF2 | 0xF3 => {
            for r in 0..2 {
                xdata.push((u16::from_be_bytes([p2, iram[bank | r]]), rng.byte()));
            }
        }
        _ => {}
    }
    Setup {
        op,
        seed,
        pc,
        iram,
        sfrs,
        code,
        xdata,
    }
}

/// Whether `s` leaves what `s51` models as the hardware does: `JMP @A+DPTR` and
/// `MOVC A,@A+DPTR` with A + DPTR past FFFFh. The 8051 forms that address in 16 bits (its
/// address bus has 16 lines), so it wraps to the bottom of code memory; `s51` does not wrap
/// and reads 00h there (docs/decisions.md). The random comparison draws another state instead.
pub fn beyond_s51(s: &Setup) -> bool {
    if !matches!(s.op, 0x73 | 0x93) {
        return false;
    }
    let sfr = |addr: u8| {
        s.sfrs
            .iter()
            .rev()
            .find(|(a, _)| *a == addr)
            .map_or(0, |v| v.1)
    };
    let dptr = u16::from_be_bytes([sfr(sfr::DPH), sfr(sfr::DPL)]);
    dptr.checked_add(u16::from(sfr(sfr::ACC))).is_none()
}

/// What is compared.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Snapshot {
    pub pc: u16,
    pub iram: [u8; 128],
    /// The [`WATCHED_SFRS`], in that order.
    pub sfrs: Vec<u8>,
    /// The setup's external data addresses, in its order.
    pub xdata: Vec<(u16, u8)>,
}

impl Setup {
    fn sfr(&self, addr: u8) -> u8 {
        self.sfrs
            .iter()
            .rev()
            .find(|(a, _)| *a == addr)
            .map(|&(_, v)| v)
            .expect("every watched SFR is set up")
    }

    /// External data addresses to look at afterwards.
    pub fn xdata_addresses(&self) -> Vec<u16> {
        self.xdata.iter().map(|&(a, _)| a).collect()
    }

    /// The state before the instruction.
    pub fn before(&self) -> Snapshot {
        Snapshot {
            pc: self.pc,
            iram: self.iram,
            sfrs: WATCHED_SFRS.iter().map(|&a| self.sfr(a)).collect(),
            xdata: self
                .xdata_addresses()
                .into_iter()
                .map(|a| (a, lookup(&self.xdata, a).expect("set")))
                .collect(),
        }
    }
}

fn lookup(bytes: &[(u16, u8)], addr: u16) -> Option<u8> {
    bytes
        .iter()
        .rev()
        .find(|(a, _)| *a == addr)
        .map(|&(_, v)| v)
}

/// The changes from `before` to `after`, as the vector file writes them: `pc=0102`, then
/// RAM `i1f=22`, SFRs `se0=55`, external data `x1234=56`.
pub fn changes(before: &Snapshot, after: &Snapshot) -> String {
    let mut out = format!("pc={:04x}", after.pc);
    for (i, (x, y)) in before.iram.iter().zip(&after.iram).enumerate() {
        if x != y {
            write!(out, " i{i:02x}={y:02x}").unwrap();
        }
    }
    for (k, (x, y)) in before.sfrs.iter().zip(&after.sfrs).enumerate() {
        if x != y {
            write!(out, " s{:02x}={y:02x}", WATCHED_SFRS[k]).unwrap();
        }
    }
    for ((addr, x), (_, y)) in before.xdata.iter().zip(&after.xdata) {
        if x != y {
            write!(out, " x{addr:04x}={y:02x}").unwrap();
        }
    }
    out
}

/// One line of the vector file: `OP SEED CYCLES CHANGES...` (hex opcode, decimal seed and
/// machine cycles).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Vector {
    pub op: u8,
    pub seed: u32,
    pub cycles: u64,
    pub changes: String,
}

impl Vector {
    pub fn line(&self) -> String {
        format!(
            "{:02x} {} {} {}",
            self.op, self.seed, self.cycles, self.changes
        )
    }

    pub fn parse(line: &str) -> Result<Vector, String> {
        let mut parts = line.splitn(4, ' ');
        let mut field = |name: &str| {
            parts
                .next()
                .ok_or_else(|| format!("no {name} in vector line {line:?}"))
        };
        let op = u8::from_str_radix(field("opcode")?, 16).map_err(|e| e.to_string())?;
        let seed = field("seed")?.parse().map_err(|e| format!("seed: {e}"))?;
        let cycles = field("cycles")?
            .parse()
            .map_err(|e| format!("cycles: {e}"))?;
        let changes = field("changes")?.to_string();
        Ok(Vector {
            op,
            seed,
            cycles,
            changes,
        })
    }
}

/// Code and external data as two memories (as in `s51`), knowing only the setup's bytes: an
/// instruction that reads anything else is a broken vector.
pub struct SetupBus {
    code: Vec<(u16, u8)>,
    pub xdata: Vec<(u16, u8)>,
    pub unknown_reads: Vec<u16>,
}

impl Bus for SetupBus {
    fn code(&mut self, addr: u16) -> u8 {
        lookup(&self.code, addr).unwrap_or_else(|| {
            self.unknown_reads.push(addr);
            0
        })
    }

    fn read_xdata(&mut self, addr: u16, _at: Clocks) -> u8 {
        lookup(&self.xdata, addr).unwrap_or_else(|| {
            self.unknown_reads.push(addr);
            0
        })
    }

    fn write_xdata(&mut self, addr: u16, value: u8, _at: Clocks) {
        self.xdata.push((addr, value));
    }
}

/// Runs the setup's instruction on this core: the state after it and its machine cycles.
pub fn run_core(s: &Setup) -> Result<(Snapshot, u64), String> {
    let mut core = Mcs51::new();
    core.iram_mut().copy_from_slice(&s.iram);
    for &(addr, value) in &s.sfrs {
        core.write_direct(addr, value);
    }
    let r = core.registers();
    core.set_registers(Registers { pc: s.pc, ..r });
    while core.poll_event().is_some() {}
    let mut bus = SetupBus {
        code: s.code.clone(),
        xdata: s.xdata.clone(),
        unknown_reads: Vec::new(),
    };
    let start = core.now();
    let stop = core.step(&mut bus);
    if !matches!(stop, Stop::Limit | Stop::Events) {
        return Err(format!("step stopped with {stop:?}"));
    }
    if !bus.unknown_reads.is_empty() {
        return Err(format!(
            "read memory the setup never wrote: {:04x?}",
            bus.unknown_reads
        ));
    }
    let cycles = (core.now() - start).cycles();
    let after = Snapshot {
        pc: core.pc(),
        iram: *core.iram(),
        sfrs: WATCHED_SFRS.iter().map(|&a| core.read_direct(a)).collect(),
        xdata: s
            .xdata_addresses()
            .into_iter()
            .map(|a| (a, lookup(&bus.xdata, a).expect("set")))
            .collect(),
    };
    Ok((after, cycles))
}

/// Checks one vector against this core; the error says what differs.
pub fn check(v: &Vector) -> Result<(), String> {
    let s = setup(v.op, v.seed);
    let (after, cycles) = run_core(&s)?;
    let got = changes(&s.before(), &after);
    if cycles == v.cycles && got == v.changes {
        return Ok(());
    }
    let insn = buslab_mcs51::Instruction {
        pc: s.pc,
        bytes: [0, 1, 2].map(|i| lookup(&s.code, s.pc.wrapping_add(i)).unwrap_or(0)),
    };
    Err(format!(
        "opcode {:02x} seed {} ({insn}): expected {} cycles `{}`, core gave {} cycles `{}`",
        v.op, v.seed, v.cycles, v.changes, cycles, got
    ))
}
