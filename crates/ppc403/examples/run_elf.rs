//! Runs a static 32-bit big-endian PowerPC ELF program (as `qemu-ppc` would) on the core in
//! a flat 4 MiB memory: its loadable segments copied in, the PC at its entry, r1 at the top of
//! program RAM (0x001F_FFF0, as the board's loader leaves it), `sc` served as Linux's
//! `write` (r0 = 4) and `exit` (r0 = 1) — the two services the board's firmware offers.
//!
//! ```sh
//! cargo run --release -p buslab-ppc403 --example run_elf -- PROGRAM [REPEAT]
//! ```
//!
//! The program's output goes to stdout (of the first run), and after REPEAT runs (default 1),
//! each on a fresh core and memory, one line to stderr: `exit STATUS instructions N cycles C`
//! (the totals of all runs). bench/ppc403_speed.sh times it against qemu-ppc.

use std::io::Write as _;
use std::process::ExitCode;

use buslab_ppc403::{Cycles, FlatMemory, Ppc403, Stop};

const MEMORY: usize = 4 << 20;
const STACK: u32 = 0x001F_FFF0;
/// A run that has not exited by then is stuck: 40 s of the board's 25 MHz clock... times 100.
const CYCLE_LIMIT: Cycles = Cycles(100_000_000_000);
const PT_LOAD: u32 = 1;
const EM_PPC: u16 = 20;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (file, repeat) = match &args[..] {
        [file] => (file, Ok(1)),
        [file, n] => (file, n.parse::<u32>().map_err(|_| n.clone())),
        _ => {
            eprintln!("usage: run_elf PROGRAM [REPEAT]");
            return ExitCode::from(2);
        }
    };
    let result = repeat
        .map_err(|n| format!("REPEAT {n:?} is not a count"))
        .and_then(|repeat| {
            let image = std::fs::read(file).map_err(|e| format!("{file}: {e}"))?;
            let (mem, entry) = load(&image).map_err(|e| format!("{file}: {e}"))?;
            let (mut instructions, mut cycles, mut status) = (0, 0, 0);
            for run in 0..repeat.max(1) {
                let mut out = Vec::new();
                let (s, cpu) = run_program(mem.clone(), entry, &mut out)?;
                if run == 0 {
                    std::io::stdout()
                        .write_all(&out)
                        .map_err(|e| format!("stdout: {e}"))?;
                }
                instructions += cpu.instructions();
                cycles += cpu.now().0;
                status = s;
            }
            eprintln!("exit {status} instructions {instructions} cycles {cycles}");
            Ok(status)
        });
    match result {
        Ok(0) => ExitCode::SUCCESS,
        Ok(status) => ExitCode::from(status.clamp(1, 255) as u8),
        Err(e) => {
            eprintln!("run_elf: {e}");
            ExitCode::from(2)
        }
    }
}

fn be16(b: &[u8], at: usize) -> Result<u16, String> {
    b.get(at..at + 2)
        .map(|s| u16::from_be_bytes(s.try_into().unwrap()))
        .ok_or_else(|| format!("truncated at byte {at}"))
}

fn be32(b: &[u8], at: usize) -> Result<u32, String> {
    b.get(at..at + 4)
        .map(|s| u32::from_be_bytes(s.try_into().unwrap()))
        .ok_or_else(|| format!("truncated at byte {at}"))
}

/// The memory with the program's segments, and its entry point.
fn load(elf: &[u8]) -> Result<(FlatMemory, u32), String> {
    if elf.get(..6) != Some(b"\x7fELF\x01\x02") {
        return Err("not a 32-bit big-endian ELF file".into());
    }
    if be16(elf, 18)? != EM_PPC {
        return Err(format!("machine {} is not PowerPC (20)", be16(elf, 18)?));
    }
    let entry = be32(elf, 24)?;
    let phoff = be32(elf, 28)? as usize;
    let phentsize = usize::from(be16(elf, 42)?);
    let phnum = usize::from(be16(elf, 44)?);
    let mut mem = FlatMemory::new(MEMORY);
    for i in 0..phnum {
        let ph = phoff + i * phentsize;
        if be32(elf, ph)? != PT_LOAD {
            continue;
        }
        let (offset, vaddr) = (be32(elf, ph + 4)? as usize, be32(elf, ph + 8)?);
        let (filesz, memsz) = (be32(elf, ph + 16)? as usize, be32(elf, ph + 20)? as usize);
        if vaddr as usize + memsz.max(filesz) > MEMORY {
            return Err(format!(
                "segment {vaddr:#x}+{memsz:#x} lies outside the {MEMORY:#x} bytes of memory \
                 (link it lower, e.g. -Wl,-Ttext=0x30000 -Wl,-z,noseparate-code)"
            ));
        }
        let data = elf
            .get(offset..offset + filesz)
            .ok_or_else(|| format!("segment data {offset:#x}+{filesz:#x} past the file's end"))?;
        mem.load(vaddr, data);
    }
    Ok((mem, entry))
}

/// Runs to the program's exit; its status and the core.
fn run_program(
    mut mem: FlatMemory,
    entry: u32,
    out: &mut Vec<u8>,
) -> Result<(i32, Ppc403), String> {
    let mut cpu = Ppc403::new();
    cpu.set_trap_sc(true);
    cpu.set_pc(entry);
    cpu.set_gpr(1, STACK);
    loop {
        match cpu.run(&mut mem, CYCLE_LIMIT) {
            Stop::SystemCall { at } => match cpu.gpr(0) {
                1 => return Ok((cpu.gpr(3) as i32, cpu)),
                4 => {
                    let (buf, len) = (cpu.gpr(4) as usize, cpu.gpr(5) as usize);
                    let bytes = mem
                        .as_bytes()
                        .get(buf..buf.saturating_add(len))
                        .ok_or_else(|| format!("write of {len} bytes at {buf:#x} leaves memory"))?;
                    out.extend_from_slice(bytes);
                    cpu.set_gpr(3, len as u32);
                }
                n => {
                    return Err(format!(
                        "system call {n} at {at:#010x}: only 1 (exit) and 4 (write)"
                    ));
                }
            },
            Stop::Limit => return Err(format!("no exit after {} cycles", CYCLE_LIMIT.0)),
            other => return Err(format!("{other:?} (pc {:#010x})", cpu.pc())),
        }
    }
}
