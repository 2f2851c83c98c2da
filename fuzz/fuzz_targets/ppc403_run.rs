//! The PowerPC 403 core (`buslab_ppc403`) running arbitrary instruction words from arbitrary
//! registers and machine state, with interrupt lines changing between slices of the run: no
//! panic (overflow checks on), every `run` returns within one instruction of its limit, time
//! never goes back, no more instructions than cycles, and the whole input runs in a bounded
//! number of cycles.
#![no_main]

use buslab_ppc403::{Cycles, FlatMemory, Irq, Ppc403, Stop};
use libfuzzer_sys::fuzz_target;

/// The memory the program sees (the rest of the address space is a bus error).
const MEMORY: usize = 64 * 1024;
/// Cycles an input runs at most, in slices between which the interrupt lines change.
const SLICE: u64 = 1_000;
const SLICES: u64 = 16;
/// The longest an instruction runs past a limit, as docs/ppc403.md gives it: 32 cycles (a
/// `divw`, a 32-word `lmw`, a 127-byte string).
const OVERSHOOT: u64 = 32;
/// `run` calls an input may make: a call that ends before its limit took an exception or ran
/// `sc`, which costs its instruction at least a cycle, or took an interrupt, which masks
/// further ones of its kind until the program unmasks them with an instruction.
const CALLS: usize = 2 * (SLICE * SLICES) as usize + SLICES as usize;

const IRQS: [Irq; 8] = [
    Irq::Critical,
    Irq::SerialReceive,
    Irq::SerialTransmit,
    Irq::External(0),
    Irq::External(1),
    Irq::External(2),
    Irq::External(3),
    Irq::External(4),
];

/// A register's start value from a byte: small numbers, addresses inside memory, near the
/// top of the address space, or bytes spread over the word.
fn register(b: u8) -> u32 {
    let v = u32::from(b);
    match b >> 6 {
        0 => v,
        1 => v << 8,
        2 => 0xFFFF_FF00 | v,
        _ => v << 24 | v << 8 | v,
    }
}

/// Input: a flags byte (bit 0: `sc` stops the run instead of vectoring; bits 1-7 pick MSR
/// bits: EE, PR, CE, ME, DE, WE, and EVPR at 0x8000 instead of 0), a byte of interrupt line
/// levels toggled per slice, 32 bytes of register start values (see `register`), 4 bytes of
/// CR/XER/CTR/LR seeds, then instruction words loaded at address 0 (the vectors) where the
/// program starts.
fn run(data: &[u8]) {
    let [flags, irq_bits, rest @ ..] = data else {
        return;
    };
    let (regs, program) = rest.split_at(rest.len().min(36));
    let mut mem = FlatMemory::new(MEMORY);
    let len = program.len().min(MEMORY);
    mem.load(0, &program[..len]);
    let mut cpu = Ppc403::new();
    cpu.set_trap_sc(flags & 1 != 0);
    {
        let r = cpu.registers_mut();
        r.pc = 0;
        for (i, &b) in regs.iter().take(32).enumerate() {
            r.gpr[i] = register(b);
        }
        let extra = |i: usize| regs.get(32 + i).copied().map_or(0, register);
        r.cr = extra(0).wrapping_mul(0x0101_0101);
        r.xer = extra(1);
        r.ctr = extra(2);
        r.lr = extra(3) & !3;
        const MSR_BITS: [u32; 6] = [
            0x0000_8000, // EE
            0x0000_4000, // PR
            0x0002_0000, // CE
            0x0000_1000, // ME
            0x0000_0200, // DE
            0x0004_0000, // WE
        ];
        r.msr = MSR_BITS
            .iter()
            .enumerate()
            .filter(|(k, _)| flags >> (k + 1) & 1 != 0)
            .fold(0, |m, (_, bit)| m | bit);
        r.evpr = if flags & 0x80 != 0 { 0x8000 } else { 0 };
    }
    let mut calls = 0;
    let mut last = cpu.now();
    for slice in 0..SLICES {
        for (k, irq) in IRQS.iter().enumerate() {
            cpu.set_irq(*irq, (irq_bits.rotate_left(slice as u32) >> k) & 1 != 0);
        }
        let limit = Cycles((slice + 1) * SLICE);
        loop {
            calls += 1;
            assert!(calls <= CALLS, "{CALLS} run calls did not reach {limit:?}");
            let stop = cpu.run(&mut mem, limit);
            let now = cpu.now();
            assert!(now >= last, "time went back from {last:?} to {now:?}");
            assert!(
                now.0 <= limit.0 + OVERSHOOT,
                "ran to {now:?}, the limit was {limit:?} ({stop:?})"
            );
            assert!(
                cpu.instructions() <= now.0,
                "{} instructions in {now:?}",
                cpu.instructions()
            );
            last = now;
            match stop {
                Stop::Limit => {
                    assert!(
                        now >= limit,
                        "{stop:?} at {now:?} before the limit {limit:?}"
                    );
                    break;
                }
                // Waiting ends at the limit or at the next timer event; a watchdog reset
                // leaves the core running from its reset vector.
                Stop::Wait
                | Stop::Exception { .. }
                | Stop::SystemCall { .. }
                | Stop::Reset { .. } => {
                    if now >= limit {
                        break;
                    }
                }
            }
        }
    }
}

fuzz_target!(|data: &[u8]| run(data));
