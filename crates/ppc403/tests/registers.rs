//! Every SPR and DCR of the 403GA through `mtspr`/`mfspr`/`mtdcr`/`mfdcr`: plain ones keep
//! what was written, the write-1-to-clear ones clear, read-only ones refuse writes.

mod common;

use buslab_ppc403::spr::number as spr;
use buslab_ppc403::{Exception, Stop};
use common::*;

/// Writes `value` to SPR `n` and reads it back into r4, in supervisor state.
fn spr_round_trip(n: u32, value: u32) -> Board {
    let [hi, lo] = load_const(3, value);
    exec(&[], &[hi, lo, mtspr(n, 3), mfspr(4, n)])
}

#[test]
fn plain_sprs_keep_what_was_written() {
    let plain = [
        spr::XER,
        spr::LR,
        spr::CTR,
        spr::SRR0,
        spr::SRR1,
        272,
        273,
        274,
        275,
        spr::ESR,
        spr::DEAR,
        spr::CDBCR,
        spr::SRR2,
        spr::SRR3,
        spr::DBCR,
        spr::IAC1,
        spr::IAC2,
        spr::DAC1,
        spr::DAC2,
        spr::DCCR,
        spr::ICCR,
        0x3FC,
        0x3FD,
        0x3FE,
        0x3FF,
    ];
    for n in plain {
        let b = spr_round_trip(n, 0xA5C3_0F81);
        assert_eq!(b.r(4), 0xA5C3_0F81, "SPR {n:#x}");
        assert_eq!(b.cpu.spr(n), Some(0xA5C3_0F81), "SPR {n:#x}");
    }
}

#[test]
fn evpr_keeps_its_upper_half_and_tcr_all_of_it() {
    assert_eq!(spr_round_trip(spr::EVPR, 0x1234_5678).r(4), 0x1234_0000);
    assert_eq!(spr_round_trip(spr::TCR, 0x0C00_0000).r(4), 0x0C00_0000);
}

#[test]
fn tsr_and_dbsr_clear_the_bits_written_as_one() {
    // TSR: run past two watchdog periods (ENW, WIS) and a FIT period (FIS), clear WIS only.
    let mut b = Board::new(&[b(0)]);
    assert_eq!(b.run(1 << 18), Stop::Limit);
    assert_eq!(b.cpu.spr(spr::TSR), Some(0xC400_0000));
    assert_eq!(b.cpu.set_spr(spr::TSR, 0x4000_0000), Some(true));
    assert_eq!(b.cpu.spr(spr::TSR), Some(0x8400_0000));
    // DBSR: nothing sets it; a write clears, never sets.
    assert_eq!(spr_round_trip(spr::DBSR, u32::MAX).r(4), 0);
}

#[test]
fn read_only_sprs_refuse_writes() {
    for n in [spr::PVR, spr::TBHU, spr::TBLU, spr::ICDBDR] {
        let word = mtspr(n, 3);
        let mut b = Board::new(&[word]);
        assert_eq!(
            b.run(10),
            Stop::Exception {
                kind: Exception::Illegal { word },
                at: ORG
            },
            "SPR {n:#x}"
        );
    }
    let b = exec(&[], &[mfspr(4, spr::PVR), mfspr(5, spr::ICDBDR)]);
    assert_eq!((b.r(4), b.r(5)), (0x0020_0011, 0));
}

#[test]
fn dcrs_keep_what_was_written_and_the_status_ones_clear() {
    for n in (0x80..=0x87)
        .chain([0x90, 0x91, 0xA0, 0x42])
        .chain(0xC0..=0xDF)
    {
        let [hi, lo] = load_const(3, 0x5A5A_1234);
        let b = exec(&[], &[hi, lo, mtdcr(n, 3), mfdcr(4, n)]);
        assert_eq!(b.r(4), 0x5A5A_1234, "DCR {n:#x}");
    }
    let mut b = Board::new(&[]);
    b.cpu.set_dcr(0xE0, 0); // DMASR: nothing sets it
    assert_eq!(b.cpu.dcr(0xE0), Some(0));
    assert_eq!(b.cpu.dcr(0x41), None);
    assert!(!b.cpu.set_dcr(0x100, 1));
}

#[test]
fn a_store_bus_error_marks_besr_as_a_write() {
    let mut b = Board::new(&[stw(4, 3, 0)]);
    b.cpu.set_gpr(3, 0x7000_0000);
    assert!(matches!(
        b.run(10),
        Stop::Exception {
            kind: Exception::MachineCheck { addr: 0x7000_0000 },
            ..
        }
    ));
    assert_eq!(b.cpu.dcr(0x91), Some(0x8800_0000));
    assert_eq!(b.cpu.registers().srr2, ORG);
}
