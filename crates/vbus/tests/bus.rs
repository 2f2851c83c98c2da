//! The virtual bus in virtual time: chips operated through the driver on one wire.

use buslab_can::BitTime;
use buslab_can::Frame;
use buslab_canbus::NodeRef;
use buslab_vbus::VirtualBus;

const RATE: u32 = 500_000;

fn frame(text: &str) -> Frame {
    text.parse().unwrap()
}

fn received(bus: &mut VirtualBus, number: u32) -> Vec<String> {
    let node = bus.client_mut(number).unwrap();
    node.take_deliveries()
        .map(|d| d.frame.to_string())
        .collect()
}

fn status(bus: &mut VirtualBus, number: u32) -> buslab_canbus::NodeStatus {
    bus.status(&NodeRef::Number(number)).unwrap()
}

fn send(bus: &mut VirtualBus, number: u32, text: &str) {
    bus.client_mut(number).unwrap().submit(frame(text)).unwrap();
}

#[test]
fn frames_reach_every_other_node_but_not_the_sender() {
    let mut bus = VirtualBus::new(RATE).unwrap();
    let a = bus.join().unwrap();
    let b = bus.join().unwrap();
    let c = bus.join().unwrap();
    let sent = [
        "123#1122",
        "1ABCDEF0#DEADBEEF",
        "321#R3",
        "7FF#",
        "00000001#R",
    ];
    for f in sent {
        send(&mut bus, a, f);
    }
    bus.run_until(BitTime::new(RATE as u64 / 100));
    assert_eq!(received(&mut bus, b), sent);
    assert_eq!(received(&mut bus, c), sent);
    assert!(received(&mut bus, a).is_empty());
    assert_eq!(status(&mut bus, a).counters.sent, 5);
    assert_eq!(status(&mut bus, b).counters.received, 5);
}

#[test]
fn own_frames_come_back_when_asked() {
    let mut bus = VirtualBus::new(RATE).unwrap();
    let a = bus.join().unwrap();
    let _b = bus.join().unwrap();
    bus.client_mut(a).unwrap().receive_own = true;
    send(&mut bus, a, "123#01");
    bus.run_until(BitTime::new(RATE as u64 / 100));
    assert_eq!(received(&mut bus, a), ["123#01"]);
}

#[test]
fn contending_nodes_go_in_priority_order_and_losers_capture_alc() {
    let mut bus = VirtualBus::new(RATE).unwrap();
    let rx = bus.join().unwrap();
    let senders: Vec<u32> = (0..3).map(|_| bus.join().unwrap()).collect();
    // Queued in the opposite of priority order, all before the bus runs.
    for (&n, f) in senders.iter().zip(["300#03", "200#02", "100#01"]) {
        send(&mut bus, n, f);
    }
    bus.run_until(BitTime::new(RATE as u64 / 100));
    assert_eq!(received(&mut bus, rx), ["100#01", "200#02", "300#03"]);
    // 0x300 lost twice, 0x200 once; 0x100 never.
    assert_eq!(status(&mut bus, senders[0]).counters.arbitration_lost, 2);
    assert_eq!(status(&mut bus, senders[1]).counters.arbitration_lost, 1);
    assert_eq!(status(&mut bus, senders[2]).counters.arbitration_lost, 0);
    // The last loss of 0x300 (011 0000 0000) was against 0x200 (010 ...): bit 2 (ID.26);
    // 0x200 lost to 0x100 (001 ...) at bit 1 (ID.27).
    assert_eq!(
        status(&mut bus, senders[0])
            .errors
            .unwrap()
            .alc
            .map(|a| a.0),
        Some(0x02)
    );
    assert_eq!(
        status(&mut bus, senders[1])
            .errors
            .unwrap()
            .alc
            .map(|a| a.0),
        Some(0x01)
    );
}

#[test]
fn a_node_with_the_wrong_bit_rate_cannot_communicate_and_says_so() {
    let mut bus = VirtualBus::new(RATE).unwrap();
    let good = bus.join().unwrap();
    let bad = bus.join().unwrap();
    // The seed's 50 kbit/s registers on a 500 kbit/s bus.
    bus.set_btr(bad, 0x07, 0x4D).unwrap();
    assert!(
        bus.take_events()
            .iter()
            .any(|(_, e)| e.is_warning() && e.to_string().contains("cannot communicate"))
    );
    let timing = status(&mut bus, bad).timing.unwrap();
    assert!(!timing.matches_bus);
    assert_eq!(timing.bitrate, 50_000);
    send(&mut bus, bad, "123#11");
    bus.run_until(BitTime::new(RATE as u64 / 20));
    assert!(received(&mut bus, good).is_empty());
    assert_ne!(status(&mut bus, bad).counters.bus_errors, 0);
    assert!(status(&mut bus, bad).errors.unwrap().ecc.is_some());
    // Back to the right timing: it talks again.
    let (b0, b1) = buslab_vbus::bus::timing_for(RATE).unwrap().registers();
    bus.set_btr(bad, b0, b1).unwrap();
    assert!(status(&mut bus, bad).timing.unwrap().matches_bus);
    send(&mut bus, bad, "124#22");
    let end = bus.now() + BitTime::new(RATE as u64 / 20);
    bus.run_until(end);
    assert_eq!(received(&mut bus, good), ["124#22"]);
}

#[test]
fn leaving_and_naming_nodes() {
    let mut bus = VirtualBus::new(RATE).unwrap();
    let a = bus.join().unwrap();
    let b = bus.join().unwrap();
    bus.rename(a, "pc").unwrap();
    assert!(bus.rename(b, "pc").is_err());
    assert!(bus.status(&NodeRef::Name("pc".into())).is_ok());
    bus.leave(a);
    assert!(bus.status(&NodeRef::Number(a)).is_err());
    assert_eq!(bus.nodes().len(), 1);
}

#[test]
fn an_unreachable_bit_rate_is_refused_by_name() {
    let err = VirtualBus::new(3).unwrap_err().to_string();
    assert!(err.contains("bit rate 3"), "{err}");
    // Said once, with the clock it was tried from.
    assert_eq!(err.matches("bit rate 3 bit/s").count(), 1, "{err}");
    assert!(err.contains("8000000 Hz CAN clock"), "{err}");
}

#[test]
fn scenario_nodes_and_chips_share_the_wire_without_errors() {
    let scenario = buslab_bench::Scenario::from_toml(
        "bitrate = 500000\n[[nodes]]\nname = \"ecu\"\n  [[nodes.traffic]]\n  kind = \"periodic\"\n  frame = \"0AA#55\"\n  period = \"1ms\"\n  start = \"100us\"\n",
    )
    .unwrap();
    let mut bus = VirtualBus::new(RATE)
        .unwrap()
        .with_scenario(scenario.build().unwrap());
    let a = bus.join().unwrap();
    let b = bus.join().unwrap();
    // The chip's frame loses arbitration to nothing and interleaves with the ECU's.
    send(&mut bus, a, "123#01");
    bus.run_until(BitTime::new(RATE as u64 / 100 + 10));
    let got = received(&mut bus, b);
    assert_eq!(got.iter().filter(|f| *f == "0AA#55").count(), 10, "{got:?}");
    assert_eq!(got.iter().filter(|f| *f == "123#01").count(), 1, "{got:?}");
    assert_eq!(status(&mut bus, b).bus.errors, 0);
    // The scenario node is node 1 and received the chip's frame; every frame on the wire is
    // counted once, whoever sent it.
    assert_eq!(bus.sim().node(0).stats().received, 1);
    let ecu = bus.status(&NodeRef::Name("ecu".into())).unwrap();
    assert_eq!(
        (ecu.number, ecu.counters.received, ecu.counters.sent),
        (1, 1, 10)
    );
    assert_eq!(ecu.sr, None, "a protocol controller has no status register");
    assert_eq!(status(&mut bus, b).bus.frames, 11);
}

#[test]
fn bus_wide_scenario_faults_reach_the_chips() {
    let scenario = buslab_bench::Scenario::from_toml(
        "bitrate = 500000\n[[nodes]]\nname = \"ecu\"\n[[faults]]\nkind = \"stuck_dominant\"\nstart = \"1ms\"\nend = \"3ms\"\n",
    )
    .unwrap();
    let mut bus = VirtualBus::new(RATE)
        .unwrap()
        .with_scenario(scenario.build().unwrap());
    let a = bus.join().unwrap();
    let b = bus.join().unwrap();
    bus.run_until(BitTime::new(RATE as u64 / 1000 + 100));
    send(&mut bus, a, "123#01");
    bus.run_until(BitTime::new(RATE as u64 / 100));
    // The stuck wire gave errors; once it is released the frame goes through.
    assert_ne!(status(&mut bus, a).counters.bus_errors, 0);
    assert_ne!(status(&mut bus, b).counters.bus_errors, 0);
    assert_eq!(received(&mut bus, b), ["123#01"]);
}

/// Drives client `a` to bus-off with noise at its connector while it sends.
fn jam_to_bus_off(bus: &mut VirtualBus, a: u32) {
    let index = bus.index(&NodeRef::Number(a)).unwrap();
    let start = bus.now();
    bus.sim_mut().add_fault(buslab_sim::Fault {
        kind: buslab_sim::FaultKind::Noise {
            nodes: vec![index],
            rate: 0.2,
        },
        start,
        end: start + BitTime::new(5_000),
    });
    send(bus, a, "123#0102030405060708");
    while !status(bus, a).sr.unwrap().bus_off() {
        assert!(bus.now() < start + BitTime::new(5_000), "never bus-off");
        let now = bus.now();
        bus.run_until(BitTime::new((now + BitTime::new(10)).get()));
    }
}

/// Seed 002 §5.4.7 in `bus serve`: a client chip that went bus-off comes back the seed's way,
/// TXERR falling where `buslab status` shows it, SR.ES clearing below 96 before SR.BS.
#[test]
fn a_client_chip_counts_its_way_back_from_bus_off() {
    let mut bus = VirtualBus::new(RATE).unwrap();
    let a = bus.join().unwrap();
    let _b = bus.join().unwrap();
    jam_to_bus_off(&mut bus, a);
    // The chip counts down (slowly while the noise lasts); no reading is higher than the last.
    let mut readings = Vec::new();
    loop {
        let st = status(&mut bus, a);
        let sr = st.sr.unwrap();
        readings.push((st.errors.unwrap().txerr, sr.error_status(), sr.bus_off()));
        if !sr.bus_off() {
            break;
        }
        let now = bus.now();
        bus.run_until(BitTime::new((now + BitTime::new(11)).get()));
    }
    let txerr: Vec<u8> = readings.iter().map(|r| r.0).collect();
    assert!(txerr.len() > 50, "{txerr:?}");
    assert!(txerr.windows(2).all(|w| w[1] <= w[0]), "{txerr:?}");
    // ES follows TXERR against the warning limit while BS is still set.
    for &(tx, es, bs) in &readings[..readings.len() - 1] {
        assert!(bs);
        assert_eq!(es, tx >= 96, "TXERR {tx}");
    }
    // And the frame the client sends next goes out.
    send(&mut bus, a, "124#01");
    let now = bus.now();
    bus.run_until(BitTime::new((now + BitTime::new(RATE as u64 / 100)).get()));
    assert_eq!(received(&mut bus, 2), ["124#01"]);

    // The fast restart, as an option: TXERR := 0 at once, 100 ms after bus-off.
    let mut bus = VirtualBus::new(RATE).unwrap();
    bus.set_bus_off_recovery(buslab_canbus::BusOffRecovery::Fast);
    let a = bus.join().unwrap();
    let _b = bus.join().unwrap();
    jam_to_bus_off(&mut bus, a);
    let off = bus.now();
    bus.run_until(BitTime::new(
        (off + BitTime::new(RATE as u64 / 10) - BitTime::new(50)).get(),
    ));
    assert_eq!(status(&mut bus, a).errors.unwrap().txerr, 127);
    bus.run_until(BitTime::new(
        (off + BitTime::new(RATE as u64 / 10) + BitTime::new(50)).get(),
    ));
    let st = status(&mut bus, a);
    assert!(!st.sr.unwrap().bus_off());
    assert_eq!(st.errors.unwrap().txerr, 0);
}

/// The seed's cut-wire experiment, injected by a client: the sender on the cut piece of
/// unterminated wire climbs to error-passive (and beyond), and once the wire is repaired its
/// TEC falls with each frame it gets through.
#[test]
fn an_injected_cut_makes_the_sender_error_passive_and_repair_lets_it_recover() {
    use buslab_canbus::{ErrorState, Probability, WireFault};
    let scenario = buslab_bench::Scenario::from_toml(
        "bitrate = 500000\n[[nodes]]\nname = \"engine\"\n  [[nodes.traffic]]\n  kind = \"periodic\"\n  frame = \"0C0#0FA0\"\n  period = \"1ms\"\n  start = \"100us\"\n[[nodes]]\nname = \"dash\"\n",
    )
    .unwrap();
    let mut bus = VirtualBus::new(RATE)
        .unwrap()
        .with_scenario(scenario.build().unwrap());
    bus.run_until(BitTime::new(RATE as u64 / 100));
    let engine = || NodeRef::Name("engine".into());
    assert_eq!(bus.status(&engine()).unwrap().state, ErrorState::Active);
    let cut = WireFault::Cut {
        far_side: vec![engine()],
        error_rate: Probability::new(0.05).unwrap(),
    };
    bus.inject_fault(&cut, None).unwrap();
    let mut worst = 0;
    let mut passive = false;
    for _ in 0..100 {
        bus.run_until(BitTime::new(
            (bus.now() + BitTime::new(RATE as u64 / 1000)).get(),
        ));
        let st = bus.status(&engine()).unwrap();
        worst = worst.max(st.errors.unwrap().txerr);
        passive |= st.state != ErrorState::Active;
    }
    assert!(
        passive,
        "the cut sender never left error-active (worst TEC {worst})"
    );
    assert_eq!(bus.repair(), 1);
    // Bus-off recovery (128 x 11 bits), then each frame through takes 1 off the TEC.
    bus.run_until(BitTime::new(
        (bus.now() + BitTime::new(RATE as u64 / 2)).get(),
    ));
    let st = bus.status(&engine()).unwrap();
    assert_eq!(st.state, ErrorState::Active, "{st}");
    assert!(st.errors.unwrap().txerr < 128, "{st}");
    assert_eq!(bus.repair(), 0, "nothing left to repair");
    // Unknown nodes are named in the refusal.
    let err = bus
        .inject_fault(
            &WireFault::Disconnect {
                node: NodeRef::Name("nobody".into()),
            },
            None,
        )
        .unwrap_err();
    assert!(err.to_string().contains("no node nobody"), "{err}");
}

#[test]
fn fault_injection_does_not_stop_after_1024_faults_only_1024_on_the_wire_at_once_are_refused() {
    // Every fault ever put on the bus counted, ended and repaired ones too: any client
    // reached the cap in a second and the dashboard's cut-wire button answered 400 for good.
    use buslab_canbus::admin::FaultLimit;
    use buslab_canbus::{Probability, WireFault};
    use buslab_vbus::VbusError;
    use buslab_vbus::bus::MAX_FAULTS;
    use std::time::Duration;
    let mut bus = VirtualBus::new(RATE).unwrap();
    let a = bus.join().unwrap();
    let _b = bus.join().unwrap();
    let noise = WireFault::Noise {
        nodes: vec![NodeRef::Number(a)],
        rate: Probability::new(0.001).unwrap(),
    };
    // Four times the cap, each lasting 1 ms, one after the other.
    for k in 0..4 * MAX_FAULTS {
        bus.inject_fault(&noise, Some(Duration::from_millis(1)))
            .unwrap_or_else(|e| panic!("fault {k} refused: {e}"));
        bus.run_until(BitTime::new(
            (bus.now() + BitTime::new(RATE as u64 / 1000)).get(),
        ));
    }
    assert!(bus.sim().faults().len() <= 1, "ended faults are forgotten");
    // Repaired ones too.
    for _ in 0..2 * MAX_FAULTS {
        bus.inject_fault(&noise, None).unwrap();
        assert_eq!(bus.repair(), 1);
    }
    // The cap is on faults on the wire at once (in force or to start later).
    for _ in 0..MAX_FAULTS {
        bus.inject_fault(&noise, None).unwrap();
    }
    let err = bus.inject_fault(&noise, None).unwrap_err();
    assert_eq!(
        err,
        VbusError::FaultRefused(FaultLimit::Active {
            max: MAX_FAULTS as u32
        })
    );
    assert!(err.to_string().contains("at most 1024 at once"), "{err}");
    assert_eq!(bus.repair(), MAX_FAULTS);
    bus.inject_fault(&noise, None).unwrap();
}

/// The server sleeps until `frame_end` while a client's frame is on the wire: its deliveries
/// must be there once the bus has run up to it (a late prediction costs every frame a wake-up
/// slice), and not long before (an early one delays them by the length of the frame).
#[test]
fn a_frame_on_an_idle_bus_is_done_exactly_when_the_bus_says() {
    for text in [
        "123#",
        "7FF#R",
        "123#1122",
        "00000000#R",
        "1ABCDEF0#DEADBEEF",
        "000#0000000000000000",
    ] {
        let mut bus = VirtualBus::new(RATE).unwrap();
        let a = bus.join().unwrap();
        let b = bus.join().unwrap();
        bus.run_until(BitTime::new(1000));
        assert_eq!(bus.frame_end(), None, "{text}: nothing on the wire yet");
        bus.submit(a, frame(text)).unwrap().unwrap();
        let end = bus.frame_end().expect("a client's frame on an idle bus");
        bus.run_until(BitTime::new((end - BitTime::new(2)).get()));
        assert!(
            received(&mut bus, b).is_empty(),
            "{text}: received before its end"
        );
        bus.run_until(end);
        assert_eq!(
            received(&mut bus, b),
            [text],
            "{text}: not received by its end"
        );
        assert_eq!(
            bus.client_mut(a).unwrap().done(),
            1,
            "{text}: not sent by its end"
        );
        assert_eq!(bus.frame_end(), None, "{text}: the frame has passed");
    }
}

#[test]
fn the_bus_does_not_guess_the_end_of_frames_behind_others() {
    let mut bus = VirtualBus::new(RATE).unwrap();
    let a = bus.join().unwrap();
    let b = bus.join().unwrap();
    bus.run_until(BitTime::new(1000));
    bus.submit(a, frame("100#01")).unwrap().unwrap();
    let first = bus.frame_end().unwrap();
    // Queued while the first is on the wire: it ends later than the bus says.
    bus.submit(b, frame("200#")).unwrap().unwrap();
    assert_eq!(bus.frame_end(), Some(first));
    bus.run_until(first);
    assert_eq!(bus.frame_end(), None);
    assert!(!bus.is_idle());
}
