//! How fast the virtual bus runs its SJA1000 nodes: 1 sender kept busy and 8 receivers on a
//! 1 Mbit/s bus (the `bench/can_bus_serve.py` set-up without the network), as bit-times per
//! second and the factor over real time. Every chip is stepped every bit and its driver
//! polled on each interrupt.

use std::hint::black_box;
use std::time::Instant;

use buslab_can::BitTime;
use buslab_can::{Frame, Id};
use buslab_vbus::VirtualBus;
use criterion::{Criterion, Throughput, criterion_group};

const BITRATE: u32 = 1_000_000;
const CHUNK: u64 = 100_000;

fn bus(receivers: usize) -> (VirtualBus, u32) {
    let mut bus = VirtualBus::new(BITRATE).unwrap();
    let sender = bus.join().unwrap();
    for _ in 0..receivers {
        bus.join().unwrap();
    }
    (bus, sender)
}

/// Runs `bits` more bit-times with the sender's queue kept full; returns frames sent.
fn run(bus: &mut VirtualBus, sender: u32, bits: u64) -> u64 {
    let frame = Frame::data(Id::standard(0x123).unwrap(), &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    let end = bus.now() + BitTime::new(bits);
    let mut sent = 0;
    while bus.now() < end {
        let node = bus.client_mut(sender).unwrap();
        while node.submit(frame).is_ok() {}
        let before = bus.stats().frames;
        bus.run_until(BitTime::new(
            ((bus.now() + BitTime::new(1000)).min(end)).get(),
        ));
        sent += bus.stats().frames - before;
        for (_, n) in bus.clients_mut() {
            n.take_deliveries();
        }
    }
    sent
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("vbus_1Mbit");
    group.throughput(Throughput::Elements(CHUNK));
    group.sample_size(10);
    for receivers in [1usize, 8] {
        let (mut b, s) = bus(receivers);
        group.bench_function(format!("{}_nodes_bit_times", receivers + 1), |bench| {
            bench.iter(|| black_box(run(&mut b, s, CHUNK)))
        });
    }
    group.finish();
}

fn table() {
    println!("\n nodes    bit-times/s   frames/s  × real time");
    for receivers in [1usize, 8, 16] {
        let (mut b, s) = bus(receivers);
        let bits = 2_000_000;
        let t = Instant::now();
        let frames = run(&mut b, s, bits);
        let secs = t.elapsed().as_secs_f64();
        println!(
            "{:6} {:14.0} {:10.0} {:12.1}",
            receivers + 1,
            bits as f64 / secs,
            frames as f64 / secs,
            bits as f64 / secs / BITRATE as f64
        );
    }
}

criterion_group!(benches, bench);

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
    table();
}
