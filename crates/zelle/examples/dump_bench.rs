//! Dumps data RAM from the served cell model over a real pseudo-terminal at 9600 8N2 and
//! prints the throughput as a share of the line's byte rate, pipelined vs stop-and-wait.
//!
//! `cargo run --release -p buslab-zelle --example dump_bench [BYTES]` (default 8192; about
//! 10 s pipelined and 20 s stop-and-wait per 8 KiB). Not part of the test suite.

use std::time::{Duration, Instant};

use buslab_link::{SerialLine, Serve};
use buslab_zelle::client::{Client, Transfer};
use buslab_zelle::timing::{BYTE_NS, LINE};
use buslab_zelle::{Cell, DATA_AREA};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let len: usize = match std::env::args().nth(1) {
        Some(arg) => arg
            .parse()
            .map_err(|_| format!("BYTES `{arg}` is not a number"))?,
        None => 8192,
    };
    let pattern: Vec<u8> = (0..len).map(|i| (i * 31 + 7) as u8).collect();
    let mut cell = Cell::default();
    cell.write_ram(DATA_AREA, &pattern);

    let served = Serve::new(cell, LINE).name("zelle").spawn()?;
    let path = served.path().to_path_buf();
    let mut client = Client::with_timeout(SerialLine::open(&path, LINE)?, Duration::from_secs(2));
    client.reset()?;

    let line_rate = 1e9 / BYTE_NS.get() as f64;
    println!(
        "dump of {len} bytes of data RAM from the model on {} at {LINE}",
        path.display()
    );
    println!("line limit: {line_rate:.1} B/s (one byte per {BYTE_NS} ns)\n");
    println!("| transfer      | bytes | seconds | bytes/s | % of line rate |");
    println!("|---------------|------:|--------:|--------:|---------------:|");
    for (name, mode) in [
        ("pipelined", Transfer::Pipelined),
        ("stop-and-wait", Transfer::StopAndWait),
    ] {
        let t0 = Instant::now();
        let data = client.read_data(len, mode)?;
        let secs = t0.elapsed().as_secs_f64();
        if data != pattern {
            return Err(format!("{name}: the dumped bytes differ from the RAM").into());
        }
        let rate = len as f64 / secs;
        println!(
            "| {name:<13} | {len:>5} | {secs:>7.2} | {rate:>7.1} | {:>13.1}% |",
            100.0 * rate / line_rate
        );
        client.reset()?;
    }
    served.stop()?;
    Ok(())
}
