//! Simulator speed on a saturated 1 Mbit/s bus with 2, 16 and 32 nodes.
//!
//! Criterion measures bit-times per second (throughput in "elements"); after it, a table of
//! bit-times/s, frames/s and the real-time factor (simulated seconds per wall second) is
//! printed from one longer run per size.

use std::hint::black_box;
use std::time::{Duration, Instant};

use buslab_can::controller::ControllerConfig;
use buslab_can::{Frame, Id};
use buslab_sim::{Simulation, Traffic};
use criterion::{Criterion, Throughput, criterion_group};

const BITRATE: u32 = 1_000_000;

/// `nodes` nodes, each offering about 2.5 times what the bus can carry, 8-byte frames.
fn saturated(nodes: usize) -> Simulation {
    let mut sim = Simulation::new(BITRATE, 1);
    sim.set_record_events(false);
    for i in 0..nodes {
        let node = sim.add_node(format!("n{i}"), ControllerConfig::default());
        let id = Id::standard(0x100 + i as u16).unwrap();
        let frame = Frame::data(id, &[i as u8, 0x55, 0xAA, 0, 1, 2, 3, 4]).unwrap();
        sim.add_traffic(
            node,
            Traffic::Periodic {
                frame,
                period: 50 * nodes as u64,
                start: 0,
                count: None,
            },
        );
    }
    // Past the start-up, so every queue is busy.
    sim.run_for(10_000);
    sim
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("saturated_1Mbit");
    const CHUNK: u64 = 100_000;
    group.throughput(Throughput::Elements(CHUNK));
    group.sample_size(10);
    for nodes in [2, 16, 32] {
        let mut sim = saturated(nodes);
        group.bench_function(format!("{nodes}_nodes_bit_times"), |b| {
            b.iter(|| {
                sim.run_for(CHUNK);
                black_box(sim.now())
            })
        });
    }
    group.finish();
}

/// CPU time used by this thread so far.
fn thread_cpu_time() -> Duration {
    use nix::sys::resource::{UsageWho, getrusage};
    let usage = getrusage(UsageWho::RUSAGE_THREAD).expect("getrusage");
    let tv = usage.user_time();
    Duration::new(tv.tv_sec() as u64, tv.tv_usec() as u32 * 1000)
}

/// One measurement per size, printed as a table: per wall-clock second and per second of CPU
/// time of this thread (the machine is shared; CPU time is what the simulator gets alone).
fn table() {
    const BITS: u64 = 5_000_000; // 5 s of bus time at 1 Mbit/s
    println!();
    println!("saturated 1 Mbit/s bus, 8-byte frames, {BITS} bit-times per run");
    println!(
        "{:>6} {:>14} {:>10} {:>8} {:>12} | {:>14} {:>12}",
        "nodes", "bit-times/s", "frames/s", "load", "× real time", "bit-times/s", "× real time"
    );
    println!("{:>6} {:>47} | {:>27}", "", "(wall clock)", "(CPU time)");
    for nodes in [2, 16, 32] {
        let mut sim = saturated(nodes);
        let frames_before = sim.bus_stats().frames;
        let busy_before = sim.bus_stats().busy_bits;
        let cpu = thread_cpu_time();
        let started = Instant::now();
        sim.run_for(BITS);
        let wall = started.elapsed().as_secs_f64();
        let cpu = (thread_cpu_time() - cpu).as_secs_f64();
        let frames = sim.bus_stats().frames - frames_before;
        let load = (sim.bus_stats().busy_bits - busy_before) as f64 / BITS as f64;
        let rate = BITS as f64 / wall;
        let cpu_rate = BITS as f64 / cpu;
        println!(
            "{nodes:>6} {rate:>14.0} {:>10.0} {:>7.1}% {:>12.1} | {cpu_rate:>14.0} {:>12.1}",
            frames as f64 / wall,
            load * 100.0,
            rate / BITRATE as f64,
            cpu_rate / BITRATE as f64,
        );
    }
}

criterion_group!(benches, bench);

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
    table();
}
