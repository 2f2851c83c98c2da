//! A wired-AND test bus over shared SJA1000 chips, stepped one bit-time at a time.
#![allow(dead_code)]

use buslab_can::{Frame, Level};
use buslab_canbus::{RegisterAccess, SharedChip, Sja1000Config, Sja1000Driver, shared_chip};

pub struct Bus {
    pub chips: Vec<SharedChip>,
    pub time: u64,
}

impl Bus {
    pub fn new(n: usize) -> Self {
        Self {
            chips: (0..n).map(|_| shared_chip()).collect(),
            time: 0,
        }
    }

    /// One bit-time; `force` may replace the wire level (a disturber).
    pub fn step_with(&mut self, force: impl Fn(u64, Level) -> Level) {
        let wire = self.chips.iter().fold(Level::Recessive, |bus, chip| {
            bus.and(chip.lock().unwrap().output())
        });
        let level = force(self.time, wire);
        for chip in &self.chips {
            chip.lock().unwrap().sample(level);
        }
        self.time += 1;
    }

    pub fn run(&mut self, bits: u64) {
        for _ in 0..bits {
            self.step_with(|_, level| level);
        }
    }

    /// A driver for chip `i`, initialised with `config`.
    pub fn driver(&self, i: usize, config: &Sja1000Config) -> Sja1000Driver<SharedChip> {
        let mut driver = Sja1000Driver::new(self.chips[i].clone());
        driver.init(config).expect("init");
        driver
    }
}

pub fn frame(s: &str) -> Frame {
    s.parse().unwrap()
}

/// Register access that records every write (address, value) and forwards to `inner`.
pub struct Recorder<R> {
    pub inner: R,
    pub writes: Vec<(u8, u8)>,
    pub reads: Vec<u8>,
}

impl<R: RegisterAccess> RegisterAccess for Recorder<R> {
    fn read(&mut self, addr: u8) -> u8 {
        self.reads.push(addr);
        self.inner.read(addr)
    }
    fn write(&mut self, addr: u8, value: u8) {
        self.writes.push((addr, value));
        self.inner.write(addr, value)
    }
}
