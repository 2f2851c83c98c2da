//! A fixed-capacity bit string, big enough for any classic CAN frame with its stuff bits.

use core::fmt;

use crate::Level;

/// Up to [`Bits::CAPACITY`] bits stored inline (no heap): the longest classic frame is 128 bits
/// unstuffed and at most 157 stuffed, SOF to end of EOF.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Bits {
    words: [u64; 3],
    len: u16,
}

impl Bits {
    pub const CAPACITY: usize = 192;

    pub const fn new() -> Self {
        Self {
            words: [0; 3],
            len: 0,
        }
    }

    /// Append one bit (`true` = 1 = recessive).
    ///
    /// # Panics
    /// If the buffer already holds [`Bits::CAPACITY`] bits; frames never get there.
    #[inline]
    pub fn push(&mut self, bit: bool) {
        let i = self.len as usize;
        assert!(i < Self::CAPACITY, "Bits capacity exceeded");
        self.words[i / 64] |= (bit as u64) << (i % 64);
        self.len += 1;
    }

    /// Append the `len` (≤ 64) low bits of `value`, most significant first (wire order).
    ///
    /// # Panics
    /// If the bits do not fit.
    #[inline]
    pub fn push_msb_first(&mut self, value: u64, len: u32) {
        let at = self.len as usize;
        assert!(
            len <= 64 && at + len as usize <= Self::CAPACITY,
            "Bits capacity exceeded"
        );
        if len == 0 {
            return;
        }
        // Storage is first-bit-lowest, so reverse the field into that order.
        let bits = value.reverse_bits() >> (64 - len);
        let (word, offset) = (at / 64, at % 64);
        self.words[word] |= bits << offset;
        if offset + len as usize > 64 {
            self.words[word + 1] |= bits >> (64 - offset);
        }
        self.len += len as u16;
    }

    /// From storage words (first bit lowest); bits at `len` and above must be zero so that
    /// equality and hashing see only the bits.
    pub(crate) const fn from_words(words: [u64; 3], len: u16) -> Self {
        debug_assert!(len as usize <= Self::CAPACITY);
        Self { words, len }
    }

    /// Up to 128 bits from bit `at` on, first bit lowest; zeros past the end.
    #[inline]
    pub(crate) const fn window(&self, at: usize) -> u128 {
        let [w0, w1, w2] = self.words;
        let low = w0 as u128 | (w1 as u128) << 64;
        match at {
            0 => low,
            1..=127 => low >> at | (w2 as u128) << (128 - at),
            128..=191 => (w2 >> (at - 128)) as u128,
            _ => 0,
        }
    }

    /// Bit `i`.
    ///
    /// # Panics
    /// If `i >= len()`, like slice indexing.
    #[inline]
    pub fn bit(&self, i: usize) -> bool {
        assert!(i < self.len as usize, "bit index {i} out of range");
        self.words[i / 64] >> (i % 64) & 1 == 1
    }

    /// Bit `i` as a bus level.
    #[inline]
    pub fn level(&self, i: usize) -> Level {
        Level::from_bit(self.bit(i))
    }

    /// Overwrite bit `i`.
    pub fn set(&mut self, i: usize, bit: bool) {
        assert!(i < self.len as usize, "bit index {i} out of range");
        let mask = 1u64 << (i % 64);
        if bit {
            self.words[i / 64] |= mask;
        } else {
            self.words[i / 64] &= !mask;
        }
    }

    pub const fn len(&self) -> usize {
        self.len as usize
    }

    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// How many bits are 1 (recessive).
    pub fn count_ones(&self) -> u32 {
        self.words.iter().map(|w| w.count_ones()).sum()
    }

    /// How many bits at the end are 1 (recessive), e.g. a frame's ACK delimiter and EOF.
    pub fn trailing_ones(&self) -> u32 {
        let mut n = 0;
        for i in (0..self.len()).rev() {
            if !self.bit(i) {
                break;
            }
            n += 1;
        }
        n
    }

    pub fn iter(&self) -> impl ExactSizeIterator<Item = bool> + '_ {
        (0..self.len()).map(|i| self.bit(i))
    }
}

impl FromIterator<bool> for Bits {
    /// # Panics
    /// If the iterator yields more than [`Bits::CAPACITY`] bits.
    fn from_iter<I: IntoIterator<Item = bool>>(iter: I) -> Self {
        let mut bits = Bits::new();
        for bit in iter {
            bits.push(bit);
        }
        bits
    }
}

/// `0`/`1` characters, first bit first.
impl fmt::Display for Bits {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for bit in self.iter() {
            f.write_str(if bit { "1" } else { "0" })?;
        }
        Ok(())
    }
}

impl fmt::Debug for Bits {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Bits({self})")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::string::ToString;

    #[test]
    fn push_get_set_across_words() {
        let mut bits = Bits::new();
        for i in 0..150 {
            bits.push(i % 3 == 0);
        }
        assert_eq!(bits.len(), 150);
        assert!(bits.bit(63) && !bits.bit(64) && !bits.bit(65) && bits.bit(66));
        bits.set(64, true);
        bits.set(63, false);
        assert!(bits.bit(64) && !bits.bit(63));
        assert_eq!(bits.level(64), Level::Recessive);
        let short: Bits = [false, true, true].into_iter().collect();
        assert_eq!(short.to_string(), "011");
        let mut fields = Bits::new();
        fields.push_msb_first(0b101, 3);
        fields.push_msb_first(0, 0);
        fields.push_msb_first(u64::MAX, 64);
        fields.push_msb_first(0x123, 11);
        let text = fields.to_string();
        assert_eq!(&text[..3], "101");
        assert_eq!(&text[3..67], "1".repeat(64));
        assert_eq!(&text[67..], "00100100011");
    }

    #[test]
    #[should_panic(expected = "out of range")]
    fn reading_past_the_end_panics() {
        Bits::new().bit(0);
    }
}
