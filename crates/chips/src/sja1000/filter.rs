//! The acceptance filter: which received frames reach the RX FIFO.
//!
//! Mask semantics everywhere: a mask bit 1 means "don't care", 0 means the bit must equal the
//! code bit. Bits the datasheet marks unused are not compared (decision in docs/decisions.md).

use buslab_can::{Frame, Id};

/// Which filter layout the code and mask registers use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FilterMode {
    /// BasicCAN: one 8-bit filter on ID bits 10..3 (ACR/AMR).
    Basic,
    /// PeliCAN MOD.AFM = 1: one 32-bit filter.
    Single,
    /// PeliCAN MOD.AFM = 0: two filters, either may match.
    Dual,
}

/// Whether `frame` passes a filter with acceptance code `code` and mask `mask` (ACR0..3,
/// AMR0..3; BasicCAN uses only index 0).
pub fn accepts(mode: FilterMode, code: [u8; 4], mask: [u8; 4], frame: &Frame) -> bool {
    if mask == [0xFF; 4] {
        return true; // no bit compared (the drivers' "accept all")
    }
    let rtr = frame.is_remote() as u8;
    let data = frame.payload();
    let byte = |i: usize| data.get(i).copied();
    // Compares `value` with register `i` on the bits in `care`.
    let eq = |i: usize, value: u8, care: u8| (value ^ code[i]) & !mask[i] & care == 0;
    match (mode, frame.id()) {
        (FilterMode::Basic, id) => eq(0, (sff_bits(id) >> 3) as u8, 0xFF),
        (FilterMode::Single, Id::Standard(id)) => {
            let id = id.as_raw();
            eq(0, (id >> 3) as u8, 0xFF)
                && eq(1, ((id & 7) << 5) as u8 | rtr << 4, 0xF0)
                && byte(0).is_none_or(|d| eq(2, d, 0xFF))
                && byte(1).is_none_or(|d| eq(3, d, 0xFF))
        }
        (FilterMode::Single, Id::Extended(id)) => {
            let id = id.as_raw();
            eq(0, (id >> 21) as u8, 0xFF)
                && eq(1, (id >> 13) as u8, 0xFF)
                && eq(2, (id >> 5) as u8, 0xFF)
                && eq(3, ((id & 0x1F) << 3) as u8 | rtr << 2, 0xFC)
        }
        (FilterMode::Dual, Id::Standard(id)) => {
            let id = id.as_raw();
            let first = eq(0, (id >> 3) as u8, 0xFF)
                && eq(1, ((id & 7) << 5) as u8 | rtr << 4, 0xF0)
                && byte(0).is_none_or(|d| eq(1, d >> 4, 0x0F) && eq(3, d & 0x0F, 0x0F));
            let second =
                eq(2, (id >> 3) as u8, 0xFF) && eq(3, ((id & 7) << 5) as u8 | rtr << 4, 0xF0);
            first || second
        }
        (FilterMode::Dual, Id::Extended(id)) => {
            let id = id.as_raw();
            let first = eq(0, (id >> 21) as u8, 0xFF) && eq(1, (id >> 13) as u8, 0xFF);
            let second = eq(2, (id >> 21) as u8, 0xFF) && eq(3, (id >> 13) as u8, 0xFF);
            first || second
        }
    }
}

/// The 11 ID bits a BasicCAN controller sees (the base ID of an extended frame).
fn sff_bits(id: Id) -> u16 {
    match id {
        Id::Standard(id) => id.as_raw(),
        Id::Extended(id) => id.base(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn f(s: &str) -> Frame {
        s.parse().unwrap()
    }

    const ALL: [u8; 4] = [0xFF; 4];

    #[test]
    fn open_mask_accepts_everything() {
        for mode in [FilterMode::Basic, FilterMode::Single, FilterMode::Dual] {
            for frame in ["000#", "7FF#R", "1FFFFFFF#0102", "123#11"] {
                assert!(accepts(mode, [0x5A; 4], ALL, &f(frame)), "{mode:?} {frame}");
            }
        }
    }

    #[test]
    fn basic_compares_id_bits_10_to_3_only() {
        let code = [0x24, 0, 0, 0]; // 0x120..0x127
        let mask = [0x00, 0xFF, 0xFF, 0xFF];
        assert!(accepts(FilterMode::Basic, code, mask, &f("120#")));
        assert!(accepts(FilterMode::Basic, code, mask, &f("127#R")));
        assert!(!accepts(FilterMode::Basic, code, mask, &f("128#")));
    }

    #[test]
    fn single_sff_exact_id_and_rtr() {
        // Accept exactly 0x123 data frames: ID1 = 0x24, ID2 = 011 0 xxxx.
        let code = [0x24, 0x60, 0, 0];
        let mask = [0x00, 0x0F, 0xFF, 0xFF];
        assert!(accepts(FilterMode::Single, code, mask, &f("123#")));
        assert!(accepts(FilterMode::Single, code, mask, &f("123#DEAD")));
        assert!(!accepts(FilterMode::Single, code, mask, &f("123#R")));
        assert!(!accepts(FilterMode::Single, code, mask, &f("122#")));
        assert!(!accepts(FilterMode::Single, code, mask, &f("00000123#")));
    }

    #[test]
    fn single_sff_data_bytes_are_checked_only_when_present() {
        let code = [0x24, 0x60, 0xAA, 0x55];
        let mask = [0x00, 0x0F, 0x00, 0x00];
        assert!(accepts(FilterMode::Single, code, mask, &f("123#AA55")));
        assert!(!accepts(FilterMode::Single, code, mask, &f("123#AA56")));
        assert!(accepts(FilterMode::Single, code, mask, &f("123#AA")));
        assert!(accepts(FilterMode::Single, code, mask, &f("123#")));
    }

    #[test]
    fn single_eff_exact_id() {
        let id = 0x1ABC_DEF0u32;
        let code = [
            (id >> 21) as u8,
            (id >> 13) as u8,
            (id >> 5) as u8,
            ((id & 0x1F) << 3) as u8,
        ];
        let mask = [0, 0, 0, 0x03];
        assert!(accepts(FilterMode::Single, code, mask, &f("1ABCDEF0#01")));
        assert!(!accepts(FilterMode::Single, code, mask, &f("1ABCDEF1#01")));
        assert!(!accepts(FilterMode::Single, code, mask, &f("1ABCDEF0#R")));
    }

    #[test]
    fn dual_sff_either_filter_matches() {
        // Filter 1: 0x100 with data1 = 0x5x; filter 2: 0x200 any.
        let code = [0x20, 0x05, 0x40, 0x00];
        let mask = [0x00, 0x00, 0x00, 0x1F];
        assert!(accepts(FilterMode::Dual, code, mask, &f("100#5A")));
        assert!(!accepts(FilterMode::Dual, code, mask, &f("100#6A")));
        assert!(accepts(FilterMode::Dual, code, mask, &f("100#")));
        assert!(accepts(FilterMode::Dual, code, mask, &f("200#FF")));
        assert!(!accepts(FilterMode::Dual, code, mask, &f("300#")));
    }

    #[test]
    fn dual_eff_checks_the_top_16_id_bits() {
        let id = 0x1234_5678u32;
        let code = [(id >> 21) as u8, (id >> 13) as u8, 0xFF, 0xFF];
        let mask = [0, 0, 0, 0];
        assert!(accepts(FilterMode::Dual, code, mask, &f("12345678#")));
        assert!(accepts(FilterMode::Dual, code, mask, &f("12345FFF#R")));
        assert!(!accepts(FilterMode::Dual, code, mask, &f("12355678#")));
    }
}
