//! A client of `buslab bus serve` written with buslab's own client library
//! (`buslab_backends::open`), for `bench/vbus_speed.py`.
//!
//! - `send URL COUNT`: sends COUNT frames `123#…` of 8 bytes as fast as the bus takes them,
//!   64 at a time (`CanBus::send_all`; little-endian sequence number, then the monotonic
//!   clock in µs when the frame was made), waits until its node
//!   has sent them all, and prints `sent N seconds S`.
//! - `recv URL IDLE_MS`: prints `ready` once on the bus, receives until IDLE_MS pass without a
//!   frame, and prints `count N in_order BOOL first_us F last_us L p50_us X p99_us Y max_us Z`
//!   (latency: from the sender's clock in the frame to the receive call returning).

use std::io::Write;
use std::time::{Duration, Instant};

use buslab_can::{Frame, Id};
use nix::time::{ClockId, clock_gettime};

fn now_us() -> u64 {
    let t = clock_gettime(ClockId::CLOCK_MONOTONIC).expect("CLOCK_MONOTONIC");
    t.tv_sec() as u64 * 1_000_000 + t.tv_nsec() as u64 / 1_000
}

fn percentile(sorted: &[u32], p: usize) -> u32 {
    if sorted.is_empty() {
        return 0;
    }
    sorted[((sorted.len() - 1) * p + 50) / 100]
}

/// Frames handed to the bus at once (`CanBus::send_all`: one write for socketcand).
const BATCH: usize = 64;

fn send(url: &str, count: u32) -> Result<(), String> {
    let mut bus = buslab_backends::open(url).map_err(|e| e.to_string())?;
    let id = Id::standard(0x123).expect("11 bits");
    let start = Instant::now();
    let mut batch = Vec::with_capacity(BATCH);
    for seq in 0..count {
        let mut data = [0u8; 8];
        data[..4].copy_from_slice(&seq.to_le_bytes());
        data[4..].copy_from_slice(&(now_us() as u32).to_le_bytes());
        batch.push(Frame::data(id, &data).expect("8 bytes"));
        if batch.len() == BATCH || seq + 1 == count {
            bus.send_all(&batch).map_err(|e| e.to_string())?;
            batch.clear();
        }
    }
    let admin = bus
        .admin()
        .ok_or("this bus has no administration side: cannot wait for the frames to be sent")?;
    let report = admin
        .flush(Duration::from_secs(600))
        .map_err(|e| e.to_string())?;
    println!(
        "sent {} failed {} seconds {:.3}",
        report.sent,
        report.failed,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn recv(url: &str, idle: Duration) -> Result<(), String> {
    let mut bus = buslab_backends::open(url).map_err(|e| e.to_string())?;
    println!("ready");
    std::io::stdout().flush().map_err(|e| e.to_string())?;
    let (mut count, mut in_order, mut next) = (0u64, true, 0u32);
    let (mut first, mut last) = (0u64, 0u64);
    let mut latencies = Vec::new();
    while let Some(message) = bus.recv(Some(idle)).map_err(|e| e.to_string())? {
        let t = now_us();
        let data = message.record.payload();
        if data.len() != 8 {
            continue;
        }
        let seq = u32::from_le_bytes(data[..4].try_into().expect("4 bytes"));
        let sent = u32::from_le_bytes(data[4..].try_into().expect("4 bytes"));
        in_order &= seq == next;
        next = seq.wrapping_add(1);
        latencies.push((t as u32).wrapping_sub(sent));
        if count == 0 {
            first = t;
        }
        last = t;
        count += 1;
    }
    latencies.sort_unstable();
    println!(
        "count {count} in_order {in_order} first_us {first} last_us {last} p50_us {} p99_us {} max_us {}",
        percentile(&latencies, 50),
        percentile(&latencies, 99),
        latencies.last().copied().unwrap_or(0)
    );
    Ok(())
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let result = match args.get(1..).unwrap_or_default() {
        [mode, url, count] if mode == "send" => count
            .parse()
            .map_err(|e| format!("COUNT {count}: {e}"))
            .and_then(|n| send(url, n)),
        [mode, url, idle] if mode == "recv" => idle
            .parse()
            .map_err(|e| format!("IDLE_MS {idle}: {e}"))
            .and_then(|ms| recv(url, Duration::from_millis(ms))),
        _ => Err("usage: vbus_speed_client send URL COUNT | recv URL IDLE_MS".into()),
    };
    if let Err(why) = result {
        eprintln!("vbus_speed_client: {why}");
        std::process::exit(1);
    }
}
