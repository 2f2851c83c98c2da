//! The core as a board sees it: reset values, reset keeping time, run limits, registers by
//! number.

mod common;

use buslab_ppc403::dcr::number::{EXIER, EXISR};
use buslab_ppc403::interrupts::exisr;
use buslab_ppc403::spr::number::{PIT, PVR, TBLO, TCR};
use buslab_ppc403::{Cycles, Irq, Ppc403, Stop};
use common::*;

#[test]
fn a_new_core_is_at_the_reset_vector_in_supervisor_state() {
    let cpu = Ppc403::new();
    let r = cpu.registers();
    assert_eq!((r.pc, r.msr, r.evpr), (0xFFFF_FFFC, 0, 0));
    assert_eq!((cpu.now(), cpu.instructions()), (Cycles(0), 0));
    assert_eq!(cpu.spr(PVR), Some(0x0020_0011));
    assert_eq!(cpu.spr(TCR), Some(0));
}

#[test]
fn reset_keeps_time_and_the_levels_of_the_lines() {
    let mut b = Board::new(&[li(3, 100), mtspr(PIT, 3), b(0)]);
    b.cpu.set_irq(Irq::External(1), true);
    b.cpu.set_irq(Irq::External(2), true);
    b.cpu.set_irq(Irq::External(2), false);
    assert!(b.cpu.set_dcr(EXIER, u32::MAX));
    b.cpu.registers_mut().evpr = 0x0005_0000;
    assert_eq!(b.run(1000), Stop::Limit);
    let (now, n) = (b.cpu.now(), b.cpu.instructions());
    b.cpu.reset();
    assert_eq!((b.cpu.now(), b.cpu.instructions()), (now, n));
    assert_eq!(b.cpu.pc(), 0xFFFF_FFFC);
    assert_eq!(*b.cpu.registers(), *Ppc403::new().registers());
    assert_eq!(
        b.cpu.dcr(EXISR),
        Some(exisr::E0IS >> 1),
        "INT1 still high, INT2's latch gone"
    );
    assert_eq!(b.cpu.dcr(EXIER), Some(0));
    assert_eq!(b.cpu.spr(PIT), Some(0));
    assert_eq!(b.cpu.spr(TBLO), Some(now.0 as u32), "the time base runs on");
}

#[test]
fn a_run_to_a_past_limit_returns_at_once() {
    let mut b = Board::new(&[b(0)]);
    assert_eq!(b.run(100), Stop::Limit);
    assert_eq!(b.run(50), Stop::Limit);
    assert_eq!(b.cpu.now().0, 100);
}

#[test]
fn a_run_ends_within_one_instruction_of_its_limit() {
    // divw is 33 cycles: a run to 10 ends at 34 (li, divw).
    let mut b = Board::new(&[li(4, 1), x31(3, 3, 4, 491, false), b(0)]);
    assert_eq!(b.run(10), Stop::Limit);
    assert_eq!(b.cpu.now().0, 34);
}

#[test]
fn waiting_at_the_largest_limit_does_not_overflow() {
    let mut b = Board::new(&[lis(3, 4), mtmsr(3)]); // MSR[WE]
    b.cpu.set_spr(TCR, 0x0C80_0000); // WIE, PIE, FIE: every timer asks for a look
    assert_eq!(b.cpu.run(&mut b.mem, Cycles::MAX), Stop::Wait);
    assert_eq!(b.cpu.now(), Cycles::MAX);
    assert_eq!(b.cpu.run(&mut b.mem, Cycles::MAX), Stop::Wait);
}

#[test]
fn running_at_the_end_of_time_saturates() {
    // A wait to the cycle before the last one, then a 33-cycle divide: time stops at the
    // last cycle instead of wrapping.
    let mut board = Board::new(&[lis(3, 4), mtmsr(3)]); // MSR[WE]
    assert_eq!(board.run(u64::MAX - 1), Stop::Wait);
    board
        .mem
        .load_words(0x500, &[x31(3, 3, 4, 491, false), b(0)]);
    board.cpu.registers_mut().msr = 0;
    board.cpu.set_pc(0x500);
    assert_eq!(board.cpu.run(&mut board.mem, Cycles::MAX), Stop::Limit);
    assert_eq!(board.cpu.now(), Cycles::MAX);
    assert_eq!(board.cpu.pc(), 0x504);
}
