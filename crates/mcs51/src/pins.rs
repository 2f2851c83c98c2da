//! The four ports: the latches the program writes, the levels the outside drives, and the
//! queue of level changes the board has announced with their times.
//!
//! A pin reads low if either its latch or the outside pulls it low (quasi-bidirectional port).
//! Pins are sampled once per machine cycle, at S5P2 (the 10th of its 12 clocks): a change is
//! seen from the sample at or after it, and a change undone before the next sample is not
//! seen at all.

use alloc::collections::VecDeque;

use crate::Clocks;

/// One of the four 8-bit ports.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Port {
    P0,
    P1,
    P2,
    P3,
}

impl Port {
    /// All four, in order.
    pub const ALL: [Port; 4] = [Port::P0, Port::P1, Port::P2, Port::P3];

    pub(crate) fn index(self) -> usize {
        self as usize
    }

    /// The port's SFR address.
    pub fn sfr(self) -> u8 {
        0x80 + 0x10 * self as u8
    }
}

/// One pin of a port.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Pin {
    port: Port,
    bit: u8,
}

impl Pin {
    /// P3.0: serial input.
    pub const RXD: Pin = Pin::p3(0);
    /// P3.1: serial output.
    pub const TXD: Pin = Pin::p3(1);
    /// P3.2: external interrupt 0.
    pub const INT0: Pin = Pin::p3(2);
    /// P3.3: external interrupt 1.
    pub const INT1: Pin = Pin::p3(3);
    /// P3.4: timer 0's counter input.
    pub const T0: Pin = Pin::p3(4);
    /// P3.5: timer 1's counter input.
    pub const T1: Pin = Pin::p3(5);

    const fn p3(bit: u8) -> Pin {
        Pin {
            port: Port::P3,
            bit,
        }
    }

    /// Pin `bit` (0..=7) of `port`.
    pub const fn new(port: Port, bit: u8) -> Result<Pin, InputError> {
        if bit > 7 {
            Err(InputError::Bit(bit))
        } else {
            Ok(Pin { port, bit })
        }
    }

    /// Its port.
    pub const fn port(self) -> Port {
        self.port
    }

    /// Its bit number.
    pub const fn bit(self) -> u8 {
        self.bit
    }

    /// Its bit as a mask.
    pub const fn mask(self) -> u8 {
        1 << self.bit
    }
}

/// P3 bits with an alternate function inside the chip.
pub(crate) mod p3 {
    pub const RXD: u8 = 0x01;
    pub const INT0: u8 = 0x04;
    pub const INT1: u8 = 0x08;
    pub const T0: u8 = 0x10;
    pub const T1: u8 = 0x20;
}

/// Latches and outside levels.
#[derive(Clone, Debug)]
pub(crate) struct Ports {
    pub latch: [u8; 4],
    /// 1 where the outside leaves the pin alone (or drives it high), 0 where it pulls it low.
    pub outside: [u8; 4],
}

impl Ports {
    pub fn new() -> Ports {
        Ports {
            latch: [0xFF; 4],
            outside: [0xFF; 4],
        }
    }

    /// The levels on `port`'s pins.
    #[inline]
    pub fn pins(&self, port: usize) -> u8 {
        self.latch[port] & self.outside[port]
    }
}

/// A change of outside levels, effective at a sample instant.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Input {
    pub at: Clocks,
    pub port: u8,
    pub mask: u8,
    pub levels: u8,
}

/// The announced changes, in time order.
#[derive(Clone, Debug, Default)]
pub(crate) struct Inputs {
    queue: VecDeque<Input>,
}

/// Changes announced ahead at most (a frame on RxD is up to 11).
pub const MAX_QUEUED_INPUTS: usize = 4096;

/// Where in its machine cycle an input is sampled (state 5, phase 2).
pub(crate) const S5P2: Clocks = Clocks(9);

/// The sample instant (S5P2) at or after `t`.
pub(crate) fn sample_instant(t: Clocks) -> Clocks {
    let cycle = t.cycle_start();
    if t.into_cycle() <= S5P2 {
        cycle + S5P2
    } else {
        cycle + Clocks::CYCLE + S5P2
    }
}

impl Inputs {
    /// Queues a change at `at` (not before `not_before`).
    pub fn push(
        &mut self,
        at: Clocks,
        not_before: Clocks,
        port: Port,
        mask: u8,
        levels: u8,
    ) -> Result<(), InputError> {
        if self.queue.len() >= MAX_QUEUED_INPUTS {
            return Err(InputError::Full {
                queued: self.queue.len(),
            });
        }
        let input = Input {
            at: sample_instant(at.max(not_before)),
            port: port as u8,
            mask,
            levels: levels & mask,
        };
        // After every change at the same instant or before: announced order is kept.
        let pos = self.queue.partition_point(|q| q.at <= input.at);
        self.queue.insert(pos, input);
        Ok(())
    }

    /// When the next change takes effect.
    #[inline]
    pub fn next_at(&self) -> Clocks {
        self.queue.front().map_or(Clocks::NEVER, |i| i.at)
    }

    /// Takes the next change if it is due by `t`.
    pub fn pop_due(&mut self, t: Clocks) -> Option<Input> {
        if self.queue.front()?.at <= t {
            self.queue.pop_front()
        } else {
            None
        }
    }

    pub fn len(&self) -> usize {
        self.queue.len()
    }
}

/// An input the core cannot take.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum InputError {
    #[error("pin bit {0} is out of range 0..=7")]
    Bit(u8),
    #[error("{queued} level changes are already waiting, the most the core keeps ahead")]
    Full { queued: usize },
    #[error("a bit time of {} clocks is out of range 1..=1000000000", .0.0)]
    BitTime(Clocks),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn changes_take_effect_at_the_next_sample() {
        assert_eq!(sample_instant(Clocks(0)), Clocks(9));
        assert_eq!(sample_instant(Clocks(9)), Clocks(9));
        assert_eq!(sample_instant(Clocks(10)), Clocks(21));
        assert_eq!(sample_instant(Clocks(12)), Clocks(21));
        let mut q = Inputs::default();
        q.push(Clocks(30), Clocks::ZERO, Port::P3, 1, 0).unwrap();
        q.push(Clocks(5), Clocks::ZERO, Port::P3, 1, 1).unwrap();
        q.push(Clocks(3), Clocks(40), Port::P1, 0xFF, 0x0F).unwrap();
        assert_eq!(q.next_at(), Clocks(9));
        assert_eq!(q.pop_due(Clocks(8)).map(|i| i.at), None);
        assert_eq!(q.pop_due(Clocks(9)).map(|i| i.levels), Some(1));
        assert_eq!(
            q.pop_due(Clocks(100)).map(|i| (i.at, i.levels)),
            Some((Clocks(33), 0))
        );
        assert_eq!(
            q.pop_due(Clocks(100)).map(|i| (i.at, i.port)),
            Some((Clocks(45), 1))
        );
        assert_eq!(Pin::new(Port::P1, 8), Err(InputError::Bit(8)));
    }
}
