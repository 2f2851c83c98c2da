//! Runs an Intel HEX program on the core until the program counter reaches a stop address,
//! and prints the machine cycles, instructions and the time taken (for
//! `bench/mcs51_speed.sh`).
//!
//! ```sh
//! cargo run --release -p buslab-mcs51 --example run_hex -- PROGRAM.hex STOP_ADDR [REPEAT]
//! ```
//! Code and external data are one 64 KiB memory (PSEN and RD combined); the program runs
//! `REPEAT` times (default 1) from a reset, its memory reloaded each time.

use std::process::ExitCode;
use std::time::Instant;

use buslab_mcs51::{Clocks, FlatMemory, Mcs51, Stop};

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("run_hex: {e}");
            ExitCode::from(2)
        }
    }
}

fn number(s: &str) -> Result<u64, String> {
    let parsed = match s.strip_prefix("0x") {
        Some(hex) => u64::from_str_radix(hex, 16),
        None => s.parse(),
    };
    parsed.map_err(|_| format!("{s:?} is not a number (decimal or 0x hex)"))
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (file, stop, repeat) = match &args[..] {
        [file, stop] => (file, number(stop)?, 1),
        [file, stop, repeat] => (file, number(stop)?, number(repeat)?),
        _ => return Err("usage: run_hex PROGRAM.hex STOP_ADDR [REPEAT]".into()),
    };
    let stop = u16::try_from(stop).map_err(|_| format!("stop address {stop:#x} is above FFFFh"))?;
    let text = std::fs::read_to_string(file).map_err(|e| format!("{file}: {e}"))?;
    let mut image = FlatMemory::new();
    for record in ihex::Reader::new(&text) {
        match record.map_err(|e| format!("{file}: {e}"))? {
            ihex::Record::Data { offset, value } => image.load(offset, &value),
            ihex::Record::EndOfFile => break,
            _ => {}
        }
    }
    let mut cycles = 0;
    let mut instructions = 0;
    let started = Instant::now();
    for _ in 0..repeat {
        let mut mem = image.clone();
        let mut cpu = Mcs51::new();
        cpu.set_traps(stop..=stop);
        loop {
            match cpu.run(&mut mem, Clocks::NEVER) {
                Stop::Trap { .. } => break,
                Stop::Events => while cpu.poll_event().is_some() {},
                other => {
                    return Err(format!(
                        "the program stopped with {other:?} before {stop:04X}h"
                    ));
                }
            }
        }
        cycles += cpu.now().cycles();
        instructions += cpu.instructions();
    }
    let seconds = started.elapsed().as_secs_f64();
    println!("cycles {cycles} instructions {instructions} seconds {seconds:.6}");
    Ok(())
}
