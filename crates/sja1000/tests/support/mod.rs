//! The test bench shared by the SJA1000 test files: chips on the one bus engine
//! (`buslab-sim`), stepped a bit-time at a time, and the TX-buffer helper a driver would use.

use std::ops::{Index, IndexMut};

use buslab_can::BitTime;
use buslab_can::{Frame, Level};
use buslab_sim::Simulation;
use buslab_sja1000::{CanMode, Sja1000};

/// The chips on the wire, reached by index like a `Vec` (`bus.chips[0].write(…)`).
pub struct Chips(Simulation);

#[allow(dead_code)] // each test file uses its own subset
impl Chips {
    pub fn iter(&self) -> impl Iterator<Item = &Sja1000> {
        self.0.nodes().iter().map(|n| n.get::<Sja1000>().unwrap())
    }

    pub fn len(&self) -> usize {
        self.0.nodes().len()
    }

    /// Takes chip `i` off the wire.
    pub fn remove(&mut self, i: usize) -> Sja1000 {
        *self.0.remove_node(i).into_any().downcast().unwrap()
    }
}

impl Index<usize> for Chips {
    type Output = Sja1000;
    fn index(&self, i: usize) -> &Sja1000 {
        self.0.node(i).get().unwrap()
    }
}

impl IndexMut<usize> for Chips {
    fn index_mut(&mut self, i: usize) -> &mut Sja1000 {
        self.0.node_mut(i).get_mut().unwrap()
    }
}

/// Chips on one wired-AND wire.
pub struct Bus {
    pub chips: Chips,
    /// Bit-times since the start.
    pub time: u64,
}

#[allow(dead_code)] // each test file uses its own subset
impl Bus {
    pub fn new(chips: Vec<Sja1000>) -> Self {
        // The bit rate only names seconds in traces; the chips count bit-times.
        let mut sim = Simulation::new(500_000, 1);
        for (i, chip) in chips.into_iter().enumerate() {
            sim.add_device(format!("chip{i}"), Box::new(chip));
        }
        Self {
            chips: Chips(sim),
            time: 0,
        }
    }

    /// One bit-time; `force` may replace the wire level (a disturber).
    pub fn step_with(&mut self, force: impl Fn(u64, Level) -> Level) {
        let time = self.time;
        self.chips.0.step_disturbed(|level| force(time, level));
        self.time = self.chips.0.now().get();
    }

    pub fn run(&mut self, bits: u64) {
        self.chips.0.run_for(BitTime::new(bits));
        self.time = self.chips.0.now().get();
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
