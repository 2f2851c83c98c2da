//! Decode speed on a frame log, for bench/dbc_speed.py: `dbc_speed FILE.dbc FRAMES SECONDS`.
//!
//! FRAMES has one frame a line, `ID#HEX` (candump's notation: 3 hex digits for a standard ID,
//! 8 for an extended one). The frames are read first; then every frame is looked up by ID and
//! decoded into a reused buffer (`Database::message`, `Message::decode_into`: every signal's
//! raw and physical value), in whole passes over the log until SECONDS have gone by. Prints
//! `frames N seconds S signals M checksum C`.

use std::time::{Duration, Instant};

use buslab_can::Id;
use buslab_dbc::Database;

fn frame(line: &str) -> (Id, Vec<u8>) {
    let (id, data) = line.split_once('#').expect("ID#HEX");
    let raw = u32::from_str_radix(id, 16).expect("a hex ID");
    let id = if id.len() == 8 {
        Id::extended(raw)
    } else {
        Id::standard(raw as u16)
    }
    .expect("an ID");
    let data = (0..data.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&data[i..i + 2], 16).expect("hex data"))
        .collect();
    (id, data)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let [_, dbc, frames, seconds] = args.as_slice() else {
        eprintln!("usage: dbc_speed FILE.dbc FRAMES SECONDS");
        std::process::exit(2);
    };
    let db = Database::from_bytes(&std::fs::read(dbc).expect("read the DBC file")).unwrap();
    let text = std::fs::read_to_string(frames).expect("read the frames");
    let frames: Vec<(Id, Vec<u8>)> = text.lines().map(frame).collect();
    let budget = Duration::from_secs_f64(seconds.parse().expect("seconds"));
    let mut out = Vec::with_capacity(64);
    let (mut decoded, mut signals, mut checksum) = (0u64, 0u64, 0f64);
    let start = Instant::now();
    while start.elapsed() < budget {
        for (id, data) in &frames {
            if let Some(message) = db.message(*id) {
                message.decode_into(data, &mut out);
                signals += out.len() as u64;
                checksum += out.iter().map(|d| d.physical).sum::<f64>();
            }
        }
        decoded += frames.len() as u64;
    }
    let elapsed = start.elapsed().as_secs_f64();
    println!("frames {decoded} seconds {elapsed} signals {signals} checksum {checksum}");
}
