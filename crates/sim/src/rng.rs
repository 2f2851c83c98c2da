//! A tiny seeded PRNG (SplitMix64) for noise: deterministic across platforms and releases,
//! which a crate's generator does not promise.

#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// `true` with the probability encoded by `threshold` (see [`threshold`]).
    pub fn hit(&mut self, threshold: u64) -> bool {
        threshold != 0 && self.next_u64() < threshold
    }
}

/// A probability 0.0..=1.0 as a `u64` threshold for [`SplitMix64::hit`].
pub fn threshold(probability: f64) -> u64 {
    if probability <= 0.0 {
        0
    } else if probability >= 1.0 {
        u64::MAX
    } else {
        (probability * u64::MAX as f64) as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_stream_and_rate_is_close() {
        let mut a = SplitMix64::new(7);
        let mut b = SplitMix64::new(7);
        assert_eq!(a.next_u64(), b.next_u64());
        let t = threshold(0.1);
        let hits = (0..100_000).filter(|_| a.hit(t)).count();
        assert!((9_000..11_000).contains(&hits), "{hits}");
        assert!(!a.hit(threshold(0.0)));
    }
}
