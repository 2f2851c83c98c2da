//! What a program's SJA1000 reads from the wire: the bus, or noise when the program gave it a
//! bit timing that is not the bus's (the seed's 50 kbit/s values on the lab's 125 kbit/s
//! bus). A chip that samples a frame at the wrong instants reads bits that have nothing to do
//! with it, errs and sends error frames, as the host's nodes do (`buslab_canbus`'s node, with
//! the same 1 % tolerance); an idle bus reads recessive at any rate. The firmware always
//! programs the bus's timing, so this applies while a program owns the chip.

use buslab_can::{BitTime, Level};
use buslab_sja1000::Sja1000;

use crate::clocks::CRYSTAL_HZ;

/// The bit rate a chip may be off the bus's and still follow it (per mille).
pub const TOLERANCE_PERMILLE: u64 = 10;
/// Recessive bits in a row after which the bus is idle (end of frame and intermission).
pub const IDLE_BITS: u64 = 11;

/// The chip's view of the wire.
#[derive(Clone, Debug)]
pub struct Sampling {
    /// BTR0/BTR1 the mismatch was worked out for.
    checked: Option<(u8, u8)>,
    mismatch: Option<u32>,
    recessive_run: u64,
    last: Option<BitTime>,
    rng: u64,
}

impl Default for Sampling {
    fn default() -> Self {
        Self {
            checked: None,
            mismatch: None,
            recessive_run: IDLE_BITS,
            last: None,
            rng: 0x9E37_79B9_7F4A_7C15,
        }
    }
}

impl Sampling {
    /// The chip's bit rate when it is not the bus's (`bus_bitrate`), from its BTR registers.
    pub fn mismatch(&mut self, chip: &Sja1000, bus_bitrate: u32) -> Option<u32> {
        let timing = chip.bit_timing();
        let registers = timing.registers();
        if self.checked != Some(registers) {
            self.checked = Some(registers);
            let rate = timing.bitrate(CRYSTAL_HZ / 2);
            let diff = u64::from(rate.abs_diff(bus_bitrate));
            self.mismatch =
                (diff * 1000 > u64::from(bus_bitrate) * TOLERANCE_PERMILLE).then_some(rate);
        }
        self.mismatch
    }

    /// Whether the timing last looked at was not the bus's (the node must then see every bit).
    pub fn mistimed(&self) -> bool {
        self.mismatch.is_some()
    }

    /// The level `chip` reads at bit-time `now` when the bus is at `bus`.
    pub fn level(&mut self, chip: &Sja1000, bus_bitrate: u32, now: BitTime, bus: Level) -> Level {
        // Bit-times the engine skipped were recessive.
        let skipped = self
            .last
            .map_or(0, |last| now.get().saturating_sub(last.get() + 1));
        self.last = Some(now);
        let idle = self.recessive_run.saturating_add(skipped) >= IDLE_BITS;
        self.recessive_run = match bus {
            Level::Recessive => (self.recessive_run + skipped + 1).min(IDLE_BITS),
            Level::Dominant => 0,
        };
        if chip.in_reset_mode()
            || self.mismatch(chip, bus_bitrate).is_none()
            || (idle && bus == Level::Recessive)
        {
            return bus;
        }
        self.rng ^= self.rng << 13;
        self.rng ^= self.rng >> 7;
        self.rng ^= self.rng << 17;
        Level::from_bit(self.rng & 1 == 1)
    }
}
