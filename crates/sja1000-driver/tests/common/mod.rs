//! A test bus over shared SJA1000 chips on the one bus engine (`buslab-sim`): the drivers
//! under test (or a manager's thread) reach the chips through their locks, the engine steps
//! them one bit-time at a time.
#![allow(dead_code)]

use std::any::Any;

use buslab_can::BitTime;
use buslab_can::controller::{ErrorState, Event, QueueFull};
use buslab_can::node::BusNode;
use buslab_can::{Frame, Level};
use buslab_sim::Simulation;
use buslab_sja1000_driver::{
    RegisterAccess, SharedChip, Sja1000Config, Sja1000Driver, shared_chip,
};

/// A chip shared with a driver, as a node of the engine (one lock per access, like one bus
/// cycle of the CPU or one bit-time of the CAN side).
struct SharedNode(SharedChip);

impl SharedNode {
    fn chip(&self) -> std::sync::MutexGuard<'_, buslab_sja1000::Sja1000> {
        self.0.lock().unwrap_or_else(|p| p.into_inner())
    }
}

impl BusNode for SharedNode {
    fn output(&self) -> Level {
        self.chip().output()
    }
    fn sample(&mut self, now: BitTime, bus: Level) {
        BusNode::sample(&mut *self.chip(), now, bus)
    }
    fn poll_event(&mut self) -> Option<Event> {
        self.chip().poll_bus_event()
    }
    fn tec(&self) -> u16 {
        BusNode::tec(&*self.chip())
    }
    fn rec(&self) -> u16 {
        BusNode::rec(&*self.chip())
    }
    fn state(&self) -> ErrorState {
        self.chip().error_state()
    }
    /// Never: the driver may write a transmission request between two steps.
    fn quiet_until(&self) -> Option<BitTime> {
        None
    }
    fn enqueue(&mut self, frame: Frame) -> Result<(), QueueFull> {
        BusNode::enqueue(&mut *self.chip(), frame)
    }
    fn pending(&self) -> usize {
        BusNode::pending(&*self.chip())
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

pub struct Bus {
    /// The chips, for drivers (`bus.driver(i, …)` or a manager).
    pub chips: Vec<SharedChip>,
    /// Bit-times since the start.
    pub time: u64,
    sim: Simulation,
}

impl Bus {
    pub fn new(n: usize) -> Self {
        Self::from_chips((0..n).map(|_| shared_chip()).collect())
    }

    /// A bus over these chips.
    pub fn from_chips(chips: Vec<SharedChip>) -> Self {
        // The bit rate only names seconds in traces; the chips count bit-times.
        let mut sim = Simulation::new(500_000, 1);
        for (i, chip) in chips.iter().enumerate() {
            sim.add_device(format!("chip{i}"), Box::new(SharedNode(chip.clone())));
        }
        Self {
            chips,
            time: 0,
            sim,
        }
    }

    /// One bit-time; `force` may replace the wire level (a disturber).
    pub fn step_with(&mut self, force: impl Fn(u64, Level) -> Level) {
        let time = self.time;
        self.sim.step_disturbed(|level| force(time, level));
        self.time = self.sim.now().get();
    }

    pub fn run(&mut self, bits: u64) {
        self.sim.run_for(BitTime::new(bits));
        self.time = self.sim.now().get();
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
