//! candump timestamps of a simulated bus's bit-times, for a trace that prints one per line.

use buslab_can::BitTime;

use crate::text;

/// Formats bit-times of a bus at a bit rate as candump log timestamps, `(0000000001.250000)`:
/// the second and microsecond [`BitTime::secs_and_micros_at`] gives. Lines come in time
/// order, mostly many to a second: the second's digits are kept while the times stay in it,
/// and the microseconds are taken by a multiply instead of a 64-bit division.
#[derive(Clone, Debug)]
pub struct BitTimeStamps {
    /// The bit rate, at least 1 (as `secs_and_micros_at` takes 0).
    bitrate: u64,
    /// ⌈2⁸⁴ / bitrate⌉: see [`Self::micros_into_second`].
    reciprocal: u128,
    /// The second the last timestamp fell in: its digits, and the bit-times it spans.
    digits: [u8; 10],
    start: BitTime,
    end: BitTime,
}

/// The largest second with ten digits.
const TEN_DIGITS: u64 = 9_999_999_999;

impl BitTimeStamps {
    pub fn new(bitrate: u32) -> Self {
        let bitrate = u64::from(bitrate.max(1));
        Self {
            bitrate,
            reciprocal: (1u128 << 84).div_ceil(u128::from(bitrate)),
            digits: [b'0'; 10],
            // No second yet: the first time looks its second up.
            start: BitTime::ZERO,
            end: BitTime::ZERO,
        }
    }

    /// Appends the timestamp of `t` to `out`.
    pub fn push(&mut self, out: &mut Vec<u8>, t: BitTime) {
        if !((self.start..self.end).contains(&t) || self.enter_second(t)) {
            // Past 317 years: more than ten digits of seconds.
            let (s, us) = t.secs_and_micros_at(self.bitrate as u32);
            out.push(b'(');
            text::push_u64_zeros(out, s, 10);
            out.push(b'.');
            text::push_u64_zeros(out, u64::from(us), 6);
            out.push(b')');
            return;
        }
        let us = self.micros_into_second((t - self.start).get());
        let mut field = *b"(0000000000.000000)";
        field[1..11].copy_from_slice(&self.digits);
        field[12..18].copy_from_slice(&text::decimal_fixed::<6>(us));
        out.extend_from_slice(&field);
    }

    /// Makes the second `t` falls in the current one, if it has ten digits (else false).
    fn enter_second(&mut self, t: BitTime) -> bool {
        let s = t.get() / self.bitrate;
        if s > TEN_DIGITS {
            return false;
        }
        // s·b ≤ t; the second's end may lie past the last bit-time there is.
        let start = s * self.bitrate;
        self.digits = text::decimal_fixed::<10>(s);
        self.start = BitTime::new(start);
        self.end = BitTime::new(start.saturating_add(self.bitrate));
        true
    }

    /// ⌊n·10⁶ / b⌋ for `n` bit-times into a second (n < b), without a division: with
    /// m = ⌈2⁸⁴/b⌉ = 2⁸⁴/b + e (0 ≤ e < 1), n·10⁶·m / 2⁸⁴ exceeds n·10⁶/b by less than
    /// b·10⁶ / 2⁸⁴ < 2⁻³², while n·10⁶/b is at least 1/b ≥ 2⁻³² below the next whole
    /// number: the floor is the same. The product stays below 10⁶·2⁸⁴ + b·10⁶ < 2¹⁰⁵.
    fn micros_into_second(&self, n: u64) -> u64 {
        let scaled = u128::from(n * 1_000_000);
        ((scaled * self.reciprocal) >> 84) as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The timestamp as `secs_and_micros_at` has it, formatted the plain way.
    fn reference(t: BitTime, bitrate: u32) -> String {
        let (s, us) = t.secs_and_micros_at(bitrate);
        format!("({s:010}.{us:06})")
    }

    fn stamps(bitrate: u32, times: &[u64]) -> Vec<String> {
        let mut stamps = BitTimeStamps::new(bitrate);
        times
            .iter()
            .map(|&t| {
                let mut out = Vec::new();
                stamps.push(&mut out, BitTime::new(t));
                String::from_utf8(out).unwrap()
            })
            .collect()
    }

    #[test]
    fn seconds_micros_and_their_edges() {
        let times = [0, 1, 999_999, 1_000_000, 1_000_001, 2_500_000, 1_999_999, 0];
        let got = stamps(1_000_000, &times);
        assert_eq!(
            got,
            [
                "(0000000000.000000)",
                "(0000000000.000001)",
                "(0000000000.999999)",
                "(0000000001.000000)",
                "(0000000001.000001)",
                "(0000000002.500000)",
                "(0000000001.999999)",
                "(0000000000.000000)",
            ]
        );
        // 125 kbit/s: a bit-time is 8 µs.
        assert_eq!(stamps(125_000, &[125_001]), ["(0000000001.000008)"]);
        // A zero bit rate counts as 1 bit/s, as in `secs_and_micros_at`.
        assert_eq!(stamps(0, &[7]), ["(0000000007.000000)"]);
    }

    #[test]
    fn seconds_past_ten_digits_widen_the_field() {
        let t = 10_000_000_000 * 1_000_000 + 5;
        assert_eq!(stamps(1_000_000, &[t]), ["(10000000000.000005)"]);
        assert_eq!(
            stamps(1, &[u64::MAX])[0],
            reference(BitTime::new(u64::MAX), 1)
        );
        // And back into ten digits.
        assert_eq!(
            stamps(1_000_000, &[t, 3])[1],
            "(0000000000.000003)".to_string()
        );
    }

    proptest! {
        /// Times in order (small steps, some jumps) and anywhere at all, at any bit rate:
        /// the same text as the plain formatting of `secs_and_micros_at`.
        #[test]
        fn same_as_secs_and_micros_at(
            bitrate in prop_oneof![
                Just(1u32), Just(10_000), Just(125_000), Just(500_000), Just(1_000_000),
                Just(8_000_000), Just(u32::MAX), Just(u32::MAX - 1), 1u32..,
            ],
            start in prop_oneof![0u64..1 << 40, any::<u64>()],
            steps in proptest::collection::vec(
                prop_oneof![0u64..200, 0u64..20_000_000, any::<u64>()], 1..60),
        ) {
            let mut t = start;
            let mut times = vec![t];
            for step in steps {
                t = t.wrapping_add(step);
                times.push(t);
            }
            let got = stamps(bitrate, &times);
            for (&t, got) in times.iter().zip(&got) {
                prop_assert_eq!(got, &reference(BitTime::new(t), bitrate), "t = {}", t);
            }
        }
    }
}
