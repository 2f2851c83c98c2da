//! A node at the wrong bit rate on a bus with traffic, in virtual time: how much it disturbs
//! the others, as on a real wire (docs/decisions.md, "An SLCAN host at the wrong bit rate").
//!
//! It reads an idle bus right (recessive at any rate) and garbage while a frame passes; while
//! error-active its error flags break the others' frames, until its receive errors make it
//! error-passive; each of its own attempts breaks the frame on the wire until its transmit
//! errors take it bus-off. With no automatic recovery (a Lawicel CANUSB's, Linux's default)
//! it then stays off; with the seed's counted recovery it comes back and starts again.

use buslab_can::BitTime;
use buslab_canbus::{BusOffRecovery, ErrorState, NodeRef};
use buslab_sja1000::BitTiming;
use buslab_vbus::VirtualBus;

const RATE: u32 = 125_000;
/// Bit-times in a second of the bus.
const SECOND: u64 = RATE as u64;
/// The host's rate: python-can's `bitrate=500000` on the lab's 125 kbit/s bus.
const HOST_RATE: u32 = 500_000;

/// A lab-like bus: `lab` sends a frame every 10 ms, `observer` listens (and acknowledges).
fn lab() -> VirtualBus {
    let scenario = buslab_bench::Scenario::from_toml(
        "bitrate = 125000\n\
         [[nodes]]\nname = \"lab\"\nkind = \"sja1000\"\n  [[nodes.traffic]]\n  kind = \"periodic\"\n  frame = \"0C0#0FA0\"\n  period = \"10ms\"\n\
         [[nodes]]\nname = \"observer\"\nkind = \"sja1000\"\n",
    )
    .unwrap();
    VirtualBus::new(RATE)
        .unwrap()
        .with_scenario(scenario.build().unwrap())
}

/// The bus errors the observer has detected.
fn observed(bus: &mut VirtualBus) -> u64 {
    let st = bus.status(&NodeRef::Name("observer".into())).unwrap();
    st.counters.bus_errors
}

fn frames_of_lab(bus: &mut VirtualBus) -> u64 {
    let st = bus.status(&NodeRef::Name("lab".into())).unwrap();
    st.counters.sent
}

/// A client node programmed for `HOST_RATE` at the adapter's 8 MHz CAN clock.
fn adapter(bus: &mut VirtualBus, recovery: BusOffRecovery) -> u32 {
    let n = bus.join().unwrap();
    bus.client_mut(n).unwrap().set_bus_off_recovery(recovery);
    let (btr0, btr1) = BitTiming::for_bitrate(8_000_000, HOST_RATE, None)
        .unwrap()
        .registers();
    bus.set_btr(n, btr0, btr1).unwrap();
    assert!(
        !bus.status(&NodeRef::Number(n))
            .unwrap()
            .timing
            .unwrap()
            .matches_bus
    );
    n
}

fn state(bus: &mut VirtualBus, n: u32) -> ErrorState {
    bus.status(&NodeRef::Number(n)).unwrap().state
}

#[test]
fn a_node_at_the_wrong_rate_on_an_idle_bus_disturbs_nobody() {
    let mut bus = VirtualBus::new(RATE).unwrap();
    let observer = bus.join().unwrap();
    let _adapter = adapter(&mut bus, BusOffRecovery::Manual);
    bus.run_until(BitTime::new(SECOND));
    assert_eq!(bus.stats().errors, 0);
    let st = bus.status(&NodeRef::Number(observer)).unwrap();
    assert_eq!(st.counters.bus_errors, 0);
}

#[test]
fn a_listening_node_at_the_wrong_rate_breaks_frames_until_it_is_error_passive_then_rarely() {
    let mut bus = lab();
    let adapter = adapter(&mut bus, BusOffRecovery::Manual);
    let mut second = 0;
    while state(&mut bus, adapter) == ErrorState::Active {
        second += 1;
        assert!(second <= 10, "still error-active after {second} s");
        bus.run_until(BitTime::new(second * SECOND));
    }
    let until_passive = observed(&mut bus);
    // Each error it detects adds at least 1 to its REC: error-passive at 128 at the latest.
    assert!((1..=128).contains(&until_passive), "{until_passive} errors");
    // Then its error flags are recessive: the lab's frames go through. What still reaches
    // the wire are its overload flags, when garbage read as a dominant bit in its
    // intermission: a real controller at the wrong rate does the same.
    let sent = frames_of_lab(&mut bus);
    bus.run_until(BitTime::new((second + 10) * SECOND));
    let later = observed(&mut bus) - until_passive;
    assert_eq!(frames_of_lab(&mut bus), sent + 1000);
    assert!(
        later <= 1000 / 100,
        "{later} errors in 1000 frames once passive"
    );
    eprintln!(
        "errors seen by the observer until the adapter was error-passive: {until_passive}, \
         in the next 10 s (1000 frames of the lab): {later}"
    );
}

/// The host sends frames it cannot get through: at most 32 attempts (TEC += 8 from below 256)
/// break the frame on the wire, then bus-off; without recovery it stays off and the bus is
/// quiet, with the seed's counted recovery it comes back and breaks frames again.
#[test]
fn a_sender_at_the_wrong_rate_goes_bus_off_once_and_stays_off_without_recovery() {
    let mut counts = Vec::new();
    for recovery in [BusOffRecovery::Manual, BusOffRecovery::Counted] {
        let mut bus = lab();
        let adapter = adapter(&mut bus, recovery);
        bus.run_until(BitTime::new(SECOND / 10));
        for k in 0..3u8 {
            let frame = format!("123#{k:02X}").parse().unwrap();
            bus.submit(adapter, frame).unwrap().unwrap();
        }
        bus.run_until(BitTime::new(SECOND * 2));
        let after_2s = observed(&mut bus);
        let sent_2s = frames_of_lab(&mut bus);
        bus.run_until(BitTime::new(SECOND * 12));
        let after_12s = observed(&mut bus);
        let st = bus.status(&NodeRef::Number(adapter)).unwrap();
        counts.push((recovery, after_2s, after_12s, st.counters.bus_off));
        if recovery == BusOffRecovery::Manual {
            assert_eq!(st.state, ErrorState::BusOff);
            assert_eq!(st.counters.bus_off, 1);
            assert_eq!(st.counters.sent, 0);
            // Receive errors until error-passive (at most 128), then its 32 attempts at most.
            assert!(after_2s <= 128 + 32, "{after_2s} errors");
            assert_eq!(after_12s, after_2s, "errors after bus-off");
            assert_eq!(frames_of_lab(&mut bus), sent_2s + 1000);
        } else {
            assert!(st.counters.bus_off > 1, "{st}");
            assert!(after_12s > after_2s, "the counted recovery starts again");
        }
    }
    eprintln!("(recovery, errors seen by the observer at 2 s, at 12 s, bus-offs): {counts:?}");
}
