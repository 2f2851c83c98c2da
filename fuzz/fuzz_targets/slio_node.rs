//! A SLIO (P82C150 model) on a wire driven from fuzz input: calibration frames, frames to any
//! identifier, runs of arbitrary bits and idle, and changing input pins, over time: no panic,
//! and its events and notices stay drained (nothing grows without bound).
#![no_main]

use buslab_can::node::BusNode;
use buslab_can::wire::encode;
use buslab_can::{BitTime, Frame, Id, Level, StandardId};
use buslab_slio::{Slio, SlioId, calibration_frame};
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;

/// Bit-times an input may run: the SLIO's longest time-out (`WATCHDOG`, 8192 bit-times
/// without a frame for it) fits four times. Every bit is a step of the model, and a long input
/// of idle runs took milliseconds to reach nothing new.
const MAX_BITS: BitTime = BitTime::new(4 * buslab_slio::slio::WATCHDOG.get());

struct Wire {
    slio: Slio,
    now: BitTime,
}

impl Wire {
    /// One bit-time: the bus is the wired-AND of what we drive and what the SLIO drives.
    fn bit(&mut self, recessive: bool) {
        let driven = if recessive {
            Level::Recessive
        } else {
            Level::Dominant
        };
        let bus = if self.slio.output() == Level::Dominant {
            Level::Dominant
        } else {
            driven
        };
        self.slio.sample(self.now, bus);
        self.now += BitTime::ONE;
        while self.slio.poll_event().is_some() {}
        for _ in self.slio.take_notices() {}
    }

    fn frame(&mut self, frame: &Frame) {
        for b in encode(frame).on_bus().iter() {
            self.bit(b);
        }
        for _ in 0..3 {
            self.bit(true);
        }
    }
}

fn run(u: &mut Unstructured) -> Result<()> {
    let id = SlioId::new(u.int_in_range(0..=15)?).unwrap();
    let bitrate = *u.choose(&[20_000, 50_000, 125_000])?;
    let mut wire = Wire {
        slio: Slio::new(id, bitrate).unwrap(),
        now: BitTime::ZERO,
    };
    while !u.is_empty() && wire.now < MAX_BITS {
        match u.int_in_range(0..=5u8)? {
            0 | 1 => wire.frame(&calibration_frame()),
            2 => {
                let id = Id::Standard(StandardId::new(u.int_in_range(0..=0x7FF)?).unwrap());
                let frame = if u.ratio(1, 8)? {
                    Frame::remote(id, u.int_in_range(0..=8)?).unwrap()
                } else {
                    let len = u.int_in_range(0..=8)?;
                    Frame::data(id, u.bytes(len.min(u.len()))?).unwrap()
                };
                wire.frame(&frame);
            }
            3 => {
                for _ in 0..u.int_in_range(1..=64)? {
                    let b: bool = u.arbitrary()?;
                    wire.bit(b);
                }
            }
            4 => {
                for _ in 0..u.int_in_range(1..=2_000)? {
                    wire.bit(true);
                }
            }
            _ => {
                let levels = u.arbitrary()?;
                let now = wire.now;
                wire.slio.set_inputs(now, levels);
            }
        }
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let _ = run(&mut Unstructured::new(data));
});
