//! Parses a candump log from memory, in rounds of about 5 M frames, and prints the best
//! round's frames per second of this thread's CPU time (from /proc; other processes on the
//! core slow it less than wall time) and of wall time:
//! `cargo run --release -p buslab-logs --example candump_rate -- FILE [ROUNDS]`.
//! bench/logs.sh uses it for its "candump parse" row.

use std::io::Cursor;
use std::time::Instant;

use buslab_logs::Message;
use buslab_logs::candump::Reader;

/// This thread's user + system CPU time in seconds (clock ticks of /proc/thread-self/stat).
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/thread-self/stat").unwrap_or_default();
    // Fields after the command name in brackets: utime and stime are the 12th and 13th.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|f| f.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) / 100.0
}

/// Parses `input` `passes` times: (frames, CPU seconds, wall seconds).
fn run(input: &[u8], passes: u32) -> (u64, f64, f64) {
    let (cpu0, wall0) = (cpu_seconds(), Instant::now());
    let mut frames = 0u64;
    let mut entry = Message::default();
    for _ in 0..passes {
        let mut reader = Reader::new(Cursor::new(input));
        while reader.read_into(&mut entry).expect("a bad line") {
            frames += 1;
        }
    }
    (frames, cpu_seconds() - cpu0, wall0.elapsed().as_secs_f64())
}

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("usage: candump_rate FILE [ROUNDS]");
    let rounds: u32 = args
        .next()
        .map_or(5, |r| r.parse().expect("ROUNDS is a number"));
    let input = std::fs::read(&path).expect("cannot read the log");
    // Rounds of about 5 M frames (CPU time comes in 10 ms ticks); the best round is the one
    // least disturbed by other processes sharing the core.
    let lines = input.iter().filter(|&&b| b == b'\n').count().max(1);
    let passes = (5_000_000 / lines).max(1) as u32;
    let (mut best_cpu, mut best_wall) = (0.0f64, 0.0f64);
    let mut total = 0u64;
    for _ in 0..rounds {
        let (frames, cpu, wall) = run(&input, passes);
        total += frames;
        best_cpu = best_cpu.max(frames as f64 / cpu.max(0.01));
        best_wall = best_wall.max(frames as f64 / wall.max(1e-9));
    }
    println!(
        "{total} frames in {rounds} rounds; best round: {:.1} M frames/s of CPU time, {:.1} M frames/s of wall time",
        best_cpu / 1e6,
        best_wall / 1e6
    );
}
