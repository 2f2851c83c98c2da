//! CAN FD frames for the format tests: every FD length with every BRS/ESI combination, with
//! standard and extended IDs, and a proptest strategy over all FD frames.

#![allow(dead_code)] // each test file uses what it needs

use std::time::Duration;

use buslab_can::{FD_LENGTHS, FdFrame, Id};
use buslab_logs::{Direction, Message, Record, Timestamp};
use proptest::prelude::*;

/// 128 frames: the 16 FD lengths × BRS/ESI 00, 01, 10, 11 × a standard and an extended ID,
/// each with its own data.
pub fn every_fd_frame() -> Vec<FdFrame> {
    let mut frames = Vec::new();
    for (k, &len) in FD_LENGTHS.iter().enumerate() {
        for flags in 0..4u8 {
            for extended in [false, true] {
                let n = (k * 8 + usize::from(flags) * 2 + usize::from(extended)) as u32;
                let id = if extended {
                    Id::extended(0x1ABC_0000 | n).unwrap()
                } else {
                    Id::standard((0x100 + n) as u16).unwrap()
                };
                let data: Vec<u8> = (0..len)
                    .map(|i| (i as u8).wrapping_mul(7) ^ n as u8)
                    .collect();
                let frame = FdFrame::new(id, &data)
                    .unwrap()
                    .with_brs(flags & 1 != 0)
                    .with_esi(flags & 2 != 0);
                frames.push(frame);
            }
        }
    }
    frames
}

/// [`every_fd_frame`] as entries 1.5 ms apart from 1700000000 s, on `can0` and `can1`, Rx and
/// Tx in turn.
pub fn every_fd_entry() -> Vec<Message> {
    every_fd_frame()
        .into_iter()
        .enumerate()
        .map(|(i, frame)| Message {
            at: Timestamp::since_epoch(
                Duration::new(1_700_000_000, 0) + Duration::from_micros(1500) * i as u32,
            ),
            channel: format!("can{}", i % 2),
            direction: Some(if i % 3 == 0 {
                Direction::Tx
            } else {
                Direction::Rx
            }),
            record: Record::Fd(frame),
        })
        .collect()
}

/// Any CAN FD frame.
pub fn fd_frame() -> impl Strategy<Value = FdFrame> {
    let id = prop_oneof![
        (0u16..=0x7FF).prop_map(|v| Id::standard(v).unwrap()),
        (0u32..=0x1FFF_FFFF).prop_map(|v| Id::extended(v).unwrap()),
    ];
    (
        id,
        prop::sample::select(FD_LENGTHS.to_vec()),
        prop::collection::vec(any::<u8>(), 64),
        any::<bool>(),
        any::<bool>(),
    )
        .prop_map(|(id, len, data, brs, esi)| {
            FdFrame::new(id, &data[..len])
                .unwrap()
                .with_brs(brs)
                .with_esi(esi)
        })
}
