//! The test bench shared by the SJA1000 test files: chips on one wired-AND wire, stepped a
//! bit-time at a time, and the TX-buffer helper a driver would use.

use buslab_can::{Frame, Level};
use buslab_sja1000::{CanMode, Sja1000};

/// Chips on one wired-AND wire.
pub struct Bus {
    pub chips: Vec<Sja1000>,
    pub time: u64,
}

#[allow(dead_code)] // each test file uses its own subset
impl Bus {
    pub fn new(chips: Vec<Sja1000>) -> Self {
        Self { chips, time: 0 }
    }

    /// One bit-time; `force` may replace the wire level (a disturber).
    pub fn step_with(&mut self, force: impl Fn(u64, Level) -> Level) {
        let wire = self
            .chips
            .iter()
            .fold(Level::Recessive, |bus, chip| bus.and(chip.output()));
        let level = force(self.time, wire);
        for chip in &mut self.chips {
            chip.sample(level);
        }
        self.time += 1;
    }

    pub fn run(&mut self, bits: u64) {
        for _ in 0..bits {
            self.step_with(|_, level| level);
        }
    }

    /// Runs until `done` holds, at most `limit` bit-times; panics with `what` otherwise.
    pub fn run_until(&mut self, limit: u64, what: &str, mut done: impl FnMut(&mut Self) -> bool) {
        for _ in 0..limit {
            if done(self) {
                return;
            }
            self.run(1);
        }
        panic!("{what} did not happen within {limit} bit-times");
    }
}

/// Writes `frame` into the TX buffer (PeliCAN 16.., BasicCAN 10..).
pub fn load_tx(chip: &mut Sja1000, frame: &str) {
    let frame: Frame = frame.parse().unwrap();
    let mut buf = [0u8; 13];
    let len = buslab_sja1000::layout::encode(chip.mode(), &frame, &mut buf);
    let base = match chip.mode() {
        CanMode::Peli => 16,
        CanMode::Basic => 10,
    };
    for (k, &byte) in buf[..len].iter().enumerate() {
        chip.write(base + k as u8, byte);
    }
}
