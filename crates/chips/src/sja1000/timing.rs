//! SJA1000 bit timing: BTR0/BTR1 ↔ segments ↔ bit rate, and choosing registers for a bit rate
//! the way Linux's `can_calc_bittiming()` does.
//!
//! The SJA1000 counts time quanta in units of two oscillator periods, so the CAN clock is
//! half the crystal: a 16 MHz crystal gives the usual 8 MHz.

use core::fmt;

/// Register limits of the SJA1000 (as in Linux `sja1000_bittiming_const`).
const BRP: (u32, u32) = (1, 64);
const TSEG1: (u32, u32) = (1, 16);
const TSEG2: (u32, u32) = (1, 8);
const SJW_MAX: u32 = 4;
/// Worst bit-rate error accepted by [`BitTiming::for_bitrate`], in per mille (Linux: 5 %).
const MAX_ERROR_PERMILLE: u64 = 50;

/// The segments of one bit, in time quanta (each field is the real length, not register − 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BitTiming {
    /// Baud-rate prescaler, 1..=64: one quantum = `brp` CAN clock periods.
    pub brp: u32,
    /// Propagation + phase segment 1, 1..=16 quanta.
    pub tseg1: u32,
    /// Phase segment 2, 1..=8 quanta.
    pub tseg2: u32,
    /// Synchronisation jump width, 1..=4 quanta.
    pub sjw: u32,
    /// Sample three times per bit (BTR1.SAM).
    pub triple_sample: bool,
}

/// A bit timing that cannot be expressed in SJA1000 registers or reached from a clock.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TimingError {
    #[error("{field} = {value} is out of range {min}..={max}")]
    OutOfRange {
        field: &'static str,
        value: u32,
        min: u32,
        max: u32,
    },
    #[error("bit rate {bitrate} bit/s cannot be reached from a {clock} Hz CAN clock within 5 %")]
    Unreachable { bitrate: u32, clock: u32 },
    #[error("sample point {permille} ‰ is out of range 500..=950")]
    SamplePoint { permille: u32 },
    #[error(
        "bit rate {bitrate} bit/s from a {clock} Hz CAN clock cannot sample as early as \
         {permille} ‰ (phase segment 2 is at most 8 quanta, phase segment 1 at least 1): \
         ask for a later sample point"
    )]
    SamplePointUnreachable {
        bitrate: u32,
        clock: u32,
        permille: u32,
    },
}

impl BitTiming {
    /// Checks every field against the register limits.
    pub fn new(
        brp: u32,
        tseg1: u32,
        tseg2: u32,
        sjw: u32,
        triple_sample: bool,
    ) -> Result<Self, TimingError> {
        check("brp", brp, BRP)?;
        check("tseg1", tseg1, TSEG1)?;
        check("tseg2", tseg2, TSEG2)?;
        check("sjw", sjw, (1, SJW_MAX))?;
        Ok(Self {
            brp,
            tseg1,
            tseg2,
            sjw,
            triple_sample,
        })
    }

    /// Decodes BTR0/BTR1; every register value maps to a valid timing.
    pub const fn from_registers(btr0: u8, btr1: u8) -> Self {
        Self {
            brp: (btr0 & 0x3F) as u32 + 1,
            sjw: (btr0 >> 6) as u32 + 1,
            tseg1: (btr1 & 0x0F) as u32 + 1,
            tseg2: ((btr1 >> 4) & 0x07) as u32 + 1,
            triple_sample: btr1 & 0x80 != 0,
        }
    }

    /// BTR0 and BTR1.
    pub const fn registers(&self) -> (u8, u8) {
        let btr0 = (((self.sjw - 1) & 3) << 6 | ((self.brp - 1) & 0x3F)) as u8;
        let btr1 = ((self.triple_sample as u32) << 7
            | ((self.tseg2 - 1) & 7) << 4
            | ((self.tseg1 - 1) & 0xF)) as u8;
        (btr0, btr1)
    }

    /// Quanta per bit: sync segment + tseg1 + tseg2.
    pub const fn quanta_per_bit(&self) -> u32 {
        1 + self.tseg1 + self.tseg2
    }

    /// The bit rate in bit/s, rounded down, for a given CAN clock (crystal / 2).
    pub const fn bitrate(&self, can_clock_hz: u32) -> u32 {
        can_clock_hz / (self.brp * self.quanta_per_bit())
    }

    /// Sample point in per mille of the bit.
    pub const fn sample_point_permille(&self) -> u32 {
        1000 * (1 + self.tseg1) / self.quanta_per_bit()
    }

    /// Registers for `bitrate` from `can_clock_hz`, with Linux's algorithm: the CiA sample
    /// point (87.5 % up to 500 kbit/s, 80 % up to 800 kbit/s, 75 % above) unless one is given,
    /// never above it, smallest bit-rate error first, then smallest sample-point error, ties to
    /// the smaller prescaler.
    pub fn for_bitrate(
        can_clock_hz: u32,
        bitrate: u32,
        sample_point_permille: Option<u32>,
    ) -> Result<Self, TimingError> {
        let unreachable = TimingError::Unreachable {
            bitrate,
            clock: can_clock_hz,
        };
        if bitrate == 0 {
            return Err(unreachable);
        }
        let sp_ref = match sample_point_permille {
            Some(sp) if !(500..=950).contains(&sp) => {
                return Err(TimingError::SamplePoint { permille: sp });
            }
            Some(sp) => sp,
            None if bitrate > 800_000 => 750,
            None if bitrate > 500_000 => 800,
            None => 875,
        };
        let clock = can_clock_hz as u64;
        let rate = bitrate as u64;
        let mut best: Option<(u64, u32, Self)> = None; // (rate error, sp error, timing)
        let mut no_split = false;
        let t_max = 2 * (TSEG1.1 + TSEG2.1) + 1;
        let t_min = 2 * (TSEG1.0 + TSEG2.0);
        for t in (t_min..=t_max).rev() {
            let tsegall = 1 + t as u64 / 2;
            let brp = clock / (tsegall * rate) + (t as u64 % 2);
            if brp < BRP.0 as u64 || brp > BRP.1 as u64 {
                continue;
            }
            let real = clock / (brp * tsegall);
            let rate_err = rate.abs_diff(real);
            if let Some((best_rate_err, _, _)) = best
                && rate_err > best_rate_err
            {
                continue;
            }
            // No split of this length samples at or before the reference (phase segment 2
            // is at most 8 quanta, so a long bit cannot sample early; phase segment 1 at
            // least 1, so a short one cannot either): Linux skips it too.
            let Some((tseg1, tseg2, sp_err)) = split(t / 2, sp_ref) else {
                no_split |= rate_err * 1000 / rate <= MAX_ERROR_PERMILLE;
                continue;
            };
            if let Some((best_rate_err, best_sp_err, _)) = best
                && rate_err == best_rate_err
                && sp_err >= best_sp_err
            {
                continue;
            }
            let timing = Self {
                brp: brp as u32,
                tseg1,
                tseg2,
                sjw: 1.max((tseg1 - tseg1 / 2).min(tseg2 / 2)),
                triple_sample: false,
            };
            best = Some((rate_err, sp_err, timing));
            if rate_err == 0 && sp_err == 0 {
                break;
            }
        }
        match best {
            Some((rate_err, _, timing)) if rate_err * 1000 / rate <= MAX_ERROR_PERMILLE => {
                Ok(timing)
            }
            _ if no_split => Err(TimingError::SamplePointUnreachable {
                bitrate,
                clock: can_clock_hz,
                permille: sp_ref,
            }),
            _ => Err(unreachable),
        }
    }
}

/// Splits `tseg` (= tseg1 + tseg2) so the sample point is as close to `sp_ref` as possible
/// without exceeding it. Returns (tseg1, tseg2, sample-point error in ‰), or `None` when every
/// split within the register limits samples after `sp_ref`.
fn split(tseg: u32, sp_ref: u32) -> Option<(u32, u32, u32)> {
    let mut best: Option<(u32, u32, u32)> = None;
    for i in 0..=1 {
        let mut tseg2 = (tseg + 1 - sp_ref * (tseg + 1) / 1000)
            .saturating_sub(i)
            .clamp(TSEG2.0, TSEG2.1);
        let mut tseg1 = tseg.saturating_sub(tseg2);
        if tseg1 > TSEG1.1 {
            tseg1 = TSEG1.1;
            tseg2 = tseg - tseg1;
        }
        let sp = 1000 * (tseg + 1 - tseg2) / (tseg + 1);
        // Linux does not check tseg1's minimum here: a 3-quantum bit sampled below 2/3 gets
        // tseg1 = 0, which kernels before 6.3 wrote to BTR1 as 16 and later ones refuse
        // (SJW above phase segment 1). Such a split is left out, so a valid timing of
        // another length is chosen where Linux fails.
        if tseg1 >= TSEG1.0 && sp <= sp_ref && best.is_none_or(|(_, _, err)| sp_ref - sp < err) {
            best = Some((tseg1, tseg2, sp_ref - sp));
        }
    }
    best
}

fn check(field: &'static str, value: u32, (min, max): (u32, u32)) -> Result<(), TimingError> {
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(TimingError::OutOfRange {
            field,
            value,
            min,
            max,
        })
    }
}

impl fmt::Display for BitTiming {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (btr0, btr1) = self.registers();
        write!(
            f,
            "BTR0=0x{btr0:02X} BTR1=0x{btr1:02X} (brp {}, tseg1 {}, tseg2 {}, sjw {}, {} quanta, sample point {:.1} %)",
            self.brp,
            self.tseg1,
            self.tseg2,
            self.sjw,
            self.quanta_per_bit(),
            self.sample_point_permille() as f64 / 10.0
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The worked examples of the facts sheet (Linux column).
    #[test]
    fn linux_algorithm_reproduces_the_worked_examples() {
        let cases = [
            (8_000_000, 1_000_000, 0x00, 0x14),
            (8_000_000, 800_000, 0x00, 0x16),
            (8_000_000, 500_000, 0x00, 0x1C),
            (8_000_000, 250_000, 0x01, 0x1C),
            (8_000_000, 125_000, 0x03, 0x1C),
            (8_000_000, 100_000, 0x04, 0x1C),
            (24_000_000, 1_000_000, 0x01, 0x27),
        ];
        for (clock, bitrate, btr0, btr1) in cases {
            let t = BitTiming::for_bitrate(clock, bitrate, None).unwrap();
            assert_eq!(
                t.registers(),
                (btr0, btr1),
                "{bitrate} bit/s from {clock} Hz: {t}"
            );
            assert_eq!(t.bitrate(clock), bitrate);
        }
    }

    /// Found by the `config_file` fuzz target: 210 kbit/s sampled at 57.5 % from an 8 MHz
    /// clock chose a bit whose phase segments were 0 quanta (no split of its length samples
    /// that early), and turning it into registers overflowed.
    #[test]
    fn every_timing_chosen_fits_the_registers_and_samples_no_later_than_asked() {
        let t = BitTiming::for_bitrate(8_000_000, 210_000, Some(575)).unwrap();
        assert_eq!(
            BitTiming::from_registers(t.registers().0, t.registers().1),
            t
        );
        assert!(t.sample_point_permille() <= 575, "{t}");
        for clock in [8_000_000, 7_372_800, 12_000_000] {
            for bitrate in (10_000..=1_000_000).step_by(10_000) {
                for sp in [None, Some(500), Some(575), Some(700), Some(875), Some(950)] {
                    let Ok(t) = BitTiming::for_bitrate(clock, bitrate, sp) else {
                        continue;
                    };
                    let checked = BitTiming::new(t.brp, t.tseg1, t.tseg2, t.sjw, false);
                    assert_eq!(checked, Ok(t), "{bitrate} bit/s, {sp:?} ‰ from {clock} Hz");
                    if let Some(sp) = sp {
                        assert!(t.sample_point_permille() <= sp, "{t} for {sp} ‰");
                    }
                }
            }
        }
        // Only 17 quanta reach 470 kbit/s within 5 %, and 17 cannot sample at 50 %: the
        // error says which of the two to change.
        assert_eq!(
            BitTiming::for_bitrate(8_000_000, 470_000, Some(500)),
            Err(TimingError::SamplePointUnreachable {
                bitrate: 470_000,
                clock: 8_000_000,
                permille: 500
            })
        );
        assert!(BitTiming::for_bitrate(8_000_000, 470_000, Some(529)).is_ok());
        assert_eq!(
            BitTiming::for_bitrate(8_000_000, 950_000, Some(500)),
            Err(TimingError::Unreachable {
                bitrate: 950_000,
                clock: 8_000_000
            })
        );
    }

    #[test]
    fn registers_round_trip_and_decode_the_seed_value() {
        // The seed's 50 kbit/s value with a 16 MHz crystal (8 MHz CAN clock).
        let t = BitTiming::from_registers(0x07, 0x4D);
        assert_eq!((t.brp, t.tseg1, t.tseg2, t.sjw), (8, 14, 5, 1));
        assert_eq!(t.bitrate(8_000_000), 50_000);
        assert_eq!(t.sample_point_permille(), 750);
        for btr0 in 0..=255u8 {
            for btr1 in [0x00, 0x14, 0x1C, 0x2F, 0x4D, 0x7F, 0xFF] {
                assert_eq!(
                    BitTiming::from_registers(btr0, btr1).registers(),
                    (btr0, btr1)
                );
            }
        }
    }

    #[test]
    fn impossible_requests_say_why() {
        assert_eq!(
            BitTiming::new(65, 13, 2, 1, false).unwrap_err().to_string(),
            "brp = 65 is out of range 1..=64"
        );
        assert!(BitTiming::new(1, 0, 2, 1, false).is_err());
        assert!(matches!(
            BitTiming::for_bitrate(8_000_000, 3_000_000, None),
            Err(TimingError::Unreachable { .. })
        ));
        assert!(BitTiming::for_bitrate(8_000_000, 0, None).is_err());
        assert!(BitTiming::for_bitrate(8_000_000, 100, None).is_err());
        assert!(matches!(
            BitTiming::for_bitrate(8_000_000, 500_000, Some(990)),
            Err(TimingError::SamplePoint { permille: 990 })
        ));
    }
}
