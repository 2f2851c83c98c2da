//! ZELLE control lines (`ControlCommand::parse`, what the control socket and `zelle ctl` take),
//! each applied to a running cell: no panic on any line or sequence of lines.
#![no_main]

use buslab_fuzz::text;
use buslab_zelle::control::{ControlCommand, apply, status};
use buslab_zelle::{BatteryRam, Cell};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    let mut cell = Cell::new(BatteryRam::default());
    let mut now = buslab_device::Nanos::ZERO;
    for line in text.lines() {
        now += buslab_device::Nanos::from_millis(1);
        if let Ok(Some(command)) = ControlCommand::parse(line) {
            let _ = apply(&mut cell, now, &command);
            let mut out = Vec::new();
            cell.poll(now, &mut out);
        }
    }
    let _ = status(&cell);
});
