//! Random instruction words: the core never panics, every run stops within one instruction
//! of its limit, and a `Stop::Limit` means the limit was reached.

mod common;

use buslab_ppc403::{Cycles, FlatMemory, Irq, Ppc403, Stop};
use proptest::prelude::*;

/// The most cycles a run passes its limit by: one instruction begun in the limit's last
/// cycle, of the longest kind (33 cycles: `divw`, `lmw`/`stmw` of 32 words).
const OVERSHOOT: u64 = 32;

/// Words biased toward real opcodes (the primary opcode drawn from the assigned ones), so
/// that most of them execute instead of being illegal.
fn instruction() -> impl Strategy<Value = u32> {
    let assigned = prop::sample::select(vec![
        3u32, 7, 8, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 23, 24, 25, 26, 27, 28, 29, 31,
        31, 31, 31, 32, 33, 34, 35, 36, 37, 38, 39, 40, 41, 42, 43, 44, 45, 46, 47,
    ]);
    prop_oneof![
        4 => (assigned, any::<u32>()).prop_map(|(op, rest)| (op << 26) | (rest & 0x03FF_FFFF)),
        1 => any::<u32>(),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn random_programs_never_panic_and_respect_the_limit(
        program in prop::collection::vec(instruction(), 1..64),
        regs in prop::array::uniform32(prop_oneof![any::<u32>(), 0u32..0x2_0000]),
        msr in any::<u32>(),
        steps in prop::collection::vec(1u64..5_000, 1..8),
        irq in any::<bool>(),
    ) {
        let mut mem = FlatMemory::new(0x2_0000);
        mem.load_words(0x1000, &program);
        // Every vector holds a copy of the program too: exceptions keep running code.
        for vector in [0x100u32, 0x200, 0x500, 0x600, 0x700, 0xC00, 0x1000, 0x1010, 0x1020] {
            mem.load_words(vector, &program[..program.len().min(4)]);
        }
        let mut cpu = Ppc403::new();
        cpu.set_pc(0x1000);
        cpu.registers_mut().gpr = regs;
        cpu.registers_mut().msr = msr;
        cpu.set_irq(Irq::External(0), irq);
        let mut limit = 0;
        for step in steps {
            limit += step;
            let before = cpu.now().0;
            let stop = cpu.run(&mut mem, Cycles(limit));
            let now = cpu.now().0;
            prop_assert!(now >= before);
            prop_assert!(now <= limit.max(before) + OVERSHOOT, "{stop:?} at {now}, limit {limit}");
            if matches!(stop, Stop::Limit | Stop::Wait) {
                prop_assert!(now >= limit);
            }
            prop_assert!(cpu.instructions() <= now);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    /// Every word disassembles, and a word the core runs is never shown as `.long`.
    #[test]
    fn what_runs_has_a_disassembly(word in instruction()) {
        let mut mem = FlatMemory::new(0x2_0000);
        mem.load_words(0x1000, &[word]);
        let mut cpu = Ppc403::new();
        cpu.set_pc(0x1000);
        cpu.set_trap_sc(true);
        let stop = cpu.run(&mut mem, Cycles(1));
        let text = buslab_ppc403::disassemble(word, 0x1000).to_string();
        let illegal = matches!(
            stop,
            Stop::Exception { kind: buslab_ppc403::Exception::Illegal { .. }, .. }
        );
        prop_assert!(illegal || !text.starts_with(".long"), "{word:#010x} ran but shows as {text}");
    }
}
