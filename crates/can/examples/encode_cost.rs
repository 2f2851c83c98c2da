//! The encoder's cost per frame, for callgrind: encodes the wire benchmark's frame mix
//! (`benches/support/mix.rs`) ROUNDS times and prints frames/s of CPU time.
//!
//! ```text
//! cargo build --release -p buslab-can --example encode_cost
//! valgrind --tool=callgrind --callgrind-out-file=/dev/null target/release/examples/encode_cost 100
//! ```
//! Instructions per frame = the `Collected` total ÷ the frames printed (the mix set-up is a few
//! thousand instructions).

use std::hint::black_box;
use std::time::Instant;

use buslab_can::wire::encode;

#[path = "../benches/support/mix.rs"]
mod mix;

fn main() {
    let rounds: u64 = match std::env::args().nth(1).map(|a| a.parse()) {
        None => 1000,
        Some(Ok(n)) if n > 0 => n,
        Some(_) => {
            eprintln!("usage: encode_cost [ROUNDS > 0]");
            std::process::exit(2);
        }
    };
    let frames = mix::frames();
    let encoded: Vec<_> = frames.iter().map(encode).collect();
    let per_frame = |f: fn(&buslab_can::wire::Encoded) -> usize| {
        encoded.iter().map(f).sum::<usize>() as f64 / frames.len() as f64
    };
    println!(
        "mix: {} frames, {:.1} wire bits and {:.1} stuff bits each on average",
        frames.len(),
        per_frame(|e| e.stuffed().len()),
        per_frame(|e| e.stuff_bits()),
    );
    let start = Instant::now();
    for _ in 0..rounds {
        for frame in &frames {
            black_box(encode(black_box(frame)));
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    let count = rounds * frames.len() as u64;
    println!(
        "encoded {count} frames in {elapsed:.3} s: {:.1} M frames/s",
        count as f64 / elapsed / 1e6
    );
}
