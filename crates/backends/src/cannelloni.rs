//! cannelloni (`cannelloni://` UDP, `cannelloni+tcp://`): the transport threads around
//! `buslab-cannelloni`'s codec.
//!
//! UDP is point to point: frames go to the peer's address in packets of at most
//! [`DATAGRAM_SIZE`] bytes (as many frames as were waiting: no timer, so no added latency),
//! and only the peer's packets are taken. Their 8-bit sequence numbers are widened and
//! counted: a lost or late *packet* shows in the report. TCP keeps order and loses nothing
//! while connected; the server side takes one peer at a time, and frames sent while no peer
//! is connected are counted as unsent.

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, SyncSender};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use buslab_bus::BusError;
use buslab_cannelloni::{
    CanFrame, GREETING, MAX_DATAGRAM, OpCode, StreamDecoder, decode_packet, encode_packets,
    encode_record,
};

use crate::join::{Accounting, Inbound, JoinBus, Shared, new_origin};

/// The UDP payload sent at most: an Ethernet MTU less the IP and UDP headers.
pub const DATAGRAM_SIZE: usize = 1472;
/// How often a blocked read looks whether the bus was closed.
const POLL: Duration = Duration::from_millis(100);

/// Stops the threads when the bus is dropped.
/// Stops the threads when the bus is dropped, after the sending thread sent what was queued
/// (a `buslab send` that exits at once still gets its frames out).
struct Stop {
    stop: Arc<AtomicBool>,
    /// The sending thread first, then the receiving one (which lets go of the socket within
    /// [`POLL`], so the address can be bound again).
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl Drop for Stop {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// The next frame to send; `None` once the bus is closing and nothing is queued.
fn next_frame(outbox: &Receiver<CanFrame>, stop: &AtomicBool) -> Option<CanFrame> {
    loop {
        match outbox.recv_timeout(POLL) {
            Ok(f) => return Some(f),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) if !stop.load(Ordering::SeqCst) => {}
            Err(_) => return None,
        }
    }
}

/// Frames waiting in `outbox` after `first`, at most `max`.
fn drain(first: CanFrame, outbox: &Receiver<CanFrame>, max: usize) -> Vec<CanFrame> {
    let mut frames = vec![first];
    while frames.len() < max {
        match outbox.try_recv() {
            Ok(f) => frames.push(f),
            Err(_) => break,
        }
    }
    frames
}

fn count(shared: &Shared, f: impl FnOnce(&mut Accounting)) {
    if let Ok(mut a) = shared.lock() {
        f(&mut a);
    }
}

/// cannelloni over UDP between `listen` (bound here) and `peer`.
pub fn open_udp(url: String, peer: SocketAddr, listen: SocketAddr) -> io::Result<JoinBus> {
    let socket = UdpSocket::bind(listen)?;
    socket.set_read_timeout(Some(POLL))?;
    let origin = new_origin();
    let shared: Shared = Arc::new(Mutex::new(Accounting::new(origin)));
    let ((out_tx, outbox), (inbox_tx, inbox)) = JoinBus::queues();
    let stop = Arc::new(AtomicBool::new(false));
    tracing::info!(
        "{url}: cannelloni over UDP, listening on {}, sending to {peer}",
        socket.local_addr()?
    );
    let tx_socket = socket.try_clone()?;
    let tx_shared = shared.clone();
    let tx_stop = stop.clone();
    let sender = std::thread::Builder::new()
        .name("cannelloni-tx".into())
        .spawn(move || {
            let mut seq = 0u8;
            while let Some(first) = next_frame(&outbox, &tx_stop) {
                let frames = drain(first, &outbox, 4096);
                let Ok(packets) = encode_packets(seq, &frames, DATAGRAM_SIZE) else {
                    unreachable!("DATAGRAM_SIZE is a valid size");
                };
                seq = seq.wrapping_add(packets.len() as u8);
                for p in packets {
                    let n = u64::from(u16::from_be_bytes([p[3], p[4]]));
                    match tx_socket.send_to(&p, peer) {
                        Ok(_) => count(&tx_shared, |a| a.report.sent += n),
                        // Nobody listens at the peer yet (ICMP port unreachable): lost.
                        Err(e) => {
                            tracing::debug!("cannelloni to {peer}: {e}");
                            count(&tx_shared, |a| a.report.unsent += n);
                        }
                    }
                }
            }
        })?;
    let rx_stop = stop.clone();
    let rx_shared = shared.clone();
    let receiver = std::thread::Builder::new()
        .name("cannelloni-rx".into())
        .spawn(move || {
            let mut buf = vec![0u8; MAX_DATAGRAM + 1];
            let name = format!("cannelloni {peer} (packets)");
            let peer_origin = u64::from(peer.port());
            // The peer's sequence widened to 64 bits.
            let mut last: Option<u64> = None;
            while !rx_stop.load(Ordering::SeqCst) {
                let (n, from) = match socket.recv_from(&mut buf) {
                    Ok(got) => got,
                    Err(e)
                        if matches!(
                            e.kind(),
                            io::ErrorKind::WouldBlock
                                | io::ErrorKind::TimedOut
                                | io::ErrorKind::ConnectionRefused
                                | io::ErrorKind::Interrupted
                        ) =>
                    {
                        continue;
                    }
                    Err(e) => {
                        let _ = inbox_tx.send(Inbound::Failed(BusError::Io(e)));
                        return;
                    }
                };
                if from.ip() != peer.ip() {
                    count(&rx_shared, |a| a.report.garbage += 1);
                    continue;
                }
                let packet = match decode_packet(&buf[..n]) {
                    Ok(p) if p.op == OpCode::Data => p,
                    Ok(_) => continue,
                    Err(e) => {
                        tracing::debug!("cannelloni from {from}: {e}");
                        count(&rx_shared, |a| a.report.garbage += 1);
                        continue;
                    }
                };
                let seq = widen(&mut last, packet.seq);
                let deliver = rx_shared
                    .lock()
                    .map(|mut a| a.tracker.accept_numbered(peer_origin, &name, seq))
                    .unwrap_or(false);
                if deliver {
                    for f in packet.frames {
                        if inbox_tx.send(Inbound::Frame(f)).is_err() {
                            return;
                        }
                    }
                }
            }
        })?;
    Ok(JoinBus::new(
        url,
        out_tx,
        inbox,
        shared,
        Box::new(Stop {
            stop,
            threads: vec![sender, receiver],
        }),
    ))
}

/// cannelloni's 8-bit packet number as a 64-bit one, nearest to the last (a jump of more
/// than 127 packets either way is taken as the nearer direction).
fn widen(last: &mut Option<u64>, seq: u8) -> u64 {
    let wide = match *last {
        // Far from 0, so a few late packets before the first do not go below it.
        None => (1 << 32) + u64::from(seq),
        Some(l) => l.wrapping_add_signed(i64::from(seq.wrapping_sub(l as u8) as i8)),
    };
    *last = Some(last.map_or(wide, |l| l.max(wide)));
    wide
}

/// cannelloni over TCP, connecting to `peer` (as can-cannelloni does).
pub fn open_tcp_client(
    url: String,
    peer: SocketAddr,
    connect_timeout: Duration,
    reply_timeout: Duration,
) -> io::Result<JoinBus> {
    let mut stream = TcpStream::connect_timeout(&peer, connect_timeout)?;
    stream.set_nodelay(true)?;
    stream.write_all(GREETING)?;
    // The peer's greeting before the bus is handed over: a wrong peer is an error now.
    stream.set_read_timeout(Some(reply_timeout))?;
    let mut decoder = StreamDecoder::new();
    let mut early = Vec::new();
    let mut byte = [0u8; 1];
    while !decoder.greeted() {
        match stream.read(&mut byte) {
            Ok(0) => return Err(io::Error::other("the peer closed before its greeting")),
            Ok(_) => decoder
                .push(&byte, &mut early)
                .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e))?,
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                return Err(io::Error::new(
                    io::ErrorKind::TimedOut,
                    "no cannelloni greeting (CANNELLONIv1) from the peer",
                ));
            }
            Err(e) => return Err(e),
        }
    }
    stream.set_read_timeout(Some(POLL))?;
    tracing::info!("{url}: cannelloni over TCP, connected to {peer}");
    let origin = new_origin();
    let shared: Shared = Arc::new(Mutex::new(Accounting::new(origin)));
    let ((out_tx, outbox), (inbox_tx, inbox)) = JoinBus::queues();
    let stop = Arc::new(AtomicBool::new(false));
    let writer: Arc<Mutex<Option<TcpStream>>> = Arc::new(Mutex::new(Some(stream.try_clone()?)));
    let sender = spawn_tcp_writer(outbox, writer, shared.clone(), stop.clone())?;
    let rx_stop = stop.clone();
    let rx_shared = shared.clone();
    let receiver = std::thread::Builder::new()
        .name("cannelloni-rx".into())
        .spawn(move || {
            let end = read_stream(stream, decoder, &inbox_tx, &rx_stop, &rx_shared);
            if let Some(e) = end {
                let _ = inbox_tx.send(Inbound::Failed(e));
            }
        })?;
    Ok(JoinBus::new(
        url,
        out_tx,
        inbox,
        shared,
        Box::new(Stop {
            stop,
            threads: vec![sender, receiver],
        }),
    ))
}

/// cannelloni over TCP, listening on `listen` for one peer at a time.
pub fn open_tcp_server(url: String, listen: SocketAddr) -> io::Result<JoinBus> {
    let listener = TcpListener::bind(listen)?;
    listener.set_nonblocking(true)?;
    tracing::info!(
        "{url}: cannelloni over TCP, waiting for a peer on {}",
        listener.local_addr()?
    );
    let origin = new_origin();
    let shared: Shared = Arc::new(Mutex::new(Accounting::new(origin)));
    let ((out_tx, outbox), (inbox_tx, inbox)) = JoinBus::queues();
    let stop = Arc::new(AtomicBool::new(false));
    let writer: Arc<Mutex<Option<TcpStream>>> = Arc::new(Mutex::new(None));
    let sender = spawn_tcp_writer(outbox, writer.clone(), shared.clone(), stop.clone())?;
    let rx_stop = stop.clone();
    let rx_url = url.clone();
    let rx_shared = shared.clone();
    let receiver = std::thread::Builder::new()
        .name("cannelloni-accept".into())
        .spawn(move || {
            while !rx_stop.load(Ordering::SeqCst) {
                let (mut stream, from) = match listener.accept() {
                    Ok(got) => got,
                    Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                        std::thread::sleep(POLL);
                        continue;
                    }
                    Err(e) => {
                        tracing::warn!("{rx_url}: accept failed: {e}");
                        std::thread::sleep(POLL);
                        continue;
                    }
                };
                let ready = stream
                    .set_nonblocking(false)
                    .and_then(|()| stream.set_nodelay(true))
                    .and_then(|()| stream.set_read_timeout(Some(POLL)))
                    .and_then(|()| stream.write_all(GREETING))
                    .and_then(|()| stream.try_clone());
                let clone = match ready {
                    Ok(c) => c,
                    Err(e) => {
                        tracing::warn!("{rx_url}: peer {from}: {e}");
                        continue;
                    }
                };
                tracing::info!("{rx_url}: peer {from} connected");
                if let Ok(mut w) = writer.lock() {
                    *w = Some(clone);
                }
                let end = read_stream(
                    stream,
                    StreamDecoder::new(),
                    &inbox_tx,
                    &rx_stop,
                    &rx_shared,
                );
                if let Ok(mut w) = writer.lock() {
                    *w = None;
                }
                match end {
                    Some(BusError::Closed) | None => {
                        tracing::info!("{rx_url}: peer {from} left")
                    }
                    Some(e) => tracing::warn!("{rx_url}: peer {from} dropped: {e}"),
                }
            }
        })?;
    Ok(JoinBus::new(
        url,
        out_tx,
        inbox,
        shared,
        Box::new(Stop {
            stop,
            threads: vec![sender, receiver],
        }),
    ))
}

/// Writes what the bus sends to the current connection; with none, the frames are unsent.
fn spawn_tcp_writer(
    outbox: Receiver<CanFrame>,
    writer: Arc<Mutex<Option<TcpStream>>>,
    shared: Shared,
    stop: Arc<AtomicBool>,
) -> io::Result<std::thread::JoinHandle<()>> {
    std::thread::Builder::new()
        .name("cannelloni-tx".into())
        .spawn(move || {
            let mut bytes = Vec::new();
            while let Some(first) = next_frame(&outbox, &stop) {
                let frames = drain(first, &outbox, 4096);
                bytes.clear();
                for f in &frames {
                    encode_record(f, &mut bytes);
                }
                let n = frames.len() as u64;
                let written = match writer.lock().as_deref_mut() {
                    Ok(Some(stream)) => stream.write_all(&bytes).is_ok(),
                    _ => false,
                };
                count(&shared, |a| {
                    if written {
                        a.report.sent += n
                    } else {
                        a.report.unsent += n
                    }
                });
            }
        })
}

/// Reads frames until the stream ends (`None`: closed by the peer or the bus dropped) or
/// breaks its format.
/// TCP loses nothing while connected: frames are counted as received from the peer, numbered
/// in the order they came.
fn read_stream(
    mut stream: TcpStream,
    mut decoder: StreamDecoder,
    inbox: &SyncSender<Inbound>,
    stop: &AtomicBool,
    shared: &Shared,
) -> Option<BusError> {
    let mut buf = [0u8; 16 * 1024];
    let mut frames = Vec::new();
    let peer = stream.peer_addr().ok();
    let name = format!(
        "cannelloni+tcp {}",
        peer.map_or_else(|| "?".to_string(), |p| p.to_string())
    );
    let origin = peer.map_or(0, |p| u64::from(p.port()));
    let mut seq = 0u64;
    while !stop.load(Ordering::SeqCst) {
        match stream.read(&mut buf) {
            Ok(0) => return Some(BusError::Closed),
            Ok(n) => {
                if let Err(e) = decoder.push(&buf[..n], &mut frames) {
                    return Some(BusError::Protocol(Box::new(e)));
                }
                count(shared, |a| {
                    for _ in 0..frames.len() {
                        a.tracker.accept_numbered(origin, &name, seq);
                        seq += 1;
                    }
                });
                for f in frames.drain(..) {
                    if inbox.send(Inbound::Frame(f)).is_err() {
                        return None;
                    }
                }
            }
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock
                        | io::ErrorKind::TimedOut
                        | io::ErrorKind::Interrupted
                ) => {}
            Err(e) => return Some(BusError::Io(e)),
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packet_numbers_widen_across_the_wrap_and_back() {
        let mut last = None;
        let a = widen(&mut last, 250);
        assert_eq!(widen(&mut last, 255), a + 5);
        assert_eq!(widen(&mut last, 3), a + 9, "wrapped");
        assert_eq!(
            widen(&mut last, 1),
            a + 7,
            "a late packet before the wrap's top"
        );
        assert_eq!(widen(&mut last, 4), a + 10);
    }
}
