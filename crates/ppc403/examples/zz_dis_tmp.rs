use buslab_ppc403::{Cycles, Exception, FlatMemory, Ppc403, Stop, disassemble};
fn main() {
    let words: Vec<u32> = std::fs::read(std::env::args().nth(1).unwrap())
        .unwrap()
        .chunks(4)
        .map(|c| u32::from_be_bytes(c.try_into().unwrap()))
        .collect();
    for (i, &w) in words.iter().enumerate() {
        let pc = 0x1000 + 4 * i as u32;
        let mut mem = FlatMemory::new(0x20000);
        mem.load_words(pc, &[w]);
        let mut cpu = Ppc403::new();
        cpu.set_pc(pc);
        cpu.set_trap_sc(true);
        let legal = !matches!(
            cpu.run(&mut mem, Cycles(1)),
            Stop::Exception {
                kind: Exception::Illegal { .. },
                ..
            }
        );
        println!("{:08x} {} {}", pc, legal as u8, disassemble(w, pc));
    }
}
