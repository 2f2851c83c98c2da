//! CRC-15/CAN, computed bit-serially as the protocol defines it.

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

    /// Feed the bytes MSB first (handy for the byte-wise cross-check).
    pub fn push_bytes(&mut self, bytes: &[u8]) {
        for byte in bytes {
            for n in (0..8).rev() {
                self.push(byte >> n & 1 == 1);
            }
        }
    }

    /// The 15-bit register; transmitted MSB (bit 14) first.
    pub const fn value(self) -> u16 {
        self.0
    }
}

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
