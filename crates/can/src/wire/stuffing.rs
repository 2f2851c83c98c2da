//! Word operations shared by the table-driven encoder and the whole-frame decoder: bit strings
//! held in a `u128`, first wire bit lowest.

/// The `len` (≤ 128) low bits set.
#[inline]
pub(crate) const fn low_mask(len: u32) -> u128 {
    if len >= 128 {
        u128::MAX
    } else {
        (1 << len) - 1
    }
}

/// The first index `k` (4 ≤ k < `len`) where bits `k-4..=k` of `seg` are equal: where a run
/// of 5 ends and a stuff bit must follow. The run cannot reach back before bit 0, so a caller
/// that continues a run puts its earlier bits (at most 4) or the stuff bit that started it at
/// the bottom of `seg`.
///
/// One pass over the word instead of one step per bit: bit `j` of `same` says bit `j` equals
/// bit `j-1`; four of those in a row make a run of 5.
#[inline]
pub(crate) const fn first_run_end(seg: u128, len: u32) -> Option<u32> {
    let same = !(seg ^ seg << 1) & low_mask(len) & !1;
    let runs = same & same << 1 & same << 2 & same << 3;
    if runs == 0 {
        None
    } else {
        Some(runs.trailing_zeros())
    }
}

/// The `len` (1..=32) bits of `seg` from bit `start` on, read as a number whose most
/// significant bit came first on the wire.
#[inline]
pub(crate) const fn msb_first(seg: u128, start: u32, len: u32) -> u32 {
    let bits = (seg >> start) as u32 & ((1u64 << len) - 1) as u32;
    bits.reverse_bits() >> (32 - len)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_of_five_are_found_where_they_end() {
        assert_eq!(first_run_end(0, 4), None, "4 zeros are no run of 5");
        assert_eq!(first_run_end(0, 5), Some(4));
        assert_eq!(first_run_end(0b11_1110, 6), Some(5));
        assert_eq!(first_run_end(0b1011_0111_1011, 12), None);
        // Bits past `len` do not count.
        assert_eq!(first_run_end(0b1111_1010, 7), None);
        assert_eq!(first_run_end(0b1111_1010, 8), Some(7));
        assert_eq!(first_run_end(u128::MAX, 128), Some(4));
        assert_eq!(first_run_end(u128::MAX / 3, 128), None, "alternating");
        assert_eq!(msb_first(0b0011, 0, 4), 0b1100);
        assert_eq!(msb_first(0b1 << 100, 100, 1), 1);
    }
}
