//! The SLCAN adapter model (`buslab_slcan::Adapter`, `buslab slcan serve`): bytes from the host,
//! frames from the bus and a host that reads slowly or not at all. No panic, and nothing grows
//! without bound: the output for the host stays within `MAX_OUTPUT`, the events are drained.
//!
//! Input: the first byte's top bit makes the adapter speak CAN FD (a CANable 2.0's kind) or
//! classic CAN; then data bytes go to the adapter; `FF` then an op byte (see
//! `buslab_fuzz::items`): `00..7B` delivers frames from the bus (a classic frame and an FD
//! frame, ID and data from the op, extended above 3F), `7C..7F` an error frame of the
//! adapter's controller (bus error, passive, bus-off, back to active), `80..FE` lets the host
//! read `(op & 7F) * 16` bytes.
#![no_main]

use buslab_can::{FD_LENGTHS, FdFrame, Frame, Id};
use buslab_canbus::{ControllerState, Ecc, ErrorCounters, ErrorFrame};
use buslab_fuzz::{Item, items};
use buslab_slcan::{Adapter, AdapterEvent, MAX_OUTPUT};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let fd = data.first().is_some_and(|b| b & 0x80 != 0);
    let mut adapter = Adapter::default().with_fd(fd);
    let mut transmitted = 0usize;
    let mut lines = 0usize;
    // One item a millisecond.
    for (now_ms, item) in (0u64..).zip(items(data)) {
        match item {
            Item::Data(byte) => {
                lines += usize::from(byte == b'\r' || byte == 0x07);
                adapter.receive(&[byte]);
            }
            Item::Op(op @ 0x7C..=0x7F) => {
                let counters = ErrorCounters { tx: op, rx: 0 };
                adapter.controller_error(&match op {
                    0x7C => ErrorFrame::sja1000_bus_error(Ecc(0x3C), Some(counters)),
                    0x7D => ErrorFrame::state_change(ControllerState::Passive, counters),
                    0x7E => ErrorFrame::state_change(ControllerState::BusOff, counters),
                    _ => ErrorFrame::state_change(ControllerState::Active, counters),
                });
            }
            Item::Op(op @ 0x00..=0x7B) => {
                let id = if op > 0x3F {
                    Id::extended((u32::from(op) * 0x0123_4567) & 0x1FFF_FFFF)
                } else {
                    Id::standard((u16::from(op) * 0x21) & 0x7FF)
                }
                .expect("an ID in range");
                let payload = [op; 64];
                let frame = Frame::data(id, &payload[..usize::from(op % 9)]).expect("0..8 bytes");
                let long = FD_LENGTHS[usize::from(op % 16)];
                let fd_frame = FdFrame::new(id, &payload[..long])
                    .expect("an FD length")
                    .with_brs(op & 1 == 1);
                let now = buslab_can::Nanos::from_millis(now_ms);
                for _ in 0..64 {
                    adapter.deliver(&frame, now);
                    adapter.deliver_fd(&fd_frame, now);
                }
            }
            Item::Op(op) => adapter.consume(usize::from(op & 0x7F) * 16),
        }
        assert!(
            adapter.output().len() <= MAX_OUTPUT,
            "{} bytes",
            adapter.output().len()
        );
        while let Some(event) = adapter.poll_event() {
            match event {
                AdapterEvent::TransmitFd(_) if !fd => panic!("a classic adapter sent FD"),
                AdapterEvent::RefusedFd(_) if fd => panic!("an FD adapter refused FD"),
                AdapterEvent::Transmit(_)
                | AdapterEvent::TransmitFd(_)
                | AdapterEvent::RefusedBusOff(_)
                | AdapterEvent::RefusedFd(_) => transmitted += 1,
                _ => {}
            }
        }
        // A frame to send (or refused while bus-off) is one command line.
        assert!(transmitted <= lines);
    }
});
