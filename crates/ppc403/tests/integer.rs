//! The integer instructions: results, XER[SO, OV, CA], CR0 and the other CR fields.

mod common;

use common::*;

const SO: u32 = 0x8000_0000;
const OV: u32 = 0x4000_0000;
const CA: u32 = 0x2000_0000;
const LT: u32 = 8;
const GT: u32 = 4;
const EQ: u32 = 2;
const CR_SO: u32 = 1;

fn cr0(b: &Board) -> u32 {
    b.cpu.registers().cr >> 28
}
fn xer(b: &Board) -> u32 {
    b.cpu.registers().xer
}
/// An XO-form instruction `xo` (OE adds 512) rD, rA, rB.
fn xo(rt: u32, ra: u32, rb: u32, xo: u32, oe: bool, rc: bool) -> u32 {
    x31(rt, ra, rb, xo + if oe { 512 } else { 0 }, rc)
}

#[test]
fn addo_dot_sets_ov_so_and_cr0_from_the_signed_result() {
    let b = exec(&[(3, 0x7FFF_FFFF), (4, 1)], &[xo(5, 3, 4, 266, true, true)]);
    assert_eq!(b.r(5), 0x8000_0000);
    assert_eq!(xer(&b), SO | OV);
    assert_eq!(cr0(&b), LT | CR_SO);
}

#[test]
fn so_is_sticky_while_ov_follows_each_oe_instruction() {
    let b = exec(
        &[(3, 0x7FFF_FFFF), (4, 1)],
        &[
            xo(5, 3, 4, 266, true, false), // overflows
            xo(6, 4, 4, 266, true, true),  // 1 + 1: no overflow
            xo(7, 4, 4, 266, false, true), // no OE: XER untouched
        ],
    );
    assert_eq!(b.r(6), 2);
    assert_eq!(xer(&b), SO, "OV cleared by the second addo, SO stays");
    assert_eq!(cr0(&b), GT | CR_SO, "CR0 copies SO");
}

#[test]
fn add_without_oe_never_touches_xer() {
    let b = exec(
        &[(3, 0x7FFF_FFFF), (4, 1)],
        &[xo(5, 3, 4, 266, false, false)],
    );
    assert_eq!((b.r(5), xer(&b)), (0x8000_0000, 0));
}

#[test]
fn addc_adde_carry_a_64_bit_sum() {
    // (r3:r4) + (r5:r6) = 0x00000001_FFFFFFFF + 0x00000002_00000001
    let b = exec(
        &[(3, 1), (4, 0xFFFF_FFFF), (5, 2), (6, 1)],
        &[
            xo(8, 4, 6, 10, false, false),
            xo(7, 3, 5, 138, false, false),
        ],
    );
    assert_eq!((b.r(7), b.r(8)), (4, 0));
    assert_eq!(xer(&b) & CA, 0, "adde of 1 + 2 + 1 carries nothing out");
}

#[test]
fn addc_sets_ca_on_unsigned_carry_only() {
    let b = exec(&[(3, 0xFFFF_FFFF), (4, 1)], &[xo(5, 3, 4, 10, true, true)]);
    assert_eq!(b.r(5), 0);
    assert_eq!(xer(&b), CA, "carry without signed overflow (-1 + 1)");
    assert_eq!(cr0(&b), EQ);
}

#[test]
fn subfc_ca_is_not_borrow() {
    let b = exec(
        &[(3, 3), (4, 5)],
        &[xo(5, 3, 4, 8, false, false)], // 5 - 3
    );
    assert_eq!((b.r(5), xer(&b) & CA), (2, CA));
    let b = exec(&[(3, 5), (4, 3)], &[xo(5, 3, 4, 8, false, false)]);
    assert_eq!((b.r(5), xer(&b) & CA), (0xFFFF_FFFE, 0));
    let b = exec(&[(3, 5), (4, 5)], &[xo(5, 3, 4, 8, false, false)]);
    assert_eq!((b.r(5), xer(&b) & CA), (0, CA), "equal operands: no borrow");
}

#[test]
fn subfo_overflows_from_min_minus_one() {
    let b = exec(&[(3, 1), (4, 0x8000_0000)], &[xo(5, 3, 4, 40, true, true)]);
    assert_eq!(b.r(5), 0x7FFF_FFFF);
    assert_eq!(xer(&b), SO | OV);
    assert_eq!(cr0(&b), GT | CR_SO);
}

#[test]
fn subfe_addme_addze_subfme_subfze_use_ca() {
    // CA = 1 from addic r0,r0(-1)... use addic r9, r10, -1 with r10 = 1 → 0, CA=1.
    let set_ca = d_form(12, 9, 10, -1);
    let b = exec(
        &[(10, 1), (3, 10), (4, 20)],
        &[
            set_ca,
            xo(5, 3, 4, 136, false, false), // subfe: 20 + !10 + 1 = 10, CA=1
            xo(6, 3, 0, 234, false, false), // addme: 10 + -1 + CA(1) = 10, CA=1
            xo(7, 3, 0, 202, false, false), // addze: 10 + 0 + 1 = 11, CA=0
            xo(8, 3, 0, 232, false, false), // subfme: !10 + -1 + 0 = -12, CA=1
            xo(11, 3, 0, 200, false, false), // subfze: !10 + 0 + 1 = -10, CA=0
        ],
    );
    assert_eq!(b.r(5), 10);
    assert_eq!(b.r(6), 10);
    assert_eq!(b.r(7), 11);
    assert_eq!(b.r(8), (-12i32) as u32);
    assert_eq!(b.r(11), (-10i32) as u32);
    assert_eq!(xer(&b) & CA, 0);
}

#[test]
fn addme_overflow_and_carry_at_the_edges() {
    // addmeo of 0x80000000 with CA = 0: 0x80000000 - 1 overflows, carries out (adds 0xFFFFFFFF).
    let b = exec(&[(3, 0x8000_0000)], &[xo(5, 3, 0, 234, true, false)]);
    assert_eq!(b.r(5), 0x7FFF_FFFF);
    assert_eq!(xer(&b), SO | OV | CA);
}

#[test]
fn nego_of_min_overflows_and_neg_keeps_ca() {
    let b = exec(&[(3, 0x8000_0000)], &[xo(5, 3, 0, 104, true, true)]);
    assert_eq!(b.r(5), 0x8000_0000);
    assert_eq!(xer(&b), SO | OV);
    assert_eq!(cr0(&b), LT | CR_SO);
    let b = exec(&[(3, 7)], &[xo(5, 3, 0, 104, false, false)]);
    assert_eq!((b.r(5), xer(&b)), ((-7i32) as u32, 0));
}

#[test]
fn addic_sets_ca_and_addic_dot_cr0() {
    let b = exec(&[(3, 0xFFFF_FFFF)], &[d_form(13, 4, 3, 1)]);
    assert_eq!((b.r(4), xer(&b), cr0(&b)), (0, CA, EQ));
    let b = exec(&[(3, 5)], &[d_form(12, 4, 3, -6)]);
    assert_eq!((b.r(4), xer(&b)), (0xFFFF_FFFF, 0));
}

#[test]
fn subfic_and_addi_addis_with_ra_zero() {
    let b = exec(
        &[(0, 100), (3, 5)],
        &[
            d_form(8, 4, 3, 3),
            addi(5, 0, -2),
            addis(6, 0, 0x1234),
            addi(7, 3, 1),
        ],
    );
    assert_eq!(b.r(4), (-2i32) as u32);
    assert_eq!(xer(&b) & CA, 0, "3 - 5 borrows");
    assert_eq!(b.r(5), (-2i32) as u32, "addi with rA = 0 is li");
    assert_eq!(b.r(6), 0x1234_0000);
    assert_eq!(b.r(7), 6);
}

#[test]
fn multiplies() {
    let b = exec(
        &[(3, 0x1_0000), (4, 0x1_0000), (5, (-3i32) as u32), (6, 7)],
        &[
            xo(7, 3, 4, 235, true, false),  // mullwo: 2^32 overflows
            xo(8, 3, 4, 75, false, false),  // mulhw: 1
            xo(9, 5, 6, 75, false, false),  // mulhw -21 >> 32: -1
            xo(10, 5, 6, 11, false, false), // mulhwu (2^32-3)*7 >> 32 = 6
            d_form(7, 11, 5, -5),           // mulli: 15
            xo(12, 5, 6, 235, false, true), // mullw. -21
        ],
    );
    assert_eq!(b.r(7), 0);
    assert_eq!(b.r(8), 1);
    assert_eq!(b.r(9), 0xFFFF_FFFF);
    assert_eq!(b.r(10), 6);
    assert_eq!(b.r(11), 15);
    assert_eq!(b.r(12), (-21i32) as u32);
    assert_eq!(xer(&b), SO | OV, "mullwo set OV; mullw. (no OE) leaves it");
    assert_eq!(cr0(&b), LT | CR_SO);
}

#[test]
fn divides_and_their_undefined_cases() {
    let b = exec(
        &[
            (3, (-7i32) as u32),
            (4, 2),
            (5, 0),
            (6, 0x8000_0000),
            (7, u32::MAX),
        ],
        &[
            xo(8, 3, 4, 491, false, false),  // divw -7/2 = -3 (toward zero)
            xo(9, 3, 4, 459, false, false),  // divwu 0xFFFFFFF9 / 2
            xo(10, 4, 5, 491, true, false),  // divwo by 0
            xo(11, 6, 7, 491, false, false), // divw MIN / -1 without OE
        ],
    );
    assert_eq!(b.r(8), (-3i32) as u32);
    assert_eq!(b.r(9), 0x7FFF_FFFC);
    assert_eq!(b.r(10), 2, "decided: the dividend");
    assert_eq!(b.r(11), 0x8000_0000, "decided: the dividend");
    assert_eq!(xer(&b), SO | OV);
    let b = exec(&[(3, 9), (4, 0)], &[xo(5, 3, 4, 459, true, true)]);
    assert_eq!((b.r(5), xer(&b)), (9, SO | OV));
}

#[test]
fn logical_and_immediate_forms() {
    let b = exec(
        &[(3, 0xF0F0_1234), (4, 0x0FF0_FF00)],
        &[
            x31(3, 5, 4, 28, false),   // and
            x31(3, 6, 4, 60, false),   // andc
            x31(3, 7, 4, 444, false),  // or
            x31(3, 8, 4, 412, false),  // orc
            x31(3, 9, 4, 316, false),  // xor
            x31(3, 10, 4, 476, false), // nand
            x31(3, 11, 4, 124, false), // nor
            x31(3, 12, 4, 284, false), // eqv
            d_form(28, 3, 13, 0x00FF), // andi.
        ],
    );
    let (s, r) = (0xF0F0_1234u32, 0x0FF0_FF00u32);
    assert_eq!(b.r(5), s & r);
    assert_eq!(b.r(6), s & !r);
    assert_eq!(b.r(7), s | r);
    assert_eq!(b.r(8), s | !r);
    assert_eq!(b.r(9), s ^ r);
    assert_eq!(b.r(10), !(s & r));
    assert_eq!(b.r(11), !(s | r));
    assert_eq!(b.r(12), !(s ^ r));
    assert_eq!(b.r(13), 0x34);
    assert_eq!(cr0(&b), GT);
    let b = exec(&[(3, 0x8000_0000)], &[d_form(29, 3, 4, 0x8000)]); // andis.
    assert_eq!((b.r(4), cr0(&b)), (0x8000_0000, LT));
    let b = exec(&[(3, 0x0000_00FF)], &[d_form(28, 3, 4, 0xFF00)]); // andi. → 0
    assert_eq!((b.r(4), cr0(&b)), (0, EQ));
    let b = exec(
        &[(3, 0x1234_5678)],
        &[
            ori(4, 3, 0xF),
            d_form(25, 3, 5, 0xF),
            d_form(26, 3, 6, 0xFF),
            d_form(27, 3, 7, 0xFF),
        ],
    );
    assert_eq!(b.r(4), 0x1234_567F);
    assert_eq!(b.r(5), 0x123F_5678);
    assert_eq!(b.r(6), 0x1234_5687);
    assert_eq!(b.r(7), 0x12CB_5678);
}

#[test]
fn sign_extension_and_count_leading_zeros() {
    let b = exec(
        &[(3, 0x1234_5680), (4, 0)],
        &[
            x31(3, 5, 0, 954, true),  // extsb.
            x31(3, 6, 0, 922, false), // extsh
            x31(3, 7, 0, 26, false),  // cntlzw
            x31(4, 8, 0, 26, true),   // cntlzw. of 0 = 32
        ],
    );
    assert_eq!(b.r(5), 0xFFFF_FF80);
    assert_eq!(b.r(6), 0x0000_5680);
    assert_eq!(b.r(7), 3);
    assert_eq!(b.r(8), 32);
    assert_eq!(cr0(&b), GT);
}

#[test]
fn shifts_take_six_bits_of_rb() {
    let b = exec(
        &[(3, 0x8000_0011), (4, 4), (5, 32), (6, 63), (7, 31)],
        &[
            x31(3, 8, 4, 24, false),   // slw 4
            x31(3, 9, 5, 24, false),   // slw 32 → 0
            x31(3, 10, 4, 536, false), // srw 4
            x31(3, 11, 6, 536, false), // srw 63 → 0
            x31(3, 12, 7, 24, false),  // slw 31
        ],
    );
    assert_eq!(b.r(8), 0x0000_0110);
    assert_eq!(b.r(9), 0);
    assert_eq!(b.r(10), 0x0800_0001);
    assert_eq!(b.r(11), 0);
    assert_eq!(b.r(12), 0x8000_0000);
}

#[test]
fn algebraic_shifts_set_ca_when_a_negative_value_loses_ones() {
    let srawi = |ra, rs, sh| x31(rs, ra, sh, 824, false);
    let sraw = |ra, rs, rb| x31(rs, ra, rb, 792, false);
    let b = exec(&[(3, (-5i32) as u32)], &[srawi(4, 3, 1)]);
    assert_eq!((b.r(4), xer(&b)), ((-3i32) as u32, CA));
    let b = exec(&[(3, (-4i32) as u32)], &[srawi(4, 3, 2)]);
    assert_eq!((b.r(4), xer(&b)), ((-1i32) as u32, 0), "no 1 bits lost");
    let b = exec(&[(3, 5)], &[srawi(4, 3, 1)]);
    assert_eq!((b.r(4), xer(&b)), (2, 0), "positive: never CA");
    let b = exec(&[(3, (-5i32) as u32), (5, 40)], &[sraw(4, 3, 5)]);
    assert_eq!((b.r(4), xer(&b)), (u32::MAX, CA), "32..63: all sign");
    let b = exec(&[(3, 0x4000_0000), (5, 40)], &[sraw(4, 3, 5)]);
    assert_eq!((b.r(4), xer(&b)), (0, 0));
    let b = exec(&[(3, (-5i32) as u32), (5, 0)], &[sraw(4, 3, 5)]);
    assert_eq!((b.r(4), xer(&b)), ((-5i32) as u32, 0), "shift 0: no CA");
}

#[test]
fn rotates() {
    let rlwimi = (20 << 26) | (3 << 21) | (5 << 16) | (8 << 11) | (16 << 6) | (23 << 1);
    let rlwnm = (23 << 26) | (3 << 21) | (6 << 16) | (4 << 11) | (31 << 1) | 1; // MB 0, ME 31
    let b = exec(
        &[(3, 0x1234_5678), (4, 36), (5, 0xAAAA_AAAA)],
        &[
            rlwinm(7, 3, 8, 24, 31), // extract the top byte: 0x12
            rlwinm(8, 3, 0, 31, 0),  // wrapping mask 0x80000001
            rlwimi,                  // insert (rot 8) bits 16..23 into r5
            rlwnm,                   // rotate by 36 & 31 = 4, record
        ],
    );
    assert_eq!(b.r(7), 0x12);
    assert_eq!(b.r(8), 0x1234_5678 & 0x8000_0001);
    assert_eq!(b.r(5), 0xAAAA_78AA, "0x34567812's bits 16..23 into r5");
    assert_eq!(b.r(6), 0x2345_6781);
    assert_eq!(cr0(&b), GT);
}

#[test]
fn compares_go_to_any_field_and_copy_so() {
    let cmpw = |crf: u32, ra, rb| x31(crf << 2, ra, rb, 0, false);
    let cmplw = |crf: u32, ra, rb| x31(crf << 2, ra, rb, 32, false);
    let b = exec(
        &[(3, (-1i32) as u32), (4, 1), (9, 0x7FFF_FFFF), (10, 1)],
        &[
            xo(11, 9, 10, 266, true, false), // set SO
            cmpw(3, 3, 4),                   // -1 < 1
            cmplw(4, 3, 4),                  // 0xFFFFFFFF > 1
            cmpwi(7, 4, 1),                  // equal
            cmplwi(1, 4, 2),                 // less
        ],
    );
    let cr = b.cpu.registers().cr;
    assert_eq!((cr >> 16) & 0xF, LT | CR_SO, "cr3");
    assert_eq!((cr >> 12) & 0xF, GT | CR_SO, "cr4");
    assert_eq!(cr & 0xF, EQ | CR_SO, "cr7");
    assert_eq!((cr >> 24) & 0xF, LT | CR_SO, "cr1");
    assert_eq!(cr >> 28, 0, "cr0 untouched");
}

#[test]
fn cr_logical_mcrf_mcrxr_mtcrf_mfcr() {
    let xl = |bt: u32, ba: u32, bb: u32, xo: u32| {
        (19 << 26) | (bt << 21) | (ba << 16) | (bb << 11) | (xo << 1)
    };
    let b = exec(
        &[(3, 0x8421_0000), (9, 0x7FFF_FFFF), (10, 1)],
        &[
            x31(3, 0, 0, 144, false) | (0xFF << 12), // mtcrf 0xFF, r3
            xl(31, 0, 5, 193),                       // crxor 31 = 0 ^ 5 → 1^1 = 0
            xl(30, 0, 1, 449),                       // cror 30 = 1 | 0 = 1
            xl(29, 0, 10, 257),                      // crand 29 = 1 & bit 10 (cr2 = 2) = 1
            xl(28, 1, 1, 33),                        // crnor 28 = !(0|0) = 1
            xl(6 << 2, 0 << 2, 0, 0),                // mcrf cr6, cr0
            xo(11, 9, 10, 266, true, false),         // OV, SO; addo: no CA
            x31(5 << 2, 0, 0, 512, false),           // mcrxr cr5
            x31(12, 0, 0, 19, false),                // mfcr r12
        ],
    );
    let cr = b.r(12);
    assert_eq!(cr & 0xF, 0b1110, "cr7: crnor 1, crand 1, cror 1, crxor 0");
    assert_eq!((cr >> 4) & 0xF, 0x8, "cr6 = cr0");
    assert_eq!((cr >> 8) & 0xF, 0b1100, "cr5 = XER SO OV CA 0");
    assert_eq!(xer(&b) & (SO | OV | CA), 0, "mcrxr clears them");
    let b = exec(
        &[(3, 0xFFFF_FFFF)],
        &[x31(3, 0, 0, 144, false) | (0x41 << 12)],
    );
    assert_eq!(b.cpu.registers().cr, 0x0F00_000F, "mtcrf only cr1 and cr7");
}

#[test]
fn lr_ctr_xer_move_through_mtspr_mfspr() {
    let b = exec(
        &[(3, 0x1111), (4, 0x2222), (5, 0xE000_0000)],
        &[
            mtspr(8, 3),
            mtspr(9, 4),
            mtspr(1, 5),
            mfspr(6, 8),
            mfspr(7, 9),
            mfspr(8, 1),
        ],
    );
    assert_eq!((b.r(6), b.r(7), b.r(8)), (0x1111, 0x2222, 0xE000_0000));
    let r = b.cpu.registers();
    assert_eq!((r.lr, r.ctr, r.xer), (0x1111, 0x2222, 0xE000_0000));
}
