//! The `slcan:` client's wait for frames can be ended from another thread
//! (`CanBus::recv_waker`): a pump that owns the bus hands it a frame at once instead of
//! waiting out a read timeout. A wait for the adapter's answer to a command is not ended by it.
//! (That bytes already there come before a pending wake is `buslab_link::wake`'s own test.)

#[path = "support/fake_adapter.rs"]
#[allow(dead_code)] // the kinds and knobs the opening tests use
mod fake_adapter;

use std::sync::mpsc;
use std::thread;
use std::time::Duration;

use buslab_bus::CanBus;
use buslab_can::Frame;
use buslab_slcan::{SlcanBus, SlcanOptions};
use fake_adapter::{FakeAdapter, Kind};

/// A deadline for what normally comes within milliseconds (CI machines are loaded).
const EVENT: Duration = Duration::from_secs(60);

fn open(fake: &FakeAdapter) -> SlcanBus {
    let options = SlcanOptions {
        bitrate: Some(500_000),
        reply_timeout: EVENT,
        ..SlcanOptions::default()
    };
    SlcanBus::open(fake.path(), &options).unwrap()
}

/// Runs `wait` on the bus in a thread; what it returned, or a failure if it did not return
/// within [`EVENT`] (without the wake it would wait forever).
fn returns<T: Send + 'static>(
    bus: SlcanBus,
    wait: impl FnOnce(&mut SlcanBus) -> T + Send + 'static,
) -> (SlcanBus, T) {
    let (tx, rx) = mpsc::channel();
    thread::spawn(move || {
        let mut bus = bus;
        let got = wait(&mut bus);
        let _ = tx.send((bus, got));
    });
    rx.recv_timeout(EVENT)
        .expect("the wait for frames was not ended by the wake")
}

#[test]
fn a_wake_ends_a_wait_for_frames_not_a_wait_for_an_answer() {
    let fake = FakeAdapter::start(Kind::Model);
    let mut bus = open(&fake);
    let waker = bus.recv_waker().expect("an SLCAN bus can be woken");

    // A wake while nobody waits ends the next wait (a wake is never lost), even one with
    // no deadline.
    waker.wake();
    let (bus, got) = returns(bus, |bus| bus.recv(None).map(|m| m.is_some()));
    assert!(matches!(got, Ok(false)), "{got:?}");

    // A wake from another thread while the wait is on.
    let woken = waker.clone();
    let (bus, got) = returns(bus, move |bus| {
        thread::spawn(move || woken.wake());
        bus.recv(None).map(|m| m.is_some())
    });
    assert!(matches!(got, Ok(false)), "{got:?}");

    // Frames come through a bus with a wake line as before, and a wake is kept over them.
    let (mut bus, _) = returns(bus, |_| ());
    fake.deliver("t1232AABB");
    let m = bus.recv(Some(EVENT)).unwrap().expect("the frame");
    assert_eq!(m.record, "123#AABB".parse::<Frame>().unwrap());
    waker.wake();
    fake.deliver("t1241CC");
    let m = bus.recv(Some(EVENT)).unwrap().expect("the frame");
    assert_eq!(m.record, "124#CC".parse::<Frame>().unwrap());
    let (bus, got) = returns(bus, |bus| bus.recv(None).map(|m| m.is_some()));
    assert!(matches!(got, Ok(false)), "the wake was kept: {got:?}");
    let mut bus = bus;

    // Waits for an adapter's answer go on through a wake.
    waker.wake();
    bus.status_flags(EVENT).expect("the adapter's status flags");
    assert!(
        bus.recv(Some(Duration::ZERO)).unwrap().is_none(),
        "the wake waited for the next wait for frames"
    );
    drop(bus);
    fake.wait_for(EVENT, |s| !s.open);
}
