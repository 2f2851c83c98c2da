//! The manager owning a driver, with the bus stepped by another thread.

// The driver crate's test bus (shared chips on the one engine), one file for both crates.
#[path = "../../sja1000-driver/tests/common/mod.rs"]
mod common;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Receiver;
use std::thread::{self, JoinHandle};
use std::time::Duration;

use buslab_can::Level;
use buslab_canbus::driver::DriverEvent;
use buslab_canbus::manager::{ManagerError, SendError};
use buslab_canbus::{
    CanBus, ErrorState, Filter, Manager, ManagerConfig, ManagerHandle, SharedChip, Sja1000Config,
    Sja1000Driver, Status,
};
use common::{Bus, frame};

/// The ceiling of every wait for an event (a confirmation, a frame, a status change): each
/// needs a few hundred bit-times of a bus stepped flat out, so only a broken manager gets near
/// it, even on a loaded machine.
const LONG: Duration = Duration::from_secs(60);

/// Steps the bus in a thread until dropped. While `jam` is set, a disturber forces the 21st
/// bit of each of chip 0's transmissions dominant, so its every attempt fails with a bit error.
struct Stepper {
    stop: Arc<AtomicBool>,
    jam: Arc<AtomicBool>,
    join: Option<JoinHandle<()>>,
}

impl Stepper {
    fn start(chips: Vec<SharedChip>) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let jam = Arc::new(AtomicBool::new(false));
        let (s, j) = (stop.clone(), jam.clone());
        let join = thread::spawn(move || {
            let mut bus = Bus::from_chips(chips);
            let (mut was_transmitting, mut sof) = (false, 0);
            while !s.load(Ordering::Relaxed) {
                for _ in 0..64 {
                    let transmitting = bus.chips[0].lock().unwrap().peek(2) & 0x20 != 0;
                    if transmitting && !was_transmitting {
                        sof = bus.time - 1;
                    }
                    was_transmitting = transmitting;
                    // The first data bit of each attempt (recessive for 0xFF) goes dominant.
                    let hit = j.load(Ordering::Relaxed) && transmitting && bus.time == sof + 20;
                    bus.step_with(|_, level| if hit { Level::Dominant } else { level });
                }
                thread::sleep(Duration::from_micros(50));
            }
        });
        Self {
            stop,
            jam,
            join: Some(join),
        }
    }
}

impl Drop for Stepper {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(join) = self.join.take() {
            let _ = join.join();
        }
    }
}

fn manage(chip: &SharedChip, config: &Sja1000Config, channel: &str) -> ManagerHandle {
    let mut driver = Sja1000Driver::new(chip.clone());
    driver.init(config).unwrap();
    Manager::start(
        driver,
        ManagerConfig {
            poll_interval: Duration::from_micros(200),
            channel: channel.into(),
            ..ManagerConfig::default()
        },
    )
}

/// Waits for the first value from `rx` that satisfies `want`.
fn wait_for<T: std::fmt::Debug>(rx: &Receiver<T>, what: &str, want: impl Fn(&T) -> bool) -> T {
    loop {
        match rx.recv_timeout(LONG) {
            Ok(value) if want(&value) => return value,
            Ok(_) => {}
            Err(e) => panic!("{what}: {e}"),
        }
    }
}

#[test]
fn confirmations_come_in_order_and_listeners_get_the_frames() {
    let bus = Bus::new(2);
    let a = manage(&bus.chips[0], &Sja1000Config::default(), "a");
    let b = manage(&bus.chips[1], &Sja1000Config::basic_can(), "b");
    let frames_b = b.subscribe_frames();
    let events_a = a.subscribe_events();
    let _stepper = Stepper::start(bus.chips.clone());

    // Short frames: all ten fit the receiver's FIFO even if its manager is slow.
    let sent: Vec<String> = (0..10)
        .map(|i| format!("{:03X}#{i:02X}", 0x700 - i))
        .collect();
    let confirmations: Vec<_> = sent.iter().map(|f| a.send(frame(f))).collect();
    for confirmation in &confirmations {
        assert_eq!(confirmation.wait(Some(LONG)), Ok(()));
        assert_eq!(confirmation.wait(None), Ok(()), "asked again: same answer");
    }
    let done: Vec<String> = events_a
        .try_iter()
        .filter_map(|e| match e {
            DriverEvent::TxDone(f) => Some(f.to_string()),
            _ => None,
        })
        .collect();
    assert_eq!(done, sent, "one at a time, in the order queued");
    let got: Vec<String> = (0..10)
        .map(|_| {
            let message = frames_b.recv_timeout(LONG).unwrap();
            assert!(message.is_rx());
            assert_eq!(message.channel, "b");
            assert!(message.at.as_secs() > 1_000_000_000, "wall-clock seconds");
            message.record.to_string()
        })
        .collect();
    assert_eq!(got, sent);
    a.shutdown();
    b.shutdown();
}

#[test]
fn status_and_error_listeners_see_a_lone_transmitter_struggle_and_abort_all_fails_the_queue() {
    let bus = Bus::new(1); // nobody acknowledges
    let a = manage(&bus.chips[0], &Sja1000Config::default(), "a");
    let status = a.subscribe_status();
    let errors = a.subscribe_errors();
    let first = status.recv_timeout(LONG).unwrap();
    assert!(
        first.transmit_buffer_released(),
        "the current status first: {first}"
    );
    assert_eq!(errors.recv_timeout(LONG).unwrap().txerr, 0);
    let _stepper = Stepper::start(bus.chips.clone());

    let confirmations: Vec<_> = ["100#01", "101#02", "102#03"]
        .iter()
        .map(|f| a.send(frame(f)))
        .collect();
    wait_for(&status, "TX buffer locked", |s: &Status| {
        !s.transmit_buffer_released()
    });
    let warned = wait_for(&status, "error status", |s: &Status| s.error_status());
    assert!(
        warned
            .to_string()
            .contains("error status (≥ warning limit)")
    );
    let counted = wait_for(&errors, "TXERR ≥ 96", |e| e.txerr >= 96);
    assert_eq!(
        counted.ecc.map(|e| e.to_string()),
        Some("other error (CRC or ACK) during transmission in acknowledge slot".into())
    );
    assert_eq!(confirmations[0].try_result(), None, "still retrying");
    assert_eq!(a.snapshot().unwrap().queued, 3);

    a.abort_all();
    for confirmation in &confirmations {
        assert_eq!(confirmation.wait(Some(LONG)), Err(SendError::Aborted));
    }
    assert_eq!(a.snapshot().unwrap().queued, 0);
    a.shutdown();
}

#[test]
fn abort_current_fails_only_the_frame_in_the_buffer() {
    let bus = Bus::new(1);
    let a = manage(&bus.chips[0], &Sja1000Config::default(), "a");
    let errors = a.subscribe_errors();
    let _stepper = Stepper::start(bus.chips.clone());
    let first = a.send(frame("100#"));
    let second = a.send(frame("101#"));
    wait_for(&errors, "a failed attempt", |e| e.txerr > 0);
    a.abort_current();
    assert_eq!(first.wait(Some(LONG)), Err(SendError::Aborted));
    assert_eq!(
        second.try_result(),
        None,
        "the next frame is now being tried"
    );
    a.abort_current();
    assert_eq!(second.wait(Some(LONG)), Err(SendError::Aborted));
    a.shutdown();
}

#[test]
fn bus_off_fails_sends_and_restart_recovers() {
    let bus = Bus::new(2);
    let a = manage(&bus.chips[0], &Sja1000Config::default(), "a");
    let b = manage(&bus.chips[1], &Sja1000Config::default(), "b");
    let status = a.subscribe_status();
    let frames_b = b.subscribe_frames();
    let stepper = Stepper::start(bus.chips.clone());

    stepper.jam.store(true, Ordering::Relaxed);
    let queued_behind = {
        let first = a.send(frame("123#FF"));
        let second = a.send(frame("124#FF"));
        assert_eq!(first.wait(Some(LONG)), Err(SendError::BusOff));
        second
    };
    assert_eq!(queued_behind.wait(Some(LONG)), Err(SendError::BusOff));
    wait_for(&status, "bus-off", |s: &Status| s.bus_off());
    assert_eq!(
        a.send(frame("125#")).wait(Some(LONG)),
        Err(SendError::BusOff)
    );
    let mut bus_a = a.bus("a");
    assert_eq!(bus_a.state().unwrap(), ErrorState::BusOff);

    stepper.jam.store(false, Ordering::Relaxed);
    a.restart().unwrap();
    assert_eq!(a.send(frame("126#01")).wait(Some(LONG)), Ok(()));
    let message = wait_for(&frames_b, "the frame after restart", |_| true);
    assert_eq!(message.record, frame("126#01"));
    assert_eq!(bus_a.state().unwrap(), ErrorState::Active);
    a.shutdown();
    b.shutdown();
}

#[test]
fn reinit_reports_bad_configurations_and_rejected_frames_say_why() {
    let bus = Bus::new(2);
    // Started without init: everything comes through reinit.
    let a = Manager::start(
        Sja1000Driver::new(bus.chips[0].clone()),
        ManagerConfig::default(),
    );
    let b = manage(&bus.chips[1], &Sja1000Config::default(), "b");
    let _stepper = Stepper::start(bus.chips.clone());
    assert_eq!(
        a.send(frame("123#")).wait(Some(LONG)),
        Err(SendError::Rejected(
            buslab_canbus::DriverError::NotInitialized
        ))
    );
    let bad = Sja1000Config {
        crystal_hz: 100,
        ..Sja1000Config::default()
    };
    let err = a.reinit(bad).unwrap_err();
    assert_eq!(
        err.to_string(),
        "invalid configuration: crystal frequency 100 Hz is out of range 1000000..=24000000 Hz"
    );
    a.reinit(Sja1000Config::basic_can()).unwrap();
    let refused = a.send(frame("12345678#")).wait(Some(LONG)).unwrap_err();
    assert_eq!(
        refused.to_string(),
        "the driver refused the frame: frame 12345678# has an extended ID; BasicCAN mode sends 11-bit IDs only"
    );
    assert_eq!(a.send(frame("123#")).wait(Some(LONG)), Ok(()));
    assert_eq!(a.error_registers().unwrap(), None, "BasicCAN");
    assert!(b.error_registers().unwrap().is_some());
    a.shutdown();
    b.shutdown();
}

#[test]
fn the_manager_as_a_can_bus_filters_in_software() {
    let bus = Bus::new(2);
    let a = manage(&bus.chips[0], &Sja1000Config::default(), "a");
    let b = manage(&bus.chips[1], &Sja1000Config::default(), "b");
    let mut rx = b.bus("vcan-b");
    let mut tx = a.bus("vcan-a");
    tx.confirm_timeout = Some(LONG);
    assert_eq!(rx.channel_info(), "SJA1000 manager on vcan-b");
    rx.set_filters(&[Filter::standard(0x123), Filter::extended(0x42)])
        .unwrap();
    let _stepper = Stepper::start(bus.chips.clone());
    // The last frame passes the filter: frames arrive in bus order, so any frame the filter
    // let through by mistake shows up before it (no quiet period to wait out).
    for f in [
        "122#01",
        "123#02",
        "00000123#03",
        "042#04",
        "00000042#05",
        "123#FF",
    ] {
        tx.send(&frame(f)).unwrap();
    }
    let got: Vec<String> = (0..3)
        .map(|_| rx.recv(Some(LONG)).unwrap().unwrap().record.to_string())
        .collect();
    assert_eq!(got, ["123#02", "00000042#05", "123#FF"]);
    assert_eq!(rx.state().unwrap(), ErrorState::Active);
    a.shutdown();
    b.shutdown();
}

#[test]
fn shutdown_fails_pending_sends_and_ends_subscriptions() {
    let bus = Bus::new(1);
    let a = manage(&bus.chips[0], &Sja1000Config::default(), "a");
    let frames = a.subscribe_frames();
    let _stepper = Stepper::start(bus.chips.clone());
    let pending = a.send(frame("123#")); // never acknowledged
    let clone = a.clone();
    assert!(clone.is_running());
    clone.shutdown();
    assert_eq!(pending.wait(Some(LONG)), Err(SendError::Shutdown));
    assert!(frames.recv_timeout(LONG).is_err(), "subscription ended");
    assert!(!a.is_running());
    a.shutdown(); // twice is fine
    assert_eq!(a.send(frame("124#")).wait(None), Err(SendError::Shutdown));
    assert_eq!(a.status(), Err(ManagerError::Shutdown));
    assert_eq!(
        a.reinit(Sja1000Config::default()),
        Err(ManagerError::Shutdown)
    );
    let mut bus_a = a.bus("a");
    assert!(bus_a.recv(None).is_err(), "a closed bus does not block");
}
