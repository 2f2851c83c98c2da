//! `SocketcandBus` against a scripted fake server: flush by event and its fallback, late
//! replies, error frames in order with frames, plain socketcand without extensions.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::Duration;

use buslab_bus::{
    CanBus, CanError, ErrorState, Message, NodeCounters, NodeStatus, ProtocolLocation,
    ProtocolViolation, Record, Timestamp, TxReport,
};
use buslab_socketcand::{ClientError, Command, Deframer, SocketcandBus, status_fields};

/// Long enough never to matter: the fake server answers at once or not at all.
const WAIT: Option<Duration> = Some(Duration::from_secs(30));

/// A server that greets like socketcand and answers each command with what `script` returns
/// (the handshake and `buslab_ext` are answered `< ok >` unless `plain`). Every command it
/// saw is in `seen`.
struct Fake {
    addr: SocketAddr,
    seen: Arc<Mutex<Vec<Command>>>,
    thread: Option<JoinHandle<()>>,
}

impl Fake {
    fn start(plain: bool, mut script: impl FnMut(&Command) -> String + Send + 'static) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        let seen = Arc::new(Mutex::new(Vec::new()));
        let log = seen.clone();
        let thread = thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            s.write_all(b"< hi >").unwrap();
            let mut deframer = Deframer::new();
            let mut buf = [0u8; 4096];
            loop {
                let n = match s.read(&mut buf) {
                    Ok(0) | Err(_) => return,
                    Ok(n) => n,
                };
                deframer.push(&buf[..n]);
                while let Some(element) = deframer.next_element() {
                    let cmd = Command::parse(&element.unwrap()).unwrap();
                    log.lock().unwrap().push(cmd.clone());
                    let answer = match &cmd {
                        Command::Open(_) | Command::RawMode => "< ok >".to_string(),
                        Command::Extensions if plain => "< error unknown command >".to_string(),
                        Command::Extensions => "< ok >".to_string(),
                        other => script(other),
                    };
                    if s.write_all(answer.as_bytes()).is_err() {
                        return;
                    }
                }
            }
        });
        Self {
            addr,
            seen,
            thread: Some(thread),
        }
    }

    fn client(&self) -> SocketcandBus {
        let mut bus = SocketcandBus::connect(self.addr, "vcan0").unwrap();
        bus.enable_extensions().unwrap();
        bus
    }

    fn count(&self, want: &Command) -> usize {
        self.seen
            .lock()
            .unwrap()
            .iter()
            .filter(|c| *c == want)
            .count()
    }
}

impl Drop for Fake {
    fn drop(&mut self) {
        if let Some(t) = self.thread.take() {
            // The client is gone by now: the server's read ends.
            let _ = t.join();
        }
    }
}

fn status_with(sent: u64, tx_failed: u64) -> String {
    let st = NodeStatus {
        number: 1,
        name: "node1".into(),
        state: ErrorState::Active,
        errors: None,
        sr: None,
        timing: None,
        counters: NodeCounters {
            sent,
            tx_failed,
            ..NodeCounters::default()
        },
        tx_queued: 0,
        bus: Default::default(),
    };
    format!("< buslab_status {} >", status_fields(&st).join(" "))
}

fn frame(text: &str) -> buslab_can::Frame {
    text.parse().unwrap()
}

#[test]
fn flush_waits_for_the_servers_answer_and_keeps_frames_that_came_meanwhile() {
    let fake = Fake::start(false, |cmd| match cmd {
        Command::Send(_) => String::new(),
        // A frame from the bus arrives before the answer.
        Command::Flush => "< frame 321 1.000000 AA >< buslab_flushed 2 0 >".into(),
        _ => "< error unexpected >".into(),
    });
    let mut bus = fake.client();
    bus.send(&frame("123#01")).unwrap();
    bus.send(&frame("124#02")).unwrap();
    let admin = bus.admin().expect("a buslab server");
    assert_eq!(
        admin.flush(Duration::from_secs(30)).unwrap(),
        TxReport { sent: 2, failed: 0 }
    );
    let m = bus.recv(WAIT).unwrap().unwrap();
    assert_eq!(m.record, frame("321#AA"));
    drop(bus);
    // One request, no status polling.
    assert_eq!(fake.count(&Command::Flush), 1);
    assert_eq!(fake.count(&Command::Status(None)), 0);
}

#[test]
fn flush_falls_back_to_polling_status_only_on_a_server_that_does_not_know_it() {
    let polls = Arc::new(Mutex::new(0u64));
    let p = polls.clone();
    let fake = Fake::start(false, move |cmd| match cmd {
        Command::Send(_) => String::new(),
        // What buslab servers before buslab_flush answer.
        Command::Flush => "< error ( buslab_flush ) is not an extension command >".into(),
        Command::Status(None) => {
            let mut n = p.lock().unwrap();
            *n += 1;
            // The frames go out while the client polls: 0, 1, then both (one failed).
            match *n {
                1 => status_with(0, 0),
                2 => status_with(1, 0),
                _ => status_with(1, 1),
            }
        }
        _ => "< error unexpected >".into(),
    });
    let mut bus = fake.client();
    bus.send(&frame("123#01")).unwrap();
    bus.send(&frame("124#02")).unwrap();
    assert_eq!(
        bus.flush(Duration::from_secs(30)).unwrap(),
        TxReport { sent: 1, failed: 1 }
    );
    assert_eq!(*polls.lock().unwrap(), 3);
    // Known now: the next flush polls at once.
    assert_eq!(
        bus.flush(Duration::from_secs(30)).unwrap(),
        TxReport { sent: 1, failed: 1 }
    );
    drop(bus);
    assert_eq!(fake.count(&Command::Flush), 1);
}

#[test]
fn a_flush_refused_for_another_reason_is_an_error() {
    let fake = Fake::start(false, |cmd| match cmd {
        Command::Flush => "< error the node left the bus >".into(),
        _ => "< error unexpected >".into(),
    });
    let mut bus = fake.client();
    let err = bus.flush(Duration::from_secs(30)).unwrap_err();
    assert!(
        matches!(&err, ClientError::Server(t) if t == "the node left the bus"),
        "{err}"
    );
    drop(bus);
    assert_eq!(fake.count(&Command::Status(None)), 0);
}

#[test]
fn a_late_reply_does_not_answer_the_next_request() {
    let flushes = Arc::new(Mutex::new(0));
    let f = flushes.clone();
    let fake = Fake::start(false, move |cmd| match cmd {
        Command::Flush => {
            let mut n = f.lock().unwrap();
            *n += 1;
            // The first is answered only together with the second.
            if *n == 1 {
                String::new()
            } else {
                "< buslab_flushed 1 0 >< buslab_flushed 2 0 >".into()
            }
        }
        _ => "< error unexpected >".into(),
    });
    let mut bus = fake.client();
    let err = bus.flush(Duration::from_millis(50)).unwrap_err();
    assert!(
        err.to_string()
            .starts_with("no answer to < buslab_flush > within 50"),
        "{err}"
    );
    assert_eq!(
        bus.flush(Duration::from_secs(30)).unwrap(),
        TxReport { sent: 2, failed: 0 }
    );
}

#[test]
fn error_frames_come_in_order_with_frames_when_asked_for() {
    let fake = Fake::start(false, |cmd| match cmd {
        Command::ErrorFrames(true) => {
            "< ok >< frame 123 1.000000 11 >< error 088 1.000100 >< frame 124 1.000200 22 >".into()
        }
        // More traffic, arriving with the answer to a request.
        Command::Name(_) => "< frame 125 2.000000 33 >< error 002 2.000100 01 >< ok >".into(),
        _ => "< error unexpected >".into(),
    });
    let mut bus = fake.client();
    bus.set_error_frames(true).unwrap();
    let events: Vec<Message> = (0..3)
        .map(|_| bus.recv_event(WAIT).unwrap().unwrap())
        .collect();
    assert_eq!(events[0].frame(), Some(&frame("123#11")), "{events:?}");
    let Some(error) = events[1].error_frame() else {
        panic!("{events:?}")
    };
    assert_eq!(events[1].at, Timestamp::from_micros(1_000_100));
    assert_eq!(events[1].channel, "vcan0");
    assert_eq!(
        (&error.errors[..], error.counters),
        (
            &[
                CanError::Protocol {
                    violation: ProtocolViolation(0),
                    location: ProtocolLocation::Unspecified
                },
                CanError::BusError
            ][..],
            None
        )
    );
    assert_eq!(events[2].frame(), Some(&frame("124#22")));
    // `recv` stays frames-only: it passes over the error frame.
    bus.set_name("x").unwrap();
    assert_eq!(bus.recv(WAIT).unwrap().unwrap().record, frame("125#33"));
    assert!(bus.recv(Some(Duration::ZERO)).unwrap().is_none());
}

#[test]
fn a_plain_socketcand_has_no_admin_and_its_error_frames_are_kept_once_asked_for() {
    let fake = Fake::start(true, |cmd| match cmd {
        // socketcand -e sends error frames unasked; here one comes after each frame sent.
        Command::Send(_) => "< frame 7FF 3.000000  >< error 040 3.000001 >".into(),
        _ => "< error unknown command >".into(),
    });
    let mut bus = fake.client();
    assert!(!bus.has_extensions());
    assert!(bus.admin().is_none());
    assert!(matches!(
        bus.flush(Duration::from_secs(1)),
        Err(ClientError::NoExtensions(_))
    ));
    bus.send(&frame("100#")).unwrap();
    assert!(matches!(
        bus.recv_event(WAIT).unwrap(),
        Some(Message {
            record: Record::Frame(_),
            ..
        })
    ));
    // Not asked for: dropped.
    assert!(bus.recv_event(Some(Duration::ZERO)).unwrap().is_none());
    bus.set_error_frames(true).unwrap();
    bus.send(&frame("100#")).unwrap();
    assert!(matches!(
        bus.recv_event(WAIT).unwrap(),
        Some(Message {
            record: Record::Frame(_),
            ..
        })
    ));
    let Some(Message {
        record: Record::Error(e),
        ..
    }) = bus.recv_event(WAIT).unwrap()
    else {
        panic!("an error frame")
    };
    assert_eq!(e.errors, [CanError::BusOff]);
    // The plain server never saw a buslab command after buslab_ext.
    drop(bus);
    assert_eq!(fake.count(&Command::ErrorFrames(true)), 0);
}

#[test]
fn garbage_in_a_status_reply_is_an_error_naming_the_key() {
    let fake = Fake::start(false, |cmd| match cmd {
        Command::Status(_) => "< buslab_status 1 pc state=sleepy >".into(),
        _ => "< error unexpected >".into(),
    });
    let mut bus = fake.client();
    let err = bus.node_status(None).unwrap_err().to_string();
    assert!(
        err.contains("buslab_status: state=\"sleepy\" must be error-active"),
        "{err}"
    );
    // Through the admin trait too, as a protocol error whose reason is the client's own
    // typed error, not its text.
    let err = bus.admin().unwrap().node_status(None).unwrap_err();
    let buslab_bus::BusError::Protocol(reason) = err else {
        panic!("{err:?}")
    };
    assert!(
        reason
            .downcast_ref::<buslab_socketcand::ClientError>()
            .is_some(),
        "{reason:?}"
    );
}

#[test]
fn fd_frames_are_refused_with_the_reason_and_nothing_is_sent() {
    use buslab_bus::{BusError, NoFd};
    let fd: buslab_can::FdFrame = "123##1112233445566778899AABBCC".parse().unwrap();
    for (plain, why) in [(false, NoFd::BitLevelBus), (true, NoFd::Socketcand)] {
        let fake = Fake::start(plain, |_| String::new());
        let mut bus = fake.client();
        assert!(!bus.fd_support().carried());
        let err = bus.send_fd(&fd).unwrap_err();
        let BusError::ClassicOnly {
            bus: name,
            why: got,
        } = &err
        else {
            panic!("{err:?}");
        };
        assert_eq!(*got, why);
        assert_eq!(*name, bus.channel_info());
        let text = err.to_string();
        assert!(
            text.starts_with(&format!(
                "socketcand://{}/vcan0 is classic CAN: ",
                fake.addr
            )),
            "{text}"
        );
        // A classic frame after it goes out alone: the FD frame left nothing on the wire.
        bus.send(&frame("100#")).unwrap();
        drop(bus);
        // The server has read everything once its thread ended.
        let seen = fake.seen.clone();
        drop(fake);
        let seen = seen.lock().unwrap().clone();
        let sent: Vec<&Command> = seen
            .iter()
            .filter(|c| !matches!(c, Command::Open(_) | Command::RawMode | Command::Extensions))
            .collect();
        assert_eq!(sent, [&Command::Send(frame("100#"))], "plain={plain}");
    }
    let fake = Fake::start(false, |_| String::new());
    assert_eq!(
        fake.client().send_fd(&fd).unwrap_err().to_string(),
        format!(
            "socketcand://{}/vcan0 is classic CAN: buslab's bit-level bus carries no FD frames (its engine, SJA1000 and SLIO nodes are classic CAN)",
            fake.addr
        )
    );
}

#[test]
fn a_wait_for_frames_ends_when_another_thread_wakes_it() {
    // The server never sends a frame: only the wake can end the wait.
    let fake = Fake::start(false, |_| String::new());
    let mut bus = fake.client();
    let waker = bus.recv_waker().expect("a socketcand client can be woken");
    let woken = thread::spawn(move || waker.wake());
    assert!(bus.recv(None).unwrap().is_none());
    woken.join().unwrap();
}

#[test]
fn a_wake_does_not_end_a_request_and_ends_the_next_wait_for_frames() {
    let fake = Fake::start(false, |cmd| match cmd {
        Command::Status(None) => status_with(3, 0),
        _ => "< error unexpected >".into(),
    });
    let mut bus = fake.client();
    let waker = bus.recv_waker().unwrap();
    waker.wake();
    let status = bus.admin().unwrap().node_status(None).unwrap();
    assert_eq!(status.counters.sent, 3);
    assert!(bus.recv_event(None).unwrap().is_none());
}

#[test]
fn frames_that_came_are_received_before_a_wake_ends_the_wait() {
    let fake = Fake::start(false, |cmd| match cmd {
        Command::Status(None) => format!("< frame 321 1.000000 AA >{}", status_with(0, 0)),
        _ => "< error unexpected >".into(),
    });
    let mut bus = fake.client();
    let waker = bus.recv_waker().unwrap();
    // The frame comes with the answer, and is kept for recv.
    bus.admin().unwrap().node_status(None).unwrap();
    waker.wake();
    assert_eq!(bus.recv(None).unwrap().unwrap().record, frame("321#AA"));
    assert!(bus.recv(None).unwrap().is_none());
}
