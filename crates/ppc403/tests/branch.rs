//! Branches: relative and absolute, links, every BO (CTR decrement, condition, both, always),
//! bclr/bcctr, and their cycles.

mod common;

use buslab_ppc403::Stop;
use common::*;

#[test]
fn b_and_bl_relative_with_link() {
    // 0: bl +12 ; 4: li r3,1 ; 8: sc ; 12: li r4,2 ; 16: blr
    let mut b = Board::new(&[bl(12), li(3, 1), SC, li(4, 2), blr()]);
    assert_eq!(b.run_to_sc(), Stop::SystemCall { at: ORG + 8 });
    assert_eq!((b.r(3), b.r(4)), (1, 2));
    assert_eq!(b.cpu.registers().lr, ORG + 4);
}

#[test]
fn backward_branch_and_absolute_forms() {
    // ba 0x2000 from ORG; at 0x2000: bla 0x2010 ; at 0x2010: sc
    let mut board = Board::new(&[b(0) | 2 | 0x2000]);
    board.mem.load_words(0x2000, &[b(0) | 3 | 0x2010]);
    board.mem.load_words(0x2010, &[SC]);
    assert_eq!(board.run_to_sc(), Stop::SystemCall { at: 0x2010 });
    assert_eq!(board.cpu.registers().lr, 0x2004);
    // li; b +8 → addi; cmpwi; bne -12 (back to addi) until r3 = 3; sc
    let mut board = Board::new(&[
        li(3, 0),
        b(8),
        SC,
        addi(3, 3, 1),
        cmpwi(0, 3, 3),
        bc(4, 2, -8),
        SC,
    ]);
    assert_eq!(board.run_to_sc(), Stop::SystemCall { at: ORG + 24 });
    assert_eq!(board.r(3), 3);
}

#[test]
fn bdnz_counts_ctr_down_to_zero() {
    let mut b = Board::new(&[
        li(3, 10),
        mtspr(9, 3),
        li(4, 0),
        addi(4, 4, 2),
        bdnz(-4),
        SC,
    ]);
    assert_eq!(b.run_to_sc(), Stop::SystemCall { at: ORG + 20 });
    assert_eq!(b.r(4), 20);
    assert_eq!(b.cpu.registers().ctr, 0);
}

#[test]
fn every_bo_decides_as_book_i_says() {
    // BO bits: 16 ignore cond, 8 cond value, 4 no CTR decrement, 2 branch when CTR = 0.
    // CR bit 2 (cr0 EQ) is set; CTR starts at 2 (→ 1 after a decrement, not zero) or 1
    // (→ 0).
    for bo in 0..32u32 {
        for ctr in [1u32, 2] {
            for eq in [false, true] {
                let mut b = Board::new(&[bc(bo, 2, 8), SC, SC]);
                b.cpu.registers_mut().ctr = ctr;
                b.cpu.registers_mut().cr = if eq { 0x2000_0000 } else { 0 };
                let decrements = bo & 4 == 0;
                let ctr_after = if decrements { ctr - 1 } else { ctr };
                let ctr_ok = !decrements || ((ctr_after != 0) != (bo & 2 != 0));
                let cond_ok = bo & 16 != 0 || eq == (bo & 8 != 0);
                let taken = ctr_ok && cond_ok;
                let at = if taken { ORG + 8 } else { ORG + 4 };
                assert_eq!(
                    b.run_to_sc(),
                    Stop::SystemCall { at },
                    "BO {bo} ctr {ctr} eq {eq}"
                );
                assert_eq!(b.cpu.registers().ctr, ctr_after, "BO {bo}");
            }
        }
    }
}

#[test]
fn bclr_and_bcctr_with_link() {
    // bcctrl to 0x3000 (saves LR = ORG+4), 0x3000: bclr back (always).
    let mut b = Board::new(&[bcctr(20, 0, true), li(5, 7), SC]);
    b.mem.load_words(0x3000, &[li(6, 9), blr()]);
    b.cpu.registers_mut().ctr = 0x3000;
    assert_eq!(b.run_to_sc(), Stop::SystemCall { at: ORG + 8 });
    assert_eq!((b.r(5), b.r(6)), (7, 9));
    // bclrl: branches to the old LR, LR = the next instruction.
    let mut b = Board::new(&[bclr(20, 0, true)]);
    b.mem.load_words(0x4000, &[SC]);
    b.cpu.registers_mut().lr = 0x4000;
    assert_eq!(b.run_to_sc(), Stop::SystemCall { at: 0x4000 });
    assert_eq!(b.cpu.registers().lr, ORG + 4);
}

#[test]
fn bcctr_decrementing_ctr_is_an_invalid_form() {
    let word = bcctr(16, 0, false);
    let mut b = Board::new(&[word]);
    assert_eq!(
        b.run(10),
        Stop::Exception {
            kind: buslab_ppc403::Exception::Illegal { word },
            at: ORG
        }
    );
}

#[test]
fn a_bc_with_link_links_even_when_not_taken() {
    let mut b = Board::new(&[bc(12, 2, 8) | 1, SC, SC]); // beql, EQ clear
    assert_eq!(b.run_to_sc(), Stop::SystemCall { at: ORG + 4 });
    assert_eq!(b.cpu.registers().lr, ORG + 4);
}

#[test]
fn taken_branches_cost_one_cycle_more() {
    // li (1) ; mtctr (1) ; loop: bdnz (2 taken, 1 not) × 3
    let mut b = Board::new(&[li(3, 3), mtspr(9, 3), bdnz(0), SC]);
    assert_eq!(b.run_to_sc(), Stop::SystemCall { at: ORG + 12 });
    assert_eq!(b.cpu.now().0, 1 + 1 + 2 + 2 + 1 + 1, "the sc is one cycle");
    assert_eq!(b.cpu.instructions(), 6, "li, mtctr, 3 × bdnz, sc");
}
