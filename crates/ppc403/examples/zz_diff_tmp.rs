use buslab_ppc403::{Cycles, FlatMemory, Ppc403, Stop};
use std::io::Write;
fn main() {
    let bin = std::fs::read(std::env::args().nth(1).unwrap()).unwrap();
    let mut mem = FlatMemory::new(4 << 20);
    mem.load(0x100000, &bin);
    let mut cpu = Ppc403::new();
    cpu.set_pc(0x100000);
    cpu.set_gpr(1, 0x3F_FF00);
    cpu.set_trap_sc(true);
    let mut out = Vec::new();
    let mut limit = 0;
    loop {
        limit += 10_000_000;
        match cpu.run(&mut mem, Cycles(limit)) {
            Stop::SystemCall { .. } if cpu.gpr(0) == 4 => {
                let (a, n) = (cpu.gpr(4) as usize, cpu.gpr(5) as usize);
                out.extend_from_slice(&mem.as_bytes()[a..a + n]);
                cpu.set_gpr(3, n as u32);
            }
            Stop::SystemCall { .. } if cpu.gpr(0) == 1 => break,
            Stop::Limit => {}
            s => {
                eprintln!("stop {s:?} at pc {:#x}", cpu.pc());
                break;
            }
        }
    }
    std::io::stdout().write_all(&out).unwrap();
}
