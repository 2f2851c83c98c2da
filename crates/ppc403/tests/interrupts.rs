//! The interrupt controller: EXISR latches the lines, EXIER and MSR[EE] (MSR[CE] for the
//! critical pin) decide, interrupts are taken at instruction boundaries; MSR[WE] waits.

mod common;

use buslab_ppc403::dcr::number::{EXIER, EXISR};
use buslab_ppc403::exceptions::msr;
use buslab_ppc403::interrupts::exisr;
use buslab_ppc403::{Exception, Irq, Stop};
use common::*;

/// A board spinning at ORG (`b .`) with `msr` and EXIER set.
fn spinning(msr_value: u32, exier: u32) -> Board {
    let mut b = Board::new(&[b(0)]);
    b.cpu.registers_mut().msr = msr_value;
    assert!(b.cpu.set_dcr(EXIER, exier));
    b
}

#[test]
fn an_external_interrupt_needs_its_enable_bit_and_ee() {
    let e0 = exisr::E0IS;
    // Neither: EE clear.
    let mut b = spinning(0, e0);
    b.cpu.set_irq(Irq::External(0), true);
    assert_eq!(b.run(100), Stop::Limit);
    assert_eq!(b.cpu.dcr(EXISR), Some(e0), "latched all the same");
    // EE but not enabled in EXIER.
    let mut b = spinning(msr::EE, exisr::E0IS >> 1);
    b.cpu.set_irq(Irq::External(0), true);
    assert_eq!(b.run(100), Stop::Limit);
    // Both.
    let mut b = spinning(msr::EE | msr::ME, e0);
    assert_eq!(b.run(10), Stop::Limit);
    b.cpu.set_irq(Irq::External(0), true);
    assert_eq!(
        b.run(100),
        Stop::Exception {
            kind: Exception::External,
            at: ORG
        }
    );
    let r = *b.cpu.registers();
    assert_eq!(
        (r.pc, r.srr0, r.srr1, r.msr),
        (0x500, ORG, msr::EE | msr::ME, msr::ME)
    );
    assert_eq!(
        b.cpu.now().0,
        10,
        "taken at the boundary where the run began"
    );
}

#[test]
fn ee_set_by_wrteei_lets_a_pending_interrupt_in_after_that_instruction() {
    let mut b = Board::new(&[li(3, 1), wrteei(true), li(4, 2), SC]);
    assert!(b.cpu.set_dcr(EXIER, exisr::SRIS));
    b.cpu.set_irq(Irq::SerialReceive, true);
    assert_eq!(
        b.run(100),
        Stop::Exception {
            kind: Exception::External,
            at: ORG + 8
        }
    );
    assert_eq!((b.r(3), b.r(4)), (1, 0));
}

#[test]
fn lines_are_level_sensitive_and_exisr_is_write_one_to_clear() {
    let mut b = Board::new(&[
        load_const(3, exisr::E0IS | exisr::STIS)[0],
        load_const(3, exisr::E0IS | exisr::STIS)[1],
        mtdcr(EXISR, 3),
        mfdcr(4, EXISR),
        SC,
    ]);
    b.cpu.set_irq(Irq::External(0), true); // still high
    b.cpu.set_irq(Irq::SerialTransmit, true);
    b.cpu.set_irq(Irq::SerialTransmit, false); // a pulse: latched
    b.cpu.set_irq(Irq::External(4), true);
    assert_eq!(b.run_to_sc(), Stop::SystemCall { at: ORG + 16 });
    assert_eq!(
        b.r(4),
        exisr::E0IS | (exisr::E0IS >> 4),
        "E0 set again (still high), ST cleared, E4 untouched"
    );
}

#[test]
fn the_critical_pin_needs_ce_not_ee_and_saves_in_srr2_srr3() {
    let mut b = spinning(msr::EE, exisr::CIS);
    b.cpu.set_irq(Irq::Critical, true);
    assert_eq!(b.run(50), Stop::Limit, "CE clear");
    b.cpu.registers_mut().msr = msr::CE | msr::EE | msr::ME | msr::DE;
    assert_eq!(
        b.run(100),
        Stop::Exception {
            kind: Exception::Critical,
            at: ORG
        }
    );
    let r = *b.cpu.registers();
    assert_eq!(
        (r.pc, r.srr2, r.srr3),
        (0x100, ORG, msr::CE | msr::EE | msr::ME | msr::DE)
    );
    assert_eq!(r.msr, msr::ME, "CE, EE, DE cleared");
    assert_eq!((r.srr0, r.srr1), (0, 0));
}

#[test]
fn rfci_returns_from_a_critical_interrupt() {
    let mut b = spinning(msr::CE, exisr::CIS);
    b.mem.load_words(0x100, &[li(3, 5), RFCI]);
    b.cpu.set_irq(Irq::Critical, true);
    assert!(matches!(
        b.run(100),
        Stop::Exception {
            kind: Exception::Critical,
            ..
        }
    ));
    b.cpu.set_irq(Irq::Critical, false);
    b.cpu.set_dcr(EXISR, exisr::CIS);
    let start = b.cpu.now().0;
    assert_eq!(b.run(start + 20), Stop::Limit);
    assert_eq!(
        (b.r(3), b.cpu.pc(), b.cpu.registers().msr),
        (5, ORG, msr::CE)
    );
}

#[test]
fn the_external_inputs_come_before_the_pit() {
    let mut b = spinning(msr::EE, exisr::E0IS);
    b.cpu.set_irq(Irq::External(0), true);
    b.cpu.set_spr(0x3DA, 0x0400_0000); // TCR[PIE]
    b.cpu.set_spr(0x3DB, 1); // PIT = 1: due almost at once
    assert!(matches!(
        b.run(100),
        Stop::Exception {
            kind: Exception::External,
            ..
        }
    ));
}

#[test]
fn a_high_numbered_external_line_is_ignored() {
    let mut b = spinning(msr::EE, u32::MAX);
    b.cpu.set_irq(Irq::External(9), true);
    assert_eq!(b.run(100), Stop::Limit);
    assert_eq!(b.cpu.dcr(EXISR), Some(0));
}

#[test]
fn wait_state_jumps_to_the_limit_and_an_interrupt_wakes_it() {
    let mut b = Board::new(&[
        load_const(3, msr::WE | msr::EE)[0],
        load_const(3, msr::WE | msr::EE)[1],
        mtmsr(3),
        li(4, 1),
        SC,
    ]);
    assert!(b.cpu.set_dcr(EXIER, exisr::E0IS));
    assert_eq!(b.run(1_000_000), Stop::Wait);
    assert_eq!(b.cpu.now().0, 1_000_000, "time advanced, nothing run");
    assert_eq!(b.cpu.instructions(), 3);
    assert_eq!(b.run(2_000_000), Stop::Wait);
    b.cpu.set_irq(Irq::External(0), true);
    assert_eq!(
        b.run(3_000_000),
        Stop::Exception {
            kind: Exception::External,
            at: ORG + 12
        }
    );
    assert_eq!(b.cpu.now().0, 2_000_000);
    assert_eq!(b.cpu.registers().msr & msr::WE, 0);
    assert_eq!(b.cpu.registers().srr1, msr::WE | msr::EE);
}
