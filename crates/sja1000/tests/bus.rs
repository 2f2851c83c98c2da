//! SJA1000 chips on a wired-AND bus, programmed only through their registers.

mod support;

use buslab_can::Level;
use buslab_sja1000::Sja1000;
use support::{Bus, load_tx};

const MOD: u8 = 0;
const CMR: u8 = 1;
const SR: u8 = 2;
const IR: u8 = 3;
const IER: u8 = 4;
const ALC: u8 = 11;
const ECC: u8 = 12;
const RXERR: u8 = 14;
const TXERR: u8 = 15;
const RMC: u8 = 29;
const CDR: u8 = 31;

const SR_RBS: u8 = 0x01;
const SR_DOS: u8 = 0x02;
const SR_TBS: u8 = 0x04;
const SR_TCS: u8 = 0x08;
const SR_ES: u8 = 0x40;
const SR_BS: u8 = 0x80;

/// The seed's `sja_init_pelican`: reset → PeliCAN → accept all → 50 kbit/s timing (16 MHz
/// crystal) → interrupts → output control → normal mode with the single filter. Every wait
/// loop polls the register as the PowerPC code does.
fn seed_init(chip: &mut Sja1000, ier: u8, mode: u8) {
    loop {
        chip.write(MOD, 0x01);
        if chip.read(MOD) & 0x01 != 0 {
            break;
        }
    }
    loop {
        chip.write(CDR, 0x80);
        if chip.read(CDR) & 0x80 != 0 {
            break;
        }
    }
    for amr in 20..24 {
        chip.write(amr, 0xFF);
    }
    chip.write(6, 0x07);
    chip.write(7, 0x4D);
    chip.write(IER, ier);
    chip.write(8, 0xDB);
    loop {
        chip.write(MOD, mode);
        if chip.read(MOD) & 0x01 == 0 {
            break;
        }
    }
}

/// `n` PeliCAN chips after the seed's init, on one wire.
fn peli_bus(n: usize, ier: u8) -> Bus {
    Bus::new(
        (0..n)
            .map(|_| {
                let mut chip = Sja1000::new();
                seed_init(&mut chip, ier, 0x08);
                chip
            })
            .collect(),
    )
}

/// Reads the message in the receive window and releases it (the driver's RX path).
fn take_rx(chip: &mut Sja1000) -> Vec<u8> {
    let first = chip.read(16);
    let header = if first & 0x80 != 0 { 5 } else { 3 };
    let data = if first & 0x40 != 0 {
        0
    } else {
        (first & 0x0F).min(8) as usize
    };
    let bytes = (0..header + data)
        .map(|k| chip.read(16 + k as u8))
        .collect();
    chip.write(CMR, 0x04); // RRB
    bytes
}

#[test]
fn seed_init_then_a_frame_crosses_the_bus() {
    let mut bus = peli_bus(2, 0x03); // RIE, TIE
    load_tx(&mut bus.chips[0], "123#AABB");
    bus.chips[0].write(CMR, 0x01);
    bus.run_until(300, "reception", |bus| bus.chips[1].read(SR) & SR_RBS != 0);
    bus.run(20);
    let tx = &mut bus.chips[0];
    assert_eq!(tx.read(SR) & (SR_TBS | SR_TCS), SR_TBS | SR_TCS);
    assert_eq!(tx.read(IR) & 0x02, 0x02, "TI");
    let rx = &mut bus.chips[1];
    assert!(rx.interrupt());
    assert_eq!(rx.read(RMC), 1);
    assert_eq!(rx.read(IR) & 0x01, 0x01, "RI");
    assert_eq!(take_rx(rx), [0x02, 0x24, 0x60, 0xAA, 0xBB]);
    assert_eq!(rx.read(RMC), 0);
    assert_eq!(rx.read(SR) & SR_RBS, 0);
    assert!(!rx.interrupt(), "RI goes away with the last message");
}

#[test]
fn fifo_overflow_keeps_the_first_frames_and_sets_data_overrun() {
    let mut bus = peli_bus(2, 0x08); // DOIE on both
    let frames: Vec<String> = (0..7)
        .map(|i| format!("{:03X}#{}", 0x100 + i, "11".repeat(8)))
        .collect();
    for frame in &frames {
        let tx = &mut bus.chips[0];
        load_tx(tx, frame);
        tx.write(CMR, 0x01);
        bus.run_until(400, "transmission", |bus| {
            bus.chips[0].read(SR) & SR_TBS != 0
        });
    }
    bus.run(20);
    let rx = &mut bus.chips[1];
    // 11 bytes per message: five fit in 64 bytes, the sixth and seventh are lost.
    assert_eq!(rx.read(RMC), 5);
    assert_eq!(rx.read(SR) & SR_DOS, SR_DOS);
    assert_eq!(rx.read(IR) & 0x08, 0x08, "DOI");
    for i in 0..5u16 {
        let msg = take_rx(rx);
        let id = (msg[1] as u16) << 3 | (msg[2] >> 5) as u16;
        assert_eq!(id, 0x100 + i, "frames kept in order");
    }
    rx.write(CMR, 0x08); // CDO
    assert_eq!(rx.read(SR) & SR_DOS, 0);
}

#[test]
fn acceptance_filter_drops_frames_before_the_fifo() {
    let mut bus = peli_bus(2, 0);
    let rx = &mut bus.chips[1];
    rx.write(MOD, 0x01);
    // Single filter, exactly 0x123 data frames.
    for (k, v) in [0x24, 0x60, 0, 0, 0x00, 0x0F, 0xFF, 0xFF]
        .into_iter()
        .enumerate()
    {
        rx.write(16 + k as u8, v);
    }
    rx.write(MOD, 0x08);
    for frame in ["122#01", "123#R", "123#02", "00000123#03"] {
        load_tx(&mut bus.chips[0], frame);
        bus.chips[0].write(CMR, 0x01);
        bus.run_until(400, "transmission", |bus| {
            bus.chips[0].read(SR) & SR_TCS != 0
        });
    }
    bus.run(20);
    let rx = &mut bus.chips[1];
    assert_eq!(rx.read(RMC), 1);
    assert_eq!(take_rx(rx), [0x01, 0x24, 0x60, 0x02]);
}

#[test]
fn arbitration_loss_is_captured_in_alc() {
    let mut bus = peli_bus(2, 0x40); // ALIE
    load_tx(&mut bus.chips[0], "123#");
    load_tx(&mut bus.chips[1], "122#");
    bus.chips[0].write(CMR, 0x01);
    bus.chips[1].write(CMR, 0x01);
    bus.run(200);
    let loser = &mut bus.chips[0];
    assert_eq!(loser.read(IR) & 0x40, 0x40, "ALI");
    assert_eq!(loser.read(ALC), 10, "lost at ID.18 (the last SFF ID bit)");
    // The loser retried when the bus was free and succeeded.
    assert_eq!(loser.read(SR) & SR_TCS, SR_TCS);
    assert_eq!(bus.chips[1].read(RMC), 1);
    assert_eq!(bus.chips[0].read(RMC), 1);
}

#[test]
fn a_bit_error_in_the_data_field_is_captured_in_ecc() {
    let mut bus = peli_bus(2, 0x80); // BEIE
    load_tx(&mut bus.chips[0], "123#FF");
    bus.chips[0].write(CMR, 0x01);
    // Find when the frame starts (SOF) and force the first data bit dominant once.
    let mut sof = None;
    for _ in 0..200 {
        let time = bus.time;
        let starting = sof.is_none() && bus.chips[0].output() == Level::Dominant;
        if starting {
            sof = Some(time);
        }
        // SFF data starts at unstuffed bit 19; 0x123 DLC 1 has one stuff bit before it.
        let first_data_bit = sof.map(|s| s + 20);
        bus.step_with(|t, level| {
            if Some(t) == first_data_bit {
                Level::Dominant
            } else {
                level
            }
        });
        if bus.chips[0].peek(IR) & 0x80 != 0 {
            break;
        }
    }
    let tx = &mut bus.chips[0];
    let ecc = tx.read(ECC);
    assert_eq!(ecc >> 6, 0b00, "bit error, ECC = {ecc:#04x}");
    assert_eq!(ecc & 0x20, 0, "during transmission");
    assert_eq!(ecc & 0x1F, 0x0A, "in the data field");
    assert_eq!(tx.read(TXERR), 8);
}

#[test]
fn repeated_bit_errors_drive_the_transmitter_to_bus_off_and_it_recovers() {
    let mut bus = peli_bus(2, 0x04); // EIE
    load_tx(&mut bus.chips[0], "123#FF");
    bus.chips[0].write(CMR, 0x01);
    // Every attempt, a disturber forces the first data bit (recessive) dominant.
    let (mut was_transmitting, mut sof) = (false, 0);
    let mut saw_warning = false;
    for _ in 0..20_000 {
        let transmitting = bus.chips[0].peek(SR) & 0x20 != 0;
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
        saw_warning |= bus.chips[0].peek(SR) & SR_ES != 0;
        if bus.chips[0].peek(SR) & SR_BS != 0 {
            break;
        }
    }
    let tx = &mut bus.chips[0];
    assert!(saw_warning, "ES set on the way");
    assert_eq!(tx.read(SR) & SR_BS, SR_BS, "bus-off");
    assert_eq!(tx.read(MOD) & 0x01, 0x01, "the chip set RM itself");
    assert_eq!((tx.read(TXERR), tx.read(RXERR)), (127, 0));
    assert_eq!(tx.read(IR) & 0x04, 0x04, "EI on bus-off");
    // The CPU leaves reset mode: 128 × 11 recessive bits later the chip is back.
    tx.write(MOD, 0x08);
    bus.run(128 * 11 - 20);
    assert_eq!(bus.chips[0].read(SR) & SR_BS, SR_BS, "still recovering");
    bus.run(200);
    let tx = &mut bus.chips[0];
    assert_eq!(tx.read(SR) & (SR_BS | SR_ES), 0);
    assert_eq!((tx.read(TXERR), tx.read(RXERR)), (0, 0));
    assert_eq!(tx.read(IR) & 0x04, 0x04, "EI on recovery");
    bus.run(300);
    assert_eq!(
        bus.chips[1].read(RMC),
        0,
        "bus-off aborted the frame: it is not sent later"
    );
}

/// Seed 002 §5.4.7: "Si on rebranche alors le bus, le compteur rediminue, mais plus lentement
/// qu'il n'avait augmenté. Lorsqu'il atteint 96, le bit Error Status repasse à OK." Reset mode
/// cleared, the chip counts TXERR down once per 11 recessive bits; ES clears as TXERR passes
/// below the warning limit, BS only at the end.
#[test]
fn during_the_bus_off_recovery_txerr_falls_and_es_clears_below_the_warning_limit() {
    let mut bus = peli_bus(2, 0x04); // EIE
    load_tx(&mut bus.chips[0], "123#FF");
    bus.chips[0].write(CMR, 0x01);
    let (mut was_transmitting, mut sof, mut rising) = (false, 0, Vec::new());
    while bus.chips[0].peek(SR) & SR_BS == 0 {
        let transmitting = bus.chips[0].peek(SR) & 0x20 != 0;
        if transmitting && !was_transmitting {
            sof = bus.time - 1;
            rising.push((bus.time, bus.chips[0].peek(TXERR)));
        }
        was_transmitting = transmitting;
        bus.step_with(|t, level| {
            if transmitting && t == sof + 20 {
                Level::Dominant
            } else {
                level
            }
        });
    }
    let tx = &mut bus.chips[0];
    assert_eq!((tx.read(TXERR), tx.read(SR) & SR_ES), (127, SR_ES));
    tx.read(IR);
    tx.write(MOD, 0x08);
    let mut falling = Vec::new();
    let mut es_cleared_at = None;
    while bus.chips[0].peek(SR) & SR_BS != 0 {
        bus.run(1);
        let tx = &bus.chips[0];
        let txerr = tx.peek(TXERR);
        if falling.last().is_none_or(|&(_, last)| last != txerr) {
            falling.push((bus.time, txerr));
        }
        if es_cleared_at.is_none() && tx.peek(SR) & SR_ES == 0 {
            es_cleared_at = Some(txerr);
            assert_eq!(tx.peek(IR) & 0x04, 0x04, "EI when ES clears");
            assert_eq!(tx.peek(SR) & SR_BS, SR_BS, "still bus-off when ES clears");
        }
    }
    // TXERR falls one by one, visibly: 127, 126, ... down to 0.
    let values: Vec<u8> = falling.iter().map(|&(_, v)| v).collect();
    assert_eq!(values, (0..=127).rev().collect::<Vec<u8>>());
    // ES clears as TXERR passes below EWLR (96): the first value under it.
    assert_eq!(es_cleared_at, Some(95));
    // "Plus lentement qu'il n'avait augmenté": 8 per failed attempt up, 1 per 11 bits down.
    let up_per_bit = 248.0 / (rising.last().unwrap().0 - rising[0].0) as f64;
    let down_per_bit = 127.0 / (falling.last().unwrap().0 - falling[0].0) as f64;
    assert!(down_per_bit < up_per_bit, "{down_per_bit} vs {up_per_bit}");
    assert_eq!(bus.chips[0].peek(SR) & (SR_BS | SR_ES), 0);
}

/// Facts sheet §6.1: "DLC > 8 is transmitted as coded, but at most 8 data bytes are sent".
#[test]
fn a_dlc_of_9_to_15_in_the_tx_buffer_goes_on_the_wire_as_coded() {
    let mut bus = peli_bus(2, 0);
    load_tx(&mut bus.chips[0], "123#0102030405060708");
    bus.chips[0].write(16, 0x0C); // frame info: standard data frame, DLC 12
    bus.chips[0].write(CMR, 0x01);
    // The wire: the wired-AND of what the chips drive, bit-time by bit-time.
    let mut bits = Vec::new();
    for _ in 0..200 {
        let wire = bus
            .chips
            .iter()
            .fold(Level::Recessive, |wire, chip| wire.and(chip.output()));
        bits.push(wire.bit());
        bus.run(1);
    }
    let sof = bits.iter().position(|&b| !b).expect("a frame was sent");
    let decoded = buslab_can::wire::decode(bits[sof..].iter().copied()).unwrap();
    assert_eq!(decoded.dlc, 12);
    assert_eq!(decoded.frame.to_string(), "123#0102030405060708");
    // The receiver takes 8 bytes (its RX buffer shows DLC 8: buslab's frames carry 0..8).
    assert_eq!(bus.chips[0].read(SR) & SR_TCS, SR_TCS);
    assert_eq!(
        take_rx(&mut bus.chips[1]),
        [0x08, 0x24, 0x60, 1, 2, 3, 4, 5, 6, 7, 8]
    );
}

#[test]
fn listen_only_chip_receives_but_never_drives_the_bus() {
    let mut chips: Vec<Sja1000> = (0..3).map(|_| Sja1000::new()).collect();
    seed_init(&mut chips[0], 0, 0x08);
    seed_init(&mut chips[1], 0, 0x08);
    seed_init(&mut chips[2], 0, 0x0A); // LOM
    let mut bus = Bus::new(chips);
    load_tx(&mut bus.chips[0], "321#01");
    bus.chips[0].write(CMR, 0x01);
    for _ in 0..300 {
        assert_eq!(bus.chips[2].output(), Level::Recessive);
        bus.run(1);
    }
    assert_eq!(bus.chips[2].read(RMC), 1);
    load_tx(&mut bus.chips[2], "100#");
    bus.chips[2].write(CMR, 0x01);
    bus.run(200);
    assert_eq!(
        bus.chips[1].read(RMC),
        1,
        "the listen-only chip sent nothing"
    );
}

#[test]
fn self_test_with_self_reception_needs_no_other_node() {
    let mut chip = Sja1000::new();
    seed_init(&mut chip, 0x03, 0x0C); // STM, AFM
    let mut bus = Bus::new(vec![chip]);
    load_tx(&mut bus.chips[0], "7FF#0102");
    bus.chips[0].write(CMR, 0x10); // SRR
    bus.run(200);
    let chip = &mut bus.chips[0];
    assert_eq!(chip.read(SR) & SR_TCS, SR_TCS);
    assert_eq!(chip.read(IR) & 0x03, 0x03, "RI and TI together");
    assert_eq!(take_rx(chip), [0x02, 0xFF, 0xE0, 0x01, 0x02]);
    assert_eq!(chip.read(TXERR), 0);
}

#[test]
fn single_shot_without_ack_tries_once() {
    let mut bus = peli_bus(1, 0x02);
    load_tx(&mut bus.chips[0], "123#");
    bus.chips[0].write(CMR, 0x03); // TR + AT
    bus.run(400);
    let chip = &mut bus.chips[0];
    assert_eq!(
        chip.read(SR) & (SR_TBS | SR_TCS),
        SR_TBS,
        "released, not completed"
    );
    assert_eq!(chip.read(IR) & 0x02, 0x02, "TI");
    assert_eq!(chip.read(TXERR), 8, "one ACK error, no retries");
}
