//! The UART against the manual's arithmetic (not against `s51`, whose serial timing is known to
//! be off): in modes 1 and 3 a bit is 16 ticks of timer 1's overflow rate halved unless SMOD,
//! i.e. 384 × (256 − TH1) / 2^SMOD clocks with timer 1 reloading TH1; in mode 2 it is 64 clocks
//! (32 with SMOD); in mode 0 one machine cycle. TI is set at the start of the stop bit, RI in
//! the middle of it, with the SM2 and overrun rules.

mod common;

use buslab_mcs51::{Clocks, Crystal, LineFrame, SerialMode, sfr};
use common::{Board, CYCLE};

/// Timer 1 in mode 2 reloading `th1`, PCON = `pcon`, SCON = `scon`: 11 cycles of set-up at
/// 0000h..000Fh, then `rest` at 0010h.
fn serial_board(th1: u8, pcon: u8, scon: u8, rest: &[u8]) -> Board {
    let mut program = vec![
        0x75, 0x89, 0x20, // MOV TMOD,#20h
        0x75, 0x8D, th1, // MOV TH1,#th1
        0x75, 0x8B, th1, // MOV TL1,#th1
        0x75, 0x87, pcon, // MOV PCON,#pcon
        0xD2, 0x8E, // SETB TR1
        0x75, 0x98, scon, // MOV SCON,#scon
    ];
    program.extend(rest);
    Board::new(&program)
}

/// The bit time by the manual: 32 / 2^SMOD timer-1 overflows of (256 − TH1) cycles each.
fn bit_clocks(th1: u8, smod: bool) -> u64 {
    let overflow = (256 - u64::from(th1)) * CYCLE;
    if smod { 16 * overflow } else { 32 * overflow }
}

const SEND_TWO: [u8; 14] = [
    0x75, 0x99, 0x55, // 0010: MOV SBUF,#55h   (write in cycle 12)
    0x30, 0x99, 0xFD, // 0013: JNB TI,$
    0xC2, 0x99, // 0016: CLR TI
    0x75, 0x99, 0xAA, // 0018: MOV SBUF,#0AAh
    0x80, 0xFE, // 001B: SJMP $
    0x00,
];

#[test]
fn mode_1_sends_at_the_rate_timer_1_and_smod_give() {
    for (th1, smod) in [
        (0xFD, false),
        (0xFD, true),
        (0xFA, false),
        (0xE8, true),
        (0x00, false),
    ] {
        let bit = bit_clocks(th1, smod);
        let mut b = serial_board(th1, if smod { 0x80 } else { 0 }, 0x40, &SEND_TWO);
        b.run_to(40 * bit);
        let frames = b.frames();
        assert_eq!(frames.len(), 2, "TH1 {th1:02X}h SMOD {smod}");
        let (first, second) = (frames[0], frames[1]);
        assert_eq!((first.data, second.data), (0x55, 0xAA));
        assert_eq!((first.mode, first.ninth), (SerialMode::Mode1, None));
        for f in [first, second] {
            // Start bit and 8 data bits before TI.
            assert_eq!(f.end.0 - f.start.0, 9 * bit);
            assert_eq!(f.bit_clocks(), Clocks(bit));
        }
        // The first frame starts at the first bit boundary after the write (cycle 12).
        let write = 12 * CYCLE;
        assert!(first.start.0 > write && first.start.0 <= write + bit + CYCLE);
        // The second write comes within the stop bit: it goes out right after it.
        assert_eq!(second.start, first.stop_end());
    }
    let xtal = Crystal::MHZ_11_0592;
    assert_eq!(u64::from(xtal.hz()) / bit_clocks(0xFD, false), 9600);
    assert_eq!(u64::from(xtal.hz()) / bit_clocks(0xFD, true), 19200);
}

#[test]
fn mode_1_receives_with_ri_in_the_middle_of_the_stop_bit() {
    let bit = bit_clocks(0xFD, false);
    let mut b = serial_board(0xFD, 0, 0x50, &[0x80, 0xFE]);
    b.run_cycles(20);
    let t0 = b.now() + 7;
    b.cpu
        .send_rxd(
            Clocks(t0),
            LineFrame {
                data: 0xC3,
                ninth: None,
                bit_clocks: Clocks(bit),
            },
        )
        .unwrap();
    while b.sfr(sfr::SCON) & 0x01 == 0 {
        assert!(b.now() < t0 + 20 * bit, "RI never came");
        b.step();
    }
    let ri = b.now() - t0;
    assert!(
        ri > 9 * bit + bit / 2 && ri <= 9 * bit + 3 * bit / 4,
        "RI {ri} clocks after the start edge, a bit is {bit}"
    );
    assert_eq!(b.sfr(sfr::SBUF), 0xC3);
    assert_eq!(b.sfr(sfr::SCON) & 0x04, 0x04, "RB8 holds the stop bit");
}

#[test]
fn an_echo_program_sends_back_each_byte_it_receives() {
    let echo = [
        0x30, 0x98, 0xFD, // 0010: JNB RI,$
        0xE5, 0x99, // MOV A,SBUF
        0xC2, 0x98, // CLR RI
        0xF5, 0x99, // MOV SBUF,A
        0x30, 0x99, 0xFD, // JNB TI,$
        0xC2, 0x99, // CLR TI
        0x80, 0xF0, // SJMP 0010h
    ];
    let bit = bit_clocks(0xFD, false);
    let mut b = serial_board(0xFD, 0, 0x50, &echo);
    let message = b"Hello\x00\xFF\x80";
    // 8N2 at 9600 baud: a byte every 11 bits.
    let t0 = 100 * CYCLE;
    for (i, &byte) in message.iter().enumerate() {
        let frame = LineFrame {
            data: byte,
            ninth: None,
            bit_clocks: Clocks(bit),
        };
        b.cpu
            .send_rxd(Clocks(t0 + i as u64 * 11 * bit), frame)
            .unwrap();
    }
    b.run_to(t0 + 11 * bit * (message.len() as u64 + 2));
    let frames = b.frames();
    let echoed: Vec<u8> = frames.iter().map(|f| f.data).collect();
    assert_eq!(echoed, message);
    for (i, f) in frames.iter().enumerate() {
        let sent = t0 + i as u64 * 11 * bit;
        // Received in the stop bit, sent from the next bit boundary on.
        assert!(f.start.0 > sent + 9 * bit && f.start.0 <= sent + 11 * bit);
        assert_eq!(f.bit_clocks(), Clocks(bit));
    }
}

#[test]
fn sm2_and_a_full_buffer_drop_frames_as_the_manual_says() {
    let bit = bit_clocks(0xFD, false);
    let frame = |data, ninth| LineFrame {
        data,
        ninth,
        bit_clocks: Clocks(bit),
    };
    // Mode 1, a frame whose stop bit is 0 (the 9th bit position low): with SM2 it is dropped,
    // without it RI comes with RB8 = 0.
    for (scon, ri) in [(0x70, false), (0x50, true)] {
        let mut b = serial_board(0xFD, 0, scon, &[0x80, 0xFE]);
        b.cpu
            .send_rxd(Clocks(100 * CYCLE), frame(0x5A, Some(false)))
            .unwrap();
        b.run_to(100 * CYCLE + 12 * bit);
        assert_eq!(b.sfr(sfr::SCON) & 0x05, if ri { 0x01 } else { 0x00 });
    }
    // Two frames, nobody reading: the second is lost, SBUF keeps the first.
    let mut b = serial_board(0xFD, 0, 0x50, &[0x80, 0xFE]);
    b.cpu
        .send_rxd(Clocks(100 * CYCLE), frame(0x11, None))
        .unwrap();
    b.cpu
        .send_rxd(Clocks(100 * CYCLE + 11 * bit), frame(0x22, None))
        .unwrap();
    b.run_to(100 * CYCLE + 25 * bit);
    assert_eq!(b.sfr(sfr::SBUF), 0x11);
    // Mode 3 with SM2: only frames whose 9th bit is 1 (addresses) set RI, and RB8 is that bit.
    for (ninth, ri) in [(false, false), (true, true)] {
        let mut b = serial_board(0xFD, 0, 0xF0, &[0x80, 0xFE]);
        b.cpu
            .send_rxd(Clocks(100 * CYCLE), frame(0x42, Some(ninth)))
            .unwrap();
        b.run_to(100 * CYCLE + 12 * bit);
        let scon = b.sfr(sfr::SCON);
        assert_eq!(scon & 0x01 != 0, ri, "9th bit {ninth}");
        if ri {
            assert_eq!((scon & 0x04, b.sfr(sfr::SBUF)), (0x04, 0x42));
        }
    }
}

#[test]
fn a_glitch_on_rxd_is_a_false_start_and_the_next_frame_still_arrives() {
    let bit = bit_clocks(0xFD, false);
    let mut b = serial_board(0xFD, 0, 0x50, &[0x80, 0xFE]);
    let t0 = 100 * CYCLE;
    // Low for a quarter bit: the start bit's samples (7..9/16) see it high again.
    b.cpu
        .set_pin(Clocks(t0), buslab_mcs51::Pin::RXD, false)
        .unwrap();
    b.cpu
        .set_pin(Clocks(t0 + bit / 4), buslab_mcs51::Pin::RXD, true)
        .unwrap();
    b.run_to(t0 + 12 * bit);
    assert_eq!(b.sfr(sfr::SCON) & 0x01, 0);
    let frame = LineFrame {
        data: 0x99,
        ninth: None,
        bit_clocks: Clocks(bit),
    };
    b.cpu.send_rxd(Clocks(t0 + 12 * bit), frame).unwrap();
    b.run_to(t0 + 24 * bit);
    assert_eq!(b.sfr(sfr::SCON) & 0x01, 0x01);
    assert_eq!(b.sfr(sfr::SBUF), 0x99);
}

#[test]
fn mode_3_sends_tb8_as_the_ninth_bit() {
    let bit = bit_clocks(0xFD, false);
    let mut b = serial_board(0xFD, 0, 0xC8, &SEND_TWO);
    b.run_to(40 * bit);
    let f = b.frames()[0];
    assert_eq!(
        (f.mode, f.data, f.ninth),
        (SerialMode::Mode3, 0x55, Some(true))
    );
    // Start bit, 8 data bits and the 9th before TI.
    assert_eq!(f.end.0 - f.start.0, 10 * bit);
    assert_eq!(b.frames()[1].start, f.stop_end());
}

#[test]
fn mode_2_runs_at_a_64th_of_the_crystal_or_a_32nd_with_smod() {
    for (pcon, bit) in [(0x00, 64), (0x80, 32)] {
        // Timer 1 is stopped here (TH1 00h, but no SETB TR1 below matters: mode 2 ignores it).
        let mut b = serial_board(0x00, pcon, 0x80, &SEND_TWO);
        b.run_to(40 * bit);
        let frames = b.frames();
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[0].mode, SerialMode::Mode2);
        assert_eq!(frames[0].ninth, Some(false));
        assert_eq!(frames[0].bit_clocks(), Clocks(bit));
        assert_eq!(frames[0].end.0 - frames[0].start.0, 10 * bit);
    }
}

#[test]
fn mode_0_shifts_one_bit_per_cycle_both_ways() {
    // Send: TI at the start of the 10th cycle after the write.
    let mut b = Board::new(&[0x75, 0x99, 0xA5, 0x80, 0xFE]); // MOV SBUF,#A5h (write in cycle 1)
    b.run_cycles(20);
    let f = b.frames()[0];
    assert_eq!(
        (f.mode, f.data, f.bit_clocks().0),
        (SerialMode::Mode0, 0xA5, CYCLE)
    );
    assert_eq!(f.start.0, 2 * CYCLE);
    assert_eq!(f.end.0, (1 + 10) * CYCLE);
    // Receive: writing SCON with REN (write in cycle 1) samples RxD in cycles 3..10, RI at 11.
    let mut b = Board::new(&[0x75, 0x98, 0x10]); // MOV SCON,#10h, then NOPs
    let pattern = 0b1011_0010u8;
    for k in 0..8u64 {
        let high = pattern >> k & 1 != 0;
        b.cpu
            .set_pin(Clocks((3 + k) * CYCLE), buslab_mcs51::Pin::RXD, high)
            .unwrap();
    }
    b.run_to(10 * CYCLE);
    assert_eq!(b.sfr(sfr::SCON) & 0x01, 0, "RI not before the 11th cycle");
    b.run_cycles(1);
    assert_eq!(b.sfr(sfr::SCON) & 0x01, 0x01);
    assert_eq!(b.sfr(sfr::SBUF), pattern);
}
