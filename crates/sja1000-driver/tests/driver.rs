//! The SJA1000 driver against register-level chips on a wired-AND bus.

mod common;

use buslab_can::Level;
use buslab_sja1000::Sja1000;
use buslab_sja1000_driver::driver::{ControllerState, DriverError, DriverEvent, TxFailure, TxMode};
use buslab_sja1000_driver::regs::NoChip;
use buslab_sja1000_driver::{
    AcceptanceFilter, CanMode, RegisterAccess, Sja1000Config, Sja1000Driver, Timing,
};
use common::{Bus, Recorder, frame};

fn received(events: &[DriverEvent]) -> Vec<String> {
    events
        .iter()
        .filter_map(|e| match e {
            DriverEvent::Received(f) => Some(f.to_string()),
            _ => None,
        })
        .collect()
}

/// Polls `driver` while stepping the bus until `done` holds for the collected events.
fn run_until<R: RegisterAccess>(
    bus: &mut Bus,
    driver: &mut Sja1000Driver<R>,
    limit: u64,
    done: impl Fn(&[DriverEvent]) -> bool,
) -> Vec<DriverEvent> {
    let mut events = Vec::new();
    for _ in 0..limit {
        events.extend(driver.poll());
        if done(&events) {
            return events;
        }
        bus.run(1);
    }
    panic!("not done within {limit} bit-times; events: {events:?}");
}

#[test]
fn default_config_is_the_seed_init_in_the_seed_order() {
    let mut recorder = Recorder {
        inner: Sja1000::new(),
        writes: Vec::new(),
        reads: Vec::new(),
    };
    let mut driver = Sja1000Driver::new(&mut recorder);
    driver.init(&Sja1000Config::default()).unwrap();
    let chip = &recorder.inner;
    assert_eq!(chip.mode(), CanMode::Peli);
    assert!(!chip.in_reset_mode());
    assert_eq!(
        (chip.peek(6), chip.peek(7)),
        (0x07, 0x4D),
        "the seed's 50 kbit/s"
    );
    assert_eq!(chip.peek(8), 0xDA, "OCR");
    assert_eq!(chip.peek(0), 0x08, "MOD: operating, single filter");
    assert_eq!(chip.peek(4), 0xFF, "IER");
    // The order of the first write to each step's register.
    let first = |addr: u8| {
        recorder
            .writes
            .iter()
            .position(|&(a, _)| a == addr)
            .unwrap_or_else(|| panic!("no write to {addr}"))
    };
    let last_mod = recorder.writes.iter().rposition(|&(a, _)| a == 0).unwrap();
    let order = [
        first(0),
        first(31),
        first(20),
        first(6),
        first(4),
        first(8),
        last_mod,
    ];
    assert!(
        order.is_sorted(),
        "reset, CDR, masks, timing, IER, OCR, normal: {order:?}"
    );
    assert_eq!(recorder.writes[first(0)], (0, 0x01), "reset first");
    assert_eq!(recorder.writes[last_mod], (0, 0x08), "normal mode last");
    assert!(recorder.writes[first(31)].1 & 0x80 != 0, "PeliCAN");
}

/// Seed 002 §4.1.2.1, `sja_init_pelican`: "wrsjai 0x00,INTERRUPT_ENABLE", OCR DBh, MOD 08h.
#[test]
fn seed_pelican_is_the_seeds_init_register_for_register() {
    let mut chip = Sja1000::new();
    let mut driver = Sja1000Driver::new(&mut chip);
    driver.init(&Sja1000Config::seed_pelican()).unwrap();
    assert_eq!(chip.peek(4), 0x00, "IER: the seed polls");
    assert_eq!(chip.peek(8), 0xDB, "OCR");
    assert_eq!((chip.peek(6), chip.peek(7)), (0x07, 0x4D));
    assert_eq!(chip.peek(0), 0x08, "MOD");
    assert_eq!(chip.peek(31) & 0x80, 0x80, "PeliCAN");
}

#[test]
fn a_missing_or_dead_chip_is_reported_not_waited_for() {
    let mut driver = Sja1000Driver::new(NoChip);
    let err = driver.init(&Sja1000Config::default()).unwrap_err();
    assert_eq!(
        err.to_string(),
        "no SJA1000 answers: MOD/CR (address 0) reads 0xFF (nothing drives the data bus)"
    );

    /// A chip stuck in operating mode: MOD reads 0x00 whatever is written.
    struct Stuck(u32);
    impl RegisterAccess for Stuck {
        fn read(&mut self, _: u8) -> u8 {
            self.0 += 1;
            0
        }
        fn write(&mut self, _: u8, _: u8) {}
    }
    let mut driver = Sja1000Driver::new(Stuck(0)).with_max_tries(7);
    let err = driver.init(&Sja1000Config::default()).unwrap_err();
    assert_eq!(
        err.to_string(),
        "the chip did not enter reset mode: MOD reads 0x00 after 7 tries (wrote 0x01)"
    );
    assert_eq!(driver.registers().0, 1 + 7, "probe plus seven tries");
    assert!(matches!(
        driver.send(&frame("123#")),
        Err(DriverError::NotInitialized)
    ));

    /// A data line stuck low: bit 0 of every written byte is lost.
    struct Bit0Stuck(Sja1000);
    impl RegisterAccess for Bit0Stuck {
        fn read(&mut self, addr: u8) -> u8 {
            self.0.read(addr)
        }
        fn write(&mut self, addr: u8, value: u8) {
            // Keep MOD/CR writable so the chip can enter reset mode.
            let value = if addr == 0 { value } else { value & !1 };
            self.0.write(addr, value)
        }
    }
    let mut driver = Sja1000Driver::new(Bit0Stuck(Sja1000::new()));
    let err = driver.init(&Sja1000Config::default()).unwrap_err();
    assert_eq!(
        err.to_string(),
        "BTR0 reads 0x06 after writing 0x07 in reset mode"
    );
}

#[test]
fn basic_and_peli_drivers_exchange_frames() {
    let mut bus = Bus::new(2);
    let mut basic = bus.driver(0, &Sja1000Config::basic_can());
    let mut peli = bus.driver(1, &Sja1000Config::default());
    assert_eq!(bus.chips[0].lock().unwrap().mode(), CanMode::Basic);
    bus.run(20);

    basic.send(&frame("123#DEADBEEF")).unwrap();
    assert!(matches!(
        basic.send(&frame("124#")),
        Err(DriverError::TxBusy)
    ));
    let events = run_until(&mut bus, &mut peli, 400, |e| !received(e).is_empty());
    assert_eq!(received(&events), ["123#DEADBEEF"]);
    let events = run_until(&mut bus, &mut basic, 100, |e| {
        e.iter().any(|e| matches!(e, DriverEvent::TxDone(_)))
    });
    assert!(events.contains(&DriverEvent::TxDone(frame("123#DEADBEEF"))));

    // An extended frame is acknowledged by the BasicCAN chip but not stored ("2.0B passive").
    peli.send(&frame("12345678#01")).unwrap();
    run_until(&mut bus, &mut peli, 400, |e| {
        e.contains(&DriverEvent::TxDone(frame("12345678#01")))
    });
    peli.send(&frame("7FF#R2")).unwrap();
    let events = run_until(&mut bus, &mut basic, 400, |e| !received(e).is_empty());
    assert_eq!(
        received(&events),
        ["7FF#R2"],
        "the extended frame never arrived"
    );

    let err = basic.send(&frame("12345678#01")).unwrap_err();
    assert_eq!(
        err.to_string(),
        "frame 12345678#01 has an extended ID; BasicCAN mode sends 11-bit IDs only"
    );
    assert_eq!(
        basic.send_with(&frame("100#"), TxMode::SelfReception),
        Err(DriverError::SelfReceptionInBasicCan)
    );
    assert_eq!(
        basic.error_registers(),
        None,
        "BasicCAN has no error registers"
    );
    assert_eq!(peli.error_registers().unwrap().txerr, 0);
}

#[test]
fn acceptance_filters_select_frames_in_both_modes() {
    let mut bus = Bus::new(3);
    let mut tx = bus.driver(0, &Sja1000Config::default());
    let mut peli = bus.driver(
        1,
        &Sja1000Config {
            filter: AcceptanceFilter::standard_id(0x123),
            ..Sja1000Config::default()
        },
    );
    let mut basic = bus.driver(
        2,
        &Sja1000Config {
            // ID bits 10..3 = 0x24 → 0x120..0x127.
            filter: AcceptanceFilter::Basic {
                code: 0x24,
                mask: 0x00,
            },
            ..Sja1000Config::basic_can()
        },
    );
    bus.run(20);
    for f in ["122#01", "123#02", "123#R", "128#03", "00000123#04"] {
        tx.send(&frame(f)).unwrap();
        run_until(&mut bus, &mut tx, 400, |e| {
            e.iter().any(|e| matches!(e, DriverEvent::TxDone(_)))
        });
    }
    bus.run(20);
    assert_eq!(received(&peli.poll()), ["123#02", "123#R"]);
    assert_eq!(received(&basic.poll()), ["122#01", "123#02", "123#R"]);
}

#[test]
fn data_overrun_is_reported_once_and_cleared() {
    let mut bus = Bus::new(2);
    let mut tx = bus.driver(0, &Sja1000Config::default());
    let mut rx = bus.driver(1, &Sja1000Config::default());
    bus.run(20);
    for i in 0..7 {
        tx.send(&frame(&format!("{:03X}#1122334455667788", 0x100 + i)))
            .unwrap();
        run_until(&mut bus, &mut tx, 400, |e| {
            e.iter().any(|e| matches!(e, DriverEvent::TxDone(_)))
        });
    }
    bus.run(20);
    let events = rx.poll();
    assert!(events.contains(&DriverEvent::DataOverrun), "{events:?}");
    // Five 11-byte messages fit the 64-byte FIFO; they come in order.
    let ids: Vec<String> = received(&events)
        .iter()
        .map(|f| f[..3].to_string())
        .collect();
    assert_eq!(ids, ["100", "101", "102", "103", "104"]);
    assert!(!rx.status().data_overrun(), "CDO cleared SR.DOS");
    assert!(rx.poll().is_empty());
}

#[test]
fn arbitration_loss_and_bus_errors_are_decoded() {
    let mut bus = Bus::new(2);
    let mut a = bus.driver(0, &Sja1000Config::default());
    let mut b = bus.driver(1, &Sja1000Config::default());
    bus.run(20);
    a.send(&frame("123#")).unwrap();
    b.send(&frame("122#")).unwrap();
    let events = run_until(&mut bus, &mut a, 600, |e| {
        e.iter().any(|e| matches!(e, DriverEvent::TxDone(_)))
    });
    let lost = events
        .iter()
        .find_map(|e| match e {
            DriverEvent::ArbitrationLost(alc) => Some(alc.to_string()),
            _ => None,
        })
        .expect("ALC reported");
    assert_eq!(lost, "arbitration lost at bit 10 (ID.18)");
    assert_eq!(a.error_registers().unwrap().alc.unwrap().bit(), 10);

    // A disturber forces the first data bit of the next frame dominant once.
    b.poll();
    a.send(&frame("123#FF")).unwrap();
    let mut sof = None;
    let mut events = Vec::new();
    for _ in 0..400 {
        if sof.is_none() && bus.chips[0].lock().unwrap().output() == Level::Dominant {
            sof = Some(bus.time);
        }
        let hit = sof.map(|s| s + 20);
        bus.step_with(|t, level| {
            if Some(t) == hit {
                Level::Dominant
            } else {
                level
            }
        });
        events.extend(a.poll());
        if events.iter().any(|e| matches!(e, DriverEvent::TxDone(_))) {
            break;
        }
    }
    let ecc = events
        .iter()
        .find_map(|e| match e {
            DriverEvent::BusError(ecc) => Some(*ecc),
            _ => None,
        })
        .expect("ECC reported");
    assert_eq!(
        ecc.to_string(),
        "bit error during transmission in data field"
    );
    assert!(
        events.contains(&DriverEvent::TxDone(frame("123#FF"))),
        "retried"
    );
    let errors = a.error_registers().unwrap();
    assert_eq!(errors.ecc, Some(ecc));
    assert_eq!(errors.txerr, 8 - 1, "one error (+8), one success (-1)");
}

/// Drives chip 0's transmission of `123#FF` to bus-off: a disturber forces the first data bit
/// of every attempt dominant. Returns the events its driver reported.
fn jam_to_bus_off<R: RegisterAccess>(bus: &mut Bus, tx: &mut Sja1000Driver<R>) -> Vec<DriverEvent> {
    tx.send(&frame("123#FF")).unwrap();
    let mut events = Vec::new();
    let (mut was_transmitting, mut sof) = (false, 0);
    for _ in 0..20_000 {
        let transmitting = bus.chips[0].lock().unwrap().peek(2) & 0x20 != 0;
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
        events.extend(tx.poll());
        if tx.state() == ControllerState::BusOff {
            return events;
        }
    }
    panic!("no bus-off: {events:?}");
}

fn states(events: &[DriverEvent]) -> Vec<ControllerState> {
    events
        .iter()
        .filter_map(|e| match e {
            DriverEvent::StateChanged { to, .. } => Some(*to),
            _ => None,
        })
        .collect()
}

#[test]
fn bus_off_is_reported_and_restart_brings_the_node_back() {
    let mut bus = Bus::new(2);
    let mut tx = bus.driver(0, &Sja1000Config::default());
    let mut rx = bus.driver(1, &Sja1000Config::default());
    bus.run(20);
    let events = jam_to_bus_off(&mut bus, &mut tx);
    assert_eq!(
        states(&events),
        [
            ControllerState::Warning,
            ControllerState::Passive,
            ControllerState::BusOff
        ]
    );
    assert!(events.contains(&DriverEvent::TxFailed {
        frame: frame("123#FF"),
        reason: TxFailure::BusOff
    }));
    assert!(tx.status().bus_off());
    assert_eq!(tx.send(&frame("124#")), Err(DriverError::BusOff));

    // PeliCAN: TXERR := 0 ends bus-off at once (Linux's restart).
    tx.restart().unwrap();
    let events = tx.poll();
    assert!(
        events.contains(&DriverEvent::StateChanged {
            from: ControllerState::BusOff,
            to: ControllerState::Active
        }),
        "{events:?}"
    );
    bus.run(20);
    tx.send(&frame("124#01")).unwrap();
    let events = run_until(&mut bus, &mut rx, 400, |e| !received(e).is_empty());
    assert_eq!(received(&events), ["124#01"]);
    let errors = tx.error_registers().unwrap();
    assert_eq!((errors.txerr, errors.rxerr), (0, 0));
}

/// Seed 002 §5.4.7, the default recovery: reset mode cleared, the chip counts its way back;
/// TXERR falls where the driver can read it, the state goes BusOff → Active at the end only.
#[test]
fn the_default_recovery_lets_the_chip_count_txerr_down() {
    let mut bus = Bus::new(2);
    let mut tx = bus.driver(0, &Sja1000Config::default());
    let mut rx = bus.driver(1, &Sja1000Config::default());
    bus.run(20);
    jam_to_bus_off(&mut bus, &mut tx);
    assert_eq!(tx.error_registers().unwrap().txerr, 127);
    tx.recover().unwrap();
    assert!(!tx.status().bus_off() || tx.state() == ControllerState::BusOff);
    let events = run_until(&mut bus, &mut tx, 128 * 11 + 100, |e| {
        e.iter()
            .any(|e| matches!(e, DriverEvent::StateChanged { .. }))
    });
    assert_eq!(
        states(&events),
        [ControllerState::Active],
        "back only at the end"
    );
    assert_eq!(tx.error_registers().unwrap().txerr, 0);
    tx.send(&frame("124#01")).unwrap();
    let events = run_until(&mut bus, &mut rx, 400, |e| !received(e).is_empty());
    assert_eq!(received(&events), ["124#01"]);
    // TXERR fell by one every 11 recessive bits on the way (the chip test watches each step).
    let mut fast = bus.driver(
        0,
        &Sja1000Config {
            bus_off_recovery: buslab_sja1000_driver::BusOffRecovery::Fast,
            ..Sja1000Config::default()
        },
    );
    bus.run(20);
    jam_to_bus_off(&mut bus, &mut fast);
    fast.recover().unwrap();
    assert_eq!(
        states(&fast.poll()),
        [ControllerState::Active],
        "the fast restart is back at once"
    );
}

#[test]
fn basic_can_restart_waits_for_the_chips_own_recovery() {
    let mut bus = Bus::new(2);
    let mut tx = bus.driver(0, &Sja1000Config::basic_can());
    let mut rx = bus.driver(1, &Sja1000Config::basic_can());
    bus.run(20);
    let events = jam_to_bus_off(&mut bus, &mut tx);
    // BasicCAN cannot read its counters: no passive state, straight from warning to bus-off.
    assert_eq!(
        states(&events),
        [ControllerState::Warning, ControllerState::BusOff]
    );
    tx.restart().unwrap();
    assert!(
        tx.poll().is_empty(),
        "still bus-off: 128 × 11 recessive bits to go"
    );
    bus.run(128 * 11 - 20);
    assert!(tx.poll().is_empty());
    let events = run_until(&mut bus, &mut tx, 200, |e| !e.is_empty());
    assert_eq!(
        events,
        [DriverEvent::StateChanged {
            from: ControllerState::BusOff,
            to: ControllerState::Active
        }]
    );
    tx.send(&frame("124#01")).unwrap();
    let events = run_until(&mut bus, &mut rx, 400, |e| !received(e).is_empty());
    assert_eq!(received(&events), ["124#01"]);
}

#[test]
fn single_shot_and_abort_end_with_a_reason() {
    let mut bus = Bus::new(1); // nobody acknowledges
    let mut tx = bus.driver(0, &Sja1000Config::default());
    bus.run(20);
    tx.send_with(&frame("123#"), TxMode::SingleShot).unwrap();
    let events = run_until(&mut bus, &mut tx, 400, |e| {
        e.iter().any(|e| matches!(e, DriverEvent::TxFailed { .. }))
    });
    assert!(events.contains(&DriverEvent::TxFailed {
        frame: frame("123#"),
        reason: TxFailure::SingleShot
    }));

    tx.send(&frame("124#")).unwrap();
    bus.run(300); // retried again and again without ACK
    assert!(
        tx.poll()
            .iter()
            .all(|e| !matches!(e, DriverEvent::TxFailed { .. }))
    );
    tx.abort();
    let events = run_until(&mut bus, &mut tx, 400, |e| {
        e.iter().any(|e| matches!(e, DriverEvent::TxFailed { .. }))
    });
    assert!(events.contains(&DriverEvent::TxFailed {
        frame: frame("124#"),
        reason: TxFailure::Aborted
    }));
    assert!(!tx.tx_pending());
}

#[test]
fn self_test_with_self_reception_on_a_lone_node() {
    let mut bus = Bus::new(1);
    let config = Sja1000Config {
        self_test: true,
        ..Sja1000Config::default()
    };
    let mut node = bus.driver(0, &config);
    bus.run(20);
    node.send_with(&frame("7FF#0102"), TxMode::SelfReception)
        .unwrap();
    let events = run_until(&mut bus, &mut node, 400, |e| {
        e.iter().any(|e| matches!(e, DriverEvent::TxDone(_)))
    });
    assert_eq!(received(&events), ["7FF#0102"]);
}

#[test]
fn listen_only_refuses_to_send() {
    let bus = Bus::new(1);
    let config = Sja1000Config {
        listen_only: true,
        ..Sja1000Config::default()
    };
    let mut node = bus.driver(0, &config);
    assert_eq!(node.send(&frame("123#")), Err(DriverError::ListenOnly));
    assert_eq!(bus.chips[0].lock().unwrap().peek(0) & 0x02, 0x02, "MOD.LOM");
}

#[test]
fn bitrate_configuration_programs_linux_registers() {
    let bus = Bus::new(1);
    let config = Sja1000Config {
        timing: Timing::Bitrate {
            bitrate: 500_000,
            sample_point_permille: None,
        },
        ..Sja1000Config::default()
    };
    bus.driver(0, &config);
    let chip = bus.chips[0].lock().unwrap();
    assert_eq!((chip.peek(6), chip.peek(7)), (0x00, 0x1C));
}

#[test]
fn register_dump_leaves_the_chip_alone() {
    let mut bus = Bus::new(2);
    let mut a = bus.driver(0, &Sja1000Config::default());
    let mut b = bus.driver(1, &Sja1000Config::default());
    bus.run(20);
    a.send(&frame("123#")).unwrap();
    b.send(&frame("122#")).unwrap();
    bus.run(300);
    // A peeking dump shows IR and ALC and leaves them set.
    let dump = a.register_dump();
    assert_eq!(dump.mode, CanMode::Peli);
    assert_eq!(dump.get(3).map(|ir| ir & 0x40), Some(0x40), "ALI pending");
    assert_eq!(dump.get(11), Some(10), "ALC");
    assert_eq!(dump.get(1), None, "CMR is write-only");
    assert!(dump.to_string().contains("  6 BTR0   07"), "{dump}");
    // Hardware that cannot peek: IR, ALC and ECC are skipped.
    let mut plain = Sja1000Driver::new(Recorder {
        inner: bus.chips[0].clone(),
        writes: Vec::new(),
        reads: Vec::new(),
    });
    let dump = plain.register_dump();
    assert_eq!(
        (dump.get(3), dump.get(11), dump.get(12)),
        (None, None, None)
    );
    assert!(
        !plain
            .registers()
            .reads
            .iter()
            .any(|a| [1, 3, 11, 12].contains(a))
    );
    assert_eq!(dump.get(6), Some(0x07));
    // The capture is still there for the driver.
    assert!(
        a.poll()
            .iter()
            .any(|e| matches!(e, DriverEvent::ArbitrationLost(_)))
    );
}

mod round_trip {
    use super::*;
    use buslab_can::{Frame, Id};
    use proptest::prelude::*;

    fn any_frame() -> impl Strategy<Value = Frame> {
        let id = prop_oneof![
            (0u16..=0x7FF).prop_map(|raw| Id::standard(raw).unwrap()),
            (0u32..=0x1FFF_FFFF).prop_map(|raw| Id::extended(raw).unwrap()),
        ];
        let body = prop_oneof![
            proptest::collection::vec(any::<u8>(), 0..=8).prop_map(Ok),
            (0u8..=8).prop_map(Err),
        ];
        (id, body).prop_map(|(id, body)| match body {
            Ok(data) => Frame::data(id, &data).unwrap(),
            Err(dlc) => Frame::remote(id, dlc).unwrap(),
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Whatever a PeliCAN driver sends, a PeliCAN driver receives unchanged, and a
        /// BasicCAN driver too when the ID is standard.
        #[test]
        fn frames_cross_the_bus_unchanged(frame in any_frame()) {
            let mut bus = Bus::new(3);
            let mut tx = bus.driver(0, &Sja1000Config::default());
            let mut peli = bus.driver(1, &Sja1000Config::default());
            let mut basic = bus.driver(2, &Sja1000Config::basic_can());
            bus.run(20);
            tx.send(&frame).unwrap();
            run_until(&mut bus, &mut tx, 400, |e| e.contains(&DriverEvent::TxDone(frame)));
            bus.run(20);
            prop_assert_eq!(peli.poll(), vec![DriverEvent::Received(frame)]);
            let expected = if frame.is_extended() {
                vec![]
            } else {
                vec![DriverEvent::Received(frame)]
            };
            prop_assert_eq!(basic.poll(), expected);
        }
    }
}
