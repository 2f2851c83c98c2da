//! The cannelloni transports between two buses of this process on loopback, and what their
//! counters say when packets are lost, late or not cannelloni (a raw UDP socket plays the
//! peer). The MQTT transport is tested with a real broker in crates/buslab/tests/join_buses.rs.

use std::net::{SocketAddr, TcpListener, UdpSocket};
use std::time::Duration;

use buslab_backends::{BusUrl, JoinBus, OpenOptions, open_join};
use buslab_bus::CanBus;
use buslab_can::Frame;
use buslab_cannelloni::{CanFrame, decode_packet, encode_packets};

/// Generous: frames on loopback come within milliseconds; a loaded CI machine may take far
/// longer, and a test that passes only waits for what it expects.
const WAIT: Option<Duration> = Some(Duration::from_secs(60));

fn free_udp() -> SocketAddr {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
}

fn join(url: &str) -> JoinBus {
    open_join(&url.parse::<BusUrl>().unwrap(), &OpenOptions::default()).unwrap()
}

fn frame(k: u32) -> Frame {
    Frame::data(
        buslab_can::Id::standard((k % 0x7FF) as u16).unwrap(),
        &k.to_be_bytes(),
    )
    .unwrap()
}

fn exchange(a: &mut JoinBus, b: &mut JoinBus, n: u32) {
    for k in 0..n {
        a.send(&frame(k)).unwrap();
    }
    for k in 0..n {
        let got = b.recv(WAIT).unwrap().expect("a frame within the wait");
        assert_eq!(got.record, frame(k));
    }
}

#[test]
fn two_buses_joined_by_cannelloni_udp_exchange_frames_in_order_both_ways() {
    let (pa, pb) = (free_udp(), free_udp());
    let mut a = join(&format!("cannelloni://{pb}?listen={pa}"));
    let mut b = join(&format!("cannelloni://{pa}?listen={pb}"));
    exchange(&mut a, &mut b, 5000);
    exchange(&mut b, &mut a, 5000);
    let (ra, rb) = (a.report(), b.report());
    assert_eq!((ra.sent, ra.unsent, rb.sent, rb.unsent), (5000, 0, 5000, 0));
    assert_eq!(ra.lost() + rb.lost(), 0, "{ra}\n{rb}");
}

#[test]
fn two_buses_joined_by_cannelloni_tcp_exchange_frames_both_ways() {
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let mut server = join(&format!("cannelloni+tcp://127.0.0.1:{port}?role=server"));
    let mut client = join(&format!("cannelloni+tcp://127.0.0.1:{port}"));
    // The server sends once its peer is there: wait for the client's first frame.
    exchange(&mut client, &mut server, 3000);
    exchange(&mut server, &mut client, 3000);
    assert_eq!(server.report().received(), 3000);
    assert_eq!(client.report().received(), 3000);
}

#[test]
fn lost_late_and_foreign_packets_are_counted_not_delivered_twice() {
    let peer = UdpSocket::bind("127.0.0.1:0").unwrap();
    let me = free_udp();
    let mut bus = join(&format!(
        "cannelloni://{}?listen={me}",
        peer.local_addr().unwrap()
    ));
    let packet = |seq: u8, k: u32| {
        encode_packets(seq, &[CanFrame::Classic(frame(k))], 1472)
            .unwrap()
            .remove(0)
    };
    // Packets 0, 1, 3 (2 lost), then 2 late, then 1 again, then garbage.
    for (seq, k) in [(0, 0), (1, 1), (3, 3), (2, 2), (1, 1)] {
        peer.send_to(&packet(seq, k), me).unwrap();
    }
    peer.send_to(b"not cannelloni", me).unwrap();
    peer.send_to(&packet(4, 4), me).unwrap();
    let got: Vec<Frame> = (0..5)
        .map(|_| bus.recv(WAIT).unwrap().unwrap().record)
        .collect();
    assert_eq!(got, [frame(0), frame(1), frame(3), frame(2), frame(4)]);
    let r = bus.report();
    let p = &r.peers[0];
    assert_eq!(
        (p.received, p.lost, p.reordered, p.duplicates, r.garbage),
        (5, 0, 1, 1, 1),
        "{r}"
    );
    // What this bus sends is cannelloni to the peer.
    bus.send(&frame(9)).unwrap();
    let mut buf = [0u8; 2048];
    let (n, _) = peer.recv_from(&mut buf).unwrap();
    let p = decode_packet(&buf[..n]).unwrap();
    assert_eq!(p.frames, [CanFrame::Classic(frame(9))]);
}

#[test]
fn a_tcp_peer_that_is_not_cannelloni_is_refused_at_open() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let server = std::thread::spawn(move || {
        use std::io::Write;
        let (mut s, _) = listener.accept().unwrap();
        s.write_all(b"< hi >").unwrap();
        // Held open until the client gave up.
        let mut buf = [0u8; 64];
        let _ = std::io::Read::read(&mut s, &mut buf);
    });
    let err = open_join(
        &format!("cannelloni+tcp://{addr}").parse().unwrap(),
        &OpenOptions::default(),
    )
    .err()
    .expect("not cannelloni");
    let text = err.to_string();
    assert!(
        text.starts_with(&format!("cannot join cannelloni+tcp://{addr}: ")),
        "{text}"
    );
    assert!(text.contains("expected \"CANNELLONIv1\""), "{text}");
    server.join().unwrap();
}

#[test]
fn a_frame_sent_right_before_the_bus_is_dropped_still_leaves() {
    // `buslab send cannelloni://…` exits right after handing its frame over: the bus's drop
    // waits until the sending thread sent what was queued.
    let peer = UdpSocket::bind("127.0.0.1:0").unwrap();
    let me = free_udp();
    for k in 0..20 {
        let mut bus = join(&format!(
            "cannelloni://{}?listen={me}",
            peer.local_addr().unwrap()
        ));
        bus.send(&frame(k)).unwrap();
        drop(bus);
        let mut buf = [0u8; 2048];
        peer.set_read_timeout(WAIT).unwrap();
        let (n, _) = peer.recv_from(&mut buf).expect("the frame left");
        assert_eq!(
            decode_packet(&buf[..n]).unwrap().frames,
            [CanFrame::Classic(frame(k))]
        );
    }
}
