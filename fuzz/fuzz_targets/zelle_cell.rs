//! The ZELLE cell model fed arbitrary bytes on its line (input: the bytes, with ops for pauses,
//! deadlines, the key and power; see `drive_byte_device`): no panic, it never sends faster
//! than 9600 8N2, and does not keep asking to be woken in the past.
#![no_main]

use buslab_fuzz::drive_byte_device;
use buslab_zelle::{BatteryRam, Cell};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut cell = Cell::new(BatteryRam::default());
    let byte_ns = cell.line().byte_time();
    drive_byte_device(&mut cell, byte_ns, data, |cell, now, op| match op % 4 {
        0 => cell.key_down(now),
        1 => cell.key_up(now),
        2 => cell.reset(now),
        _ if cell.is_powered() => cell.power_off(now),
        _ => cell.power_on(now),
    });
});
