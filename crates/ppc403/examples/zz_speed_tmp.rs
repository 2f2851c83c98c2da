use buslab_ppc403::{Cycles, FlatMemory, Ppc403, Stop};
use std::time::Instant;
fn main() {
    let prog = [
        0x3860_0000u32, // li r3,0
        0x3C80_0400,    // lis r4,0x400
        0x7C89_03A6,    // mtctr r4
        0x3863_0001,    // addi r3,r3,1
        0x7C65_2278,    // xor r5,r3,r4
        0x7CC5_1A14,    // add r6,r5,r3
        0x9061_2000,    // stw r3, 0x2000(r1)
        0x80E1_2000,    // lwz r7, 0x2000(r1)
        0x4200_FFF0,    // bdnz -16
        0x4400_0002,
    ];
    let mut mem = FlatMemory::new(0x10000);
    mem.load_words(0x1000, &prog);
    let mut cpu = Ppc403::new();
    cpu.set_pc(0x1000);
    cpu.set_gpr(1, 0);
    cpu.set_trap_sc(true);
    let t = Instant::now();
    let mut stop;
    let mut limit = 0;
    loop {
        limit += std::env::args()
            .nth(1)
            .map_or(25_000, |s| s.parse().unwrap());
        stop = cpu.run(&mut mem, Cycles(limit));
        if stop != Stop::Limit {
            break;
        }
    }
    let dt = t.elapsed().as_secs_f64();
    println!(
        "{stop:?} instr {} cycles {} in {:.3}s: {:.1} M instr/s, {:.1} M cycles/s",
        cpu.instructions(),
        cpu.now().0,
        dt,
        cpu.instructions() as f64 / dt / 1e6,
        cpu.now().0 as f64 / dt / 1e6
    );
}
