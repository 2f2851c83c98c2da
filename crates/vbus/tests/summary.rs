//! The server's periodic bus summary is logged when something changed, not every 5 s forever
//! after one bus error (its own test binary: it installs the process's log subscriber).

use std::io::Write;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use buslab_can::BitTime;
use buslab_canbus::CanBus;
use buslab_socketcand::SocketcandBus;
use buslab_vbus::{ServerConfig, spawn};

/// Log lines, shared with the subscriber.
#[derive(Clone, Default)]
struct Lines(Arc<Mutex<Vec<u8>>>);

impl Write for Lines {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn one_bus_error_is_summarised_once_not_every_five_seconds() {
    let lines = Lines::default();
    let writer = lines.clone();
    tracing_subscriber::fmt()
        .with_writer(move || writer.clone())
        .with_ansi(false)
        .init();
    let s = spawn(ServerConfig::new("127.0.0.1:0".parse().unwrap(), 500_000)).unwrap();
    let mut b = SocketcandBus::connect(s.local_addr(), "vcan0").unwrap();
    // A node queues a frame and one bit is flipped while it is on the wire: one error, one
    // retransmission. Done in one job on the bus thread, so the fault meets the frame whatever
    // the wall clock does.
    s.with_bus(|bus| {
        let a = bus.join().unwrap();
        bus.client_mut(a)
            .unwrap()
            .submit("123#0102030405060708".parse().unwrap())
            .unwrap();
        let now = bus.now();
        bus.sim_mut().add_fault(buslab_sim::Fault {
            kind: buslab_sim::FaultKind::Flip { node: None },
            start: now + BitTime::new(30),
            end: now + BitTime::new(31),
        });
    })
    .unwrap();
    let got = b
        .recv(Some(Duration::from_secs(60)))
        .unwrap()
        .expect("the frame");
    assert_eq!(got.record.to_string(), "123#0102030405060708");
    // Two summary periods and more: the one change is summarised once.
    std::thread::sleep(Duration::from_secs(12));
    s.shutdown();
    let text = String::from_utf8(lines.0.lock().unwrap().clone()).unwrap();
    let summaries: Vec<&str> = text.lines().filter(|l| l.contains("bus: load")).collect();
    assert_eq!(summaries.len(), 1, "{text}");
    assert!(summaries[0].contains("1 frames, "), "{}", summaries[0]);
    assert!(!summaries[0].contains(" 0 errors"), "{}", summaries[0]);
}
