//! Where a signal's bits are in a payload, in DBC's two numberings, resolved once so that
//! decoding is a load and two shifts.
//!
//! Intel (`@1`, little-endian): the start bit is the signal's least significant bit, bit `k`
//! being bit `k % 8` of byte `k / 8`; the signal grows towards higher bits and bytes.
//! Motorola (`@0`, big-endian): the start bit is the signal's most significant bit in the same
//! per-byte numbering, and the signal runs towards lower bits, then on into the *next* byte's
//! bit 7 (the "sawtooth"). Counting bits from the first byte's MSB (`7 - k % 8 + 8 * (k / 8)`)
//! turns a Motorola signal into one straight run of big-endian bits.

/// The bytes a signal covers and how to shift them into place.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Layout {
    first: usize,
    /// Bytes covered, 1..=9 (a 64-bit signal not on a byte boundary spans nine).
    len: usize,
    shift: u32,
    /// The shift of the signal in the 64-bit word of the 8 bytes from `first` (signals of up
    /// to 8 bytes, all but a 64-bit one off a byte boundary).
    word_shift: u32,
    mask: u64,
    big_endian: bool,
}

impl Layout {
    /// The layout of a signal of `size` bits (1..=64) starting at `start_bit`.
    pub(crate) fn new(start_bit: u32, size: u32, big_endian: bool) -> Self {
        debug_assert!((1..=64).contains(&size));
        let mask = if size == 64 {
            u64::MAX
        } else {
            (1u64 << size) - 1
        };
        if big_endian {
            let msb = 8 * (start_bit / 8) + 7 - start_bit % 8;
            let end = msb + size;
            let first = msb / 8;
            let last = (end - 1) / 8;
            let len = last - first + 1;
            let shift = 8 * (last + 1) - end;
            Self {
                first: first as usize,
                len: len as usize,
                shift,
                // The bytes are the word's top `len`.
                word_shift: (64 - 8 * len.min(8)) + shift,
                mask,
                big_endian,
            }
        } else {
            Self {
                first: (start_bit / 8) as usize,
                len: (start_bit % 8 + size).div_ceil(8) as usize,
                shift: start_bit % 8,
                word_shift: start_bit % 8,
                mask,
                big_endian,
            }
        }
    }

    /// The payload length the signal needs: one past its last byte.
    pub(crate) fn end(&self) -> usize {
        self.first + self.len
    }

    /// The signal's raw bits, right-aligned; `None` when the payload is too short for it.
    #[inline]
    pub(crate) fn extract(&self, payload: &[u8]) -> Option<u64> {
        let end = self.end();
        if end > payload.len() {
            return None;
        }
        if self.len > 8 {
            let window = self.load(&payload[self.first..end]);
            return Some((window >> self.shift) as u64 & self.mask);
        }
        // One 8-byte load: from the payload when 8 bytes are there, else zero-padded.
        let word: [u8; 8] = match payload.get(self.first..self.first + 8) {
            Some(bytes) => bytes.try_into().expect("8 bytes"),
            None => {
                let mut word = [0; 8];
                word[..self.len].copy_from_slice(&payload[self.first..end]);
                word
            }
        };
        let word = if self.big_endian {
            u64::from_be_bytes(word)
        } else {
            u64::from_le_bytes(word)
        };
        Some((word >> self.word_shift) & self.mask)
    }

    /// Writes `raw`'s low bits into the payload, keeping every other bit. The payload must hold
    /// [`Layout::end`] bytes.
    pub(crate) fn insert(&self, payload: &mut [u8], raw: u64) {
        let bytes = &mut payload[self.first..self.first + self.len];
        let mask = u128::from(self.mask) << self.shift;
        let window = (self.load(bytes) & !mask) | (u128::from(raw & self.mask) << self.shift);
        for (i, byte) in bytes.iter_mut().enumerate() {
            let at = if self.big_endian {
                8 * (self.len - 1 - i)
            } else {
                8 * i
            };
            *byte = (window >> at) as u8;
        }
    }

    #[inline]
    fn load(&self, bytes: &[u8]) -> u128 {
        if self.big_endian {
            bytes.iter().fold(0u128, |w, &b| (w << 8) | u128::from(b))
        } else {
            bytes
                .iter()
                .rev()
                .fold(0u128, |w, &b| (w << 8) | u128::from(b))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intel_signals_grow_towards_higher_bytes() {
        // 12 bits from bit 4: the high nibble of byte 0, all of byte 1.
        let l = Layout::new(4, 12, false);
        assert_eq!(l.extract(&[0xA0, 0xCB]), Some(0xCBA));
        assert_eq!(l.end(), 2);
    }

    #[test]
    fn motorola_signals_run_on_into_the_next_byte() {
        // Start bit 7 (MSB of byte 0), 16 bits: bytes 0 and 1 as a big-endian number.
        let l = Layout::new(7, 16, true);
        assert_eq!(l.extract(&[0x12, 0x34]), Some(0x1234));
        // Start bit 3, 8 bits: low nibble of byte 0, then the high nibble of byte 1.
        let l = Layout::new(3, 8, true);
        assert_eq!(l.extract(&[0x0A, 0xB0]), Some(0xAB));
        assert_eq!(l.end(), 2);
    }

    #[test]
    fn sixty_four_bits_off_a_byte_boundary_span_nine_bytes() {
        let l = Layout::new(4, 64, false);
        let mut payload = [0u8; 9];
        l.insert(&mut payload, u64::MAX);
        assert_eq!(
            payload,
            [0xF0, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x0F]
        );
        assert_eq!(l.extract(&payload), Some(u64::MAX));
    }

    #[test]
    fn a_payload_too_short_gives_nothing() {
        assert_eq!(Layout::new(8, 8, false).extract(&[0xFF]), None);
    }

    #[test]
    fn insert_keeps_the_other_bits() {
        let l = Layout::new(3, 8, true);
        let mut payload = [0xF5, 0x0F];
        l.insert(&mut payload, 0xAB);
        assert_eq!(payload, [0xFA, 0xBF]);
    }
}
