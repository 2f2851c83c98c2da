//! The time base, the PIT (auto-reload), the FIT and the watchdog, in CPU cycles.

mod common;

use buslab_ppc403::exceptions::msr;
use buslab_ppc403::spr::number::{PIT, TBHI, TBLO, TCR, TSR};
use buslab_ppc403::timers::{tcr, tsr};
use buslab_ppc403::{Exception, Stop, WatchdogReset};
use common::*;

/// Where the tests' vectors are (EVPR).
const VECTORS: u32 = 0x0004_0000;

/// A board running `program` followed by nops (one cycle each), EVPR at [`VECTORS`].
fn board(program: &[u32]) -> Board {
    let mut words = program.to_vec();
    words.resize(program.len() + 20_000, NOP);
    let mut b = Board::new(&words);
    b.cpu.registers_mut().evpr = VECTORS;
    b
}

#[test]
fn the_pit_interrupts_at_its_cycle_and_reloads() {
    // Cycle 6 ends with the mtspr PIT: expiries at 1006, 2006, ...
    let mut b = board(&[
        load_const(3, tcr::PIE | tcr::ARE)[0],
        load_const(3, tcr::PIE | tcr::ARE)[1],
        mtspr(TCR, 3),
        li(4, 1000),
        wrteei(true),
        mtspr(PIT, 4),
    ]);
    // The handler acknowledges (TSR[PIS]) and returns.
    b.mem.load_words(
        VECTORS + 0x1000,
        &[addi(20, 20, 1), lis(5, 0x0800), mtspr(TSR, 5), RFI],
    );
    assert_eq!(
        b.run(100_000),
        Stop::Exception {
            kind: Exception::Pit,
            at: ORG + 4 * 1006
        }
    );
    assert_eq!(b.cpu.now().0, 1006);
    assert_eq!(b.cpu.pc(), VECTORS + 0x1000);
    assert_eq!(b.cpu.spr(TSR).unwrap() & tsr::PIS, tsr::PIS);
    assert_eq!(b.cpu.spr(PIT), Some(1000), "reloaded");
    assert_eq!(
        b.run(100_000),
        Stop::Exception {
            kind: Exception::Pit,
            at: ORG + 4 * (2006 - 5) // the handler took 5 cycles (rfi: 2)
        }
    );
    assert_eq!(b.cpu.now().0, 2006);
    assert_eq!(b.r(20), 1);
}

#[test]
fn without_auto_reload_the_pit_stops_at_zero() {
    let mut b = board(&[li(4, 100), mtspr(PIT, 4), mfspr(5, PIT)]);
    assert_eq!(b.run(50), Stop::Limit);
    assert_eq!(b.r(5), 99, "read one cycle after the write");
    assert_eq!(b.run(500), Stop::Limit);
    assert_eq!(b.cpu.spr(PIT), Some(0));
    assert_eq!(
        b.cpu.spr(TSR),
        Some(tsr::PIS),
        "status without an interrupt (PIE clear)"
    );
}

#[test]
fn the_fit_fires_when_the_time_base_crosses_its_period() {
    let mut b = board(&[
        lis(3, (tcr::FIE >> 16) as i32), // FP = 0: 2^9 cycles
        mtspr(TCR, 3),
        wrteei(true),
    ]);
    assert_eq!(
        b.run(10_000),
        Stop::Exception {
            kind: Exception::Fit,
            at: ORG + 4 * 512
        }
    );
    assert_eq!(b.cpu.now().0, 512);
    assert_eq!(b.cpu.pc(), VECTORS + 0x1010);
}

#[test]
fn the_watchdog_interrupts_on_its_second_timeout_and_resets_on_the_third() {
    let wait = msr::WE | msr::CE;
    let mut b = board(&[
        load_const(3, tcr::WIE | 0x1000_0000)[0], // WP = 0: 2^17; WRC = core
        load_const(3, tcr::WIE | 0x1000_0000)[1],
        mtspr(TCR, 3),
        load_const(4, wait)[0],
        load_const(4, wait)[1],
        mtmsr(4),
    ]);
    // The handler waits again, critical interrupts off.
    b.mem.load_words(
        VECTORS + 0x1020,
        &[lis(5, (msr::WE >> 16) as i32), mtmsr(5)],
    );
    assert_eq!(
        b.run(10_000_000),
        Stop::Exception {
            kind: Exception::Watchdog,
            at: ORG + 24
        }
    );
    assert_eq!(b.cpu.now().0, 1 << 18);
    let r = *b.cpu.registers();
    assert_eq!((r.srr2, r.srr3, r.pc), (ORG + 24, wait, VECTORS + 0x1020));
    let watchdog_bits = tsr::ENW | tsr::WIS | tsr::WRS;
    assert_eq!(b.cpu.spr(TSR).unwrap() & watchdog_bits, tsr::ENW | tsr::WIS);
    assert_eq!(
        b.run(10_000_000),
        Stop::Reset {
            by: WatchdogReset::Core
        }
    );
    assert_eq!(b.cpu.now().0, 3 << 17);
    assert_eq!(b.cpu.pc(), 0xFFFF_FFFC);
    assert_eq!(b.cpu.registers().msr, 0);
    assert_eq!(b.cpu.spr(TCR), Some(0));
    assert_eq!(
        b.cpu.spr(TSR).unwrap() & watchdog_bits,
        tsr::ENW | tsr::WIS | 0x1000_0000,
        "WRS = core"
    );
}

#[test]
fn a_watchdog_without_wie_or_wrc_only_sets_status() {
    let mut b = Board::new(&[b(0)]);
    b.cpu.registers_mut().msr = msr::CE;
    assert_eq!(b.run(3 << 17), Stop::Limit);
    assert_eq!(
        b.cpu.spr(TSR),
        Some(tsr::ENW | tsr::WIS | tsr::FIS),
        "the FIT's status too: its timer always runs"
    );
}

#[test]
fn the_time_base_counts_cycles_and_can_be_written() {
    let mut b = board(&[
        mfspr(3, TBLO),
        li(4, -1),
        mtspr(TBLO, 4),
        li(5, 7),
        mtspr(TBHI, 5),
        mfspr(6, TBLO),
        mfspr(7, TBHI),
        x31(8, 12, 8, 371, false), // mftb r8 (TBL: 268)
    ]);
    assert_eq!(b.run(8), Stop::Limit);
    assert_eq!(b.r(3), 1, "read at the end of its own cycle");
    assert_eq!(b.r(6), 2, "0xFFFFFFFF at cycle 3, three cycles later");
    assert_eq!(
        b.r(7),
        7,
        "the low word carried at cycle 4, then 7 was written"
    );
    assert_eq!(b.r(8), 4);
    assert_eq!(b.cpu.time_base(), (7 << 32) | 4);
}
