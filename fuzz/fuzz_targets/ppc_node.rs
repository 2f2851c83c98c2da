//! The PowerPC node (`buslab_ppc::PpcNode`: an SJA1000 on the wire with MoniCAN as its program)
//! driven from fuzz input: frames to any identifier (SLIO replies, the mail notifier), runs of
//! arbitrary bits and idle, keys from the terminal, over time. No panic, and nothing grows
//! without bound: events drained, screen output bounded, keys beyond its buffer counted.
#![no_main]

use buslab_can::node::BusNode;
use buslab_can::wire::encode;
use buslab_can::{BitTime, Frame, Id, Level, StandardId};
use buslab_monican::{Config, DEFAULT_MAIL_ID};
use buslab_ppc::PpcNode;
use buslab_slio::SlioId;
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;

/// One full redraw of a 24 × 80 VT100 screen with attributes is a few kB.
const MAX_SCREEN: usize = 64 * 1024;
/// Bit-times an input runs at most. Every bit is a step of the SJA1000 and MoniCAN models, so
/// a long input of idle runs took a second of CPU; the longest time-out the node keeps (a
/// SLIO's answer, `buslab_slio::master::ANSWER_WITHIN`, 4000 bit-times) fits 12 times.
const MAX_BITS: BitTime = BitTime::new(12 * buslab_slio::master::ANSWER_WITHIN.get());

struct Wire {
    node: PpcNode,
    now: BitTime,
}

impl Wire {
    /// One bit-time: the bus is the wired-AND of what we drive and what the node drives.
    fn bit(&mut self, recessive: bool) {
        let bus = if self.node.output() == Level::Dominant || !recessive {
            Level::Dominant
        } else {
            Level::Recessive
        };
        self.node.sample(self.now, bus);
        self.now += BitTime::ONE;
        while self.node.poll_event().is_some() {}
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
    let bitrate = *u.choose(&[20_000, 125_000])?;
    let config = Config {
        bitrate,
        ..Config::default()
    };
    let mut wire = Wire {
        node: PpcNode::new(config).unwrap(),
        now: BitTime::ZERO,
    };
    while !u.is_empty() && wire.now < MAX_BITS {
        match u.int_in_range(0..=5u8)? {
            0 | 1 => {
                let raw = match u.int_in_range(0..=2u8)? {
                    0 => SlioId::new(u.int_in_range(0..=15)?)
                        .unwrap()
                        .reply_id()
                        .as_raw() as u16,
                    1 => DEFAULT_MAIL_ID,
                    _ => u.int_in_range(0..=0x7FF)?,
                };
                let id = Id::Standard(StandardId::new(raw).unwrap());
                let frame = if u.ratio(1, 8)? {
                    Frame::remote(id, u.int_in_range(0..=8)?).unwrap()
                } else {
                    let len = u.int_in_range(0..=8)?;
                    Frame::data(id, u.bytes(len.min(u.len()))?).unwrap()
                };
                wire.frame(&frame);
            }
            2 => {
                for _ in 0..u.int_in_range(1..=64)? {
                    let b: bool = u.arbitrary()?;
                    wire.bit(b);
                }
            }
            3 => {
                for _ in 0..u.int_in_range(1..=2_000)? {
                    wire.bit(true);
                }
            }
            _ => {
                let n = u.int_in_range(1..=8)?.min(u.len());
                for &key in u.bytes(n)? {
                    wire.node.key(key);
                }
            }
        }
        let screen = wire.node.take_screen();
        assert!(
            screen.len() <= MAX_SCREEN,
            "{} bytes of screen",
            screen.len()
        );
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let _ = run(&mut Unstructured::new(data));
});
