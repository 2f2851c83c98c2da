//! One test per documented register rule of the facts sheet (`/work/shared/facts/sja1000.md`)
//! that `registers.rs` and `bus.rs` do not already pin. Section numbers in the test comments
//! refer to the facts sheet. Everything is observed through register reads, as a driver would.

mod support;

use buslab_can::Level;
use buslab_sja1000::{CanMode, Sja1000};
use support::{Bus, load_tx};

const MOD: u8 = 0;
const CMR: u8 = 1;
const SR: u8 = 2;
const IR: u8 = 3;
const IER: u8 = 4;
const ALC: u8 = 11;
const ECC: u8 = 12;
const EWLR: u8 = 13;
const RXERR: u8 = 14;
const TXERR: u8 = 15;
const RMC: u8 = 29;
const RBSA: u8 = 30;
const CDR: u8 = 31;

const MOD_RM: u8 = 0x01;
const MOD_STM: u8 = 0x04;
const MOD_AFM: u8 = 0x08;
const MOD_SM: u8 = 0x10;

const TR: u8 = 0x01;
const AT: u8 = 0x02;
const RRB: u8 = 0x04;
const CDO: u8 = 0x08;
const SRR: u8 = 0x10;
const GTS: u8 = 0x10;

const SR_RBS: u8 = 0x01;
const SR_DOS: u8 = 0x02;
const SR_TBS: u8 = 0x04;
const SR_TCS: u8 = 0x08;
const SR_RS: u8 = 0x10;
const SR_TS: u8 = 0x20;
const SR_ES: u8 = 0x40;
const SR_BS: u8 = 0x80;

const RI: u8 = 0x01;
const TI: u8 = 0x02;
const EI: u8 = 0x04;
const DOI: u8 = 0x08;
const WUI: u8 = 0x10;
const EPI: u8 = 0x20;
const ALI: u8 = 0x40;
const BEI: u8 = 0x80;

/// A PeliCAN chip in reset mode, accepting everything, 50 kbit/s timing, interrupts `ier`.
fn peli_reset(ier: u8) -> Sja1000 {
    let mut chip = Sja1000::new();
    chip.write(CDR, 0x80);
    for amr in 20..24 {
        chip.write(amr, 0xFF);
    }
    chip.write(6, 0x07);
    chip.write(7, 0x4D);
    chip.write(IER, ier);
    chip
}

/// [`peli_reset`], then operating mode with MOD = `mode` (RM clear).
fn peli(ier: u8, mode: u8) -> Sja1000 {
    let mut chip = peli_reset(ier);
    chip.write(MOD, mode);
    chip
}

/// A BasicCAN chip in operating mode: accept all, CR enables `cr` (bits 1..4).
fn basic(cr: u8) -> Sja1000 {
    let mut chip = Sja1000::new();
    chip.write(4, 0x00); // ACR
    chip.write(5, 0xFF); // AMR
    chip.write(6, 0x07);
    chip.write(7, 0x4D);
    chip.write(0, cr & 0x1E);
    chip
}

/// Chips on one wire, after everybody integrated (11 recessive bits).
fn integrated(chips: Vec<Sja1000>) -> Bus {
    let mut bus = Bus::new(chips);
    bus.run(12);
    bus
}

/// Chip `n` sends `frame` with command `cmd` and the bus runs until its TX buffer is released
/// again (plus the intermission).
fn send(bus: &mut Bus, n: usize, frame: &str, cmd: u8) {
    load_tx(&mut bus.chips[n], frame);
    bus.chips[n].write(CMR, cmd);
    bus.run_until(2_000, "transmission end", |bus| {
        bus.chips[n].peek(SR) & SR_TBS != 0
    });
    bus.run(4);
}

/// The first `n` bytes of the receive window.
fn window(chip: &mut Sja1000, n: usize) -> Vec<u8> {
    let base = match chip.mode() {
        CanMode::Peli => 16,
        CanMode::Basic => 20,
    };
    (0..n).map(|k| chip.read(base + k as u8)).collect()
}

/// A lone PeliCAN chip in self-test mode (no ACK needed) that receives its own frames (SRR).
fn self_test_chip(ier: u8) -> Bus {
    integrated(vec![peli(ier, MOD_STM | MOD_AFM)])
}

// ------------------------------------------------------------------ §2, §4: access tables

/// §2: for each address, the value read after writing 0x5A in reset mode, after writing 0xA5
/// in operating mode, and after going back to reset mode. Every row starts from a fresh chip.
#[test]
fn peli_access_table() {
    #[rustfmt::skip]
    let rows: &[(u8, &str, [u8; 3])] = &[
        (2, "SR read-only (RS/TS shown in reset mode)", [0x3C, 0x0C, 0x3C]),
        (3, "IR read-only", [0x00, 0x00, 0x00]),
        (4, "IER R/W in both modes", [0x5A, 0xA5, 0xA5]),
        (5, "reserved", [0x00, 0x00, 0x00]),
        (6, "BTR0 W in reset only", [0x5A, 0x5A, 0x5A]),
        (7, "BTR1 W in reset only", [0x5A, 0x5A, 0x5A]),
        (8, "OCR W in reset only", [0x5A, 0x5A, 0x5A]),
        (10, "reserved", [0x00, 0x00, 0x00]),
        (11, "ALC read-only", [0x00, 0x00, 0x00]),
        (12, "ECC read-only", [0x00, 0x00, 0x00]),
        (13, "EWLR W in reset only", [0x5A, 0x5A, 0x5A]),
        (14, "RXERR W in reset only", [0x5A, 0x5A, 0x5A]),
        (15, "TXERR W in reset only", [0x5A, 0x5A, 0x5A]),
        (16, "ACR0 / RX window", [0x5A, 0x00, 0x5A]),
        (19, "ACR3 / RX window", [0x5A, 0x00, 0x5A]),
        (20, "AMR0 / RX window", [0x5A, 0x00, 0x5A]),
        (23, "AMR3 / RX window", [0x5A, 0x00, 0x5A]),
        (24, "reserved in reset / RX window", [0x00, 0x00, 0x00]),
        (28, "reserved in reset / RX window", [0x00, 0x00, 0x00]),
        (29, "RMC read-only", [0x00, 0x00, 0x00]),
        (30, "RBSA bits 5..0, W in reset only", [0x1A, 0x1A, 0x1A]),
        (32, "FIFO RAM, W in reset only", [0x5A, 0x5A, 0x5A]),
        (95, "FIFO RAM, W in reset only", [0x5A, 0x5A, 0x5A]),
        (96, "TX buffer RAM, W in reset only", [0x5A, 0x5A, 0x5A]),
        (108, "TX buffer RAM, W in reset only", [0x5A, 0x5A, 0x5A]),
        (109, "free RAM, W in reset only", [0x5A, 0x5A, 0x5A]),
        (111, "free RAM, W in reset only", [0x5A, 0x5A, 0x5A]),
        (112, "not used", [0x00, 0x00, 0x00]),
        (127, "not used", [0x00, 0x00, 0x00]),
    ];
    for &(addr, what, expected) in rows {
        let mut chip = peli_reset(0);
        chip.write(addr, 0x5A);
        let in_reset = chip.read(addr);
        chip.write(MOD, 0x00);
        chip.write(addr, 0xA5);
        let operating = chip.read(addr);
        chip.write(MOD, MOD_RM);
        let back = chip.read(addr);
        assert_eq!(
            [in_reset, operating, back],
            expected,
            "address {addr}: {what}"
        );
    }
}

/// §3.3: CMR reads 0x00 in PeliCAN and 0xFF in BasicCAN, in both modes.
#[test]
fn cmr_reads_0_in_pelican_and_ff_in_basiccan() {
    for (mut chip, expected) in [(peli_reset(0), 0x00), (Sja1000::new(), 0xFF)] {
        assert_eq!(chip.read(CMR), expected, "reset mode");
        chip.write(0, 0x00);
        assert_eq!(chip.read(CMR), expected, "operating mode");
    }
}

/// §4: the BasicCAN map, rows as in [`peli_access_table`].
#[test]
fn basic_access_table() {
    #[rustfmt::skip]
    let rows: &[(u8, &str, [u8; 3])] = &[
        (1, "CMR reads 0xFF", [0xFF, 0xFF, 0xFF]),
        (2, "SR read-only", [0x0C, 0x0C, 0x0C]),
        (3, "IR read-only, bits 7..5 read 1", [0xE0, 0xE0, 0xE0]),
        (4, "ACR: reset R/W, 0xFF when operating", [0x5A, 0xFF, 0x5A]),
        (5, "AMR: reset R/W, 0xFF when operating", [0x5A, 0xFF, 0x5A]),
        (6, "BTR0: reset R/W, 0xFF when operating", [0x5A, 0xFF, 0x5A]),
        (7, "BTR1: reset R/W, 0xFF when operating", [0x5A, 0xFF, 0x5A]),
        (8, "OCR: reset R/W, 0xFF when operating", [0x5A, 0xFF, 0x5A]),
        (10, "TX buffer: 0xFF in reset, R/W when operating", [0xFF, 0xA5, 0xFF]),
        (19, "TX buffer: 0xFF in reset, R/W when operating", [0xFF, 0xA5, 0xFF]),
        (20, "RX buffer read-only", [0x00, 0x00, 0x00]),
        (29, "RX buffer read-only", [0x00, 0x00, 0x00]),
        (30, "unused (decision: 0xFF)", [0xFF, 0xFF, 0xFF]),
    ];
    for &(addr, what, expected) in rows {
        let mut chip = Sja1000::new();
        chip.write(addr, 0x5A);
        let in_reset = chip.read(addr);
        chip.write(0, 0x00);
        chip.write(addr, 0xA5);
        let operating = chip.read(addr);
        chip.write(0, 0x01);
        let back = chip.read(addr);
        assert_eq!(
            [in_reset, operating, back],
            expected,
            "address {addr}: {what}"
        );
    }
}

/// §3.1: MOD bits 7..5 are reserved and read 0.
#[test]
fn mod_reserved_bits_read_0() {
    let mut chip = peli_reset(0);
    chip.write(MOD, 0xE1 | MOD_AFM);
    assert_eq!(chip.read(MOD), MOD_RM | MOD_AFM);
}

/// §3.2: CR bit 5 reads 1, bit 6 reads back what was written, bit 7 reads 0; the enables
/// (bits 4..1) are readable in both modes.
#[test]
fn basic_cr_bits() {
    let mut chip = Sja1000::new();
    chip.write(0, 0xFF);
    assert_eq!(chip.read(0), 0x7F);
    chip.write(0, 0x40 | 0x1E); // operating, bit 6 and all enables
    assert_eq!(chip.read(0), 0x7E);
    chip.write(0, 0x00);
    assert_eq!(chip.read(0), 0x20);
}

/// §3.8, §7: CDR bit 4 reads 0; a software reset keeps CDR.
#[test]
fn cdr_bit_4_reads_0_and_software_reset_keeps_cdr() {
    let mut chip = Sja1000::new();
    chip.write(CDR, 0xFF);
    assert_eq!(chip.read(CDR), 0xEF);
    chip.write(MOD, 0x00);
    chip.write(MOD, MOD_RM);
    assert_eq!(chip.read(CDR), 0xEF);
}

// ------------------------------------------------------------------ §3.5, §5: interrupts

/// §3.5: reading IR clears every bit except RI; RI stays while the FIFO holds a message, RRB
/// clears it with the last one.
#[test]
fn peli_ir_read_keeps_ri_while_the_fifo_holds_messages() {
    let mut bus = self_test_chip(RI | TI);
    send(&mut bus, 0, "100#01", SRR);
    send(&mut bus, 0, "101#02", SRR);
    let chip = &mut bus.chips[0];
    assert_eq!(chip.read(RMC), 2);
    assert_eq!(chip.read(IR), RI | TI);
    assert_eq!(chip.read(IR), RI, "TI cleared by the read, RI kept");
    chip.write(CMR, RRB);
    assert_eq!(chip.read(IR), RI, "one message left");
    chip.write(CMR, RRB);
    assert_eq!(chip.read(IR), 0);
    assert!(!chip.interrupt());
}

/// §3.5: clearing RIE drops RI (and INT) at once; setting it again shows RI while the FIFO
/// holds a message (RI mirrors RBS in PeliCAN).
#[test]
fn peli_ri_follows_rie() {
    let mut bus = self_test_chip(RI);
    send(&mut bus, 0, "100#01", SRR);
    let chip = &mut bus.chips[0];
    assert!(chip.interrupt());
    chip.write(IER, 0);
    assert!(!chip.interrupt());
    assert_eq!(chip.read(IR), 0);
    chip.write(IER, RI);
    assert_eq!(chip.read(IR), RI);
}

/// §3.5: BasicCAN: reading IR clears RI too; RRB raises it again while a message remains.
#[test]
fn basic_ir_read_clears_ri_and_rrb_raises_it_again() {
    let mut bus = integrated(vec![peli(0, 0), basic(0x02)]); // RIE
    send(&mut bus, 0, "100#01", TR);
    send(&mut bus, 0, "101#02", TR);
    let rx = &mut bus.chips[1];
    assert_eq!(rx.read(SR) & SR_RBS, SR_RBS);
    assert!(rx.interrupt());
    assert_eq!(rx.read(IR), 0xE0 | RI);
    assert_eq!(rx.read(IR), 0xE0, "RI cleared by the read");
    assert!(!rx.interrupt());
    assert_eq!(window(rx, 3), [0x20, 0x01, 0x01]);
    rx.write(CMR, RRB);
    assert_eq!(rx.read(IR), 0xE0 | RI, "raised again: a message remains");
    assert_eq!(window(rx, 3), [0x20, 0x21, 0x02]);
    rx.write(CMR, RRB);
    assert_eq!(rx.read(IR), 0xE0);
    assert_eq!(rx.read(SR) & SR_RBS, 0);
}

/// A lone node (nobody ACKs) retries until error-passive, then the request is aborted:
/// BEI, EI (ES at 96), EPI (passive at 128) and TI (abort) happen. Returns the chip.
fn lone_node_until_passive_then_abort(ier: u8) -> Sja1000 {
    let mut bus = integrated(vec![peli(ier, 0)]);
    load_tx(&mut bus.chips[0], "123#AA");
    bus.chips[0].write(CMR, TR);
    bus.run_until(5_000, "error-passive", |bus| {
        bus.chips[0].peek(TXERR) >= 128
    });
    bus.chips[0].write(CMR, AT);
    bus.run_until(500, "abort", |bus| bus.chips[0].peek(SR) & SR_TBS != 0);
    bus.chips.remove(0)
}

/// §3.5: an IR bit is set only if its enable bit is 1 (one run per enable bit).
#[test]
fn interrupt_bits_are_set_only_when_enabled() {
    let happened = BEI | EI | EPI | TI;
    for bit in 0..8 {
        let ier = 1u8 << bit;
        let mut chip = lone_node_until_passive_then_abort(ier);
        assert_eq!(chip.interrupt(), ier & happened != 0, "IER = {ier:#04x}");
        assert_eq!(chip.read(IR), ier & happened, "IER = {ier:#04x}");
    }
    let mut chip = lone_node_until_passive_then_abort(0);
    chip.write(IER, 0xFF);
    assert_eq!(
        chip.read(IR),
        0,
        "enabling later does not raise past events"
    );
}

/// §3.5: BasicCAN enables live in CR: TI only with TIE, RI only with RIE.
#[test]
fn basic_interrupts_need_their_cr_enable() {
    for (cr, expected_tx, expected_rx) in [(0x00, 0xE0, 0xE0), (0x06, 0xE0 | TI, 0xE0 | RI)] {
        let mut bus = integrated(vec![basic(cr), basic(cr)]);
        send(&mut bus, 0, "123#01", TR);
        assert_eq!(bus.chips[0].read(SR) & SR_TCS, SR_TCS);
        assert_eq!(bus.chips[0].read(IR), expected_tx, "CR = {cr:#04x}");
        assert_eq!(bus.chips[1].read(IR), expected_rx, "CR = {cr:#04x}");
    }
}

// ------------------------------------------------------------------ §3.6: EWLR, ES, EI, EPI

/// §3.6: a new EWLR takes effect (ES, EI) only after reset mode is left; ES uses the limit.
#[test]
fn ewlr_takes_effect_after_leaving_reset_mode() {
    let mut chip = peli_reset(EI);
    chip.write(TXERR, 10);
    chip.write(EWLR, 10);
    assert_eq!(chip.read(SR) & SR_ES, 0, "not yet: still in reset mode");
    assert_eq!(chip.read(IR), 0);
    chip.write(MOD, 0x00);
    assert_eq!(chip.read(SR) & SR_ES, SR_ES, "TXERR 10 >= EWLR 10");
    assert_eq!(chip.read(IR), EI);

    let mut chip = peli_reset(EI);
    chip.write(TXERR, 10);
    chip.write(EWLR, 11);
    chip.write(MOD, 0x00);
    assert_eq!(chip.read(SR) & SR_ES, 0, "TXERR 10 < EWLR 11");
    assert_eq!(chip.read(IR), 0);
}

/// §3.5, §8.3: EI when ES is set and again when it is cleared.
#[test]
fn ei_on_es_set_and_on_es_clear() {
    let mut tx = peli_reset(EI);
    tx.write(EWLR, 1);
    tx.write(TXERR, 1);
    tx.write(MOD, 0x00);
    let mut bus = integrated(vec![tx, peli(0, 0)]);
    assert_eq!(bus.chips[0].read(SR) & SR_ES, SR_ES);
    assert_eq!(bus.chips[0].read(IR), EI, "ES set");
    assert_eq!(bus.chips[0].read(IR), 0);
    send(&mut bus, 0, "123#", TR);
    let tx = &mut bus.chips[0];
    assert_eq!(tx.read(TXERR), 0, "a success counts TEC down");
    assert_eq!(tx.read(SR) & SR_ES, 0);
    assert_eq!(tx.read(IR), EI, "ES cleared");
}

/// §3.5, §8.3: EPI on entering error-passive and on returning to error-active.
#[test]
fn epi_on_entering_and_leaving_error_passive() {
    // Chip 1 stays in reset mode (it gives no ACK) until chip 0 is passive.
    let mut bus = integrated(vec![peli(EPI, 0), peli_reset(0)]);
    load_tx(&mut bus.chips[0], "123#AA");
    bus.chips[0].write(CMR, TR);
    bus.run_until(5_000, "error-passive", |bus| {
        bus.chips[0].peek(IR) & EPI != 0
    });
    assert_eq!(bus.chips[0].read(TXERR), 128);
    assert_eq!(bus.chips[0].read(IR), EPI, "entering passive");
    bus.chips[1].write(MOD, 0x00); // now somebody ACKs
    bus.run_until(2_000, "success", |bus| bus.chips[0].peek(SR) & SR_TCS != 0);
    let tx = &mut bus.chips[0];
    assert_eq!(tx.read(TXERR), 127);
    assert_eq!(tx.read(IR), EPI, "back to error-active");
}

// ------------------------------------------------------------------ §3.3, §8.1: overrun, RMC

/// §8.1, §3.5: a PeliCAN FIFO holds at most 21 three-byte messages; the next one sets DOS and
/// DOI; while DOS = 1 no new DOI; CDO clears DOS and re-arms DOI.
#[test]
fn doi_only_when_dos_was_0() {
    let mut bus = self_test_chip(DOI);
    for i in 0..21 {
        send(&mut bus, 0, &format!("{:03X}#", 0x100 + i), SRR);
    }
    assert_eq!(bus.chips[0].read(RMC), 21);
    assert_eq!(bus.chips[0].read(SR) & SR_DOS, 0);
    send(&mut bus, 0, "200#", SRR);
    let chip = &mut bus.chips[0];
    assert_eq!(chip.read(RMC), 21, "the 22nd message was dropped");
    assert_eq!(chip.read(SR) & SR_DOS, SR_DOS);
    assert_eq!(chip.read(IR), DOI);
    send(&mut bus, 0, "201#", SRR);
    assert_eq!(bus.chips[0].read(IR), 0, "DOS still 1: no new DOI");
    bus.chips[0].write(CMR, CDO);
    assert_eq!(bus.chips[0].read(SR) & SR_DOS, 0, "CDO clears DOS");
    send(&mut bus, 0, "202#", SRR);
    assert_eq!(bus.chips[0].read(IR), DOI, "DOI again after CDO");
    assert_eq!(window(&mut bus.chips[0], 3), [0x00, 0x20, 0x00]);
}

/// §8.1: RRB with an empty FIFO changes nothing.
#[test]
fn rrb_on_an_empty_fifo_has_no_effect() {
    let mut bus = self_test_chip(0);
    send(&mut bus, 0, "100#0102", SRR);
    let chip = &mut bus.chips[0];
    chip.write(CMR, RRB);
    assert_eq!((chip.read(RMC), chip.read(RBSA)), (0, 5));
    chip.write(CMR, RRB);
    assert_eq!((chip.read(RMC), chip.read(RBSA)), (0, 5));
    assert_eq!(chip.read(SR) & SR_RBS, 0);
}

// ------------------------------------------------------------------ §3.3: commands

/// What a lone chip shows 400 bit-times after a command.
#[derive(Clone, Copy)]
struct Outcome {
    tcs: bool,
    received: u8,
    /// `None`: still retrying (TBS 0, TXERR above 8).
    txerr: Option<u8>,
}

/// §3.3, §8.6: command combinations on a lone chip, with and without self-test:
/// (STM, CMR, expected TCS, messages received, TXERR).
#[test]
fn command_combinations() {
    const fn out(tcs: bool, received: u8, txerr: Option<u8>) -> Outcome {
        Outcome {
            tcs,
            received,
            txerr,
        }
    }
    #[rustfmt::skip]
    let rows: &[(bool, u8, &str, Outcome)] = &[
        (true, TR, "TR", out(true, 0, Some(0))),
        (true, SRR, "SRR: self-reception", out(true, 1, Some(0))),
        (true, TR | SRR, "TR+SRR: SRR ignored", out(true, 0, Some(0))),
        (true, SRR | AT, "SRR+AT: single-shot self-reception", out(true, 1, Some(0))),
        (true, TR | AT | SRR, "TR+AT+SRR = TR+AT", out(true, 0, Some(0))),
        (false, TR, "no ACK: retried", out(false, 0, None)),
        (false, TR | AT, "TR+AT: single shot", out(false, 0, Some(8))),
        (false, SRR | AT, "SRR+AT: single shot", out(false, 0, Some(8))),
        (false, TR | AT | SRR, "TR+AT+SRR: single shot", out(false, 0, Some(8))),
    ];
    for (stm, cmd, what, expected) in rows {
        let Outcome {
            tcs,
            received,
            txerr,
        } = *expected;
        let (stm, cmd, what) = (*stm, *cmd, *what);
        let mode = if stm { MOD_STM | MOD_AFM } else { MOD_AFM };
        let mut bus = integrated(vec![peli(0, mode)]);
        load_tx(&mut bus.chips[0], "321#55");
        bus.chips[0].write(CMR, cmd);
        bus.run(400);
        let chip = &mut bus.chips[0];
        let sr = chip.read(SR);
        assert_eq!(sr & SR_TCS != 0, tcs, "{what}: TCS");
        assert_eq!(sr & SR_TBS != 0, txerr.is_some(), "{what}: TBS");
        assert_eq!(chip.read(RMC), received, "{what}: RMC");
        match txerr {
            Some(n) => assert_eq!(chip.read(TXERR), n, "{what}: TXERR"),
            None => assert!(chip.read(TXERR) > 8, "{what}: TXERR"),
        }
    }
}

/// §3.3: a request cannot be withdrawn by writing TR = 0; the frame is still sent.
#[test]
fn tr_cannot_be_withdrawn_by_writing_0() {
    let mut bus = integrated(vec![peli(0, 0), peli(0, 0)]);
    load_tx(&mut bus.chips[0], "123#");
    bus.chips[0].write(CMR, TR);
    bus.chips[0].write(CMR, 0x00);
    assert_eq!(bus.chips[0].read(SR) & SR_TBS, 0);
    bus.run(200);
    assert_eq!(bus.chips[0].read(SR) & SR_TCS, SR_TCS);
    assert_eq!(bus.chips[1].read(RMC), 1);
}

/// §3.3: AT does not stop a frame already on the bus; TI comes when TBS returns to 1 and TCS
/// tells that the frame was sent.
#[test]
fn abort_does_not_stop_a_frame_on_the_bus() {
    let mut bus = integrated(vec![peli(TI, 0), peli(0, 0)]);
    load_tx(&mut bus.chips[0], "123#AABB");
    bus.chips[0].write(CMR, TR);
    bus.run_until(50, "frame start", |bus| bus.chips[0].peek(SR) & SR_TS != 0);
    bus.run(5);
    bus.chips[0].write(CMR, AT);
    assert_eq!(bus.chips[0].read(SR) & SR_TBS, 0, "still sending");
    bus.run(200);
    let tx = &mut bus.chips[0];
    assert_eq!(tx.read(SR) & (SR_TBS | SR_TCS), SR_TBS | SR_TCS);
    assert_eq!(tx.read(IR), TI);
    assert_eq!(bus.chips[1].read(RMC), 1);
}

/// §3.3: AT during a frame that then fails: not retried, TBS 1, TCS 0, TI.
#[test]
fn abort_during_a_failing_frame_stops_the_retries() {
    let mut bus = integrated(vec![peli(TI, 0)]);
    load_tx(&mut bus.chips[0], "123#AABB");
    bus.chips[0].write(CMR, TR);
    bus.run_until(50, "frame start", |bus| bus.chips[0].peek(SR) & SR_TS != 0);
    bus.chips[0].write(CMR, AT);
    bus.run(400);
    let tx = &mut bus.chips[0];
    assert_eq!(tx.read(SR) & (SR_TBS | SR_TCS), SR_TBS);
    assert_eq!(tx.read(TXERR), 8, "one ACK error, no retry");
    assert_eq!(tx.read(IR), TI);
}

/// §3.3, regression (the manager's rare `Timeout` instead of `Aborted`): the aborted frame is
/// dropped at its error, TBS returns to 1 while the chip still sends its error frame (TS 1); a
/// frame loaded and requested then has not started, so an AT right away releases it at once.
/// It used to be taken for a frame on the bus: withdrawn, yet TBS stayed 0 forever.
#[test]
fn abort_of_a_frame_requested_during_the_error_frame_of_an_aborted_one_releases_it() {
    let mut bus = integrated(vec![peli(TI, 0)]);
    load_tx(&mut bus.chips[0], "100#");
    bus.chips[0].write(CMR, TR);
    bus.run_until(50, "frame start", |bus| bus.chips[0].peek(SR) & SR_TS != 0);
    bus.chips[0].write(CMR, AT);
    bus.run_until(200, "the aborted frame's release", |bus| {
        bus.chips[0].peek(SR) & SR_TBS != 0
    });
    let tx = &mut bus.chips[0];
    assert_eq!(tx.read(SR) & SR_TS, SR_TS, "still in our error frame");
    assert_eq!(tx.read(IR), TI);
    load_tx(tx, "101#");
    tx.write(CMR, TR);
    assert_eq!(tx.read(SR) & SR_TBS, 0, "requested");
    tx.write(CMR, AT);
    assert_eq!(tx.read(SR) & (SR_TBS | SR_TCS), SR_TBS, "released unsent");
    assert_eq!(tx.read(IR), TI);
    bus.run(400);
    let tx = &mut bus.chips[0];
    assert_eq!(tx.read(TXERR), 8, "the second frame never went on the bus");
    assert_eq!(tx.read(SR) & (SR_TBS | SR_TS), SR_TBS);
}

/// §3.4: TS while transmitting, RS while receiving, both 0 on an idle bus.
#[test]
fn sr_shows_transmitting_and_receiving() {
    let mut bus = integrated(vec![peli(0, 0), peli(0, 0)]);
    assert_eq!(bus.chips[0].read(SR) & (SR_RS | SR_TS), 0);
    load_tx(&mut bus.chips[0], "123#AABB");
    bus.chips[0].write(CMR, TR);
    bus.run(10);
    assert_eq!(bus.chips[0].read(SR) & (SR_RS | SR_TS), SR_TS);
    assert_eq!(bus.chips[1].read(SR) & (SR_RS | SR_TS), SR_RS);
    bus.run(200);
    assert_eq!(bus.chips[0].read(SR) & (SR_RS | SR_TS), 0);
    assert_eq!(bus.chips[1].read(SR) & (SR_RS | SR_TS), 0);
}

// ------------------------------------------------------------------ §3.6: ALC, ECC

/// §3.6: ALC gives the bit position where arbitration was lost.
#[test]
fn alc_positions() {
    #[rustfmt::skip]
    let rows: &[(&str, &str, u8, &str)] = &[
        ("400#", "000#", 0, "ID.28 (first ID bit)"),
        ("123#", "122#", 10, "ID.18 (last SFF ID bit)"),
        ("123#R", "123#", 11, "SRTR: remote loses to data"),
        ("048C0000#", "123#", 11, "SRR of an extended frame against the SFF RTR"),
        ("048C0000#", "123#R", 12, "IDE: extended loses to a standard remote frame"),
        ("048E0000#", "048C0000#", 13, "ID.17"),
        ("048C0001#", "048C0000#", 30, "ID.0"),
        ("048C0000#R", "048C0000#", 31, "RTR of an extended frame"),
    ];
    for &(loser, winner, alc, what) in rows {
        let mut bus = integrated(vec![peli(ALI, 0), peli(0, 0)]);
        load_tx(&mut bus.chips[0], loser);
        load_tx(&mut bus.chips[1], winner);
        bus.chips[0].write(CMR, TR);
        bus.chips[1].write(CMR, TR);
        bus.run(60);
        let chip = &mut bus.chips[0];
        assert_eq!(chip.read(IR), ALI, "{what}");
        assert_eq!(chip.read(ALC), alc, "{what}");
    }
}

/// §3.6: ALC is frozen after a capture and no new ALI comes until ALC has been read.
#[test]
fn no_new_ali_until_alc_is_read() {
    let mut bus = integrated(vec![peli(ALI, 0), peli(0, 0)]);
    let round = |bus: &mut Bus, loser: &str, winner: &str| {
        load_tx(&mut bus.chips[0], loser);
        load_tx(&mut bus.chips[1], winner);
        bus.chips[0].write(CMR, TR);
        bus.chips[1].write(CMR, TR);
        bus.run_until(1_000, "both sent", |bus| {
            bus.chips.iter().all(|c| c.peek(SR) & SR_TBS != 0)
        });
        bus.run(4);
    };
    round(&mut bus, "123#", "122#");
    assert_eq!(bus.chips[0].read(IR), ALI);
    round(&mut bus, "100#", "0FF#"); // would be captured at bit 2
    assert_eq!(bus.chips[0].read(IR), 0, "ALC not read: no ALI");
    assert_eq!(bus.chips[0].read(ALC), 10, "first capture kept");
    assert_eq!(
        bus.chips[0].read(ALC),
        10,
        "reading does not clear it (decision)"
    );
    round(&mut bus, "100#", "0FF#");
    assert_eq!(bus.chips[0].read(IR), ALI);
    assert_eq!(bus.chips[0].read(ALC), 2, "captured again after the read");
}

/// §3.6, §3.5: ECC for a missing ACK; ECC frozen and no new BEI until ECC has been read.
#[test]
fn no_new_bei_until_ecc_is_read() {
    let mut bus = integrated(vec![peli(BEI, 0)]);
    load_tx(&mut bus.chips[0], "7FF#FF");
    bus.chips[0].write(CMR, TR);
    bus.run_until(200, "first error", |bus| bus.chips[0].peek(IR) & BEI != 0);
    assert_eq!(bus.chips[0].read(IR), BEI);
    // Next attempt: a disturber forces a data bit (recessive: 0xFF) dominant, a bit error.
    bus.run_until(200, "error frame end", |bus| {
        bus.chips[0].peek(SR) & SR_TS == 0
    });
    bus.run_until(200, "next SOF", |bus| bus.chips[0].peek(SR) & SR_TS != 0);
    let sof = bus.time - 1;
    for _ in 0..40 {
        bus.step_with(|time, level| {
            if time == sof + 23 {
                Level::Dominant
            } else {
                level
            }
        });
    }
    assert_eq!(bus.chips[0].read(TXERR), 16, "a second error happened");
    assert_eq!(bus.chips[0].read(IR), 0, "ECC not read: no BEI");
    assert_eq!(
        bus.chips[0].read(ECC),
        0xC0 | 0x19,
        "first capture kept: other error, TX, ACK slot"
    );
    bus.run_until(200, "third error", |bus| bus.chips[0].peek(IR) & BEI != 0);
    assert_eq!(bus.chips[0].read(ECC), 0xD9, "ACK error captured again");
}

// ------------------------------------------------------------------ §3.6, §8.4: bus-off

/// A PeliCAN chip on a bus, put into a CPU-forced bus-off (TXERR 255, then RM cleared).
fn forced_bus_off(ier: u8) -> Bus {
    let mut chip = peli_reset(ier);
    chip.write(TXERR, 255);
    chip.write(MOD, 0x00);
    integrated(vec![chip, peli(0, 0)])
}

/// §8.4: writing TXERR 255 forces a bus-off when reset mode is left.
#[test]
fn txerr_255_forces_bus_off_when_reset_mode_is_left() {
    let mut chip = peli_reset(EI);
    chip.write(RXERR, 5);
    chip.write(TXERR, 255);
    assert_eq!(chip.read(SR) & SR_BS, 0, "not before RM is cleared");
    chip.write(MOD, 0x00);
    assert_eq!(chip.read(MOD) & MOD_RM, MOD_RM, "back in reset mode");
    assert_eq!(chip.read(SR) & (SR_BS | SR_ES), SR_BS | SR_ES);
    assert_eq!((chip.read(TXERR), chip.read(RXERR)), (127, 0));
    assert_eq!(chip.read(IR), EI);
}

/// §8.4: after a bus-off the chip comes back 128 × 11 recessive bits after RM is cleared,
/// counting TXERR down on the way; then BS = ES = 0, counters 0, EI.
#[test]
fn bus_off_recovery_counts_txerr_down() {
    let mut bus = forced_bus_off(EI);
    assert_eq!(bus.chips[0].read(IR), EI);
    bus.chips[0].write(MOD, 0x00);
    assert_eq!(bus.chips[0].read(SR) & SR_BS, SR_BS);
    bus.run(64 * 11);
    let txerr = bus.chips[0].read(TXERR);
    assert!((60..=66).contains(&txerr), "TXERR shows progress: {txerr}");
    assert_eq!(bus.chips[0].read(SR) & SR_BS, SR_BS);
    bus.run(64 * 11 + 2);
    let chip = &mut bus.chips[0];
    assert_eq!(chip.read(SR) & (SR_BS | SR_ES), 0, "recovered");
    assert_eq!((chip.read(TXERR), chip.read(RXERR)), (0, 0));
    assert_eq!(chip.read(IR), EI);
    send(&mut bus, 0, "123#", TR);
    assert_eq!(bus.chips[0].read(SR) & SR_TCS, SR_TCS, "can send again");
}

/// §8.4: re-entering reset mode before recovery ends keeps bus-off and freezes TXERR.
#[test]
fn reset_mode_during_recovery_freezes_txerr() {
    let mut bus = forced_bus_off(0);
    bus.chips[0].write(MOD, 0x00);
    bus.run(20 * 11);
    bus.chips[0].write(MOD, MOD_RM);
    let frozen = bus.chips[0].read(TXERR);
    assert!(frozen < 127, "recovery started: {frozen}");
    bus.run(200 * 11);
    assert_eq!(bus.chips[0].read(TXERR), frozen);
    assert_eq!(bus.chips[0].read(SR) & SR_BS, SR_BS);
}

/// §3.6: while bus-off, writes to RXERR have no effect.
#[test]
fn rxerr_writes_are_ignored_while_bus_off() {
    let mut bus = forced_bus_off(0);
    bus.chips[0].write(RXERR, 50);
    assert_eq!(bus.chips[0].read(RXERR), 0);
}

/// §8.4: writing TXERR 0..254 while bus-off ends bus-off at once; after RM is cleared only
/// one bus-free (11 recessive bits) is waited.
#[test]
fn txerr_below_255_while_bus_off_ends_bus_off_at_once() {
    let mut bus = forced_bus_off(0);
    bus.chips[0].write(TXERR, 0);
    assert_eq!(bus.chips[0].read(SR) & SR_BS, 0);
    bus.chips[0].write(MOD, 0x00);
    load_tx(&mut bus.chips[0], "123#");
    bus.chips[0].write(CMR, TR);
    bus.run(11 + 100);
    assert_eq!(bus.chips[0].read(SR) & SR_TCS, SR_TCS);
    assert_eq!(bus.chips[1].read(RMC), 1);
}

/// §3.6: forced counter values raise ES/EPI only when reset mode is left.
#[test]
fn forced_counters_raise_epi_when_reset_mode_is_left() {
    let mut chip = peli_reset(EPI | EI);
    chip.write(TXERR, 200);
    assert_eq!(chip.read(IR), 0);
    assert_eq!(chip.read(SR) & SR_ES, 0);
    chip.write(MOD, 0x00);
    let mut bus = integrated(vec![chip]);
    let chip = &mut bus.chips[0];
    assert_eq!(chip.read(SR) & SR_ES, SR_ES);
    assert_eq!(chip.read(IR), EI | EPI);
}

// ------------------------------------------------------------------ §8.7: sleep

/// §8.7: sleep is refused (WUI) while an interrupt is pending.
#[test]
fn sleep_is_refused_while_an_interrupt_is_pending() {
    let mut bus = self_test_chip(RI | WUI);
    send(&mut bus, 0, "100#", SRR); // RI pending
    bus.chips[0].write(MOD, MOD_STM | MOD_AFM | MOD_SM);
    assert_eq!(bus.chips[0].read(MOD) & MOD_SM, 0);
    assert_eq!(bus.chips[0].read(IR), RI | WUI);
}

/// §8.7: sleep is refused (WUI) while the bus is busy.
#[test]
fn sleep_is_refused_while_the_bus_is_busy() {
    let mut bus = integrated(vec![peli(0, 0), peli(WUI, 0)]);
    load_tx(&mut bus.chips[0], "123#AABB");
    bus.chips[0].write(CMR, TR);
    bus.run(10);
    bus.chips[1].write(MOD, MOD_SM);
    assert_eq!(bus.chips[1].read(MOD) & MOD_SM, 0);
    assert_eq!(bus.chips[1].read(IR), WUI);
}

/// §8.7: a sleeping chip wakes on a dominant bit (WUI), misses that frame while it integrates
/// (11 recessive bits), then receives again.
#[test]
fn a_dominant_bit_wakes_a_sleeping_chip() {
    // Chip 0 sends, chip 1 acknowledges, chip 2 sleeps.
    let mut bus = integrated(vec![peli(0, 0), peli(0, 0), peli(WUI, 0)]);
    bus.chips[2].write(MOD, MOD_SM);
    assert_eq!(bus.chips[2].read(MOD), MOD_SM, "asleep");
    assert_eq!(bus.chips[2].read(IR), 0);
    bus.run(50);
    assert_eq!(
        bus.chips[2].read(MOD),
        MOD_SM,
        "still asleep on a quiet bus"
    );
    send(&mut bus, 0, "123#01", TR);
    assert_eq!(bus.chips[2].read(MOD) & MOD_SM, 0, "woken");
    assert_eq!(bus.chips[2].read(IR), WUI);
    assert_eq!(
        bus.chips[2].read(RMC),
        0,
        "the waking frame is not received"
    );
    bus.run(12);
    send(&mut bus, 0, "124#02", TR);
    assert_eq!(bus.chips[2].read(RMC), 1);
}

/// §8.7: clearing SM wakes the chip (WUI).
#[test]
fn clearing_sm_wakes_the_chip() {
    let mut bus = integrated(vec![peli(WUI, 0)]);
    bus.chips[0].write(MOD, MOD_SM);
    assert_eq!(bus.chips[0].read(MOD), MOD_SM);
    bus.chips[0].write(MOD, 0x00);
    assert_eq!(bus.chips[0].read(MOD), 0x00);
    assert_eq!(bus.chips[0].read(IR), WUI);
}

/// §3.3, §8.7: BasicCAN sleeps with CMR.GTS and wakes when it is written 0; WUI has no enable
/// bit there.
#[test]
fn basic_go_to_sleep() {
    let mut bus = integrated(vec![basic(0)]);
    let chip = &mut bus.chips[0];
    chip.write(CMR, 0x00);
    assert_eq!(chip.read(IR), 0xE0, "GTS = 0 while awake: no wake-up");
    chip.write(CMR, GTS);
    assert_eq!(chip.read(IR), 0xE0, "asleep, nothing pending");
    chip.write(CMR, 0x00);
    assert_eq!(chip.read(IR), 0xE0 | WUI, "woken");
}

// ------------------------------------------------------------------ §2, §6, §8.1: buffers

/// §2: the TX buffer written through the window reads back at 96..108.
#[test]
fn tx_buffer_reads_back_at_96_to_108() {
    let mut chip = peli(0, 0);
    for k in 0..13 {
        chip.write(16 + k, 0xA0 + k);
    }
    let read: Vec<u8> = (96..109).map(|a| chip.read(a)).collect();
    assert_eq!(read, (0xA0..0xAD).collect::<Vec<u8>>());
    assert_eq!(
        chip.read(16),
        0x00,
        "reads at 16 show the RX window, not the TX buffer"
    );
}

/// §2, §8.1: the FIFO RAM at 32..95 shows received messages at RBSA; writable only in reset
/// mode.
#[test]
fn fifo_ram_shows_received_messages() {
    let mut bus = self_test_chip(0);
    send(&mut bus, 0, "123#AABB", SRR);
    send(&mut bus, 0, "7FF#R", SRR);
    let chip = &mut bus.chips[0];
    let ram: Vec<u8> = (32..40).map(|a| chip.read(a)).collect();
    assert_eq!(ram, [0x02, 0x24, 0x60, 0xAA, 0xBB, 0x40, 0xFF, 0xF0]);
    chip.write(32, 0x77);
    assert_eq!(chip.read(32), 0x02, "not writable in operating mode");
    chip.write(MOD, MOD_RM | MOD_STM | MOD_AFM);
    chip.write(32, 0x77);
    assert_eq!(chip.read(32), 0x77, "writable in reset mode");
}

/// §8.1, §7: a software reset empties the FIFO (RMC 0, RBS 0, DOS 0) and keeps RBSA; the
/// next message is stored from there.
#[test]
fn software_reset_empties_the_fifo_and_keeps_rbsa() {
    let mut bus = self_test_chip(0);
    for i in 0..22 {
        send(&mut bus, 0, &format!("{:03X}#", 0x100 + i), SRR); // the 22nd overruns
    }
    bus.chips[0].write(CMR, RRB);
    let chip = &mut bus.chips[0];
    assert_eq!((chip.read(RMC), chip.read(RBSA)), (20, 3));
    assert_eq!(chip.read(SR) & (SR_RBS | SR_DOS), SR_RBS | SR_DOS);
    chip.write(MOD, MOD_RM | MOD_STM | MOD_AFM);
    assert_eq!((chip.read(RMC), chip.read(RBSA)), (0, 3));
    assert_eq!(chip.read(SR) & (SR_RBS | SR_DOS), 0);
    chip.write(MOD, MOD_STM | MOD_AFM);
    bus.run(12);
    send(&mut bus, 0, "555#", SRR);
    let chip = &mut bus.chips[0];
    assert_eq!((chip.read(RMC), chip.read(RBSA)), (1, 3));
    assert_eq!(window(chip, 3), [0x00, 0xAA, 0xA0]);
    assert_eq!((chip.read(32 + 3), chip.read(32 + 4)), (0x00, 0xAA));
}

/// §8.1: the window shows FIFO bytes from the current message on, running into the next one;
/// remote frames store no data bytes; RX ID2/ID4 carry the RTR copy.
#[test]
fn rx_window_runs_into_the_next_message() {
    let mut bus = self_test_chip(0);
    send(&mut bus, 0, "123#R4", SRR);
    send(&mut bus, 0, "02468ACE#R2", SRR);
    send(&mut bus, 0, "456#01", SRR);
    let chip = &mut bus.chips[0];
    assert_eq!(
        window(chip, 13),
        [
            0x44, 0x24, 0x70, 0xC2, 0x12, 0x34, 0x56, 0x74, 0x01, 0x8A, 0xC0, 0x01, 0x00
        ],
        "SFF remote (3 bytes), EFF remote (5 bytes), then the next SFF message"
    );
    chip.write(CMR, RRB);
    assert_eq!(chip.read(RBSA), 3);
    chip.write(CMR, RRB);
    assert_eq!(chip.read(RBSA), 8);
    assert_eq!(window(chip, 4), [0x01, 0x8A, 0xC0, 0x01]);
}

/// §6.1 (decision): DLC 9..15 written to the TX buffer goes out as DLC 8 with 8 data bytes.
#[test]
fn dlc_above_8_in_the_tx_buffer() {
    let mut bus = self_test_chip(0);
    let chip = &mut bus.chips[0];
    chip.write(16, 0x0C); // SFF data, DLC 12
    chip.write(17, 0x24);
    chip.write(18, 0x60);
    for k in 0..8 {
        chip.write(19 + k, k + 1);
    }
    chip.write(CMR, SRR);
    bus.run(200);
    let chip = &mut bus.chips[0];
    assert_eq!(chip.read(SR) & SR_TCS, SR_TCS);
    assert_eq!(window(chip, 11), [0x08, 0x24, 0x60, 1, 2, 3, 4, 5, 6, 7, 8]);
}

// ------------------------------------------------------------------ §4, §8.2: BasicCAN RX

/// §4: BasicCAN does not store extended frames (CAN 2.0B passive) but still ACKs them.
#[test]
fn basic_can_does_not_store_extended_frames() {
    let mut bus = integrated(vec![peli(0, 0), basic(0)]);
    send(&mut bus, 0, "12345678#01", TR);
    assert_eq!(bus.chips[0].read(SR) & SR_TCS, SR_TCS, "acknowledged");
    assert_eq!(bus.chips[1].read(SR) & SR_RBS, 0, "not stored");
    send(&mut bus, 0, "123#01", TR);
    assert_eq!(window(&mut bus.chips[1], 3), [0x24, 0x61, 0x01]);
}

/// §8.2: the BasicCAN filter compares ID bits 10..3 with ACR where AMR is 0.
#[test]
fn basic_can_filter() {
    let mut rx = Sja1000::new();
    rx.write(4, 0x24); // ACR: IDs 0x120..0x127
    rx.write(5, 0x00); // AMR: compare all 8 bits
    rx.write(0, 0x00);
    let mut bus = integrated(vec![peli(0, 0), rx]);
    for frame in ["120#01", "128#02", "127#R", "0A0#03"] {
        send(&mut bus, 0, frame, TR);
    }
    let rx = &mut bus.chips[1];
    assert_eq!(window(rx, 3), [0x24, 0x01, 0x01]);
    rx.write(CMR, RRB);
    assert_eq!(window(rx, 2), [0x24, 0xF0]);
    rx.write(CMR, RRB);
    assert_eq!(rx.read(SR) & SR_RBS, 0, "0x128 and 0x0A0 were filtered out");
}

// ------------------------------------------------------------------ more §3, §7, §8 rules

/// §8.4 (decision): ending bus-off by writing TXERR 0..254 changes BS, so it raises EI at
/// once; leaving reset mode then clears ES (EI again).
#[test]
fn fast_restart_raises_ei() {
    let mut bus = forced_bus_off(EI);
    let chip = &mut bus.chips[0];
    assert_eq!(chip.read(IR), EI, "bus-off");
    chip.write(TXERR, 0);
    assert_eq!(chip.read(IR), EI, "BS cleared");
    assert_eq!(
        chip.read(SR) & (SR_BS | SR_ES),
        SR_ES,
        "ES kept until reset mode is left"
    );
    chip.write(MOD, 0x00);
    assert_eq!(chip.read(SR) & SR_ES, 0);
    assert_eq!(chip.read(IR), EI, "ES cleared");
}

/// §8.4: a bus-off reached by bit errors shows TXERR 127 counting down once reset mode is
/// left (not the protocol controller's TEC above 255).
#[test]
fn real_bus_off_recovery_counts_txerr_down_from_127() {
    let mut bus = integrated(vec![peli(0, 0), peli(0, 0)]);
    load_tx(&mut bus.chips[0], "123#FF");
    bus.chips[0].write(CMR, TR);
    // Every attempt, a disturber forces a recessive data bit dominant (a bit error).
    let (mut was_transmitting, mut sof) = (false, 0);
    for _ in 0..20_000 {
        let transmitting = bus.chips[0].peek(SR) & SR_TS != 0;
        if transmitting && !was_transmitting {
            sof = bus.time - 1;
        }
        was_transmitting = transmitting;
        bus.step_with(|t, level| {
            if transmitting && t == sof + 20 {
                Level::Dominant
            } else {
                level
            }
        });
        if bus.chips[0].peek(SR) & SR_BS != 0 {
            break;
        }
    }
    assert_eq!(bus.chips[0].read(SR) & SR_BS, SR_BS, "bus-off");
    assert_eq!(bus.chips[0].read(TXERR), 127);
    bus.chips[0].write(MOD, 0x00);
    // The other node may still be finishing its error frame: wait for the first bus-free.
    bus.run_until(40, "the first bus-free", |bus| {
        bus.chips[0].peek(TXERR) == 126
    });
    bus.run(100 * 11);
    assert_eq!(bus.chips[0].read(TXERR), 26);
}

/// §3.1, §7: after RM is cleared the chip takes part only after 11 recessive bits.
#[test]
fn leaving_reset_mode_waits_for_bus_free() {
    let mut bus = integrated(vec![peli_reset(0), peli(0, 0)]);
    bus.chips[0].write(MOD, 0x00);
    load_tx(&mut bus.chips[0], "123#");
    bus.chips[0].write(CMR, TR);
    for bit in 0..11 {
        assert_eq!(bus.chips[0].output(), Level::Recessive, "bit {bit}");
        bus.run(1);
    }
    assert_eq!(
        bus.chips[0].output(),
        Level::Dominant,
        "SOF after the bus-free"
    );
}

/// §3.1, §8.6: a listen-only chip gives no ACK, and its error counters stay frozen.
#[test]
fn listen_only_counters_are_frozen() {
    let mut bus = integrated(vec![peli(0, 0), peli(0, 0x02)]); // chip 1: LOM
    load_tx(&mut bus.chips[0], "123#AA");
    bus.chips[0].write(CMR, TR);
    bus.run(300);
    assert!(
        bus.chips[0].read(TXERR) >= 16,
        "no ACK: the sender keeps failing"
    );
    let lom = &mut bus.chips[1];
    assert_eq!((lom.read(RXERR), lom.read(TXERR)), (0, 0));
    assert_eq!(lom.read(RMC), 0, "the frame never completed");
}

/// §3.6: ECC bit 5 (DIR) is 0 for an error while transmitting and 1 while receiving.
#[test]
fn ecc_direction_bit() {
    let mut bus = integrated(vec![peli(BEI, 0), peli(BEI, 0)]);
    load_tx(&mut bus.chips[0], "123#FF");
    bus.chips[0].write(CMR, TR);
    bus.run_until(50, "SOF", |bus| bus.chips[0].peek(SR) & SR_TS != 0);
    let sof = bus.time - 1;
    for _ in 0..60 {
        bus.step_with(|t, level| {
            if t == sof + 20 {
                Level::Dominant
            } else {
                level
            }
        });
    }
    let tx = bus.chips[0].read(ECC);
    let rx = bus.chips[1].read(ECC);
    assert_eq!(bus.chips[1].read(IR), BEI, "the receiver saw an error too");
    assert_eq!(tx & 0x20, 0x00, "transmitter: ECC = {tx:#04x}");
    assert_eq!(rx & 0x20, 0x20, "receiver: ECC = {rx:#04x}");
    assert_eq!(bus.chips[1].read(RXERR), 1, "receiver REC +1");
}

/// §7: a software reset aborts the pending request (TBS 1, nothing sent later), leaves the
/// error counters alone and clears SM.
#[test]
fn software_reset_aborts_the_request_and_keeps_the_counters() {
    let mut bus = integrated(vec![peli(0, 0)]);
    load_tx(&mut bus.chips[0], "123#");
    bus.chips[0].write(CMR, TR);
    bus.run_until(500, "two failed attempts", |bus| {
        bus.chips[0].peek(TXERR) == 16
    });
    bus.chips[0].write(MOD, MOD_RM);
    assert_eq!(bus.chips[0].read(SR) & SR_TBS, SR_TBS, "TX buffer released");
    assert_eq!(bus.chips[0].read(TXERR), 16, "counter kept in reset mode");
    bus.chips[0].write(MOD, 0x00);
    for _ in 0..300 {
        assert_eq!(
            bus.chips[0].output(),
            Level::Recessive,
            "the request is gone"
        );
        bus.run(1);
    }
    assert_eq!(
        bus.chips[0].read(TXERR),
        16,
        "counter kept after reset mode"
    );
    bus.chips[0].write(MOD, MOD_SM);
    assert_eq!(bus.chips[0].read(MOD), MOD_SM, "asleep");
    bus.chips[0].write(MOD, MOD_SM | MOD_RM);
    assert_eq!(bus.chips[0].read(MOD), MOD_RM, "software reset clears SM");
}

/// §8.1: a BasicCAN FIFO holds 32 two-byte remote frames; the 33rd sets DOS and DOI (OIE).
#[test]
fn basic_fifo_holds_32_remote_frames() {
    let mut bus = integrated(vec![peli(0, 0), basic(0x10)]); // OIE
    for i in 0..33 {
        send(&mut bus, 0, &format!("{:03X}#R", 0x100 + i), TR);
    }
    let rx = &mut bus.chips[1];
    assert_eq!(rx.read(SR) & SR_DOS, SR_DOS);
    assert_eq!(rx.read(IR), 0xE0 | DOI);
    let mut held = 0;
    while rx.read(SR) & SR_RBS != 0 {
        held += 1;
        rx.write(CMR, RRB);
    }
    assert_eq!(held, 32);
}

/// §8.1: RBSA written in reset mode decides where the next message is stored; the window
/// and the FIFO RAM wrap from RAM address 63 to 0.
#[test]
fn rbsa_places_the_next_message_and_the_fifo_wraps() {
    let mut chip = peli_reset(0);
    chip.write(RBSA, 62);
    chip.write(MOD, MOD_STM | MOD_AFM);
    let mut bus = integrated(vec![chip]);
    send(&mut bus, 0, "123#AABB", SRR);
    let chip = &mut bus.chips[0];
    assert_eq!(chip.read(RBSA), 62);
    assert_eq!(window(chip, 5), [0x02, 0x24, 0x60, 0xAA, 0xBB]);
    let ram: Vec<u8> = [94, 95, 32, 33, 34].iter().map(|&a| chip.read(a)).collect();
    assert_eq!(ram, [0x02, 0x24, 0x60, 0xAA, 0xBB]);
    chip.write(CMR, RRB);
    assert_eq!(chip.read(RBSA), 3, "(62 + 5) mod 64");
}

/// §3.3: CDO may be given together with RRB: both take effect.
#[test]
fn cdo_together_with_rrb() {
    let mut bus = self_test_chip(0);
    for i in 0..22 {
        send(&mut bus, 0, &format!("{:03X}#", 0x100 + i), SRR);
    }
    let chip = &mut bus.chips[0];
    assert_eq!(chip.read(SR) & SR_DOS, SR_DOS);
    chip.write(CMR, RRB | CDO);
    assert_eq!(chip.read(SR) & SR_DOS, 0);
    assert_eq!(chip.read(RMC), 20);
}
