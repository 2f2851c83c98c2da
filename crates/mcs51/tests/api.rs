//! The core as a board sees it: traps for an operating system's entry points, run limits,
//! events, pins against latches, reset values, and what the core refuses.

mod common;

use buslab_mcs51::{
    Clocks, Crystal, Event, FlatMemory, InputError, LineFrame, MAX_QUEUED_INPUTS, Mcs51, Pin, Port,
    Registers, Stop, sfr,
};
use common::{Board, CYCLE};

#[test]
fn a_trap_hands_an_os_call_to_the_board_which_returns_from_it() {
    let mut b = Board::new(&[]);
    b.load(
        0x0400,
        &[
            0x74, 0x41, // MOV A,#41h
            0x12, 0x01, 0x00, // LCALL 0100h   (an OS routine, say "Sende")
            0x0F, // INC R7
            0x80, 0xFE, // SJMP $
        ],
    );
    b.cpu.set_traps(0x0000..=0x03FF);
    b.cpu.set_pc(0x0400);
    assert_eq!(b.run_cycles(50), Stop::Trap { pc: 0x0100 });
    assert_eq!(b.now(), 3 * CYCLE, "MOV (1) and LCALL (2)");
    assert_eq!(b.cpu.a(), 0x41);
    assert_eq!(b.cpu.registers().sp, 0x09);
    // Until the board moves the PC on, every run returns at once.
    assert_eq!(b.run_cycles(50), Stop::Trap { pc: 0x0100 });
    assert_eq!(b.now(), 3 * CYCLE);
    // The board spends the routine's time, then returns from it.
    assert_eq!(b.cpu.stall(Clocks(1000 * CYCLE)), Stop::Limit);
    assert_eq!(b.now(), 1000 * CYCLE);
    b.cpu.ret();
    b.run_cycles(10);
    assert_eq!((b.iram(7), b.cpu.registers().sp), (1, 0x07));
}

#[test]
fn run_stops_at_the_first_boundary_at_or_after_its_limit() {
    // LJMP 0000h: two cycles, over and over.
    let mut b = Board::new(&[0x02, 0x00, 0x00]);
    assert_eq!(b.run_to(13), Stop::Limit);
    assert_eq!(b.now(), 24);
    assert_eq!(b.run_to(24), Stop::Limit);
    assert_eq!(b.now(), 24, "already there: nothing runs");
    assert_eq!(b.run_to(25), Stop::Limit);
    assert_eq!(b.now(), 48);
    b.step();
    assert_eq!(b.now(), 72);
}

#[test]
fn port_writes_are_events_with_the_time_of_the_write() {
    let mut b = Board::new(&[
        0x75, 0x90, 0x0F, // MOV P1,#0Fh     write in cycle 1
        0x75, 0x90, 0x0F, // MOV P1,#0Fh     no change: no event
        0xC2, 0x90, // CLR P1.0              cycle 4
        0x75, 0x80, 0x00, // MOV P0,#00h     cycle 6
        0xF0, // MOVX @DPTR,A                cycle 8: P0 carries the bus, its latch gets 1s
        0x80, 0xFE, // SJMP $
    ]);
    b.run_cycles(20);
    let port = |port, latch, cycle: u64| Event::Port {
        port,
        latch,
        at: Clocks(cycle * CYCLE),
    };
    assert_eq!(
        b.events,
        [
            port(Port::P1, 0x0F, 1),
            port(Port::P1, 0x0E, 4),
            port(Port::P0, 0x00, 6),
            port(Port::P0, 0xFF, 8),
        ]
    );
}

#[test]
fn instructions_read_pins_and_read_modify_write_instructions_read_the_latch() {
    let mut b = Board::new(&[
        0x00, // NOP                     (the outside's levels are sampled in cycle 0)
        0xE5, 0x90, // MOV A,P1          pins
        0x53, 0x90, 0xFF, // ANL P1,#FFh latch: stays FFh
        0xA8, 0x90, // MOV R0,P1         pins
        0x63, 0x90, 0x01, // XRL P1,#01h latch FFh -> FEh
        0xA2, 0x97, // MOV C,P1.7        pin: low
        0x80, 0xFE, // SJMP $
    ]);
    // Outside circuits pull P1.7..4 low.
    b.cpu.set_port(Clocks(0), Port::P1, 0x0F).unwrap();
    b.run_cycles(20);
    assert_eq!(b.cpu.a(), 0x0F);
    assert_eq!(b.cpu.r(0), 0x0F);
    assert_eq!(b.cpu.port_latch(Port::P1), 0xFE);
    assert_eq!(b.cpu.port_pins(Port::P1), 0x0E);
    assert_eq!(b.sfr(sfr::PSW) & 0x80, 0, "C = P1.7 pin = 0");
}

#[test]
fn the_reserved_opcode_runs_as_a_one_cycle_no_op_and_is_reported() {
    let mut b = Board::new(&[0x00, 0xA5, 0x04]); // NOP; A5h; INC A
    b.step();
    assert_eq!(b.step(), (CYCLE, 0x0002));
    assert_eq!(b.now(), 2 * CYCLE);
    assert_eq!(
        b.events,
        [Event::ReservedOpcode {
            pc: 0x0001,
            at: Clocks(CYCLE)
        }]
    );
    b.step();
    assert_eq!(b.cpu.a(), 1);
}

#[test]
fn there_is_nothing_above_7fh_for_indirect_access_the_stack_or_unused_sfrs() {
    let mut b = Board::new(&[
        0x78, 0x90, // MOV R0,#90h
        0xE6, // MOV A,@R0
        0xF5, 0xF0, // MOV B,A
        0x76, 0x55, // MOV @R0,#55h
        0x75, 0x81, 0x7F, // MOV SP,#7Fh
        0xC0, 0xE0, // PUSH ACC       (to 80h: lost)
        0xD0, 0x83, // POP DPH        (from 80h: FFh)
        0x75, 0x85, 0x12, // MOV 85h,#12h  (no register there)
        0xE5, 0x85, // MOV A,85h
        0x80, 0xFE, // SJMP $
    ]);
    let ram_before = *b.cpu.iram();
    b.run_cycles(30);
    assert_eq!(b.sfr(sfr::B), 0xFF, "indirect read of 90h");
    assert_eq!(b.sfr(sfr::DPH), 0xFF, "pop from 80h");
    assert_eq!(b.cpu.a(), 0xFF, "unused SFR address");
    assert_eq!(b.cpu.registers().sp, 0x7F);
    let mut expected = ram_before;
    expected[0] = 0x90;
    assert_eq!(*b.cpu.iram(), expected, "no write landed in RAM");
}

#[test]
fn reset_puts_the_registers_where_the_manual_says_and_keeps_ram() {
    let mut b = Board::new(&[0x75, 0x90, 0x00, 0x78, 0x33, 0x80, 0xFE]);
    b.run_cycles(10);
    b.cpu.set_registers(Registers {
        pc: 0x1234,
        a: 1,
        b: 2,
        psw: 0x18,
        sp: 0x40,
        dptr: 0x5678,
    });
    for (addr, value) in [
        (sfr::TMOD, 0x11),
        (sfr::TCON, 0x50),
        (sfr::SCON, 0x50),
        (sfr::IE, 0x9F),
        (sfr::IP, 0x1F),
        (sfr::PCON, 0x80),
        (sfr::TH1, 0xFD),
    ] {
        b.cpu.write_direct(addr, value);
    }
    b.cpu.reset();
    assert_eq!(
        b.cpu.registers(),
        Registers {
            pc: 0,
            a: 0,
            b: 0,
            psw: 0,
            sp: 0x07,
            dptr: 0
        }
    );
    for port in Port::ALL {
        assert_eq!(b.cpu.port_latch(port), 0xFF);
    }
    for addr in [
        sfr::TMOD,
        sfr::TCON,
        sfr::TL0,
        sfr::TH0,
        sfr::TL1,
        sfr::TH1,
        sfr::SCON,
        sfr::IE,
        sfr::IP,
        sfr::PCON,
    ] {
        assert_eq!(b.sfr(addr), 0, "SFR {addr:02X}h");
    }
    assert_eq!(b.iram(0), 0x33, "internal RAM kept");
}

#[test]
fn bad_inputs_are_refused_naming_the_value() {
    let err = Pin::new(Port::P1, 9).unwrap_err();
    assert_eq!(err, InputError::Bit(9));
    assert_eq!(err.to_string(), "pin bit 9 is out of range 0..=7");
    let mut cpu = Mcs51::new();
    let err = cpu
        .send_rxd(
            Clocks(0),
            LineFrame {
                data: 0,
                ninth: None,
                bit_clocks: Clocks(0),
            },
        )
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        "a bit time of 0 clocks is out of range 1..=1000000000"
    );
    for i in 0..MAX_QUEUED_INPUTS as u64 {
        cpu.set_pin(Clocks(i * CYCLE), Pin::T0, i % 2 == 0).unwrap();
    }
    let err = cpu.set_pin(Clocks(0), Pin::T0, true).unwrap_err();
    assert_eq!(err, InputError::Full { queued: 4096 });
    assert!(err.to_string().contains("4096"), "{err}");
    // Once the core has taken them, there is room again.
    let mut mem = FlatMemory::new();
    cpu.run(&mut mem, Clocks(MAX_QUEUED_INPUTS as u64 * CYCLE + CYCLE));
    cpu.set_pin(Clocks(0), Pin::T0, true).unwrap();
    assert_eq!(
        Crystal::new(0).unwrap_err().to_string(),
        "crystal frequency 0 Hz is out of range 1..=100000000"
    );
}

#[test]
fn a_trapped_interrupt_vector_returns_with_reti_which_ends_its_level() {
    // INT0 edge-triggered and enabled; the vector at 0003h is the board's (trapped).
    let mut b = Board::new(&[]);
    b.load(
        0x0400,
        &[
            0x75, 0x88, 0x01, // MOV TCON,#01h   IT0
            0x75, 0xA8, 0x81, // MOV IE,#81h     EA, EX0
            0x05, 0x30, // INC 30h
            0x80, 0xFC, // SJMP back to INC
        ],
    );
    b.cpu.set_traps(0x0000..=0x00FF);
    b.cpu.set_pc(0x0400);
    b.run_cycles(10);
    let edge = |b: &mut Board| {
        let now = b.now();
        b.cpu.set_pin(Clocks(now), Pin::INT0, false).unwrap();
        b.cpu
            .set_pin(Clocks(now + 2 * CYCLE), Pin::INT0, true)
            .unwrap();
    };
    edge(&mut b);
    assert_eq!(b.run_cycles(20), Stop::Trap { pc: 0x0003 });
    let inside = b.now();
    b.cpu.reti();
    assert!(
        b.cpu.pc() >= 0x0406,
        "back in the loop at {:04X}h",
        b.cpu.pc()
    );
    // The routine's level ended: the next edge is taken again.
    edge(&mut b);
    assert_eq!(b.run_cycles(20), Stop::Trap { pc: 0x0003 });
    assert!(b.now() > inside);
    // With RET instead, the level stays in progress and a third edge is not taken.
    b.cpu.ret();
    edge(&mut b);
    assert_eq!(b.run_cycles(40), Stop::Limit);
}

#[test]
fn a_device_driving_a_pin_now_is_seen_by_the_next_instruction() {
    let program = [
        0xC2, 0x91, // CLR P1.1       the device answers by pulling P1.3 low
        0xA2, 0x93, // MOV C,P1.3     the very next instruction reads it
        0x92, 0x00, // MOV 20h.0,C
        0x80, 0xFE, // SJMP $
    ];
    let answered = |now: bool| {
        let mut b = Board::new(&program);
        loop {
            let stop = b.cpu.run(&mut b.mem, Clocks(20 * CYCLE));
            if let Some(Event::Port { port: Port::P1, .. }) = b.cpu.poll_event() {
                if now {
                    b.cpu.drive_now(Port::P1, 0x08, 0x00);
                } else {
                    let at = b.cpu.now();
                    b.cpu
                        .set_pin(at, Pin::new(Port::P1, 3).unwrap(), false)
                        .unwrap();
                }
            }
            if stop == Stop::Limit {
                return b.iram(0x20) & 1;
            }
        }
    };
    assert_eq!(answered(true), 0, "driven now: read low");
    assert_eq!(
        answered(false),
        1,
        "a level announced for now waits for the next sample"
    );
}

#[test]
fn set_port_bits_changes_only_the_masked_pins() {
    let mut b = Board::new(&[0x80, 0xFE]);
    b.cpu.set_port(Clocks(0), Port::P1, 0xF0).unwrap();
    b.cpu
        .set_port_bits(Clocks(2 * CYCLE), Port::P1, 0x81, 0x00)
        .unwrap();
    b.run_cycles(4);
    assert_eq!(b.cpu.port_pins(Port::P1), 0x70);
}

#[test]
fn transmitting_lasts_from_the_sbuf_write_to_ti() {
    let mut b = Board::new(&[
        0x75, 0x89, 0x20, // MOV TMOD,#20h
        0x75, 0x8D, 0xFD, // MOV TH1,#FDh
        0x75, 0x88, 0x40, // MOV TCON,#40h   TR1
        0x75, 0x98, 0x40, // MOV SCON,#40h   mode 1
        0x75, 0x99, 0x55, // MOV SBUF,#55h
        0x80, 0xFE, // SJMP $
    ]);
    // Four 2-cycle MOVs, then MOV SBUF writes at the start of cycle 9.
    b.run_cycles(8);
    assert!(!b.cpu.transmitting());
    b.run_cycles(2);
    assert!(b.cpu.transmitting());
    // Timer 1 counts from TL1 = 0: its first overflow is 256 cycles away; then 9600 baud,
    // the frame's TI within 11 bit times (96 cycles each).
    b.run_cycles(256 + 11 * 96);
    assert!(!b.cpu.transmitting());
    assert_eq!(b.frames().len(), 1);
}
