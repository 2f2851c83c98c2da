//! Synchronous exceptions: sc (trapped for the board or vectored), program exceptions
//! (illegal, privileged, trap) with ESR, returning with rfi, vectors relative to EVPR, and the
//! MSR bits an exception clears.

mod common;

use buslab_ppc403::exceptions::{esr, msr};
use buslab_ppc403::{Exception, Stop};
use common::*;

#[test]
fn a_trapped_sc_stops_past_itself_with_nothing_saved() {
    let mut b = Board::new(&[li(0, 4), SC, li(3, 1)]);
    b.cpu.set_trap_sc(true);
    assert_eq!(b.run(100), Stop::SystemCall { at: ORG + 4 });
    let r = *b.cpu.registers();
    assert_eq!((r.pc, r.srr0, r.srr1), (ORG + 8, 0, 0));
    assert_eq!(b.cpu.instructions(), 2);
    // The board serves the call and runs on.
    b.cpu.set_gpr(3, 99);
    assert_eq!(b.run(3), Stop::Limit);
    assert_eq!(b.r(3), 1);
}

#[test]
fn a_vectored_sc_saves_the_next_pc_and_msr_and_rfi_comes_back() {
    let handler = [addi(3, 3, 100), RFI];
    let mut b = Board::new(&[li(3, 1), SC, addi(3, 3, 1000), SC]);
    b.mem.load_words(0x0002_0C00, &handler);
    let r = b.cpu.registers_mut();
    r.evpr = 0x0002_0000;
    r.msr = msr::EE | msr::PR | msr::ME;
    assert_eq!(
        b.run(100),
        Stop::Exception {
            kind: Exception::SystemCall,
            at: ORG + 4
        }
    );
    let r = *b.cpu.registers();
    assert_eq!(
        (r.pc, r.srr0, r.srr1),
        (0x0002_0C00, ORG + 8, msr::EE | msr::PR | msr::ME)
    );
    assert_eq!(r.msr, msr::ME, "EE and PR cleared, ME kept");
    // The handler runs and returns to user mode; the second sc vectors again.
    assert_eq!(
        b.run(100),
        Stop::Exception {
            kind: Exception::SystemCall,
            at: ORG + 12
        }
    );
    assert_eq!(b.r(3), 1101);
    assert_eq!(b.cpu.registers().srr1, msr::EE | msr::PR | msr::ME);
}

#[test]
fn an_illegal_word_sets_esr_pil_and_vectors_to_program() {
    for word in [
        0x0000_0000,
        0xFC00_0000,
        0xC000_0000, /* lfs */
        0x7C00_0FFE,
    ] {
        let mut b = Board::new(&[word]);
        assert_eq!(
            b.run(10),
            Stop::Exception {
                kind: Exception::Illegal { word },
                at: ORG
            },
            "{word:#010x}"
        );
        let r = b.cpu.registers();
        assert_eq!((r.pc, r.srr0, r.esr), (0x700, ORG, esr::PIL));
        assert_eq!(b.cpu.instructions(), 0, "it did not complete");
    }
}

#[test]
fn supervisor_instructions_in_problem_state_are_privileged() {
    for word in [
        mtmsr(3),
        mfmsr(3),
        RFI,
        RFCI,
        wrteei(true),
        mtspr(272, 3),   // SPRG0
        mfspr(3, 0x3D8), // TSR
        mtdcr(0x42, 3),
        mfdcr(3, 0x40),
        x31(0, 0, 3, 470, false), // dcbi
    ] {
        let mut b = Board::new(&[word]);
        b.cpu.registers_mut().msr = msr::PR;
        assert_eq!(
            b.run(10),
            Stop::Exception {
                kind: Exception::Privileged { word },
                at: ORG
            },
            "{word:#010x}"
        );
        assert_eq!(b.cpu.registers().esr, esr::PPR);
        assert_eq!(b.cpu.registers().msr, 0);
    }
    // User SPRs are fine in problem state.
    let mut b = Board::new(&[mtspr(8, 0), mfspr(3, 9), mfspr(4, 0x3CD), SC]);
    b.cpu.registers_mut().msr = msr::PR;
    assert_eq!(b.run_to_sc(), Stop::SystemCall { at: ORG + 12 });
}

#[test]
fn an_unknown_spr_or_dcr_is_illegal() {
    for word in [
        mtspr(22, 3), /* DEC: not on the 403 */
        mfspr(3, 1023 - 100),
        mfdcr(3, 0x10),
        mtspr(287, 3),
    ] {
        let mut b = Board::new(&[word]);
        assert_eq!(
            b.run(10),
            Stop::Exception {
                kind: Exception::Illegal { word },
                at: ORG
            },
            "{word:#010x}"
        );
    }
}

#[test]
fn tw_and_twi_trap_when_their_condition_holds() {
    let tw = |to: u32, ra: u32, rb: u32| x31(to, ra, rb, 4, false);
    let twi = |to: u32, ra: u32, imm: i32| d_form(3, to, ra, imm);
    let cases = [
        (twi(0x10, 3, 0), true),  // -1 < 0 signed
        (twi(0x02, 3, 0), false), // 0xFFFFFFFF < 0 unsigned: no
        (twi(0x01, 3, 0), true),  // unsigned greater
        (tw(0x04, 3, 3), true),   // equal
        (tw(0x08, 3, 4), false),  // -1 > 5: no
        (tw(31, 3, 4), true),     // trap always (`trap`)
        (twi(0, 3, 0), false),    // never
    ];
    for (word, traps) in cases {
        let mut b = Board::new(&[word, SC]);
        b.cpu.set_gpr(3, u32::MAX);
        b.cpu.set_gpr(4, 5);
        b.cpu.set_trap_sc(true);
        let stop = b.run(10);
        if traps {
            assert_eq!(
                stop,
                Stop::Exception {
                    kind: Exception::Trap,
                    at: ORG
                },
                "{word:#010x}"
            );
            assert_eq!(b.cpu.registers().esr, esr::PTR);
        } else {
            assert_eq!(stop, Stop::SystemCall { at: ORG + 4 }, "{word:#010x}");
        }
    }
}

#[test]
fn vectors_follow_evpr_and_handlers_can_return() {
    // An illegal instruction, caught by the program's own handler that skips it.
    let mut b = Board::new(&[li(3, 1), 0, li(4, 2), SC]);
    b.mem.load_words(
        0x0003_0700,
        &[mfspr(5, 26), addi(5, 5, 4), mtspr(26, 5), RFI],
    );
    b.cpu.registers_mut().evpr = 0x0003_1234; // only the upper half counts
    assert_eq!(b.cpu.registers().evpr, 0x0003_1234);
    assert!(matches!(
        b.run(100),
        Stop::Exception {
            kind: Exception::Illegal { .. },
            ..
        }
    ));
    assert_eq!(b.cpu.pc(), 0x0003_0700);
    assert_eq!(b.run_to_sc(), Stop::SystemCall { at: ORG + 12 });
    assert_eq!((b.r(3), b.r(4)), (1, 2));
}

#[test]
fn the_msr_keeps_only_the_403s_bits() {
    let b = exec(&[(3, !(msr::WE | msr::PR))], &[mtmsr(3), mfmsr(4)]);
    assert_eq!(b.r(4), msr::IMPLEMENTED & !msr::WE & !msr::PR);
    assert_eq!(msr::IMPLEMENTED, 0x000F_D20D);
}

#[test]
fn mtmsr_mfmsr_wrtee_wrteei() {
    let mut b = Board::new(&[
        load_const(3, 0x0002_9000)[0],
        load_const(3, 0x0002_9000)[1],
        mtmsr(3),
        mfmsr(4),
        wrteei(false),
        mfmsr(5),
        li(6, 0x7FFF),
        addi(6, 6, 1),            // 0x8000
        x31(6, 0, 0, 131, false), // wrtee r6
        mfmsr(7),
        SC,
    ]);
    b.cpu.registers_mut().msr = 0;
    assert_eq!(b.run_to_sc(), Stop::SystemCall { at: ORG + 40 });
    assert_eq!(b.r(4), 0x0002_9000);
    assert_eq!(b.r(5), 0x0002_1000);
    assert_eq!(b.r(7), 0x0002_9000);
}
