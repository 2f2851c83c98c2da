//! The fields of an instruction word (PowerPC numbers bits from 0 at the most significant end;
//! these helpers hide that).

#[inline(always)]
pub(crate) const fn opcd(w: u32) -> u32 {
    w >> 26
}

/// RT / RS / BO / crfD (with `>> 2`), bits 6..10.
#[inline(always)]
pub(crate) const fn rd(w: u32) -> usize {
    ((w >> 21) & 31) as usize
}

/// RA / BI, bits 11..15.
#[inline(always)]
pub(crate) const fn ra(w: u32) -> usize {
    ((w >> 16) & 31) as usize
}

/// RB / SH / NB, bits 16..20.
#[inline(always)]
pub(crate) const fn rb(w: u32) -> usize {
    ((w >> 11) & 31) as usize
}

/// MB, bits 21..25.
#[inline(always)]
pub(crate) const fn mb(w: u32) -> u32 {
    (w >> 6) & 31
}

/// ME, bits 26..30.
#[inline(always)]
pub(crate) const fn me(w: u32) -> u32 {
    (w >> 1) & 31
}

/// The sign-extended 16-bit immediate (SIMM, D).
#[inline(always)]
pub(crate) const fn simm(w: u32) -> u32 {
    w as u16 as i16 as i32 as u32
}

/// The zero-extended 16-bit immediate (UIMM).
#[inline(always)]
pub(crate) const fn uimm(w: u32) -> u32 {
    w & 0xFFFF
}

/// The record bit (Rc, bit 31): update CR0 (or, for `stwcx.`, part of the opcode).
#[inline(always)]
pub(crate) const fn rc(w: u32) -> bool {
    w & 1 != 0
}

/// The overflow-enable bit (OE, bit 21) of XO-form arithmetic.
#[inline(always)]
pub(crate) const fn oe(w: u32) -> bool {
    w & 0x400 != 0
}

/// The 10-bit extended opcode of X/XL/XFX forms (bits 21..30).
#[inline(always)]
pub(crate) const fn xo(w: u32) -> u32 {
    (w >> 1) & 0x3FF
}

/// The split 10-bit SPR / DCR / TBR number of `mfspr`, `mtspr`, `mfdcr`, `mtdcr`, `mftb`.
#[inline(always)]
pub(crate) const fn split_field(w: u32) -> u32 {
    ((w >> 16) & 31) | (((w >> 11) & 31) << 5)
}

/// The mask of `rlwinm`/`rlwimi`/`rlwnm` from MB to ME (wrapping when MB > ME).
#[inline(always)]
pub(crate) const fn rotate_mask(mb: u32, me: u32) -> u32 {
    let from = u32::MAX >> mb;
    let to = u32::MAX << (31 - me);
    if mb <= me { from & to } else { from | to }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotate_masks() {
        assert_eq!(rotate_mask(0, 31), u32::MAX);
        assert_eq!(rotate_mask(24, 31), 0xFF);
        assert_eq!(rotate_mask(0, 7), 0xFF00_0000);
        assert_eq!(rotate_mask(31, 0), 0x8000_0001);
        assert_eq!(rotate_mask(5, 5), 0x0400_0000);
    }

    #[test]
    fn split_spr_numbers() {
        // mfspr r3, LR (8): 7C6802A6
        assert_eq!(split_field(0x7C68_02A6), 8);
        // mtspr TBLO (0x3DD) ,r3: 7C7DF3A6
        assert_eq!(split_field(0x7C7D_F3A6), 0x3DD);
    }
}
