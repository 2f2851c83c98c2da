//! CRC-15/CAN: bit-serially as the protocol defines it, or a byte at a time from a 256-entry
//! table built at compile time (same result).

/// The generator polynomial x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1 (x^15 implicit).
pub const CRC15_POLY: u16 = 0x4599;

/// A running CRC-15 over de-stuffed bits (SOF up to the end of the data field).
///
/// Init 0, no reflection, no final XOR. Because the register starts at 0, leading 0 bits (such
/// as the dominant SOF) do not change the result.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Crc15(u16);

impl Crc15 {
    pub const fn new() -> Self {
        Self(0)
    }

    /// Feed one bit (`true` = 1 = recessive).
    #[inline]
    pub fn push(&mut self, bit: bool) {
        // Branch-free: the bits are data, a branch on them would be mispredicted half the time.
        let feedback = (self.0 >> 14 ^ bit as u16) & 1;
        self.0 = (self.0 << 1 & 0x7FFF) ^ (CRC15_POLY & feedback.wrapping_neg());
    }

    /// Feed the `len` (≤ 32) low bits of `value`, most significant first.
    pub fn push_bits(&mut self, value: u32, len: u32) {
        for n in (0..len).rev() {
            self.push(value >> n & 1 == 1);
        }
    }

    /// Feed 8 bits at once (table-driven; same result as 8 × [`Crc15::push`]).
    #[inline]
    pub fn push_byte(&mut self, byte: u8) {
        // The register left-aligned in 16 bits, so the byte-wise step is the usual one.
        let reg = self.0 << 1;
        let reg = (reg << 8) ^ BYTE_TABLE[((reg >> 8) as u8 ^ byte) as usize];
        self.0 = reg >> 1;
    }

    /// Feed the bytes MSB first (handy for the byte-wise cross-check).
    pub fn push_bytes(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            self.push_byte(byte);
        }
    }

    /// A register holding `value` (15 bits), e.g. a CRC computed another way.
    pub(crate) const fn from_value(value: u16) -> Self {
        Self(value & 0x7FFF)
    }

    /// The 15-bit register; transmitted MSB (bit 14) first.
    pub const fn value(self) -> u16 {
        self.0
    }
}

/// The CRC-15 of the `len` low bits of `value`, most significant first, two bytes at a time.
/// Bits of `value` above `len` must be zero: they act as leading 0 bits, which do not change
/// the result, so the bits need not be aligned to bytes or byte pairs.
#[inline]
pub(crate) fn crc15_of(value: u128, len: u32) -> u16 {
    let pairs = (len.min(128) as usize).div_ceil(16);
    // The register, left-aligned in 16 bits, is replaced whole by each pair: XORed with the
    // pair, its high byte goes through two bytes' worth of steps and its low byte through one,
    // two lookups that do not wait for each other (the CRC is linear).
    // Pairs read from memory rather than shifted out (a variable shift of a u128 is several
    // instructions).
    let bytes = value.to_le_bytes();
    let mut reg = 0u16;
    for pair in (0..pairs).rev() {
        let x = reg ^ u16::from_le_bytes([bytes[2 * pair], bytes[2 * pair + 1]]);
        reg = PAIR_HIGH_TABLE[(x >> 8) as usize] ^ BYTE_TABLE[(x & 0xFF) as usize];
    }
    reg >> 1
}

/// For the high byte of a pair: the byte step's table entry followed by a step over a zero
/// byte (`T[h] << 8 ^ T[T[h] >> 8]`).
const PAIR_HIGH_TABLE: [u16; 256] = {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let once = BYTE_TABLE[i];
        table[i] = once << 8 ^ BYTE_TABLE[(once >> 8) as usize];
        i += 1;
    }
    table
};

/// CRC of each byte value for the left-aligned register (polynomial << 1).
const BYTE_TABLE: [u16; 256] = {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut reg = (i as u16) << 8;
        let mut k = 0;
        while k < 8 {
            reg = if reg & 0x8000 != 0 {
                (reg << 1) ^ (CRC15_POLY << 1)
            } else {
                reg << 1
            };
            k += 1;
        }
        table[i] = reg;
        i += 1;
    }
    table
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn catalog_check_value() {
        let mut crc = Crc15::new();
        crc.push_bytes(b"123456789");
        assert_eq!(crc.value(), 0x059E);
    }

    #[test]
    fn byte_step_equals_eight_bit_steps() {
        for start in [0u16, 1, 0x4000, 0x7FFF, 0x1234, 0x59E] {
            for byte in 0..=255u8 {
                let (mut a, mut b) = (Crc15(start), Crc15(start));
                a.push_byte(byte);
                b.push_bits(byte as u32, 8);
                assert_eq!(a, b, "start {start:#x} byte {byte:#x}");
            }
        }
    }

    #[test]
    fn whole_value_crc_equals_bit_serial() {
        let value: u128 = 0x0123_4567_89AB_CDEF_FEDC_BA98_7654_3210;
        for len in [0u32, 1, 7, 8, 19, 39, 83, 103, 127, 128] {
            let masked = if len == 128 {
                value
            } else {
                value & ((1 << len) - 1)
            };
            let mut serial = Crc15::new();
            for n in (0..len).rev() {
                serial.push(masked >> n & 1 == 1);
            }
            assert_eq!(crc15_of(masked, len), serial.value(), "len {len}");
        }
    }

    #[test]
    fn leading_zero_bits_do_not_change_the_result() {
        // SFF 0x123, DLC 2, 11 22: the covered bits left-padded to bytes (facts §1.4).
        let mut crc = Crc15::new();
        crc.push_bytes(&[0x00, 0x91, 0x82, 0x11, 0x22]);
        assert_eq!(crc.value(), 0x04B7);
        let mut unpadded = Crc15::new();
        unpadded.push_bytes(&[0x91, 0x82, 0x11, 0x22]);
        assert_eq!(unpadded.value(), 0x04B7);
    }
}
