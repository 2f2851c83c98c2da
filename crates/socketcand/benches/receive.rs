//! The socketcand client's receive path on one core, without a socket: frame elements as a
//! server sends them, pushed in reads of 64 KiB (the client's read buffer), parsed, kept, and
//! taken out as `recv` does. `cargo bench -p buslab-socketcand --bench receive`; instructions:
//! `valgrind --tool=callgrind --toggle-collect=receive::receive_all BENCH_BINARY --bench
//! --test` (the test mode runs it twice: once to check, once timed).

use std::hint::black_box;

use buslab_bus::Record;
use buslab_socketcand::Inbound;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

/// Frames per iteration.
const N: usize = 10_000;
/// The client's read size.
const READ: usize = 64 * 1024;

/// `n` frame elements as `buslab bus serve` writes them: 8 data bytes, a growing timestamp.
pub fn elements(n: usize) -> Vec<u8> {
    let mut out = String::new();
    for i in 0..n {
        let b = (i as u64).to_le_bytes();
        out.push_str(&format!(
            "< frame 123 {}.{:06} {:02X}{:02X}{:02X}{:02X}01020304 >",
            1_700_000_000 + i / 1000,
            (i % 1000) * 1000,
            b[0],
            b[1],
            b[2],
            b[3]
        ));
    }
    out.into_bytes()
}

/// Pushes `input` read by read, handles it and takes every frame out; the frames taken.
/// (Not inlined: `valgrind --tool=callgrind --toggle-collect=receive::receive_all` counts it.)
#[inline(never)]
fn receive_all(inbound: &mut Inbound, input: &[u8]) -> usize {
    let mut n = 0;
    for read in input.chunks(READ) {
        inbound.push(read);
        while let Some(m) = inbound.next_message().expect("frames only") {
            black_box(m);
        }
        while let Some(event) = inbound.pop(false) {
            if let Record::Frame(frame) = &event.record {
                black_box(frame);
                n += 1;
            }
        }
    }
    n
}

fn bench(c: &mut Criterion) {
    let input = elements(N);
    let mut inbound = Inbound::new("vcan0");
    assert_eq!(receive_all(&mut inbound, &input), N);
    let mut group = c.benchmark_group("socketcand_receive");
    group.throughput(Throughput::Elements(N as u64));
    group.bench_function("frames", |b| {
        b.iter(|| receive_all(&mut inbound, black_box(&input)))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
