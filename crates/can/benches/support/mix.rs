//! The frame mix the wire benchmarks measure (shared by `benches/wire.rs` and
//! `examples/encode_cost.rs`, so criterion's times and callgrind's counts are of the same work).

use buslab_can::{Frame, Id};

/// A fixed mix of frames: standard and extended, data and remote, every length, bytes biased
/// to 0x00 and 0xFF (stuffing), from a fixed-seed generator so every run measures the same.
pub fn frames() -> Vec<Frame> {
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    (0..1024)
        .map(|_| {
            let r = next();
            let id = if r & 1 == 0 {
                Id::standard((r >> 8) as u16 & 0x7FF).unwrap()
            } else {
                Id::extended((r >> 8) as u32 & 0x1FFF_FFFF).unwrap()
            };
            let len = (r >> 40) as usize % 9;
            if r >> 50 & 7 == 0 {
                return Frame::remote(id, len as u8).unwrap();
            }
            let bytes: Vec<u8> = (0..len)
                .map(|_| match next() % 4 {
                    0 => 0x00,
                    1 => 0xFF,
                    r => (r >> 8) as u8,
                })
                .collect();
            Frame::data(id, &bytes).unwrap()
        })
        .collect()
}
