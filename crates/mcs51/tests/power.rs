//! IDLE and power-down (PCON), as the 80C51's manual describes them: in IDLE the CPU stops
//! while timers, UART and interrupts run, and any enabled interrupt ends it; in power-down the
//! oscillator stops and only a reset ends it, internal RAM kept.

mod common;

use buslab_mcs51::{Clocks, Stop, sfr};
use common::{Board, CYCLE};

#[test]
fn idle_stops_the_cpu_until_an_interrupt_and_returns_after_the_orl() {
    let mut b = Board::new(&[0x02, 0x01, 0x00]); // LJMP 0100h
    b.load(0x000B, &[0x0F, 0x32]); // INC R7; RETI
    b.load(
        0x0100,
        &[
            0x75, 0x89, 0x01, // MOV TMOD,#01h     cycles 2-3
            0x75, 0x8C, 0xFF, // MOV TH0,#FFh      4-5
            0x75, 0x8A, 0x00, // MOV TL0,#00h      6-7
            0x75, 0xA8, 0x82, // MOV IE,#82h       8-9
            0xD2, 0x8C, // SETB TR0                10
            0x43, 0x87, 0x01, // ORL PCON,#01h     11-12: idle from cycle 13
            0x0E, // INC R6
            0x80, 0xFE, // SJMP $
        ],
    );
    b.run_to(13 * CYCLE);
    assert!(b.cpu.is_idle());
    // 256 counts from cycle 10: the overflow cycle is 10 + 255.
    let overflow_cycle = 10 + 255;
    assert_eq!(
        b.cpu.next_deadline(),
        Some(Clocks((overflow_cycle + 1) * CYCLE))
    );
    b.run_to(overflow_cycle * CYCLE);
    assert_eq!((b.iram(6), b.iram(7)), (0, 0), "nothing runs in IDLE");
    assert_eq!(b.sfr(sfr::TL0), 0xFF, "but the timer counts");
    b.run_until_pc(0x000B, 5);
    assert_eq!(b.now(), (overflow_cycle + 4) * CYCLE);
    assert!(!b.cpu.is_idle());
    assert_eq!(b.sfr(sfr::PCON) & 0x01, 0, "the interrupt cleared IDL");
    b.run_cycles(10);
    assert_eq!((b.iram(6), b.iram(7)), (1, 1), "RETI went on after the ORL");
}

#[test]
fn power_down_freezes_everything_until_reset_which_keeps_internal_ram() {
    let mut b = Board::new(&[
        0x7F, 0x2A, // MOV R7,#2Ah
        0x75, 0x89, 0x01, // MOV TMOD,#01h
        0xD2, 0x8C, // SETB TR0
        0x43, 0x87, 0x02, // ORL PCON,#02h
        0x0E, // INC R6 (never runs)
    ]);
    assert_eq!(b.run_cycles(100), Stop::PowerDown);
    assert!(b.cpu.is_powered_down());
    assert_eq!(b.cpu.next_deadline(), None);
    let frozen = b.sfr(sfr::TL0);
    assert!(frozen > 0);
    assert_eq!(b.run_to(100_000), Stop::PowerDown);
    assert_eq!(
        b.now(),
        100_008,
        "time still passes outside (the next cycle boundary)"
    );
    assert_eq!(b.sfr(sfr::TL0), frozen, "the oscillator stands still");
    assert_eq!(b.iram(6), 0);
    b.cpu.reset();
    assert!(!b.cpu.is_powered_down());
    assert_eq!(b.cpu.pc(), 0);
    assert_eq!(b.iram(7), 0x2A, "internal RAM survives");
    assert_eq!(
        (b.sfr(sfr::TL0), b.sfr(sfr::TMOD), b.sfr(sfr::PCON)),
        (0, 0, 0)
    );
    assert_eq!(
        b.run_cycles(100),
        Stop::PowerDown,
        "and the program runs again"
    );
}
