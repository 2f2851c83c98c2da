//! The CPU196 board model fed arbitrary bytes on its line, interrupts and power-button presses
//! over time: no panic, it never sends faster than its line, and does not keep asking to be woken
//! in the past.
#![no_main]

use std::sync::OnceLock;

use buslab_cpu196::source::Inputs;
use buslab_cpu196::{Board, Image};
use buslab_fuzz::drive_byte_device;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // The default image computes its log table: once, not per input.
    static IMAGE: OnceLock<Image> = OnceLock::new();
    let image = IMAGE.get_or_init(Image::default).clone();
    let mut board = Board::new(image, Inputs::default(), buslab_device::Nanos::ZERO);
    let byte_ns = board.line().byte_time();
    drive_byte_device(&mut board, byte_ns, data, |board, now, op| match op % 2 {
        0 => board.external_interrupt(now),
        _ => board.power_button(now),
    });
});
