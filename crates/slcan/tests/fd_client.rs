//! The `slcan:` client with CAN FD: opened for FD it sets the data bit rate and sends and
//! receives `d`/`D`/`b`/`B` frames; opened classic it refuses FD frames by name; a classic
//! adapter refusing `Yn` fails the opening.

#[path = "support/fake_adapter.rs"]
#[allow(dead_code)] // the kinds and knobs the opening tests use
mod fake_adapter;

use std::time::Duration;

use buslab_bus::{BusError, CanBus, Filter, NoFd, Record};
use buslab_can::FdFrame;
use buslab_slcan::{SlcanBus, SlcanError, SlcanOptions};
use fake_adapter::{FakeAdapter, Kind};

/// A deadline for an answer that normally comes within milliseconds (CI machines are loaded).
const EVENT: Duration = Duration::from_secs(60);

fn fd(text: &str) -> FdFrame {
    text.parse().unwrap()
}

fn options(fd: bool, data_bitrate: Option<u32>) -> SlcanOptions {
    SlcanOptions {
        bitrate: Some(500_000),
        reply_timeout: EVENT,
        fd,
        data_bitrate,
        ..SlcanOptions::default()
    }
}

#[test]
fn an_fd_adapter_sets_the_data_bit_rate_and_carries_fd_frames_both_ways() {
    let fake = FakeAdapter::start(Kind::Model);
    fake.speak_fd();
    let mut bus = SlcanBus::open(fake.path(), &options(false, Some(2_000_000))).unwrap();
    assert!(bus.fd_support().carried(), "a data bit rate implies FD");
    // The data bit rate after the nominal one, before opening, as python-can sends them.
    let lines = fake.seen(|s| s.lines.clone());
    let at = |l: &str| lines.iter().position(|x| x == l).unwrap();
    assert!(at("S6") < at("Y2") && at("Y2") < at("O"), "{lines:?}");

    let long = fd(&format!("1ABCDEF0##1{}", "C3".repeat(64)));
    bus.send_fd(&fd("123##0112233")).unwrap();
    bus.send(&"124#01".parse().unwrap()).unwrap();
    bus.send_fd(&long).unwrap();
    fake.wait_for(EVENT, |s| s.transmitted.len() == 3);
    assert_eq!(
        fake.seen(|s| s.transmitted.clone()),
        [
            "123##0112233".to_string(),
            "124#01".into(),
            long.to_string()
        ]
    );

    // From the adapter: FD frames with and without BRS, in order with a classic one.
    fake.deliver("b3219AABBCCDDEEFF001122334455");
    fake.deliver("t3201AA");
    fake.deliver("D123456780");
    let got: Vec<Record> = (0..3)
        .map(|_| {
            bus.recv_event(Some(EVENT))
                .unwrap()
                .expect("a frame")
                .record
        })
        .collect();
    assert_eq!(
        got,
        [
            Record::Fd(fd("321##1AABBCCDDEEFF001122334455")),
            Record::Frame("320#AA".parse().unwrap()),
            Record::Fd(fd("12345678##0")),
        ]
    );
    // recv gives classic frames only: the FD frame before this one is passed by.
    fake.deliver("d3210");
    fake.deliver("t3211BB");
    let m = bus.recv(Some(EVENT)).unwrap().expect("a frame");
    assert_eq!(m.record.to_string(), "321#BB");
    // Filters apply to FD frames by ID.
    bus.set_filters(&[Filter::standard(0x100)]).unwrap();
    fake.deliver("d2001AA");
    fake.deliver("d1001BB");
    let m = bus.recv_event(Some(EVENT)).unwrap().expect("a frame");
    assert_eq!(m.record, Record::Fd(fd("100##0BB")));
}

#[test]
fn a_classic_adapter_refuses_fd_frames_by_name_and_writes_nothing() {
    let fake = FakeAdapter::start(Kind::Model);
    let mut bus = SlcanBus::open(fake.path(), &options(false, None)).unwrap();
    assert!(!bus.fd_support().carried());
    let err = bus.send_fd(&fd("123##0AA")).unwrap_err();
    assert!(
        matches!(
            &err,
            BusError::ClassicOnly {
                why: NoFd::ClassicAdapter,
                ..
            }
        ),
        "{err:?}"
    );
    assert!(
        err.to_string().starts_with(&format!(
            "SLCAN adapter on {} is classic CAN: the adapter was opened for classic CAN (for an FD adapter such as a CANable 2.0 add fd=1 or data_bitrate=N",
            fake.path()
        )),
        "{err}"
    );
    bus.send(&"100#".parse().unwrap()).unwrap();
    fake.wait_for(EVENT, |s| !s.transmitted.is_empty());
    drop(bus);
    fake.wait_for(EVENT, |s| !s.open);
    assert!(
        fake.seen(|s| s.lines.iter().all(|l| !l.starts_with('d'))),
        "no FD line went out"
    );
    assert_eq!(fake.seen(|s| s.transmitted.clone()), ["100#"]);
}

#[test]
fn an_fd_frame_the_adapter_refuses_does_not_stop_the_frames_after_it() {
    // Opened for FD, but the adapter is classic: it answers the FD frame BEL.
    let fake = FakeAdapter::start(Kind::Model);
    let mut bus = SlcanBus::open(fake.path(), &options(true, None)).unwrap();
    bus.send_fd(&fd("123##0AA")).unwrap();
    bus.send(&"100#".parse().unwrap()).unwrap();
    fake.wait_for(EVENT, |s| !s.transmitted.is_empty());
    assert_eq!(fake.seen(|s| s.transmitted.clone()), ["100#"]);
}

#[test]
fn a_classic_adapter_refusing_the_data_bit_rate_fails_the_opening() {
    let fake = FakeAdapter::start(Kind::Lawicel);
    let err = SlcanBus::open(fake.path(), &options(true, Some(5_000_000)))
        .err()
        .expect("Y5 refused");
    assert!(
        err.to_string()
            .contains("the adapter refused \"Y5\" (answered BEL)"),
        "{err}"
    );
    let err = SlcanBus::open(fake.path(), &options(true, Some(2_500_000)))
        .err()
        .expect("no Y code");
    assert!(
        matches!(err, SlcanError::DataBitrate { bitrate: 2_500_000 }),
        "{err}"
    );
    assert!(
        err.to_string()
            .starts_with("data bit rate 2500000 bit/s cannot be set: SLCAN's Y command has Y0 = 500000, Y1 = 1000000"),
        "{err}"
    );
}
