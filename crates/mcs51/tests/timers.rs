//! Timers 0 and 1 in their four modes, GATE and counter inputs, against the manual: a timer
//! counts once per machine cycle while TRx (and, with GATE, INTx high) lets it; a counter
//! once per falling edge of its T pin seen by two samples; TF is set in the cycle of the
//! overflow, and its routine starts four cycles later at the earliest.

mod common;

use buslab_mcs51::{Clocks, Pin, Stop, sfr};
use common::{Board, CYCLE};

/// The 16-bit value of timer `t` now.
fn value(b: &mut Board, t: usize) -> u16 {
    let (tl, th) = [(sfr::TL0, sfr::TH0), (sfr::TL1, sfr::TH1)][t];
    u16::from_be_bytes([b.sfr(th), b.sfr(tl)])
}

#[test]
fn mode_1_counts_every_machine_cycle_and_overflows_into_tf0() {
    let mut b = Board::new(&[
        0x75, 0x89, 0x01, // MOV TMOD,#01h     cycles 0-1
        0x75, 0x8C, 0xFF, // MOV TH0,#FFh      2-3
        0x75, 0x8A, 0xF0, // MOV TL0,#F0h      4-5
        0xD2, 0x8C, // SETB TR0                6 (runs from the start of cycle 6)
    ]);
    b.run_to(7 * CYCLE);
    let start = 6 * CYCLE;
    for _ in 0..30 {
        let counted = (b.now() - start) / CYCLE;
        assert_eq!(value(&mut b, 0), 0xFFF0u16.wrapping_add(counted as u16));
        let tf0 = b.sfr(sfr::TCON) & 0x20 != 0;
        assert_eq!(tf0, counted >= 16, "TF0 after {counted} counts");
        b.step();
    }
}

#[test]
fn tf0_starts_its_routine_four_cycles_after_the_overflow_cycle() {
    let mut b = Board::new(&[
        0x75, 0x89, 0x01, // MOV TMOD,#01h
        0x75, 0x8C, 0xFF, // MOV TH0,#FFh
        0x75, 0x8A, 0xF0, // MOV TL0,#F0h
        0x75, 0xA8, 0x82, // MOV IE,#82h       cycles 6-7
        0xD2, 0x8C, // SETB TR0                8
    ]);
    b.cpu.set_traps(0x000B..=0x000B);
    assert_eq!(b.run_cycles(100), Stop::Trap { pc: 0x000B });
    // Counting from cycle 8, the 16th count overflows at the end of cycle 8 + 15: polled in
    // the next cycle, LCALL in the two after.
    let overflow_cycle = 8 + 15;
    assert_eq!(b.now(), (overflow_cycle + 4) * CYCLE);
    assert_eq!(b.sfr(sfr::TCON) & 0x20, 0, "vectoring cleared TF0");
}

#[test]
fn mode_2_reloads_from_th_and_overflows_every_256_minus_th_cycles() {
    // Timer 0 reloading 9Ch (100 counts); its routine counts overflows in R7.
    let mut b = Board::new(&[
        0x02, 0x01, 0x00, // LJMP 0100h
    ]);
    b.load(0x000B, &[0x0F, 0x32]); // INC R7; RETI
    b.load(
        0x0100,
        &[
            0x75, 0x89, 0x02, // MOV TMOD,#02h   cycles 2-3
            0x75, 0x8C, 0x9C, // MOV TH0,#9Ch    4-5
            0x75, 0x8A, 0x9C, // MOV TL0,#9Ch    6-7
            0x75, 0xA8, 0x82, // MOV IE,#82h     8-9
            0xD2, 0x8C, // SETB TR0              10
            0x80, 0xFE, // SJMP $
        ],
    );
    let start = 10 * CYCLE;
    // Ten periods and a half: ten overflows, each served.
    b.run_to(start + 1050 * CYCLE);
    assert_eq!(b.iram(7), 10);
    // Between overflows TL0 = 9Ch + (counts mod 100), whatever the routine does meanwhile.
    for _ in 0..3000 {
        let counted = (b.now() - start) / CYCLE;
        assert_eq!(b.sfr(sfr::TL0), 0x9C + (counted % 100) as u8);
        assert_eq!(b.sfr(sfr::TH0), 0x9C);
        b.step();
    }
}

#[test]
fn mode_0_counts_13_bits_and_leaves_the_top_of_tl_alone() {
    let mut b = Board::new(&[
        0x75, 0x8C, 0xFF, // MOV TH0,#FFh      (TMOD 00h: mode 0)
        0x75, 0x8A, 0xFA, // MOV TL0,#FAh      13-bit value 1FFAh, TL0 bits 7..5 = 111
        0xD2, 0x8C, // SETB TR0                cycle 4
    ]);
    b.run_to(5 * CYCLE);
    for counted in 1..=5u8 {
        assert_eq!((b.sfr(sfr::TL0), b.sfr(sfr::TH0)), (0xFA + counted, 0xFF));
        assert_eq!(b.sfr(sfr::TCON) & 0x20, 0);
        b.step();
    }
    // The sixth count wraps 1FFFh to 0000h; TL0's upper three bits stay as written.
    assert_eq!((b.sfr(sfr::TL0), b.sfr(sfr::TH0)), (0xE0, 0x00));
    assert_eq!(b.sfr(sfr::TCON) & 0x20, 0x20);
    b.run_cycles(0x2000);
    assert_eq!((b.sfr(sfr::TL0), b.sfr(sfr::TH0)), (0xE0, 0x00));
}

#[test]
fn mode_3_splits_timer_0_and_timer_1_runs_without_tr1() {
    let mut b = Board::new(&[
        0x75, 0x89, 0x23, // MOV TMOD,#23h     timer 1 mode 2, timer 0 mode 3   cycles 0-1
        0x75, 0x8A, 0xF0, // MOV TL0,#F0h      2-3
        0x75, 0x8C, 0xE0, // MOV TH0,#E0h      4-5
        0x75, 0x8D, 0x00, // MOV TH1,#00h      6-7
        0x75, 0x8B, 0x00, // MOV TL1,#00h      8-9 (timer 1 already runs: written here)
        0xD2, 0x8C, // SETB TR0                10: TL0 runs
    ]);
    b.run_to(11 * CYCLE);
    let tl0_start = 10 * CYCLE;
    let tl1_start = 9 * CYCLE;
    b.run_cycles(20);
    let now = b.now();
    // TL0: 8 bits from F0h, overflowed after 16 counts into TF0; TH0 stopped (TR1 clear).
    assert_eq!(b.sfr(sfr::TL0), (0xF0 + (now - tl0_start) / CYCLE) as u8);
    assert_eq!(b.sfr(sfr::TH0), 0xE0);
    assert_eq!(b.sfr(sfr::TCON) & 0xA0, 0x20, "TF0 set, TF1 not");
    // Timer 1 counts though TR1 is clear, and has no flag.
    assert_eq!(b.sfr(sfr::TL1), ((now - tl1_start) / CYCLE) as u8);
    // SETB TR1 runs TH0, whose overflow sets TF1.
    b.load(0x000D, &[0xD2, 0x8E, 0x80, 0xFE]); // SETB TR1; SJMP $
    b.cpu.set_pc(0x000D);
    b.step();
    let th0_start = b.now() - CYCLE;
    for _ in 0..40 {
        let counted = (b.now() - th0_start) / CYCLE;
        assert_eq!(u64::from(b.sfr(sfr::TH0)), (0xE0 + counted) % 0x100);
        let tf1 = b.sfr(sfr::TCON) & 0x80 != 0;
        assert_eq!(
            tf1,
            counted >= 0x20,
            "TH0's overflow sets TF1 ({counted} counts)"
        );
        b.step();
    }
    // Timer 1 in mode 3 holds its count.
    b.cpu.write_direct(sfr::TMOD, 0x33);
    let held = b.sfr(sfr::TL1);
    b.run_cycles(50);
    assert_eq!(b.sfr(sfr::TL1), held);
}

#[test]
fn gate_lets_the_timer_count_only_while_its_int_pin_is_high() {
    let mut b = Board::new(&[
        0x75, 0x89, 0x09, // MOV TMOD,#09h     GATE, mode 1
        0xD2, 0x8C, // SETB TR0                cycle 2
    ]);
    b.cpu.set_pin(Clocks(0), Pin::INT0, false).unwrap();
    b.run_cycles(40);
    assert_eq!(value(&mut b, 0), 0, "INT0 low: no count");
    let opened = b.now() + 5 * CYCLE;
    b.cpu.set_pin(Clocks(opened), Pin::INT0, true).unwrap();
    let closed = opened + 30 * CYCLE;
    b.cpu.set_pin(Clocks(closed), Pin::INT0, false).unwrap();
    b.run_to(opened + 10 * CYCLE);
    assert_eq!(value(&mut b, 0), 10);
    b.run_to(closed + 40 * CYCLE);
    assert_eq!(value(&mut b, 0), 30, "counted while INT0 was high only");
}

#[test]
fn a_counter_counts_falling_edges_on_its_t_pin() {
    let mut b = Board::new(&[
        0x75, 0x89, 0x50, // MOV TMOD,#50h     timer 1: counter, mode 1
        0xD2, 0x8E, // SETB TR1                cycle 2
    ]);
    b.run_cycles(10);
    // 25 pulses at the fastest rate the manual allows: one cycle low, one high.
    let t0 = b.now();
    for i in 0..25 {
        let t = t0 + i * 2 * CYCLE;
        b.cpu.set_pin(Clocks(t), Pin::T1, false).unwrap();
        b.cpu.set_pin(Clocks(t + CYCLE), Pin::T1, true).unwrap();
    }
    // And a glitch no sample sees.
    let g = t0 + 60 * CYCLE;
    b.cpu.set_pin(Clocks(g + 1), Pin::T1, false).unwrap();
    b.cpu.set_pin(Clocks(g + 4), Pin::T1, true).unwrap();
    b.run_to(t0 + 100 * CYCLE);
    assert_eq!(value(&mut b, 1), 25);
    // The count appears in the cycle after the one that saw the low sample.
    b.cpu.set_pin(Clocks(b.now()), Pin::T1, false).unwrap();
    assert_eq!(value(&mut b, 1), 25);
    b.run_cycles(1);
    assert_eq!(value(&mut b, 1), 26);
}
