//! Parses a candump log from memory several times and prints frames per second of this
//! thread's CPU time (from /proc; not disturbed by other processes sharing the core) and of
//! wall time: `cargo run --release -p buslab-logs --example candump_rate -- FILE [ROUNDS]`.
//! bench/logs.sh uses it for its "candump parse" row.

use std::io::Cursor;
use std::time::Instant;

use buslab_logs::Entry;
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

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("usage: candump_rate FILE [ROUNDS]");
    let rounds: u32 = args
        .next()
        .map_or(10, |r| r.parse().expect("ROUNDS is a number"));
    let input = std::fs::read(&path).expect("cannot read the log");
    let (cpu0, wall0) = (cpu_seconds(), Instant::now());
    let mut frames = 0u64;
    let mut entry = Entry::default();
    for _ in 0..rounds {
        let mut reader = Reader::new(Cursor::new(&input[..]));
        while reader.read_into(&mut entry).expect("a bad line") {
            frames += 1;
        }
    }
    let cpu = cpu_seconds() - cpu0;
    let wall = wall0.elapsed().as_secs_f64();
    println!(
        "{frames} frames: {:.1} M frames/s of CPU time, {:.1} M frames/s of wall time",
        frames as f64 / cpu.max(1e-9) / 1e6,
        frames as f64 / wall / 1e6
    );
}
