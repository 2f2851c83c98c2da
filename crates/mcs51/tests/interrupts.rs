//! Interrupt timing, priorities and the polling rules, against Intel's MCS-51 manual: a flag
//! is sampled in the machine cycle it is set in and polled in the next; a request polled in
//! the last cycle of an instruction becomes a two-cycle hardware LCALL. So at least three
//! whole cycles pass between the request's cycle and the routine's first instruction, more
//! when the poll falls inside a longer instruction, and one more instruction always runs
//! after RETI or a write to IE or IP.

mod common;

use buslab_mcs51::{Clocks, Pin, Stop};
use common::{Board, CYCLE};

/// LJMP 0100h at 0000h; at 0100h `setup`, then NOPs (the memory is zero).
fn board(setup: &[u8]) -> Board {
    let mut b = Board::new(&[0x02, 0x01, 0x00]);
    b.load(0x0100, setup);
    b
}

/// MOV IE,#85h (EA, EX1, EX0); SETB IT0; SETB IT1: both external interrupts on edges.
const EDGES_ON: [u8; 7] = [0x75, 0xA8, 0x85, 0xD2, 0x88, 0xD2, 0x8A];

#[test]
fn an_edge_reaches_its_routine_four_cycles_after_the_cycle_that_sampled_it() {
    // The minimum response: sampled in cycle C, polled in C+1 (the last cycle of a NOP),
    // LCALL in C+2 and C+3, the routine's first fetch at C+4.
    for phase in 0..12 {
        let mut b = board(&EDGES_ON);
        b.cpu.set_traps(0x0003..=0x0003);
        assert_eq!(b.run_cycles(20), Stop::Limit);
        let c = b.now() + 3 * CYCLE;
        b.cpu.set_pin(Clocks(c + phase), Pin::INT0, false).unwrap();
        assert_eq!(b.run_cycles(100), Stop::Trap { pc: 0x0003 });
        // A change after S5P2 (clock 9 of the cycle) is sampled one cycle later.
        let sampled = if phase <= 9 { c } else { c + CYCLE };
        assert_eq!(b.now(), sampled + 4 * CYCLE, "edge at phase {phase}");
    }
}

#[test]
fn a_request_polled_inside_mul_waits_for_its_last_cycle() {
    // 0100h: setup (4 cycles after the 2-cycle LJMP), NOP x3, MUL AB at 010Ah (4 cycles,
    // starting at cycle 9), NOPs.
    let mut setup = EDGES_ON.to_vec();
    setup.extend([0x00, 0x00, 0x00, 0xA4]);
    let mul = 9 * CYCLE;
    for (sampled, isr) in [
        // Sampled in the NOP before the NOP before MUL: polled in that NOP's last cycle.
        (mul - 2 * CYCLE, mul - 2 * CYCLE + 4 * CYCLE),
        // Sampled in the NOP right before MUL: polled during MUL, taken after it.
        (mul - CYCLE, mul + 4 * CYCLE + 2 * CYCLE),
        // Sampled in MUL's first cycle: still taken right after it.
        (mul, mul + 4 * CYCLE + 2 * CYCLE),
        // Sampled in MUL's third cycle: polled in its last cycle, which sees cycle 3.
        (mul + 2 * CYCLE, mul + 4 * CYCLE + 2 * CYCLE),
        // Sampled in MUL's last cycle: polled in the next instruction (a NOP).
        (mul + 3 * CYCLE, mul + 5 * CYCLE + 2 * CYCLE),
    ] {
        let mut b = board(&setup);
        b.cpu.set_traps(0x0003..=0x0003);
        b.cpu.set_pin(Clocks(sampled), Pin::INT0, false).unwrap();
        assert_eq!(b.run_cycles(100), Stop::Trap { pc: 0x0003 });
        assert_eq!(b.now(), isr, "request sampled at clock {sampled}");
    }
}

#[test]
fn one_instruction_runs_after_reti_before_the_next_request() {
    // Both edges at once, same level: IE0 first (polling order). Its routine is RETI; then one
    // main instruction runs before IE1's routine.
    let mut b = board(&EDGES_ON);
    b.load(0x0003, &[0x32]); // RETI
    b.load(0x0013, &[0x32]); // RETI
    b.run_cycles(20);
    let at = Clocks(b.now());
    b.cpu.set_pin(at, Pin::INT0, false).unwrap();
    b.cpu.set_pin(at, Pin::INT1, false).unwrap();
    b.run_until_pc(0x0003, 10);
    let (_, after_reti) = b.step();
    assert!(
        after_reti >= 0x0107,
        "RETI went back to the NOPs, not to {after_reti:04X}h"
    );
    assert_eq!(b.step().1, after_reti + 1, "one NOP runs after RETI");
    let (start, pc) = b.step();
    assert_eq!(pc, 0x0013, "then IE1's routine");
    assert_eq!(
        b.now() - start,
        2 * CYCLE,
        "the hardware LCALL takes two cycles"
    );
}

#[test]
fn one_instruction_runs_after_a_write_to_ie_or_ip() {
    // 0100h: setup (EA on), NOP, NOP, then a 2-cycle write at 0109h (cycles 8 and 9), NOPs.
    // A request sampled in the write's first cycle is polled in its last: taken right after
    // it, unless the write went to IE or IP.
    for (write, isr) in [
        ([0x75, 0x30, 0x00], 10 * CYCLE + 2 * CYCLE), // MOV 30h,#00h: no delay
        ([0x75, 0xB8, 0x00], 11 * CYCLE + 2 * CYCLE), // MOV IP,#00h: one NOP first
        ([0x75, 0xA8, 0x85], 11 * CYCLE + 2 * CYCLE), // MOV IE,#85h: one NOP first
    ] {
        let mut setup = EDGES_ON.to_vec();
        setup.extend([0x00, 0x00]);
        setup.extend(write);
        let mut b = board(&setup);
        b.cpu.set_traps(0x0003..=0x0003);
        b.cpu.set_pin(Clocks(8 * CYCLE), Pin::INT0, false).unwrap();
        assert_eq!(b.run_cycles(100), Stop::Trap { pc: 0x0003 });
        assert_eq!(b.now(), isr, "after {write:02X?}");
    }
    // A request waiting while EA is off: SETB EA, then one more instruction, then the routine.
    let mut b = board(&[0x75, 0xA8, 0x01, 0xD2, 0x88, 0x00, 0x00, 0xD2, 0xAF]);
    b.cpu.set_pin(Clocks(0), Pin::INT0, false).unwrap();
    b.run_until_pc(0x0107, 20);
    assert_eq!(b.step().1, 0x0109, "SETB EA");
    assert_eq!(b.step().1, 0x010A, "one NOP");
    assert_eq!(b.step().1, 0x0003, "then the routine");
}

#[test]
fn a_high_priority_request_interrupts_a_low_priority_routine_but_not_the_reverse() {
    // IE0 low (its routine loops), IE1 high (PX1).
    let mut setup = EDGES_ON.to_vec();
    setup.extend([0x75, 0xB8, 0x04]); // MOV IP,#04h
    let mut b = board(&setup);
    b.load(0x0003, &[0x80, 0xFE]); // SJMP $
    b.load(0x0013, &[0x80, 0xFE]); // SJMP $
    b.run_cycles(20);
    b.cpu.set_pin(Clocks(b.now()), Pin::INT0, false).unwrap();
    b.run_until_pc(0x0003, 10);
    // Another low request (a new edge on INT0) does not nest.
    b.cpu.set_pin(Clocks(b.now()), Pin::INT0, true).unwrap();
    b.cpu
        .set_pin(Clocks(b.now() + 4 * CYCLE), Pin::INT0, false)
        .unwrap();
    b.run_cycles(50);
    assert_eq!(
        b.cpu.pc(),
        0x0003,
        "a low routine is not interrupted by a low request"
    );
    // A high request does.
    b.cpu.set_pin(Clocks(b.now()), Pin::INT1, false).unwrap();
    b.run_until_pc(0x0013, 10);
    let sp = b.cpu.registers().sp;
    assert_eq!(sp, 0x07 + 4, "two return addresses on the stack");
    assert_eq!(
        (b.iram(0x0A), b.iram(0x0B)),
        (0x03, 0x00),
        "the high routine returns into the low one (PC low byte pushed first)"
    );
    // Nothing interrupts the high routine, not even another high request.
    b.cpu.set_pin(Clocks(b.now()), Pin::INT1, true).unwrap();
    b.cpu
        .set_pin(Clocks(b.now() + 4 * CYCLE), Pin::INT1, false)
        .unwrap();
    b.run_cycles(50);
    assert_eq!(b.cpu.pc(), 0x0013);
    assert_eq!(b.cpu.registers().sp, sp);
}

#[test]
fn simultaneous_requests_go_by_priority_then_polling_order() {
    // All five flags set at once by software (TCON = AFh: TF1, TF0, IE1, IT1, IE0, IT0; then
    // SETB TI, SETB RI), all enabled. Each routine is RETI; the serial one clears TI and RI.
    for (ip, expected) in [
        (0x00, [0x03, 0x0B, 0x13, 0x1B, 0x23]),
        (0x08, [0x1B, 0x03, 0x0B, 0x13, 0x23]), // PT1
        (0x14, [0x13, 0x23, 0x03, 0x0B, 0x1B]), // PS, PX1
    ] {
        let mut b = board(&[
            0x75, 0xB8, ip, // MOV IP,#ip
            0x75, 0x88, 0xAF, // MOV TCON,#AFh
            0xD2, 0x99, // SETB TI
            0xD2, 0x98, // SETB RI
            0x75, 0xA8, 0x9F, // MOV IE,#9Fh
        ]);
        for v in [0x03, 0x0B, 0x13, 0x1B] {
            b.load(v, &[0x32]);
        }
        b.load(0x0023, &[0xC2, 0x99, 0xC2, 0x98, 0x32]);
        let mut order = Vec::new();
        for _ in 0..60 {
            let (_, pc) = b.step();
            if matches!(pc, 0x03 | 0x0B | 0x13 | 0x1B | 0x23) {
                order.push(pc);
            }
        }
        assert_eq!(order, expected, "IP = {ip:02X}h");
        // The hardware cleared the timer flags and the edge flags; the routine cleared RI/TI.
        assert_eq!(b.sfr(0x88), 0x05, "TCON keeps only IT1 and IT0");
        assert_eq!(b.sfr(0x98) & 0x03, 0);
    }
}

#[test]
fn a_level_request_repeats_while_the_pin_stays_low() {
    // IT0 clear: IE0 follows the pin, and vectoring does not clear it.
    let mut b = board(&[0x75, 0xA8, 0x81]); // MOV IE,#81h
    b.load(0x0003, &[0x0F, 0x32]); // INC R7; RETI
    b.run_cycles(10);
    assert_eq!(b.sfr(0x88) & 0x02, 0, "IE0 clear while INT0 is high");
    b.cpu.set_pin(Clocks(b.now()), Pin::INT0, false).unwrap();
    b.run_cycles(40);
    let entries = b.iram(7);
    // Each round: LCALL 2 + INC 1 + RETI 2 + one main NOP = 6 cycles.
    assert!((6..=7).contains(&entries), "{entries} entries in 40 cycles");
    assert_eq!(b.sfr(0x88) & 0x02, 0x02, "IE0 set while INT0 is low");
    b.cpu.set_pin(Clocks(b.now()), Pin::INT0, true).unwrap();
    b.run_cycles(40);
    let after = b.iram(7);
    assert!(
        after <= entries + 1,
        "the routine stops once the pin is high"
    );
    assert_eq!(b.sfr(0x88) & 0x02, 0);
}

#[test]
fn an_edge_needs_a_sample_on_each_side() {
    let mut b = board(&EDGES_ON);
    b.load(0x0003, &[0x0F, 0x32]); // INC R7; RETI
    b.run_cycles(20);
    // Low and back high before the same S5P2: no sample sees it low.
    let c = b.now() + 2 * CYCLE;
    b.cpu.set_pin(Clocks(c + 1), Pin::INT0, false).unwrap();
    b.cpu.set_pin(Clocks(c + 5), Pin::INT0, true).unwrap();
    b.run_cycles(20);
    assert_eq!(b.iram(7), 0, "a glitch between two samples is not an edge");
    // Low for one cycle: sampled low once after a high sample.
    let c = b.now() + 2 * CYCLE;
    b.cpu.set_pin(Clocks(c), Pin::INT0, false).unwrap();
    b.cpu.set_pin(Clocks(c + CYCLE), Pin::INT0, true).unwrap();
    b.run_cycles(20);
    assert_eq!(b.iram(7), 1);
    // A pin held low counts once.
    b.cpu.set_pin(Clocks(b.now()), Pin::INT0, false).unwrap();
    b.run_cycles(60);
    assert_eq!(b.iram(7), 2);
}
