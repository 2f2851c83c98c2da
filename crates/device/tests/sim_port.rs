//! The virtual-time port against a toy device: timing, time-outs, line settings.

use std::time::Duration;

use buslab_device::{ByteDevice, LineSettings, Nanos, Port, SimPort};

/// Answers every byte with byte + 1, one character time after it arrived; records arrivals.
#[derive(Default)]
struct Echo {
    byte_ns: Nanos,
    pending: Vec<(Nanos, u8)>,
    arrivals: Vec<Nanos>,
}

impl ByteDevice for Echo {
    fn receive(&mut self, now_ns: Nanos, byte: u8) {
        self.arrivals.push(now_ns);
        self.pending
            .push((now_ns + self.byte_ns, byte.wrapping_add(1)));
    }
    fn poll(&mut self, now_ns: Nanos, out: &mut Vec<u8>) {
        while let Some(&(at, byte)) = self.pending.first() {
            if at > now_ns {
                break;
            }
            out.push(byte);
            self.pending.remove(0);
        }
    }
    fn next_deadline(&self) -> Option<Nanos> {
        self.pending.first().map(|&(at, _)| at)
    }
}

const LINE: LineSettings = LineSettings::n81(9600);

fn port() -> SimPort<Echo> {
    let echo = Echo {
        byte_ns: LINE.byte_time(),
        ..Echo::default()
    };
    SimPort::new(echo, LINE, Nanos::ZERO)
}

#[test]
fn bytes_arrive_back_to_back_and_replies_come_at_line_rate() {
    let mut p = port();
    let b = LINE.byte_time();
    p.send(&[1, 2, 3]).unwrap();
    let mut buf = [0u8; 8];
    let n = p.recv(&mut buf, Duration::from_secs(1)).unwrap();
    // The first reply is complete two character times after the send: one each way.
    assert_eq!((n, buf[0]), (1, 2));
    assert_eq!(p.now_ns(), b * 2);
    let mut got = vec![buf[0]];
    while got.len() < 3 {
        let n = p.recv(&mut buf, Duration::from_secs(1)).unwrap();
        got.extend_from_slice(&buf[..n]);
    }
    assert_eq!(got, [2, 3, 4]);
    assert_eq!(p.device().arrivals, [b, b * 2, b * 3]);
    assert_eq!(p.now(), (b * 4).as_duration());
}

#[test]
fn nothing_to_read_times_out_at_the_deadline_in_virtual_time() {
    let mut p = port();
    let mut buf = [0u8; 1];
    assert_eq!(p.recv(&mut buf, Duration::from_millis(250)).unwrap(), 0);
    assert_eq!(p.now_ns(), Nanos::from_millis(250));
    p.pause(Duration::from_millis(50));
    assert_eq!(p.now_ns(), Nanos::from_millis(300));
}

#[test]
fn drain_waits_for_the_bytes_on_the_line_and_discard_drops_replies() {
    let mut p = port();
    let b = LINE.byte_time();
    p.send(&[7; 4]).unwrap();
    p.drain().unwrap();
    assert_eq!(p.now_ns(), b * 4);
    assert_eq!(p.device().arrivals.len(), 4);
    p.pause(b.as_duration());
    p.discard_input().unwrap();
    let mut buf = [0u8; 8];
    assert_eq!(p.recv(&mut buf, Duration::from_millis(10)).unwrap(), 0);
}

#[test]
fn a_client_at_other_line_settings_is_not_understood_either_way() {
    let mut p = port().with_client_line(LineSettings::n81(19_200));
    p.send(&[1, 2, 3]).unwrap();
    let mut buf = [0u8; 8];
    assert_eq!(p.recv(&mut buf, Duration::from_millis(100)).unwrap(), 0);
    assert!(p.device().arrivals.is_empty());
    // The bytes still took their time on the line (at the client's rate).
    p.drain().unwrap();
    assert!(p.now_ns() >= LineSettings::n81(19_200).byte_time() * 3);
}
