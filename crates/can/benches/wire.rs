//! Wire codec and controller throughput.
//!
//! `cargo bench -p buslab-can --bench wire`
//!
//! The `wire-encode` and `wire-decode` groups put the original bit-by-bit code (the encoder
//! kept in `tests/reference/`, the bit-by-bit `Receiver`) and the table-driven code side by
//! side on the same frames, so one run gives the before/after comparison in frames/s.

use std::hint::black_box;

use buslab_can::controller::{Controller, ControllerConfig, Event};
use buslab_can::wire::{Bits, EncodeCache, Receiver, Step, decode_bits, encode};
use buslab_can::{Frame, Level};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};

#[path = "../tests/reference/mod.rs"]
mod reference;

#[path = "support/mix.rs"]
mod mix;
use mix::frames;

fn bench_encode(c: &mut Criterion) {
    let frames = frames();
    let mut group = c.benchmark_group("wire-encode");
    group.throughput(Throughput::Elements(frames.len() as u64));
    group.bench_function("reference bit by bit (frames)", |b| {
        b.iter(|| {
            for f in &frames {
                black_box(reference::encode(black_box(f)));
            }
        })
    });
    group.bench_function("table-driven (frames)", |b| {
        b.iter(|| {
            for f in &frames {
                black_box(encode(black_box(f)));
            }
        })
    });
    group.bench_function("table-driven with spans (frames)", |b| {
        b.iter(|| {
            for f in &frames {
                let enc = encode(black_box(f));
                black_box((enc.fields(), enc.wire_fields()));
            }
        })
    });
    group.bench_function("cache hit (frames)", |b| {
        let mut caches: Vec<EncodeCache> = frames.iter().map(|_| EncodeCache::new()).collect();
        b.iter(|| {
            for (f, cache) in frames.iter().zip(&mut caches) {
                black_box(cache.encode(black_box(f)));
            }
        })
    });
    group.finish();
}

fn bench_decode(c: &mut Criterion) {
    let wires: Vec<Bits> = frames().iter().map(|f| encode(f).on_bus()).collect();
    let mut group = c.benchmark_group("wire-decode");
    group.throughput(Throughput::Elements(wires.len() as u64));
    group.bench_function("Receiver bit by bit (frames)", |b| {
        b.iter(|| {
            let mut rx = Receiver::new();
            for bits in &wires {
                rx.reset();
                for bit in bits.iter() {
                    if let Step::Frame(d) = rx.push(black_box(bit)) {
                        black_box(d);
                    }
                }
            }
        })
    });
    group.bench_function("decode_bits whole frame (frames)", |b| {
        b.iter(|| {
            for bits in &wires {
                let _ = black_box(decode_bits(black_box(bits)));
            }
        })
    });
    group.finish();
}

/// `n` nodes, each always with a frame waiting: a saturated bus.
fn saturated(n: usize) -> Vec<Controller> {
    let mut nodes: Vec<Controller> = (0..n)
        .map(|_| Controller::new(ControllerConfig::default()))
        .collect();
    for (i, node) in nodes.iter_mut().enumerate() {
        node.enqueue(frame_for(i)).unwrap();
    }
    nodes
}

fn frame_for(i: usize) -> Frame {
    let id = buslab_can::Id::standard(0x100 + i as u16).unwrap();
    Frame::data(id, &[i as u8, 0x55, 0xAA, 0, 0xFF, 1, 2, 3]).unwrap()
}

fn run(nodes: &mut [Controller], bits: u64) {
    for _ in 0..bits {
        let bus = nodes
            .iter()
            .fold(Level::Recessive, |bus, n| bus.and(n.output()));
        for (i, node) in nodes.iter_mut().enumerate() {
            node.sample(bus);
            while let Some(event) = node.poll_event() {
                if let Event::Transmitted(_) = event {
                    node.enqueue(frame_for(i)).unwrap();
                }
            }
        }
    }
}

fn bench_controller(c: &mut Criterion) {
    const BITS: u64 = 10_000;
    let mut group = c.benchmark_group("controller");
    for n in [2usize, 16, 32] {
        group.throughput(Throughput::Elements(BITS * n as u64));
        group.bench_with_input(
            BenchmarkId::new("node-steps, saturated bus, nodes", n),
            &n,
            |b, &n| {
                let mut nodes = saturated(n);
                run(&mut nodes, 100);
                b.iter(|| run(&mut nodes, BITS))
            },
        );
    }
    group.finish();
}

criterion_group!(benches, bench_encode, bench_decode, bench_controller);
criterion_main!(benches);
