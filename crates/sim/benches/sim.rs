//! Simulator speed on a saturated 1 Mbit/s bus with 2, 16, 32 and 64 nodes, on the
//! frame-level fast path and bit by bit (`whole frames` off, as `buslab sim --bit-level`).
//!
//! Criterion measures bit-times per second (throughput in "elements"); after it, a table of
//! bit-times/s, frames/s and the real-time factor (simulated seconds per wall second) is
//! printed from one longer run per size and path.

use std::hint::black_box;
use std::time::{Duration, Instant};

use buslab_can::BitTime;
use buslab_can::controller::ControllerConfig;
use buslab_can::{Frame, Id};
use buslab_sim::{RecordedEvents, Simulation, Traffic};
use criterion::{Criterion, Throughput, criterion_group};

const BITRATE: u32 = 1_000_000;

/// `nodes` nodes, each offering about 2.5 times what the bus can carry, 8-byte frames.
fn saturated(nodes: usize, whole_frames: bool) -> Simulation {
    let mut sim = Simulation::new(BITRATE, 1);
    sim.set_whole_frames(whole_frames);
    sim.set_record_events(RecordedEvents::empty());
    for i in 0..nodes {
        let node = sim.add_node(format!("n{i}"), ControllerConfig::default());
        let id = Id::standard(0x100 + i as u16).unwrap();
        let frame = Frame::data(id, &[i as u8, 0x55, 0xAA, 0, 1, 2, 3, 4]).unwrap();
        sim.add_traffic(
            node,
            Traffic::Periodic {
                frame,
                period: BitTime::new(50 * nodes as u64),
                start: BitTime::ZERO,
                count: None,
            },
        );
    }
    // Past the start-up, so every queue is busy.
    sim.run_for(BitTime::new(10_000));
    sim
}

const SIZES: [usize; 4] = [2, 16, 32, 64];

/// `(name, whole frames on)` of the two paths.
const PATHS: [(&str, bool); 2] = [("fast", true), ("bit_level", false)];

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("saturated_1Mbit");
    const CHUNK: u64 = 100_000;
    group.throughput(Throughput::Elements(CHUNK));
    group.sample_size(10);
    for nodes in SIZES {
        for (path, whole) in PATHS {
            let mut sim = saturated(nodes, whole);
            group.bench_function(format!("{nodes}_nodes_{path}_bit_times"), |b| {
                b.iter(|| {
                    sim.run_for(BitTime::new(CHUNK));
                    black_box(sim.now())
                })
            });
        }
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
    // Bus time per run: 5 s on the fast path, 0.5 s bit by bit.
    const BITS: [u64; 2] = [5_000_000, 500_000];
    println!();
    println!("saturated 1 Mbit/s bus, 8-byte frames; fast path 5 s, bit-level 0.5 s per run");
    println!(
        "{:>6} {:>9} {:>14} {:>10} {:>8} {:>12} | {:>14} {:>12}",
        "nodes",
        "path",
        "bit-times/s",
        "frames/s",
        "load",
        "× real time",
        "bit-times/s",
        "× real time"
    );
    println!("{:>6} {:>57} | {:>27}", "", "(wall clock)", "(CPU time)");
    for nodes in SIZES {
        for ((path, whole), bits) in PATHS.into_iter().zip(BITS) {
            let mut sim = saturated(nodes, whole);
            let frames_before = sim.bus_stats().frames;
            let busy_before = sim.bus_stats().busy_bits;
            let cpu = thread_cpu_time();
            let started = Instant::now();
            sim.run_for(BitTime::new(bits));
            let wall = started.elapsed().as_secs_f64();
            let cpu = (thread_cpu_time() - cpu).as_secs_f64();
            let frames = sim.bus_stats().frames - frames_before;
            let load = (sim.bus_stats().busy_bits - busy_before) as f64 / bits as f64;
            let rate = bits as f64 / wall;
            let cpu_rate = bits as f64 / cpu;
            println!(
                "{nodes:>6} {path:>9} {rate:>14.0} {:>10.0} {:>7.1}% {:>12.1} | {cpu_rate:>14.0} {:>12.1}",
                frames as f64 / wall,
                load * 100.0,
                rate / BITRATE as f64,
                cpu_rate / BITRATE as f64,
            );
        }
    }
}

criterion_group!(benches, bench);

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
    table();
}
