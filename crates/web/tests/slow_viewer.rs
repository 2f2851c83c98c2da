//! A live viewer that stops reading loses only its own updates: the server pulls each
//! viewer's stream only when its connection has room, so a stalled viewer holds no queue
//! beyond the socket's buffers and one update, and the frames it missed are counted in its
//! own `lost`; a viewer that reads meanwhile gets every batch, every frame in order, none
//! lost.

use std::io::{BufRead, BufReader, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::mpsc::{self, Receiver};
use std::time::Duration;

use buslab_bus::{BusError, CanBus, ErrorState, Filter, Message};
use buslab_can::{Frame, Id};
use buslab_web::{WebConfig, WebServer};
use serde_json::Value;

/// Only a guard against a hung server: every wait ends on an event first.
const HANG: Duration = Duration::from_secs(120);
/// Frames fed per batch: fewer than one update's log holds (200), so a viewer that reads
/// loses none; each with an ID of its own, so the per-ID table changes in every row too.
const BATCH: u64 = 180;
/// The stall lasts until the reading viewer got this much: several times what the stalled
/// viewer's socket buffers hold (its receive buffer is made small).
const STALL_BYTES: usize = 2 << 20;

/// A bus whose frames the test feeds.
struct Feed(Receiver<Frame>);

impl CanBus for Feed {
    fn send(&mut self, _: &Frame) -> Result<(), BusError> {
        Ok(())
    }
    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
        match self.0.recv_timeout(timeout.unwrap_or(HANG)) {
            Ok(f) => Ok(Some(Message::rx(
                buslab_can::Timestamp::from_secs(1),
                "feed",
                f,
            ))),
            Err(mpsc::RecvTimeoutError::Timeout) => Ok(None),
            Err(mpsc::RecvTimeoutError::Disconnected) => Err(BusError::Closed),
        }
    }
    fn set_filters(&mut self, _: &[Filter]) -> Result<(), BusError> {
        Ok(())
    }
    fn state(&mut self) -> Result<ErrorState, BusError> {
        Ok(ErrorState::Active)
    }
    fn channel_info(&self) -> String {
        "feed".into()
    }
}

/// Frame `n`: ID 0x100 + n % BATCH, the counter n in its 8 bytes (little-endian).
fn frame(n: u64) -> Frame {
    let id = Id::standard(0x100 + (n % BATCH) as u16).unwrap();
    Frame::data(id, &n.to_le_bytes()).unwrap()
}

fn counter(text: &str) -> u64 {
    let data = text.split('#').nth(1).unwrap();
    let bytes: Vec<u8> = (0..8)
        .map(|i| u8::from_str_radix(&data[2 * i..2 * i + 2], 16).unwrap())
        .collect();
    u64::from_le_bytes(bytes.try_into().unwrap())
}

/// Opens `/api/events` on a connection with a small receive buffer.
fn stalled_viewer(addr: SocketAddr) -> TcpStream {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let stream = rt.block_on(async {
        let socket = tokio::net::TcpSocket::new_v4().unwrap();
        socket.set_recv_buffer_size(4096).unwrap();
        socket.connect(addr).await.unwrap().into_std().unwrap()
    });
    stream.set_nonblocking(false).unwrap();
    stream.set_read_timeout(Some(HANG)).unwrap();
    let mut s = stream;
    s.write_all(b"GET /api/events HTTP/1.1\r\nHost: localhost\r\n\r\n")
        .unwrap();
    s
}

/// One update: (its JSON, the bytes of the stream up to and including it).
fn next_update(lines: &mut impl Iterator<Item = std::io::Result<String>>) -> (Value, usize) {
    let mut bytes = 0;
    loop {
        let line = lines.next().expect("the stream ended").unwrap();
        bytes += line.len() + 1;
        if let Some(json) = line.strip_prefix("data: ") {
            return (serde_json::from_str(json).unwrap(), bytes);
        }
    }
}

#[test]
fn a_viewer_that_does_not_read_loses_only_its_own_updates() {
    let (feed, frames) = mpsc::channel();
    let server = WebServer::start(
        Box::new(Feed(frames)),
        WebConfig {
            listen: "127.0.0.1:0".parse().unwrap(),
            ..WebConfig::default()
        },
    )
    .unwrap();
    let addr = server.addr();
    let stalled = stalled_viewer(addr);

    let fast = TcpStream::connect(addr).unwrap();
    fast.set_read_timeout(Some(HANG)).unwrap();
    (&fast)
        .write_all(b"GET /api/events HTTP/1.1\r\nHost: localhost\r\n\r\n")
        .unwrap();
    let mut fast_lines = BufReader::new(fast).lines();
    let (first, _) = next_update(&mut fast_lines);
    assert_eq!(first["full"], true, "{first}");

    // Batches while the stalled viewer reads nothing: the reading one gets every frame, in
    // order, and loses none.
    let mut sent = 0u64;
    let mut seen = 0u64;
    let mut fast_bytes = 0;
    while fast_bytes < STALL_BYTES {
        for _ in 0..BATCH {
            feed.send(frame(sent)).unwrap();
            sent += 1;
        }
        while seen < sent {
            let (update, bytes) = next_update(&mut fast_lines);
            fast_bytes += bytes;
            assert_eq!(update["lost"], 0, "the reading viewer lost frames");
            for entry in update["log"].as_array().unwrap() {
                let n = counter(entry["frame"].as_str().unwrap());
                assert_eq!(n, seen, "the reading viewer got frame {n}, expected {seen}");
                seen += 1;
            }
        }
    }

    // The stalled viewer reads again: what was held for it is its socket's buffers and an
    // update, not the stall's worth; the frames it missed are counted in its own `lost`.
    let mut stalled_lines = BufReader::new(stalled.try_clone().unwrap()).lines();
    let status = stalled_lines.next().unwrap().unwrap();
    assert!(status.contains("200"), "{status}");
    // Read until it has caught up with the last frame: what it got and what it lost make up
    // every frame sent. What was held for it is what came before its first lossy update.
    let mut backlog = 0;
    let mut held = None;
    let mut got = 0;
    let lost = loop {
        let (update, bytes) = next_update(&mut stalled_lines);
        backlog += bytes;
        let log = update["log"].as_array().unwrap();
        got += log.len() as u64;
        let lost = update["lost"].as_u64().unwrap();
        if lost > 0 && held.is_none() {
            held = Some(backlog);
        }
        assert!(
            held.is_some() || backlog < STALL_BYTES,
            "the stalled viewer was sent {backlog} bytes without a loss: its updates were queued"
        );
        if log
            .last()
            .is_some_and(|e| counter(e["frame"].as_str().unwrap()) == sent - 1)
        {
            break lost;
        }
    };
    let held = held.expect("the stalled viewer lost nothing");
    eprintln!(
        "reading viewer: {fast_bytes} bytes, {seen} frames; stalled viewer: {held} bytes held, {lost} frames lost"
    );
    assert_eq!(lost + got, sent, "lost {lost} + got {got} != sent {sent}");
    assert!(
        held * 2 < fast_bytes,
        "{held} bytes were held for the stalled viewer while the other got {fast_bytes}"
    );
    // The reading viewer is still served, with nothing lost.
    feed.send(frame(sent)).unwrap();
    loop {
        let (update, _) = next_update(&mut fast_lines);
        assert_eq!(update["lost"], 0);
        if update["log"]
            .as_array()
            .unwrap()
            .iter()
            .any(|e| counter(e["frame"].as_str().unwrap()) == sent)
        {
            break;
        }
    }
    drop(stalled);
    server.stop();
}
