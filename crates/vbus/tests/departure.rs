//! Clients that leave, in virtual time: what they handed over is sent, unless their node goes
//! bus-off or sends none of it for `DEPARTURE_STALL` of bus time; then it is dropped, counted,
//! and the node leaves (issue 25; issue 11's zombie guarantee).

use buslab_can::BitTime;
use buslab_can::Frame;
use buslab_canbus::{NodeCounters, NodeRef};
use buslab_vbus::departure::GIVE_UP;
use buslab_vbus::{BusEvent, DEPARTURE_STALL, DropReason, VirtualBus};

const RATE: u32 = 125_000;
/// [`DEPARTURE_STALL`] in bit-times at [`RATE`].
const STALL_BITS: u64 = RATE as u64 * DEPARTURE_STALL.as_millis() as u64 / 1000;
/// Longer than any frame with its worst stuffing and the intermission after it.
const FRAME_BITS: u64 = 168;

fn frame(text: &str) -> Frame {
    text.parse().unwrap()
}

fn received(bus: &mut VirtualBus, number: u32) -> Vec<String> {
    let node = bus.client_mut(number).unwrap();
    node.take_deliveries()
        .map(|d| d.frame.to_string())
        .collect()
}

fn on_bus(bus: &VirtualBus, number: u32) -> bool {
    bus.nodes().iter().any(|n| n.number == number)
}

/// The `Left` events so far: number, counters, dropped, reason, and the bit-time.
fn left(bus: &mut VirtualBus) -> Vec<(u32, NodeCounters, u64, Option<DropReason>, BitTime)> {
    bus.take_events()
        .into_iter()
        .filter_map(|(time, e)| match e {
            BusEvent::Left {
                number,
                counters,
                dropped,
                reason,
                ..
            } => Some((number, counters, dropped, reason, time)),
            _ => None,
        })
        .collect()
}

/// Hands `frames` to node `number` as the server does: each as soon as its queue has room.
fn hand_over(bus: &mut VirtualBus, number: u32, frames: &[Frame]) {
    for &f in frames {
        while bus.submit(number, f).unwrap().is_err() {
            bus.run_until(BitTime::new((bus.now() + BitTime::new(FRAME_BITS)).get()));
        }
    }
}

#[test]
fn a_departed_clients_frames_are_all_sent_in_order_then_its_node_leaves() {
    // python-can's `bus.send()` then `shutdown()`: 200 frames in the socket, the connection
    // closed behind them. They all went (194 were lost when the node left at once).
    let mut bus = VirtualBus::new(RATE).unwrap();
    let sender = bus.join().unwrap();
    let receiver = bus.join().unwrap();
    let frames: Vec<Frame> = (0..200u32)
        .map(|k| frame(&format!("200#{:08X}", k)))
        .collect();
    hand_over(&mut bus, sender, &frames[..10]);
    bus.depart(sender).unwrap();
    assert!(bus.is_departing(sender));
    // The rest is read from the socket after the close was seen.
    hand_over(&mut bus, sender, &frames[10..]);
    bus.input_ended(sender);
    assert!(on_bus(&bus, sender), "it leaves once its frames are sent");
    let mut got = received(&mut bus, receiver);
    let deadline = bus.now() + BitTime::new(300) * FRAME_BITS;
    while on_bus(&bus, sender) {
        assert!(bus.now() < deadline, "the departed node stayed");
        bus.run_until(BitTime::new((bus.now() + BitTime::new(FRAME_BITS)).get()));
        got.extend(received(&mut bus, receiver));
    }
    let want: Vec<String> = frames.iter().map(Frame::to_string).collect();
    assert_eq!(got, want);
    let [(number, counters, dropped, reason, _)] = left(&mut bus)[..] else {
        panic!("one node left")
    };
    assert_eq!(
        (number, counters.sent, dropped, reason),
        (sender, 200, 0, None)
    );
}

#[test]
fn a_departed_client_nobody_acknowledges_leaves_after_the_stall_bound_and_frees_the_bus() {
    // Issue 11's zombie: alone on the bus, its frames can never go (no ACK); it stays
    // error-passive and retries for ever. It must not stay on the bus.
    let mut bus = VirtualBus::new(RATE).unwrap();
    let zombie = bus.join().unwrap();
    for f in ["123#01", "124#02", "125#03"] {
        bus.submit(zombie, frame(f)).unwrap().unwrap();
    }
    bus.run_until(BitTime::new(10 * FRAME_BITS));
    bus.depart(zombie).unwrap();
    let departed = bus.now();
    bus.input_ended(zombie);
    bus.run_until(BitTime::new(
        (departed + BitTime::new(STALL_BITS) - BitTime::new(1)).get(),
    ));
    assert!(on_bus(&bus, zombie), "it keeps trying until the bound");
    bus.run_until(BitTime::new(
        (departed + BitTime::new(STALL_BITS) + GIVE_UP + BitTime::new(1)).get(),
    ));
    assert!(!on_bus(&bus, zombie), "gone within the bound");
    let [(_, counters, dropped, reason, at)] = left(&mut bus)[..] else {
        panic!("one node left")
    };
    assert_eq!(counters.sent, 0);
    assert_eq!(dropped, 3);
    assert_eq!(reason, Some(DropReason::Stalled(DEPARTURE_STALL)));
    assert!(
        (departed + BitTime::new(STALL_BITS)..=departed + BitTime::new(STALL_BITS) + GIVE_UP)
            .contains(&at),
        "left at {at}, departed at {departed}"
    );
    // The bus is free: idle, and a new pair of nodes talks at once.
    assert!(bus.is_idle());
    let a = bus.join().unwrap();
    let b = bus.join().unwrap();
    bus.submit(a, frame("321#AA")).unwrap().unwrap();
    bus.run_until(BitTime::new((bus.now() + BitTime::new(FRAME_BITS)).get()));
    assert_eq!(received(&mut bus, b), ["321#AA"]);
}

#[test]
fn a_departed_client_whose_node_goes_bus_off_leaves_and_the_errors_stop() {
    // The zombie of issue 11: the wrong bit timing, so every frame fails and its error flags
    // disturb the others, until bus-off.
    let mut bus = VirtualBus::new(RATE).unwrap();
    let zombie = bus.join().unwrap();
    let watcher = bus.join().unwrap();
    bus.set_btr(zombie, 0x07, 0x4D).unwrap();
    for k in 0..40u32 {
        bus.submit(zombie, frame(&format!("123#{k:02X}")))
            .unwrap()
            .unwrap();
    }
    bus.depart(zombie).unwrap();
    let departed = bus.now();
    bus.input_ended(zombie);
    while on_bus(&bus, zombie) {
        assert!(
            bus.now() < departed + BitTime::new(STALL_BITS),
            "it went bus-off first"
        );
        bus.run_until(BitTime::new((bus.now() + BitTime::new(FRAME_BITS)).get()));
    }
    let [(_, counters, dropped, reason, _)] = left(&mut bus)[..] else {
        panic!("one node left")
    };
    assert_eq!(reason, Some(DropReason::BusOff));
    assert_eq!(
        counters.sent + dropped,
        40,
        "every frame is sent or counted"
    );
    let errors = bus
        .status(&NodeRef::Number(watcher))
        .unwrap()
        .counters
        .bus_errors;
    assert!(errors > 0, "the zombie disturbed the bus");
    bus.run_until(BitTime::new((bus.now() + BitTime::new(STALL_BITS)).get()));
    let after = bus.status(&NodeRef::Number(watcher)).unwrap().counters;
    assert_eq!(after.bus_errors, errors, "the bus is quiet once it left");
    assert!(bus.is_idle());
}

#[test]
fn frames_handed_over_after_a_departed_node_gave_up_are_counted_as_dropped() {
    let mut bus = VirtualBus::new(RATE).unwrap();
    let zombie = bus.join().unwrap();
    bus.submit(zombie, frame("123#01")).unwrap().unwrap();
    bus.depart(zombie).unwrap();
    // The server is still reading its socket when it gives up.
    bus.run_until(BitTime::new(
        (bus.now() + BitTime::new(STALL_BITS) + GIVE_UP + BitTime::new(1)).get(),
    ));
    assert!(!on_bus(&bus, zombie), "off the bus already");
    assert!(left(&mut bus).is_empty(), "it has not finished leaving");
    for k in 0..5u32 {
        assert!(bus.takes_frame(zombie));
        assert_eq!(
            bus.submit(zombie, frame(&format!("124#{k:02X}"))),
            Ok(Ok(()))
        );
    }
    bus.input_ended(zombie);
    let [(_, _, dropped, reason, _)] = left(&mut bus)[..] else {
        panic!("one node left")
    };
    assert_eq!(dropped, 6);
    assert_eq!(reason, Some(DropReason::Stalled(DEPARTURE_STALL)));
}

#[test]
fn a_server_that_stops_while_a_departed_clients_input_is_read_still_says_it_left() {
    let mut bus = VirtualBus::new(RATE).unwrap();
    let zombie = bus.join().unwrap();
    bus.submit(zombie, frame("123#01")).unwrap().unwrap();
    bus.depart(zombie).unwrap();
    bus.run_until(BitTime::new(
        (bus.now() + BitTime::new(STALL_BITS) + GIVE_UP + BitTime::new(1)).get(),
    ));
    assert!(!on_bus(&bus, zombie));
    bus.submit(zombie, frame("123#02")).unwrap().unwrap();
    bus.leave(zombie);
    let [(_, _, dropped, reason, _)] = left(&mut bus)[..] else {
        panic!("one node left")
    };
    assert_eq!(
        (dropped, reason),
        (2, Some(DropReason::Stalled(DEPARTURE_STALL)))
    );
    assert!(bus.departing().is_empty());
}

#[test]
fn a_node_whose_client_leaves_in_the_middle_of_a_frame_finishes_it() {
    let mut bus = VirtualBus::new(RATE).unwrap();
    let sender = bus.join().unwrap();
    let receiver = bus.join().unwrap();
    bus.submit(sender, frame("1ABCDEF0#0102030405060708"))
        .unwrap()
        .unwrap();
    bus.run_until(BitTime::new((bus.now() + BitTime::new(60)).get()));
    bus.depart(sender).unwrap();
    bus.input_ended(sender);
    bus.run_until(BitTime::new(
        (bus.now() + BitTime::new(2) * FRAME_BITS).get(),
    ));
    assert_eq!(received(&mut bus, receiver), ["1ABCDEF0#0102030405060708"]);
    assert!(!on_bus(&bus, sender));
    let st = bus.status(&NodeRef::Number(receiver)).unwrap();
    assert_eq!(st.counters.bus_errors, 0, "nobody saw a cut frame");
    let [(_, counters, 0, None, _)] = left(&mut bus)[..] else {
        panic!("it left with nothing dropped")
    };
    assert_eq!(counters.sent, 1);
}

#[test]
fn a_client_reconnecting_at_once_shares_the_bus_with_its_departing_node_and_its_name() {
    // python-can scripts run back to back: the next joins while the last one's node still
    // sends, and may ask for the same name.
    let mut bus = VirtualBus::new(RATE).unwrap();
    let receiver = bus.join().unwrap();
    let first = bus.join().unwrap();
    bus.rename(first, "script").unwrap();
    let firsts: Vec<Frame> = (0..30u32).map(|k| frame(&format!("100#{k:02X}"))).collect();
    hand_over(&mut bus, first, &firsts[..20]);
    bus.depart(first).unwrap();
    hand_over(&mut bus, first, &firsts[20..]);
    bus.input_ended(first);
    let second = bus.join().unwrap();
    bus.rename(second, "script").unwrap();
    assert_eq!(
        bus.nodes()
            .iter()
            .find(|n| n.number == first)
            .map(|n| n.name.clone()),
        Some(format!("node{first}")),
        "the departing node gave its name up"
    );
    let seconds: Vec<Frame> = (0..30u32).map(|k| frame(&format!("200#{k:02X}"))).collect();
    hand_over(&mut bus, second, &seconds);
    bus.run_until(BitTime::new(
        (bus.now() + BitTime::new(80) * FRAME_BITS).get(),
    ));
    let got = received(&mut bus, receiver);
    let of =
        |id: &str| -> Vec<String> { got.iter().filter(|f| f.starts_with(id)).cloned().collect() };
    let want = |frames: &[Frame]| -> Vec<String> { frames.iter().map(Frame::to_string).collect() };
    assert_eq!(of("100#"), want(&firsts));
    assert_eq!(of("200#"), want(&seconds));
    assert!(!on_bus(&bus, first));
    assert!(on_bus(&bus, second));
}

#[test]
fn a_node_taken_off_at_once_counts_what_it_had_not_sent() {
    // The server stops: nodes leave at once, and say what they dropped.
    let mut bus = VirtualBus::new(RATE).unwrap();
    let a = bus.join().unwrap();
    for k in 0..5u32 {
        bus.submit(a, frame(&format!("123#{k:02X}")))
            .unwrap()
            .unwrap();
    }
    bus.leave(a);
    assert!(!on_bus(&bus, a));
    let [(_, _, dropped, reason, _)] = left(&mut bus)[..] else {
        panic!("one node left")
    };
    assert_eq!((dropped, reason), (5, Some(DropReason::Removed)));
    let text = BusEvent::Left {
        number: a,
        name: "node1".into(),
        counters: NodeCounters::default(),
        dropped: 5,
        reason: Some(DropReason::Stalled(DEPARTURE_STALL)),
    }
    .to_string();
    assert_eq!(
        text,
        "node 1 (node1) left: sent 0, dropped 5 (none sent for 1.00 s of bus time), received 0, lost 0"
    );
}
