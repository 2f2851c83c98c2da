//! The protocol controller on a tiny in-test wired-AND bus.

use buslab_can::controller::{
    Controller, ControllerConfig, ErrorKind, ErrorState, Event, QueueFull,
};
use buslab_can::wire::encode;
use buslab_can::{Frame, Level};

fn frame(s: &str) -> Frame {
    s.parse().unwrap()
}

type Fault = Box<dyn FnMut(usize, u64, Level, &Controller) -> Level>;

/// N controllers on one wire. Each bit-time: every node drives, the bus is the wired-AND, every
/// node samples the bus (or what the fault makes it see).
struct Bus {
    nodes: Vec<Controller>,
    events: Vec<Vec<(u64, Event)>>,
    levels: Vec<Level>,
    fault: Option<Fault>,
    time: u64,
}

impl Bus {
    fn new(configs: &[ControllerConfig]) -> Self {
        Self {
            nodes: configs.iter().map(|&c| Controller::new(c)).collect(),
            events: vec![Vec::new(); configs.len()],
            levels: Vec::new(),
            fault: None,
            time: 0,
        }
    }

    fn with_nodes(n: usize) -> Self {
        Self::new(&vec![ControllerConfig::default(); n])
    }

    fn step(&mut self) -> Level {
        let bus = self
            .nodes
            .iter()
            .fold(Level::Recessive, |bus, n| bus.and(n.output()));
        for (i, node) in self.nodes.iter_mut().enumerate() {
            let seen = match &mut self.fault {
                Some(fault) => fault(i, self.time, bus, node),
                None => bus,
            };
            node.sample(seen);
            while let Some(event) = node.poll_event() {
                self.events[i].push((self.time, event));
            }
        }
        self.levels.push(bus);
        self.time += 1;
        bus
    }

    fn run(&mut self, bits: u64) {
        for _ in 0..bits {
            self.step();
        }
    }

    /// Whether node `i` has lost arbitration so far.
    fn lost_arbitration(&self, i: usize) -> bool {
        self.events[i]
            .iter()
            .any(|(_, e)| matches!(e, Event::ArbitrationLost { .. }))
    }

    /// Run until every node is idle with nothing pending (or `max` bits).
    fn settle(&mut self, max: u64) {
        for _ in 0..max {
            self.step();
            if self
                .nodes
                .iter()
                .all(|n| n.is_bus_idle() && (n.pending() == 0 || n.config().listen_only))
            {
                return;
            }
        }
        panic!("bus did not settle in {max} bits");
    }

    fn received(&self, i: usize) -> Vec<Frame> {
        self.events[i]
            .iter()
            .filter_map(|(_, e)| match e {
                Event::Received(f) => Some(*f),
                _ => None,
            })
            .collect()
    }

    fn transmitted(&self, i: usize) -> Vec<Frame> {
        self.events[i]
            .iter()
            .filter_map(|(_, e)| match e {
                Event::Transmitted(f) => Some(*f),
                _ => None,
            })
            .collect()
    }

    fn errors(&self, i: usize) -> Vec<(ErrorKind, bool, u16, u16)> {
        self.events[i]
            .iter()
            .filter_map(|(_, e)| match *e {
                Event::Error {
                    kind,
                    transmitter,
                    tec,
                    rec,
                    ..
                } => Some((kind, transmitter, tec, rec)),
                _ => None,
            })
            .collect()
    }

    fn state_changes(&self, i: usize) -> Vec<(u64, ErrorState, ErrorState)> {
        self.events[i]
            .iter()
            .filter_map(|(t, e)| match *e {
                Event::StateChanged { from, to, .. } => Some((*t, from, to)),
                _ => None,
            })
            .collect()
    }

    /// Bus levels as a 0/1 string from `from`.
    fn trace(&self, from: usize, len: usize) -> String {
        self.levels[from..from + len]
            .iter()
            .map(|l| if l.bit() { '1' } else { '0' })
            .collect()
    }
}

#[test]
fn waits_for_11_recessive_bits_before_taking_part() {
    let mut bus = Bus::with_nodes(2);
    bus.nodes[0].enqueue(frame("123#1122")).unwrap();
    assert_eq!(bus.nodes[0].output(), Level::Recessive);
    for _ in 0..11 {
        assert_eq!(bus.step(), Level::Recessive);
    }
    assert!(bus.nodes[0].is_bus_idle());
    assert_eq!(bus.step(), Level::Dominant, "SOF right after integration");
}

#[test]
fn one_frame_on_the_wire_is_the_encoded_frame_with_ack() {
    let mut bus = Bus::with_nodes(2);
    let f = frame("123#1122");
    bus.run(11);
    bus.nodes[0].enqueue(f).unwrap();
    bus.settle(200);
    let on_bus = encode(&f).on_bus().to_string();
    assert_eq!(bus.trace(11, on_bus.len() + 3), on_bus + "111");
    assert_eq!(bus.transmitted(0), [f]);
    assert_eq!(bus.received(1), [f]);
    assert!(bus.received(0).is_empty(), "no self-reception by default");
    assert_eq!((bus.nodes[0].tec(), bus.nodes[1].rec()), (0, 0));
    // The receiver delivers at the 6th EOF bit, the transmitter succeeds at the 7th.
    let at = |i: usize| bus.events[i][0].0;
    assert_eq!(at(1) + 1, at(0));
    assert_eq!(at(0), 11 + 61);
}

#[test]
fn arbitration_lowest_wins_and_everything_is_delivered_once() {
    // SFF beats EFF with the same base ID; data beats remote; lower ID first.
    let frames = [
        frame("200#01"),
        frame("04000000#02"), // EFF, base 0x100
        frame("100#R2"),
        frame("100#03"),
        frame("00000001#"),
        frame("7FF#FFFFFFFFFFFFFFFF"),
    ];
    let mut bus = Bus::with_nodes(frames.len());
    bus.run(11);
    for (i, f) in frames.iter().enumerate() {
        bus.nodes[i].enqueue(*f).unwrap();
    }
    bus.settle(2000);
    let mut order: Vec<(u64, Frame)> = (0..frames.len())
        .flat_map(|i| {
            bus.events[i].iter().filter_map(|(t, e)| match e {
                Event::Transmitted(f) => Some((*t, *f)),
                _ => None,
            })
        })
        .collect();
    order.sort_by_key(|(t, _)| *t);
    let order: Vec<String> = order.iter().map(|(_, f)| f.to_string()).collect();
    assert_eq!(
        order,
        [
            "00000001#",
            "100#03",
            "100#R2",
            "04000000#02",
            "200#01",
            "7FF#FFFFFFFFFFFFFFFF"
        ]
    );
    for i in 0..frames.len() {
        let mut got = bus.received(i);
        got.sort();
        let mut want: Vec<Frame> = frames.iter().copied().filter(|f| *f != frames[i]).collect();
        want.sort();
        assert_eq!(
            got, want,
            "node {i} receives every other frame exactly once"
        );
        assert!(bus.errors(i).is_empty(), "arbitration is not an error");
        assert_eq!((bus.nodes[i].tec(), bus.nodes[i].rec()), (0, 0));
    }
    // The EFF frame lost at bit 12 (SRR recessive against RTR dominant) the first time.
    let lost: Vec<u32> = bus.events[1]
        .iter()
        .filter_map(|(_, e)| match e {
            Event::ArbitrationLost { bit, .. } => Some(*bit),
            _ => None,
        })
        .collect();
    assert_eq!(lost.len(), 3, "lost to 00000001, 100#03 and 100#R2");
    assert!(lost.contains(&12) && lost.contains(&13), "{lost:?}");
}

#[test]
fn transmit_queue_is_in_priority_order() {
    let mut bus = Bus::with_nodes(2);
    for f in ["300#", "100#", "200#", "100#R"] {
        bus.nodes[0].enqueue(frame(f)).unwrap();
    }
    bus.settle(1000);
    let sent: Vec<String> = bus.transmitted(0).iter().map(|f| f.to_string()).collect();
    assert_eq!(sent, ["100#", "100#R", "200#", "300#"]);
    let mut node = Controller::new(ControllerConfig {
        tx_queue_capacity: 2,
        ..Default::default()
    });
    node.enqueue(frame("001#")).unwrap();
    node.enqueue(frame("002#")).unwrap();
    assert_eq!(node.enqueue(frame("003#")), Err(QueueFull { capacity: 2 }));
    assert_eq!(node.pending(), 2);
    node.abort_all();
    assert_eq!(node.pending(), 0);
}

/// A more important frame queued while a less important one is in flight (losing arbitration)
/// is the one tried next.
#[test]
fn a_more_important_frame_queued_while_another_loses_goes_next() {
    let mut bus = Bus::with_nodes(2);
    bus.nodes[1].enqueue(frame("100#01")).unwrap();
    bus.nodes[1].enqueue(frame("100#02")).unwrap();
    bus.nodes[0].enqueue(frame("300#")).unwrap();
    for _ in 0..1000 {
        if bus.lost_arbitration(0) {
            break;
        }
        bus.step();
    }
    assert!(bus.lost_arbitration(0), "300# loses to 100#01 first");
    bus.nodes[0].enqueue(frame("200#")).unwrap();
    bus.settle(1000);
    let sent: Vec<String> = bus.transmitted(0).iter().map(|f| f.to_string()).collect();
    assert_eq!(sent, ["200#", "300#"]);
}

/// Frames of one arbitration field leave in the order they were queued, whenever the queue is
/// looked at: at once on an idle bus, or at the end of the frame on the wire. A frame is
/// displaced from the transmit slot only by a more important field (never by its data), and
/// goes back where it was queued. (The simulator's whole-frame path looks at a queue earlier
/// than the bit-level path does; with data deciding, or a displaced frame put after the
/// later ones, the two sent equal fields in different orders.)
#[test]
fn frames_of_one_field_leave_in_queue_order_whenever_the_queue_is_looked_at() {
    let sent =
        |bus: &Bus| -> Vec<String> { bus.transmitted(0).iter().map(|f| f.to_string()).collect() };
    // On an idle bus, each frame looked at as it is queued.
    let mut bus = Bus::with_nodes(2);
    for f in ["100#05", "100#03", "080#"] {
        bus.nodes[0].enqueue(frame(f)).unwrap();
    }
    bus.settle(2000);
    assert_eq!(sent(&bus), ["080#", "100#05", "100#03"]);

    // While a frame is on the wire: 100#05 loses to node 1's 050#, the other two come in
    // the middle of that frame and are looked at at its end.
    let mut bus = Bus::with_nodes(2);
    bus.nodes[1].enqueue(frame("050#")).unwrap();
    bus.nodes[0].enqueue(frame("100#05")).unwrap();
    while !bus.lost_arbitration(0) {
        assert!(bus.time < 1000, "100#05 loses to 050#");
        bus.step();
    }
    for f in ["100#03", "080#"] {
        bus.nodes[0].enqueue(frame(f)).unwrap();
    }
    bus.settle(2000);
    assert_eq!(sent(&bus), ["080#", "100#05", "100#03"]);
}

#[test]
fn alone_on_the_bus_tec_stops_at_128() {
    let mut bus = Bus::with_nodes(1);
    bus.nodes[0].enqueue(frame("123#1122")).unwrap();
    bus.run(20_000);
    let node = &bus.nodes[0];
    assert_eq!(node.tec(), 128);
    assert_eq!(node.state(), ErrorState::Passive);
    let errors = bus.errors(0);
    assert!(errors.len() > 100, "keeps retrying: {}", errors.len());
    assert!(errors.iter().all(|e| e.0 == ErrorKind::Ack && e.1));
    let tecs: Vec<u16> = errors.iter().map(|e| e.2).take(17).collect();
    let expected: Vec<u16> = (1..=16).map(|n| 8 * n).chain([128]).collect();
    assert_eq!(tecs, expected);
    assert_eq!(
        bus.state_changes(0)
            .iter()
            .map(|c| (c.1, c.2))
            .collect::<Vec<_>>(),
        [(ErrorState::Active, ErrorState::Passive)]
    );
    assert!(bus.events[0].iter().any(|(_, e)| matches!(
        e,
        Event::Warning {
            above: true,
            tec: 96,
            ..
        }
    )));
    assert!(bus.transmitted(0).is_empty());
}

/// Flip what node `who` sees at bit `at` of the first frame it sees (counting from SOF).
fn flip_once(who: usize, at: u64) -> Fault {
    let mut sof: Option<u64> = None;
    let mut done = false;
    Box::new(move |i, time, bus, node| {
        if i != who || done {
            return bus;
        }
        if sof.is_none() && node.is_bus_idle() && bus == Level::Dominant {
            sof = Some(time);
        }
        match sof {
            Some(t) if time - t == at => {
                done = true;
                if bus == Level::Dominant {
                    Level::Recessive
                } else {
                    Level::Dominant
                }
            }
            _ => bus,
        }
    })
}

#[test]
fn bit_flipped_at_one_receiver_error_frame_and_one_delivery() {
    let f = frame("123#1122");
    let enc = encode(&f);
    // Try every position of the stuffed region and the fixed-form bits before EOF.
    for at in 1..enc.ack_slot() as u64 + 2 {
        if at == enc.ack_slot() as u64 {
            continue;
        }
        let mut bus = Bus::with_nodes(3);
        bus.run(11);
        bus.fault = Some(flip_once(2, at));
        bus.nodes[0].enqueue(f).unwrap();
        bus.settle(1000);
        assert_eq!(bus.transmitted(0), [f], "flip at {at}");
        assert_eq!(bus.received(1), [f], "flip at {at}");
        assert_eq!(bus.received(2), [f], "flip at {at}");
        let errors = bus.errors(2);
        assert!(!errors.is_empty(), "flip at {at}: node 2 detects it");
        assert!(
            !bus.errors(0).is_empty(),
            "flip at {at}: transmitter sees the error frame"
        );
        // +8 for the error, -1 for the success; unless the error flag came during arbitration,
        // where the transmitter reads it as a lost arbitration (and then a receive error).
        let lost = bus.events[0]
            .iter()
            .any(|(_, e)| matches!(e, Event::ArbitrationLost { .. }));
        let tec = bus.nodes[0].tec();
        assert!(tec == 7 || (lost && tec == 0), "flip at {at}: TEC {tec}");
    }
}

#[test]
fn dominant_last_eof_bit_at_the_transmitter_duplicates_the_frame() {
    // Known CAN behaviour: receivers accept at the 6th EOF bit, the transmitter needs the 7th.
    let f = frame("123#1122");
    let last_eof = encode(&f).on_bus().len() as u64 - 1;
    let mut bus = Bus::with_nodes(2);
    bus.run(11);
    bus.fault = Some(flip_once(0, last_eof));
    bus.nodes[0].enqueue(f).unwrap();
    bus.settle(1000);
    assert_eq!(bus.transmitted(0), [f]);
    assert_eq!(bus.received(1), [f, f], "received twice");
    assert_eq!(bus.errors(0)[0].0, ErrorKind::Form);
    // A receiver seeing the last EOF bit dominant sends an overload frame, no error.
    let mut bus = Bus::with_nodes(2);
    bus.run(11);
    bus.fault = Some(flip_once(1, last_eof));
    bus.nodes[0].enqueue(f).unwrap();
    bus.settle(1000);
    assert_eq!(bus.received(1), [f]);
    assert!(bus.errors(1).is_empty() && bus.errors(0).is_empty());
    assert!(bus.events[1].iter().any(|(_, e)| *e == Event::Overload));
    assert_eq!(bus.transmitted(0), [f]);
}

#[test]
fn repeated_bit_errors_bus_off_then_recovery_after_128_times_11_bits() {
    for auto_recover in [true, false] {
        let config = ControllerConfig {
            auto_recover,
            ..Default::default()
        };
        let mut bus = Bus::new(&[config, ControllerConfig::default()]);
        bus.run(11);
        // Node 0 reads its own data bit 20 of every attempt inverted, until bus-off.
        let (mut sof, mut went_off) = (0, false);
        bus.fault = Some(Box::new(move |i, time, level, node| {
            went_off |= node.state() == ErrorState::BusOff;
            if i != 0 || went_off {
                return level;
            }
            if node.is_bus_idle() && level == Level::Dominant {
                sof = time;
            }
            if node.is_transmitting() && time - sof == 20 {
                return if level == Level::Dominant {
                    Level::Recessive
                } else {
                    Level::Dominant
                };
            }
            level
        }));
        let f = frame("123#1122");
        bus.nodes[0].enqueue(f).unwrap();
        while bus.nodes[0].state() != ErrorState::BusOff {
            bus.step();
            assert!(bus.time < 10_000);
        }
        let errors = bus.errors(0);
        assert!(errors.iter().all(|e| e.0 == ErrorKind::Bit && e.1));
        let tecs: Vec<u16> = errors.iter().map(|e| e.2).collect();
        assert_eq!(tecs, (1..=32).map(|n| 8 * n).collect::<Vec<_>>());
        let changes: Vec<_> = bus.state_changes(0).iter().map(|c| (c.1, c.2)).collect();
        assert_eq!(
            changes,
            [
                (ErrorState::Active, ErrorState::Passive),
                (ErrorState::Passive, ErrorState::BusOff)
            ]
        );
        assert_eq!(bus.nodes[0].output(), Level::Recessive);
        let off_at = bus.time;
        if !auto_recover {
            bus.run(5000);
            assert_eq!(
                bus.nodes[0].state(),
                ErrorState::BusOff,
                "waits for recover()"
            );
            bus.nodes[0].recover();
        }
        let start = bus.time;
        while bus.nodes[0].state() == ErrorState::BusOff {
            assert_eq!(bus.nodes[0].output(), Level::Recessive);
            bus.step();
        }
        let took = bus.time - start;
        assert!(
            (128 * 11..128 * 11 + 40).contains(&took),
            "recovery took {took} bits"
        );
        assert!(off_at <= start);
        assert_eq!((bus.nodes[0].tec(), bus.nodes[0].rec()), (0, 0));
        assert_eq!(bus.nodes[0].state(), ErrorState::Active);
        bus.settle(1000);
        assert_eq!(bus.transmitted(0), [f], "sent after recovery");
        assert_eq!(bus.received(1), [f]);
    }
}

#[test]
fn listen_only_never_drives_dominant() {
    let listen = ControllerConfig {
        listen_only: true,
        ..Default::default()
    };
    let d = ControllerConfig::default();
    let mut bus = Bus::new(&[d, d, listen]);
    bus.run(11);
    bus.nodes[0].enqueue(frame("123#1122")).unwrap();
    bus.nodes[1].enqueue(frame("124#33")).unwrap();
    bus.nodes[2].enqueue(frame("001#")).unwrap();
    // A flipped bit at node 1: an error frame the listen-only node sees but does not join.
    bus.fault = Some(flip_once(1, 25));
    for _ in 0..1000 {
        bus.step();
        assert_eq!(bus.nodes[2].output(), Level::Recessive, "at {}", bus.time);
    }
    assert_eq!(bus.received(2), [frame("123#1122"), frame("124#33")]);
    assert!(!bus.errors(2).is_empty());
    assert_eq!((bus.nodes[2].tec(), bus.nodes[2].rec()), (0, 0));
    assert!(bus.transmitted(2).is_empty());
    // Alone with a listener: nobody acknowledges.
    let mut bus = Bus::new(&[d, listen]);
    bus.nodes[0].enqueue(frame("123#")).unwrap();
    bus.run(300);
    assert!(bus.errors(0).iter().all(|e| e.0 == ErrorKind::Ack));
    assert!(bus.nodes[0].tec() > 0);
}

#[test]
fn self_test_needs_no_ack_and_self_reception_delivers_our_own() {
    let config = ControllerConfig {
        self_test: true,
        self_reception: true,
        ..Default::default()
    };
    let mut bus = Bus::new(&[config]);
    let f = frame("123#1122");
    bus.nodes[0].enqueue(f).unwrap();
    bus.settle(200);
    assert_eq!(bus.transmitted(0), [f]);
    assert_eq!(bus.received(0), [f]);
    assert_eq!(bus.nodes[0].tec(), 0);
}

#[test]
fn single_shot_drops_after_an_error_or_lost_arbitration() {
    let single = ControllerConfig {
        single_shot: true,
        ..Default::default()
    };
    let mut bus = Bus::new(&[single]);
    let f = frame("123#1122");
    bus.nodes[0].enqueue(f).unwrap();
    bus.run(300);
    assert_eq!(bus.errors(0).len(), 1);
    assert!(bus.events[0].iter().any(|(_, e)| *e == Event::Dropped(f)));
    assert_eq!(bus.nodes[0].pending(), 0);
    assert_eq!(bus.nodes[0].tec(), 8);

    let mut bus = Bus::new(&[single, ControllerConfig::default()]);
    bus.run(11);
    bus.nodes[0].enqueue(frame("200#")).unwrap();
    bus.nodes[1].enqueue(frame("100#")).unwrap();
    bus.settle(500);
    assert!(
        bus.events[0]
            .iter()
            .any(|(_, e)| matches!(e, Event::ArbitrationLost { bit: 2, .. }))
    );
    assert!(
        bus.events[0]
            .iter()
            .any(|(_, e)| *e == Event::Dropped(frame("200#")))
    );
    assert!(bus.transmitted(0).is_empty());
    assert_eq!(bus.received(0), [frame("100#")]);
}

/// Regression (the manager's rare `Timeout` instead of `Aborted`): an abort during the error
/// frame of a frame that was already dropped has nothing on the wire to stop. It must not stay
/// armed and drop the next frame at its first error.
#[test]
fn abort_after_the_in_flight_frame_was_dropped_does_not_drop_the_next_frame() {
    let mut bus = Bus::with_nodes(1); // nobody acknowledges: every attempt fails
    bus.run(11);
    let first = frame("100#");
    bus.nodes[0].enqueue(first).unwrap();
    bus.run(5);
    assert!(bus.nodes[0].is_transmitting());
    bus.nodes[0].abort_all();
    let dropped = |bus: &Bus, f: Frame| {
        bus.events[0]
            .iter()
            .filter(|(_, e)| *e == Event::Dropped(f))
            .count()
    };
    for _ in 0..200 {
        if dropped(&bus, first) == 1 {
            break;
        }
        bus.step();
    }
    assert_eq!(
        dropped(&bus, first),
        1,
        "the aborted frame ends at its error"
    );
    assert!(
        bus.nodes[0].is_transmitting(),
        "still in the error frame of our own transmission"
    );
    bus.nodes[0].abort_all(); // nothing left to abort
    assert_eq!(bus.nodes[0].pending(), 0);

    let next = frame("101#");
    bus.nodes[0].enqueue(next).unwrap();
    bus.run(1_000);
    assert_eq!(
        dropped(&bus, next),
        0,
        "the next frame is retried, not dropped"
    );
    assert!(bus.errors(0).len() > 3, "{:?}", bus.errors(0));
    assert_eq!(bus.nodes[0].pending(), 1);
}

/// One node driven directly: the bus is what it drives, except where `script` overrides.
fn drive(node: &mut Controller, bits: u64, mut script: impl FnMut(u64, Level) -> Level) {
    for t in 0..bits {
        let out = node.output();
        node.sample(script(t, out));
    }
}

#[test]
fn receiver_counter_rules_1_2_and_6() {
    // Stuff error, then its own 6-bit flag, then `extra` dominant bits: REC +1 +8 (+8 per 8).
    for (extra, expected) in [(0, 1), (1, 9), (7, 9), (8, 17), (16, 25)] {
        let mut node = Controller::new(ControllerConfig::default());
        drive(&mut node, 11, |_, _| Level::Recessive);
        // SOF + 5 dominant = stuff error at wire bit 5; flag bits 6..11; then `extra` dominant.
        drive(&mut node, 6 + 6 + extra + 20, |t, out| {
            if t < 6 + 6 + extra {
                Level::Dominant
            } else {
                out
            }
        });
        assert_eq!(node.rec(), expected, "{extra} dominant bits after the flag");
        assert_eq!(node.tec(), 0);
    }
}

#[test]
fn transmitter_counter_rule_6_and_7_dominant_bits_tolerated() {
    let f = frame("123#1122");
    let sent = encode(&f).stuffed().to_string();
    // Bit 20 is a dominant data bit: read it recessive -> bit error, flag at 21..26.
    assert_eq!(&sent[20..21], "0");
    for (extra, expected) in [(7u64, 8u16), (8, 16), (16, 24)] {
        let mut node = Controller::new(ControllerConfig::default());
        drive(&mut node, 11, |_, _| Level::Recessive);
        node.enqueue(f).unwrap();
        drive(&mut node, 21 + 6 + extra + 20, |t, out| match t {
            20 => Level::Recessive,
            t if (27..27 + extra).contains(&t) => Level::Dominant,
            _ => out,
        });
        assert_eq!(node.tec(), expected, "{extra} dominant bits after the flag");
    }
}

#[test]
fn error_passive_ack_exception_only_without_dominant_in_the_flag() {
    let f = frame("123#");
    let ack_slot = encode(&f).ack_slot() as u64;
    let passive = || {
        let mut node = Controller::new(ControllerConfig::default());
        node.enqueue(f).unwrap();
        // Alone: 16 ACK errors bring TEC to 128.
        while node.tec() < 128 {
            let out = node.output();
            node.sample(out);
        }
        // Let the error frame, intermission and suspend transmission pass: then SOF.
        while !node.is_bus_idle() {
            let out = node.output();
            node.sample(out);
        }
        node
    };
    let mut node = passive();
    assert_eq!(node.state(), ErrorState::Passive);
    // We are at bit 1 of the next attempt. No ACK, passive flag undisturbed: TEC stays.
    drive(&mut node, 100, |_, out| out);
    assert_eq!(node.tec(), 128);
    // With a dominant bit during the passive flag: +8 (ISO 16845 8.6.18).
    let mut node = passive();
    drive(&mut node, 100, |t, out| {
        if t == ack_slot + 2 {
            Level::Dominant
        } else {
            out
        }
    });
    assert_eq!(node.tec(), 136);
}

#[test]
fn overload_frame_after_dominant_intermission_bit() {
    let f = frame("123#1122");
    let eof_end = encode(&f).on_bus().len() as u64;
    let mut bus = Bus::with_nodes(2);
    bus.run(11);
    // Both nodes see the first intermission bit dominant.
    let start = bus.time;
    bus.fault = Some(Box::new(move |_, time, level, _| {
        if time == start + eof_end {
            Level::Dominant
        } else {
            level
        }
    }));
    bus.nodes[0].enqueue(f).unwrap();
    bus.nodes[0].enqueue(frame("124#")).unwrap();
    bus.settle(1000);
    for i in 0..2 {
        assert!(
            bus.events[i].iter().any(|(_, e)| *e == Event::Overload),
            "node {i}"
        );
        assert!(bus.errors(i).is_empty());
        assert_eq!((bus.nodes[i].tec(), bus.nodes[i].rec()), (0, 0));
    }
    // Overload flag (6 dominant) from the bit after the dominant intermission bit.
    let t = (start + eof_end) as usize;
    // (The fault changes what the nodes see, not the recorded bus level.)
    assert_eq!(bus.trace(t, 1 + 6 + 8 + 3 + 1), "1000000111111111110");
    assert_eq!(bus.transmitted(0), [f, frame("124#")]);
    assert_eq!(bus.received(1), [f, frame("124#")]);
}

#[test]
fn error_passive_transmitter_suspends_after_its_frame() {
    let mut bus = Bus::with_nodes(2);
    bus.run(11);
    // Node 1 hears nothing until node 0 is error-passive (ACK errors) and the bus is idle;
    // then node 0 reads one of its bits wrong once more: TEC 136, still passive after a success.
    let (mut tec0, mut idle0, mut deaf, mut flipped, mut sof) = (0, false, true, false, 0);
    bus.fault = Some(Box::new(move |i, time, level, node| {
        if i == 0 {
            tec0 = node.tec();
            idle0 = node.is_bus_idle();
            if idle0 && level == Level::Dominant {
                sof = time;
            }
            if tec0 >= 128 && !deaf && !flipped && node.is_transmitting() && time - sof == 20 {
                flipped = true;
                return Level::Recessive;
            }
            return level;
        }
        if deaf && tec0 >= 128 && idle0 {
            deaf = false;
        }
        if deaf { Level::Recessive } else { level }
    }));
    bus.nodes[0].enqueue(frame("100#1122")).unwrap();
    while bus.transmitted(0).is_empty() {
        bus.step();
        assert!(bus.time < 5000);
    }
    assert_eq!(bus.nodes[0].state(), ErrorState::Passive);
    assert_eq!(bus.nodes[0].tec(), 135);
    assert_eq!(bus.received(1), [frame("100#1122")]);
    // Both queue a frame now, during node 0's intermission. Node 0's has the higher priority,
    // but node 0 suspends transmission for 8 bits, so node 1's goes first.
    bus.nodes[0].enqueue(frame("001#")).unwrap();
    bus.nodes[1].enqueue(frame("700#")).unwrap();
    bus.settle(1000);
    assert_eq!(bus.received(0), [frame("700#")]);
    assert_eq!(bus.received(1), [frame("100#1122"), frame("001#")]);
    let t001 = bus.events[1]
        .iter()
        .find(|(_, e)| *e == Event::Received(frame("001#")))
        .unwrap()
        .0;
    let t700 = bus.events[0]
        .iter()
        .find(|(_, e)| *e == Event::Received(frame("700#")))
        .unwrap()
        .0;
    assert!(t700 < t001);
    // Without the suspension (an error-active transmitter) the higher priority wins.
    let mut bus = Bus::with_nodes(2);
    bus.run(11);
    bus.nodes[0].enqueue(frame("100#1122")).unwrap();
    while bus.transmitted(0).is_empty() {
        bus.step();
    }
    bus.nodes[0].enqueue(frame("001#")).unwrap();
    bus.nodes[1].enqueue(frame("700#")).unwrap();
    bus.settle(1000);
    assert_eq!(bus.received(1), [frame("100#1122"), frame("001#")]);
    assert_eq!(bus.received(0), [frame("700#")]);
    let t001 = bus.events[1]
        .iter()
        .find(|(_, e)| *e == Event::Received(frame("001#")))
        .unwrap()
        .0;
    let t700 = bus.events[0]
        .iter()
        .find(|(_, e)| *e == Event::Received(frame("700#")))
        .unwrap()
        .0;
    assert!(t001 < t700);
}

#[test]
fn sof_read_back_recessive_is_a_bit_error() {
    let mut node = Controller::new(ControllerConfig::default());
    drive(&mut node, 11, |_, _| Level::Recessive);
    node.enqueue(frame("123#")).unwrap();
    assert_eq!(node.output(), Level::Dominant);
    node.sample(Level::Recessive);
    assert_eq!(
        node.poll_event(),
        Some(Event::Error {
            kind: ErrorKind::Bit,
            transmitter: true,
            bit: 0,
            tec: 8,
            rec: 0
        })
    );
    assert_eq!(node.output(), Level::Dominant, "active error flag");
}

#[test]
fn recessive_stuff_bit_overwritten_in_arbitration_leaves_tec_alone() {
    let f = frame("000#");
    let enc = encode(&f);
    assert!(
        enc.is_stuff_bit(5) && enc.stuffed().bit(5),
        "SOF + 4 zeros, then a 1"
    );
    let mut node = Controller::new(ControllerConfig::default());
    drive(&mut node, 11, |_, _| Level::Recessive);
    node.enqueue(f).unwrap();
    drive(
        &mut node,
        6,
        |t, out| if t == 5 { Level::Dominant } else { out },
    );
    let errors: Vec<Event> = std::iter::from_fn(|| node.poll_event()).collect();
    assert_eq!(
        errors,
        [Event::Error {
            kind: ErrorKind::Stuff,
            transmitter: true,
            bit: 5,
            tec: 0,
            rec: 0
        }]
    );
    // A dominant data bit read back recessive in arbitration is a bit error, +8.
    let mut node = Controller::new(ControllerConfig::default());
    drive(&mut node, 11, |_, _| Level::Recessive);
    node.enqueue(f).unwrap();
    drive(
        &mut node,
        5,
        |t, out| if t == 3 { Level::Recessive } else { out },
    );
    assert!(matches!(
        node.poll_event(),
        Some(Event::Error {
            kind: ErrorKind::Bit,
            bit: 3,
            tec: 8,
            ..
        })
    ));
}

#[test]
fn crc_error_at_a_receiver_is_flagged_after_the_ack_delimiter() {
    let f = frame("123#1122");
    let enc = encode(&f);
    let ack_delimiter = enc.ack_slot() as u32 + 1;
    let first_error = |bus: &Bus, i: usize| {
        bus.events[i]
            .iter()
            .find_map(|(_, e)| match *e {
                Event::Error { kind, bit, .. } => Some((kind, bit)),
                _ => None,
            })
            .unwrap()
    };
    // Wire bit 22 is a data bit whose flip changes no stuffing: only the CRC catches it.
    let mut bus = Bus::with_nodes(3);
    bus.run(11);
    bus.fault = Some(flip_once(1, 22));
    bus.nodes[0].enqueue(f).unwrap();
    bus.settle(1000);
    assert_eq!(first_error(&bus, 1), (ErrorKind::Crc, ack_delimiter));
    // Its flag starts at the first EOF bit: a form error for the others.
    assert_eq!(first_error(&bus, 0), (ErrorKind::Form, ack_delimiter + 1));
    assert_eq!(first_error(&bus, 2), (ErrorKind::Form, ack_delimiter + 1));
    for i in 1..3 {
        assert_eq!(bus.received(i), [f]);
    }
    assert_eq!(bus.transmitted(0), [f]);
    // With no other receiver to acknowledge, the transmitter's ACK error flag (from the ACK
    // delimiter on) comes first and the receiver sees a form error there.
    let mut bus = Bus::with_nodes(2);
    bus.run(11);
    bus.fault = Some(flip_once(1, 22));
    bus.nodes[0].enqueue(f).unwrap();
    bus.settle(1000);
    assert_eq!(first_error(&bus, 0), (ErrorKind::Ack, ack_delimiter - 1));
    assert_eq!(first_error(&bus, 1), (ErrorKind::Form, ack_delimiter));
    assert_eq!(bus.received(1), [f]);
}

#[test]
fn successful_reception_brings_a_passive_rec_back_to_127() {
    let mut node = Controller::new(ControllerConfig::default());
    drive(&mut node, 11, |_, _| Level::Recessive);
    // Stuff error + flag + 16 dominant bits: REC +25 each time; then the delimiter and
    // intermission.
    for _ in 0..6 {
        drive(&mut node, 6 + 6 + 16, |_, _| Level::Dominant);
        drive(&mut node, 8 + 3, |_, _| Level::Recessive);
    }
    assert_eq!(node.rec(), 150);
    assert_eq!(node.state(), ErrorState::Passive);
    while node.poll_event().is_some() {}
    let bits = encode(&frame("123#1122")).stuffed().to_string();
    let bits: Vec<bool> = bits.bytes().map(|b| b == b'1').collect();
    drive(&mut node, bits.len() as u64, |t, out| {
        out.and(Level::from_bit(bits[t as usize]))
    });
    assert_eq!(node.rec(), 127);
    assert_eq!(node.state(), ErrorState::Active);
    let events: Vec<Event> = std::iter::from_fn(|| node.poll_event()).collect();
    assert!(events.contains(&Event::Received(frame("123#1122"))));
    assert!(events.iter().any(|e| matches!(
        e,
        Event::StateChanged {
            from: ErrorState::Passive,
            to: ErrorState::Active,
            rec: 127,
            ..
        }
    )));
}

/// A receiver with a stuff error at wire bit 5: 6 dominant bits from SOF, then the script.
fn receiver_after_stuff_error(script: impl FnMut(u64, Level) -> Level, bits: u64) -> Controller {
    let mut node = Controller::new(ControllerConfig::default());
    drive(&mut node, 11, |_, _| Level::Recessive);
    drive(&mut node, 6, |_, _| Level::Dominant);
    assert_eq!(node.rec(), 1);
    drive(&mut node, bits, script);
    node
}

#[test]
fn bit_error_in_own_active_flag_costs_8_and_restarts_the_flag() {
    // Flag bit 3 reads recessive: +8 (rule 5), then a whole new 6-bit flag.
    let mut outputs = Vec::new();
    let node = receiver_after_stuff_error(
        |t, out| {
            outputs.push(out);
            if t == 2 { Level::Recessive } else { out }
        },
        30,
    );
    assert_eq!(node.rec(), 9);
    let dominant = outputs
        .iter()
        .take_while(|l| **l == Level::Dominant)
        .count();
    assert_eq!(dominant, 3 + 6, "3 flag bits, then a new flag of 6");
}

#[test]
fn form_error_in_own_error_delimiter_and_overload_at_its_last_bit() {
    // Flag bits 0..5, delimiter 6..13. Dominant at delimiter bit 3 (t = 8): form error, +1.
    let node = receiver_after_stuff_error(|t, out| if t == 8 { Level::Dominant } else { out }, 40);
    assert_eq!(node.rec(), 2);
    // Dominant at the 8th delimiter bit (t = 13): overload frame, no change.
    let mut node =
        receiver_after_stuff_error(|t, out| if t == 13 { Level::Dominant } else { out }, 40);
    assert_eq!(node.rec(), 1);
    let events: Vec<Event> = std::iter::from_fn(|| node.poll_event()).collect();
    assert!(events.contains(&Event::Overload), "{events:?}");
}

#[test]
fn passive_flag_ends_after_six_equal_bits_of_either_level() {
    // A receiver made passive, then a stuff error: its passive flag waits for 6 equal bits.
    let mut node = Controller::new(ControllerConfig::default());
    drive(&mut node, 11, |_, _| Level::Recessive);
    for _ in 0..6 {
        drive(&mut node, 6 + 6 + 16, |_, _| Level::Dominant);
        drive(&mut node, 8 + 3, |_, _| Level::Recessive);
    }
    assert_eq!(node.state(), ErrorState::Passive);
    let rec = node.rec();
    // Stuff error, then the bus alternates for 4 bits (no 6 equal bits), then stays recessive:
    // the flag ends 6 bits later, the 8-bit delimiter and 3-bit intermission follow, then idle.
    drive(&mut node, 6, |_, _| Level::Dominant);
    assert_eq!(node.rec(), rec + 1);
    drive(&mut node, 4, |t, _| Level::from_bit(t % 2 == 0));
    let mut idle_after = None;
    for t in 0..40 {
        node.sample(Level::Recessive);
        if node.is_bus_idle() {
            idle_after = Some(t + 1);
            break;
        }
    }
    // The alternating run ended with a dominant bit; 6 recessive complete the flag, then the
    // delimiter's 8 recessive bits, intermission 3.
    assert_eq!(idle_after, Some(6 + 8 + 3));
    assert_eq!(
        node.output(),
        Level::Recessive,
        "a passive node never drove dominant"
    );
}
