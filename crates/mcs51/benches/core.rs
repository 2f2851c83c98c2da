//! Core speed in machine cycles per second.
//!
//! `cargo bench -p buslab-mcs51`
//!
//! - `checksum`: CPU-bound (benches/checksum.a51: 9 instructions and 12 machine cycles a byte
//!   over 2 KiB, 255 times; 6.27 M cycles a run);
//! - `busy`: the same loop with timer 0 interrupting every 100 cycles and the UART sending at
//!   9600 baud from its interrupt (benches/busy.a51).
//!
//! Real time for the ZELLE cell's 11.0592 MHz crystal is 921 600 machine cycles a second: the
//! goal is 100 times that, 92 M cycles/s. `bench/mcs51_speed.sh` sets this core against SDCC's
//! `s51` on `checksum` in one run.

use std::hint::black_box;

use buslab_mcs51::{Clocks, FlatMemory, Mcs51, Stop};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

fn image(hex: &str) -> FlatMemory {
    let mut mem = FlatMemory::new();
    for record in ihex::Reader::new(hex) {
        match record.expect("the committed HEX file is valid") {
            ihex::Record::Data { offset, value } => mem.load(offset, &value),
            ihex::Record::EndOfFile => break,
            _ => {}
        }
    }
    mem
}

/// Runs the program from reset to `done`; its machine cycles.
fn run(image: &FlatMemory, done: u16) -> u64 {
    let mut mem = image.clone();
    let mut cpu = Mcs51::new();
    cpu.set_traps(done..=done);
    loop {
        match cpu.run(&mut mem, Clocks::NEVER) {
            Stop::Trap { .. } => return cpu.now().cycles(),
            Stop::Events => while cpu.poll_event().is_some() {},
            other => panic!("stopped with {other:?}"),
        }
    }
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("mcs51");
    group.sample_size(20);
    for (name, hex, done) in [
        (
            "checksum (machine cycles)",
            include_str!("checksum.hex"),
            0x0017,
        ),
        ("busy (machine cycles)", include_str!("busy.hex"), 0x005F),
    ] {
        let image = image(hex);
        group.throughput(Throughput::Elements(run(&image, done)));
        group.bench_function(name, |b| b.iter(|| run(black_box(&image), done)));
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
