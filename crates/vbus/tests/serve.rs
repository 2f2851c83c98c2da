//! `bus serve` end to end over loopback TCP, with buslab's socketcand client.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use buslab_can::Frame;
use buslab_canbus::{CanBus, ErrorState, Record};
use buslab_socketcand::{NodeRef, SocketcandBus};
use buslab_vbus::{ServerConfig, ServerHandle, Speed, spawn};

/// The longest wait for an event that must come (it returns as soon as it does); generous,
/// because CI machines are shared and slow at times.
const EVENT: Duration = Duration::from_secs(60);
const WAIT: Option<Duration> = Some(EVENT);

fn server(bitrate: u32, queue: usize) -> ServerHandle {
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), bitrate);
    config.client_queue = queue;
    spawn(config).unwrap()
}

fn client(s: &ServerHandle) -> SocketcandBus {
    let mut bus = SocketcandBus::connect(s.local_addr(), "vcan0").unwrap();
    assert!(bus.enable_extensions().unwrap());
    bus
}

fn frame(text: &str) -> Frame {
    text.parse().unwrap()
}

fn recv(bus: &mut SocketcandBus) -> String {
    bus.recv(WAIT)
        .unwrap()
        .expect("a frame within 5 s")
        .record
        .to_string()
}

#[test]
fn frames_flow_both_ways_standard_extended_remote() {
    let s = server(500_000, 1024);
    let mut a = client(&s);
    let mut b = client(&s);
    let there = [
        "123#1122",
        "1ABCDEF0#DEADBEEF",
        "321#R3",
        "7FF#",
        "00000123#R",
    ];
    for f in there {
        a.send(&frame(f)).unwrap();
    }
    let got: Vec<String> = there.iter().map(|_| recv(&mut b)).collect();
    assert_eq!(got, there);
    b.send(&frame("456#AA")).unwrap();
    assert_eq!(recv(&mut a), "456#AA");
    // The sender does not get its own frames back: the next thing it receives is b's.
    b.send(&frame("457#BB")).unwrap();
    assert_eq!(recv(&mut a), "457#BB");
    assert_eq!(a.state().unwrap(), ErrorState::Active);
    s.shutdown();
}

#[test]
fn timestamps_are_wall_clock_seconds() {
    let s = server(500_000, 1024);
    let mut a = client(&s);
    let mut b = client(&s);
    a.send(&frame("123#01")).unwrap();
    let m = b.recv(WAIT).unwrap().unwrap();
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64();
    let at = m.at.as_secs_f64();
    assert!((now - at).abs() < 2.0, "{at} vs {now}");
    s.shutdown();
}

#[test]
fn contending_nodes_are_received_in_priority_order() {
    let s = server(1_000_000, 8192);
    let mut rx = client(&s);
    let mut blocker = client(&s);
    let mut contenders: Vec<SocketcandBus> = (0..3).map(|_| client(&s)).collect();
    // Keep the bus busy with top-priority frames (about 0.4 s) so the three contenders'
    // frames wait in their chips and then arbitrate against each other.
    for _ in 0..3000 {
        blocker.send(&frame("001#0102030405060708")).unwrap();
    }
    for (c, f) in contenders.iter_mut().zip(["300#03", "200#02", "100#01"]) {
        c.send(&frame(f)).unwrap();
    }
    let mut order = Vec::new();
    while order.len() < 3 {
        let f = recv(&mut rx);
        if f != "001#0102030405060708" {
            order.push(f);
        }
    }
    assert_eq!(order, ["100#01", "200#02", "300#03"]);
    // The losers captured where they lost arbitration.
    let st = rx.node_status(Some(&NodeRef::Number(3))).unwrap();
    assert_ne!(st.counters.arbitration_lost, 0);
    assert!(st.errors.unwrap().alc.is_some());
    s.shutdown();
}

fn raw(s: &ServerHandle) -> TcpStream {
    let t = TcpStream::connect(s.local_addr()).unwrap();
    t.set_read_timeout(Some(EVENT)).unwrap();
    t
}

/// Reads until `want` has been seen; returns everything read.
fn read_until(t: &mut TcpStream, want: &str) -> String {
    let mut got = String::new();
    let mut buf = [0u8; 4096];
    while !got.contains(want) {
        let n = t.read(&mut buf).unwrap();
        assert!(n > 0, "closed before {want:?}; got {got:?}");
        got.push_str(&String::from_utf8_lossy(&buf[..n]));
    }
    got
}

#[test]
fn handshake_bytes_are_exactly_what_python_can_compares() {
    let s = server(500_000, 1024);
    let mut t = raw(&s);
    let mut buf = [0u8; 64];
    let n = t.read(&mut buf).unwrap();
    assert_eq!(&buf[..n], b"< hi >");
    t.write_all(b"< open vcan0 >").unwrap();
    let n = t.read(&mut buf).unwrap();
    assert_eq!(&buf[..n], b"< ok >");
    t.write_all(b"< rawmode >").unwrap();
    let n = t.read(&mut buf).unwrap();
    assert_eq!(&buf[..n], b"< ok >");
    s.shutdown();
}

#[test]
fn garbage_gets_an_error_and_the_connection_and_server_survive() {
    let s = server(500_000, 1024);
    let mut other = client(&s);
    let mut t = raw(&s);
    read_until(&mut t, "< hi >");
    t.write_all(b"< send 123 1 11 >").unwrap();
    read_until(&mut t, "< error open a bus first");
    t.write_all(b"< open vcan0 >< rawmode >").unwrap();
    read_until(&mut t, "< ok >< ok >");
    for (junk, answer) in [
        (&b"hello"[..], "< error text outside"),
        (
            b"< send 123 9 >",
            "< error DLC \"9\" must be a decimal 0..8 >",
        ),
        (b"< send 800 0 >", "< error ID \"800\""),
        (b"< fly >", "< error unknown command \"fly\" >"),
        (b"< \xff\xfe >", "< error element is not UTF-8 text >"),
        (b"< bcmmode >", "< error buslab serves raw mode only"),
        (
            b"< subscribe 0 0 123 >",
            "< error subscribe is not supported",
        ),
        (b"< buslab_status 99 >", "< error no node 99"),
    ] {
        t.write_all(junk).unwrap();
        t.write_all(b"< echo >").unwrap();
        let got = read_until(&mut t, "< echo >");
        assert!(got.contains(answer), "{junk:?}: {got:?}");
    }
    // The same connection still sends frames, and others still talk.
    t.write_all(b"< send 123 2 AA BB >").unwrap();
    assert_eq!(recv(&mut other), "123#AABB");
    other.send(&frame("321#01")).unwrap();
    read_until(&mut t, "< frame 321 ");
    s.shutdown();
}

#[test]
fn opening_another_bus_is_refused_and_closes() {
    let s = server(500_000, 1024);
    let mut t = raw(&s);
    read_until(&mut t, "< hi >");
    t.write_all(b"< open can7 >").unwrap();
    let got = read_until(&mut t, "< error could not open bus >");
    assert!(got.ends_with("< error could not open bus >"));
    let mut buf = [0u8; 16];
    assert_eq!(t.read(&mut buf).unwrap(), 0, "connection should be closed");
    s.shutdown();
}

#[test]
fn a_client_that_does_not_read_loses_only_its_own_frames() {
    let s = server(1_000_000, 4096);
    let mut sender = client(&s);
    let mut fast = client(&s);
    // Joins, then never reads.
    let mut slow = raw(&s);
    slow.write_all(b"< open vcan0 >< rawmode >< buslab_name slow >")
        .unwrap();
    let total = 20_000;
    let reader = std::thread::spawn(move || {
        let mut n = 0;
        while n < total {
            fast.recv(WAIT)
                .unwrap()
                .expect("every frame reaches the fast client");
            n += 1;
        }
        fast
    });
    for i in 0..total {
        let f = Frame::data(
            buslab_can::Id::standard(0x100).unwrap(),
            &(i as u64).to_le_bytes(),
        )
        .unwrap();
        sender.send(&f).unwrap();
    }
    let mut fast = reader.join().unwrap();
    let st = fast
        .node_status(Some(&NodeRef::Name("slow".into())))
        .unwrap();
    let lost = st.counters.rx_lost;
    assert!(lost > 0, "{st}");
    drop(slow);
    s.shutdown();
}

#[test]
fn registers_and_status_of_a_node_with_the_wrong_bit_timing() {
    let s = server(500_000, 1024);
    let mut good = client(&s);
    let mut bad = client(&s);
    bad.set_name("slowpoke").unwrap();
    bad.set_btr(0x07, 0x4D).unwrap();
    bad.send(&frame("123#11")).unwrap();
    // It fails to send; the good node sees nothing but errors.
    assert!(
        good.recv(Some(Duration::from_millis(100)))
            .unwrap()
            .is_none()
    );
    let status = |good: &mut SocketcandBus| {
        good.node_status(Some(&NodeRef::Name("slowpoke".into())))
            .unwrap()
    };
    let mut st = status(&mut good);
    // Waits for the first bus error to be captured (the server may lag on a loaded machine).
    let started = std::time::Instant::now();
    while st.errors.unwrap().ecc.is_none() {
        assert!(started.elapsed() < EVENT, "no bus error captured: {st}");
        std::thread::sleep(Duration::from_millis(10));
        st = status(&mut good);
    }
    assert!(!st.timing.unwrap().matches_bus);
    assert_eq!(st.timing.unwrap().bitrate, 50000);
    assert!(st.errors.unwrap().ecc.is_some(), "{st}");
    let errors = st.counters.bus_errors;
    assert!(errors > 0, "{st}");
    let regs = good
        .register_dump(Some(&NodeRef::Name("slowpoke".into())))
        .unwrap();
    assert_eq!((regs.number, regs.name.as_str()), (2, "slowpoke"));
    assert_eq!(regs.dump.get(6), Some(0x07));
    assert_eq!(regs.dump.get(7), Some(0x4D));
    let nodes: Vec<(u32, String)> = good
        .nodes()
        .unwrap()
        .into_iter()
        .map(|n| (n.number, n.name))
        .collect();
    assert_eq!(
        nodes,
        [(1, "node1".to_string()), (2, "slowpoke".to_string())]
    );
    s.shutdown();
}

#[test]
fn a_host_that_cannot_keep_up_is_reported() {
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 1_000_000);
    // A million times real time on a bus a scenario node keeps busy (a frame due every 50 µs,
    // each longer than that): no host simulates a terabit per second. Frames from a client
    // would not do: the whole-frame path empties any queue a client can fill before the lag
    // reaches the warning.
    config.speed = Speed::Times(1_000_000.0);
    config.scenario = Some(
        buslab_bench::Scenario::from_toml(
            "bitrate = 1000000\n[[nodes]]\nname = \"ecu\"\n  [[nodes.traffic]]\n  kind = \"periodic\"\n  frame = \"0AA#0102030405060708\"\n  period = \"50us\"\n[[nodes]]\nname = \"gateway\"\n",
        )
        .unwrap()
        .build()
        .unwrap(),
    );
    let s = spawn(config).unwrap();
    let _watcher = client(&s);
    // Waits for the event: the server measures its lag after catching up each turn.
    while s.lag().worst < buslab_vbus::server::LAG_WARNING {
        std::thread::sleep(Duration::from_millis(10));
    }
    s.shutdown();
}

#[test]
fn a_stalled_server_skips_what_lies_beyond_its_credit_instead_of_sending_it_at_once() {
    // A bus a scenario node keeps busy (a frame due every 50 µs, each longer than that), and
    // the server's thread kept from running for one second longer than its credit (as a
    // stopped process would be): before, it caught the whole stall up and sent every frame of
    // it to its clients at once; now it runs its credit's worth and skips the rest.
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 1_000_000);
    config.scenario = Some(
        buslab_bench::Scenario::from_toml(
            "bitrate = 1000000\n[[nodes]]\nname = \"ecu\"\n  [[nodes.traffic]]\n  kind = \"periodic\"\n  frame = \"0AA#0102030405060708\"\n  period = \"50us\"\n[[nodes]]\nname = \"gateway\"\n",
        )
        .unwrap()
        .build()
        .unwrap(),
    );
    let s = spawn(config).unwrap();
    let stall = buslab_vbus::server::BUS_CREDIT + Duration::from_secs(1);
    assert!(s.poster().post(move |_| std::thread::sleep(stall)));
    // Waits for the event: the first turn after the stall skips.
    let deadline = std::time::Instant::now() + stall + EVENT;
    while s.lag().skipped.is_zero() {
        assert!(
            std::time::Instant::now() < deadline,
            "nothing skipped within {EVENT:?} after the stall"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    let lag = s.lag();
    // The stall lasted at least `stall`, the bus busy throughout: all beyond the credit.
    assert!(
        lag.skipped >= stall - buslab_vbus::server::BUS_CREDIT,
        "skipped {:?}",
        lag.skipped
    );
    s.shutdown();
}

#[test]
fn speed_must_be_positive() {
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 500_000);
    config.speed = Speed::Times(0.0);
    let err = spawn(config).err().expect("refused").to_string();
    assert!(err.contains("speed 0 must be \"max\" or a number"), "{err}");
}

#[test]
fn error_frames_reach_clients_that_ask_for_them() {
    let s = server(500_000, 1024);
    let mut watcher = client(&s);
    watcher.set_error_frames(true).unwrap();
    // Raw mode with buslab's extensions, but no error frames asked for.
    let mut quiet = raw(&s);
    quiet
        .write_all(b"< open vcan0 >< rawmode >< buslab_ext >")
        .unwrap();
    read_until(&mut quiet, "< ok >< ok >< ok >");
    let mut bad = client(&s);
    bad.set_btr(0x07, 0x4D).unwrap();
    bad.send(&frame("123#11")).unwrap();
    let error = loop {
        match watcher.recv_event(WAIT).unwrap() {
            Some(m) => {
                if let Record::Error(e) = m.record {
                    break e;
                }
            }
            None => panic!("no error frame within {EVENT:?}"),
        }
    };
    // Protocol violation + bus error, with the counters, as Linux's SJA1000 driver reports a
    // bus error.
    assert_eq!(error.class(), 0x288, "{error:?}");
    assert!(error.counters.is_some(), "{error:?}");
    // The quiet client got none: its echo comes back with nothing before it.
    quiet.write_all(b"< echo >").unwrap();
    let got = read_until(&mut quiet, "< echo >");
    assert!(!got.contains("< error"), "{got}");
    s.shutdown();
}

#[test]
fn error_frames_for_everybody_in_socketcand_raw_layout() {
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 500_000);
    config.error_frames = true;
    let s = spawn(config).unwrap();
    let mut t = raw(&s);
    t.write_all(b"< open vcan0 >< rawmode >").unwrap();
    read_until(&mut t, "< ok >< ok >");
    let mut bad = client(&s);
    bad.set_btr(0x07, 0x4D).unwrap();
    bad.send(&frame("123#11")).unwrap();
    let got = read_until(&mut t, "< error 088 ");
    let line = &got[got.find("< error 088 ").unwrap()..];
    let end = line.find('>').unwrap();
    // `< error CLASS SEC.USEC >`: no data, as socketcand -e in raw mode.
    assert_eq!(line[..end + 1].split_whitespace().count(), 5, "{line}");
    s.shutdown();
}

#[test]
fn the_beacon_names_the_server_and_its_bus() {
    let udp = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    udp.set_read_timeout(Some(EVENT)).unwrap();
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 500_000);
    config.beacon = Some(udp.local_addr().unwrap());
    let s = spawn(config).unwrap();
    let mut buf = [0u8; 2048];
    let n = udp.recv(&mut buf).unwrap();
    let text = String::from_utf8_lossy(&buf[..n]);
    assert_eq!(
        text,
        format!(
            "<CANBeacon name=\"buslab\" type=\"SocketCAN\" description=\"buslab bus serve\">\n<URL>can://{}</URL><Bus name=\"vcan0\"/></CANBeacon>",
            s.local_addr()
        )
    );
    s.shutdown();
}

#[test]
fn joining_a_busy_bus_the_rawmode_ok_still_comes_alone() {
    let s = server(1_000_000, 8192);
    let mut a = client(&s);
    let _b = client(&s);
    for _ in 0..3000 {
        a.send(&frame("123#0102030405060708")).unwrap();
    }
    let mut t = raw(&s);
    let mut buf = [0u8; 256];
    let n = t.read(&mut buf).unwrap();
    assert_eq!(&buf[..n], b"< hi >");
    t.write_all(b"< open vcan0 >").unwrap();
    let n = t.read(&mut buf).unwrap();
    assert_eq!(&buf[..n], b"< ok >");
    t.write_all(b"< rawmode >").unwrap();
    // python-can compares this one read with "< ok >".
    let n = t.read(&mut buf).unwrap();
    assert_eq!(&buf[..n], b"< ok >");
    read_until(&mut t, "< frame 123 ");
    s.shutdown();
}

#[test]
fn speed_beyond_the_clock_arithmetic_is_refused() {
    // A tiny speed made the bus thread's wait overflow `Duration` (a panic); a huge one is
    // no bus at all.
    for speed in [1e-300, 1e-7, 1e300, 1e7] {
        let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 500_000);
        config.speed = Speed::Times(speed);
        let err = spawn(config).err().expect("refused").to_string();
        assert!(
            err.contains(&format!("speed {speed} must be")) && err.contains("0.001..=1000000"),
            "{err}"
        );
    }
    for speed in [0.001, 1_000_000.0] {
        let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 500_000);
        config.speed = Speed::Times(speed);
        spawn(config).expect("accepted").shutdown();
    }
}

#[test]
fn a_bus_name_clients_cannot_open_is_refused() {
    // `< open NAME >` takes one token, and the name goes into the beacon's XML.
    for name in [
        "",
        "two words",
        "a>b",
        "q\"uote",
        "a<b",
        "x".repeat(65).as_str(),
    ] {
        let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 500_000);
        config.channel = name.to_string();
        let err = spawn(config).err().expect("refused").to_string();
        assert!(
            err.contains(&format!("bus name {name:?}")) && err.contains("1..=64"),
            "{err}"
        );
    }
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 500_000);
    config.channel = "can_0-x.y".to_string();
    spawn(config).expect("accepted").shutdown();
}

#[test]
fn a_flood_of_connections_is_bounded_and_the_server_recovers() {
    // Each connection costs two threads and a queue: 1500 idle ones took 3000 threads and
    // 660 MB before there was a bound.
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 500_000);
    config.max_connections = 3;
    let s = spawn(config).unwrap();
    let mut held: Vec<TcpStream> = (0..3).map(|_| raw(&s)).collect();
    for t in &mut held {
        read_until(t, "< hi >");
        t.write_all(b"< open vcan0 >").unwrap();
        read_until(t, "< ok >");
    }
    // Every place holds a node: one more is refused.
    let mut extra = raw(&s);
    let mut got = String::new();
    extra.read_to_string(&mut got).unwrap();
    assert_eq!(
        got,
        "< error too many connections (3 open); try again later >"
    );
    // The held ones still work, and a closed one frees its place.
    held[0].write_all(b"< echo >").unwrap();
    read_until(&mut held[0], "< echo >");
    drop(held.pop());
    // Waits until the server has seen the close (it answers the next one with a greeting).
    let started = std::time::Instant::now();
    let mut greeted = false;
    while !greeted && started.elapsed() < EVENT {
        let mut t = raw(&s);
        let mut buf = [0u8; 64];
        let n = t.read(&mut buf).unwrap_or(0);
        greeted = buf[..n].starts_with(b"< hi >");
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(
        greeted,
        "a place freed by a closed connection is never reused"
    );
    s.shutdown();
}

/// The process's resident memory in KiB.
fn rss_kib() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = status.lines().find(|l| l.starts_with("VmRSS:")).unwrap();
    line.split_whitespace().nth(1).unwrap().parse().unwrap()
}

#[test]
fn idle_connections_cannot_lock_a_real_client_out() {
    // 256 connections that never opened the bus locked everyone out (no idle timeout), and
    // with `--client-queue 1048576` took 12.6 GB (each queue was allocated on accept).
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 500_000);
    config.client_queue = 1_048_576;
    let s = spawn(config).unwrap();
    let before = rss_kib();
    let mut idle: Vec<TcpStream> = (0..256).map(|_| raw(&s)).collect();
    for t in &mut idle {
        read_until(t, "< hi >");
    }
    let grown_mib = rss_kib().saturating_sub(before) / 1024;
    // Real clients still get in (each takes the place of the oldest idle connection) and talk.
    let mut a = client(&s);
    let mut b = client(&s);
    a.send(&frame("123#42")).unwrap();
    assert_eq!(recv(&mut b), "123#42");
    // The two oldest idle connections were told why and closed.
    for t in &mut idle[..2] {
        let mut got = String::new();
        t.read_to_string(&mut got).unwrap();
        assert!(got.contains("had not opened the bus"), "{got:?}");
    }
    assert!(grown_mib < 256, "256 idle connections took {grown_mib} MiB");
    eprintln!("256 idle connections: {grown_mib} MiB; real clients served");
    s.shutdown();
}

#[test]
fn a_megabyte_of_closing_brackets_gets_one_error() {
    // It got 32 MB of error replies and 15.5 s of CPU.
    let s = server(500_000, 1024);
    let mut t = raw(&s);
    read_until(&mut t, "< hi >");
    let garbage = vec![b'>'; 1 << 20];
    let writer = {
        let mut t = t.try_clone().unwrap();
        std::thread::spawn(move || {
            t.write_all(&garbage).unwrap();
            t.write_all(b"< echo >").unwrap();
        })
    };
    let started = std::time::Instant::now();
    let got = read_until(&mut t, "< echo >");
    writer.join().unwrap();
    assert_eq!(got.matches("< error").count(), 1, "{got}");
    assert!(got.len() < 200, "{} bytes of replies", got.len());
    eprintln!(
        "1 MiB of `>`: {} bytes of replies, echo after {:?}",
        got.len(),
        started.elapsed()
    );
    s.shutdown();
}

#[test]
fn clients_pipelining_requests_do_not_put_the_bus_behind() {
    // Ten clients pipelining buslab_regs/status/nodes put virtual time 4.5 s behind.
    let s = server(500_000, 1024);
    let mut pipeliners: Vec<TcpStream> = (0..10).map(|_| raw(&s)).collect();
    for t in &mut pipeliners {
        t.write_all(b"< open vcan0 >< rawmode >< buslab_ext >")
            .unwrap();
        read_until(t, "< ok >< ok >< ok >");
    }
    let mut a = client(&s);
    let mut b = client(&s);
    const REQUESTS: usize = 2000;
    let workers: Vec<_> = pipeliners
        .into_iter()
        .map(|mut t| {
            std::thread::spawn(move || {
                let mut w = t.try_clone().unwrap();
                let sender = std::thread::spawn(move || {
                    let batch = b"< buslab_regs >< buslab_status >< buslab_nodes >".repeat(50);
                    for _ in 0..REQUESTS / 150 {
                        w.write_all(&batch).unwrap();
                    }
                    w.write_all(b"< echo >").unwrap();
                });
                read_until(&mut t, "< echo >");
                sender.join().unwrap();
            })
        })
        .collect();
    // Frames keep flowing meanwhile.
    for i in 0..100u8 {
        a.send(&Frame::data(buslab_can::Id::standard(0x100).unwrap(), &[i]).unwrap())
            .unwrap();
        assert_eq!(recv(&mut b), format!("100#{i:02X}"));
    }
    for w in workers {
        w.join().unwrap();
    }
    let lag = s.lag();
    eprintln!(
        "10 clients × {REQUESTS} pipelined requests: worst lag {:?}",
        lag.worst
    );
    assert!(
        lag.worst < Duration::from_secs(1),
        "virtual time fell {:?} behind",
        lag.worst
    );
    s.shutdown();
}

#[test]
fn a_zombie_client_leaves_the_bus_at_once_with_its_queued_frames() {
    // A client with the wrong bit timing and megabytes of queued sends disconnected; its node
    // stayed for hours (bus-off every 110 ms), and a node joining later got stale frames: its
    // session thread was stuck handing frames to the full queue and never saw the end. Its
    // node now sends what it handed over until it goes bus-off (at once: nothing it sends
    // gets through), then leaves with the rest counted as dropped (issue 25).
    let s = server(500_000, 8192);
    let mut watcher = client(&s);
    let mut zombie = raw(&s);
    zombie
        .write_all(
            b"< open vcan0 >< rawmode >< buslab_name zombie >< buslab_btr 07 4D >< buslab_errors 1 >",
        )
        .unwrap();
    read_until(&mut zombie, "< ok >< ok >< ok >< ok >< ok >");
    // 4 MB of sends: far more than its queues take; the rest waits in the sockets.
    zombie.set_nonblocking(true).unwrap();
    let sends = b"< send 123 8 01 02 03 04 05 06 07 08 >".repeat(4 << 20 >> 5);
    let mut written = 0;
    while written < sends.len() {
        match zombie.write(&sends[written..]) {
            Ok(n) => written += n,
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
            Err(e) => panic!("{e}"),
        }
    }
    // It is on the bus and failing, and the server has sent it error frames it never reads.
    let started = std::time::Instant::now();
    while watcher
        .node_status(Some(&NodeRef::Name("zombie".into())))
        .unwrap()
        .counters
        .bus_errors
        == 0
    {
        assert!(
            started.elapsed() < EVENT,
            "the zombie never disturbed the bus"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    // The client goes away as a killed process does (unread data: the kernel resets the
    // connection).
    drop(zombie);
    let closed = std::time::Instant::now();
    let on_bus =
        |watcher: &mut SocketcandBus| watcher.nodes().unwrap().iter().any(|n| n.name == "zombie");
    while on_bus(&mut watcher) {
        assert!(closed.elapsed() < EVENT, "the zombie's node stayed");
        std::thread::sleep(Duration::from_millis(1));
    }
    let gone_after = closed.elapsed();
    // A node joining later gets nothing stale, and the bus is quiet.
    let mut late = client(&s);
    assert!(
        late.recv(Some(Duration::from_millis(300)))
            .unwrap()
            .is_none()
    );
    let errors = watcher.node_status(None).unwrap().counters.bus_errors;
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(
        watcher.node_status(None).unwrap().counters.bus_errors,
        errors
    );
    eprintln!(
        "the zombie ({written} bytes of sends queued) left the bus {gone_after:?} after its \
         connection closed"
    );
    s.shutdown();
}

#[test]
fn a_client_queue_the_server_cannot_allocate_is_refused() {
    // The queue is allocated whole for every client: usize::MAX panicked each client thread
    // ("capacity overflow") and a few hundred million took gigabytes per client.
    for queue in [0, 15, 1_048_577, usize::MAX] {
        let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 500_000);
        config.client_queue = queue;
        let err = spawn(config).err().expect("refused").to_string();
        assert!(
            err.contains(&format!("client queue {queue} must be 16..=1048576")),
            "{err}"
        );
    }
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 500_000);
    config.client_queue = 16;
    spawn(config).expect("accepted").shutdown();
}

#[test]
fn a_beacon_from_all_interfaces_names_a_reachable_address() {
    // Listening on 0.0.0.0, the beacon said `can://0.0.0.0:PORT`: python-can's
    // `detect_beacon()` on another host would then connect to itself. socketcand names the
    // interface's address; buslab names the one the beacon leaves from.
    use buslab_vbus::server::beacon_url_addr;
    let all: std::net::SocketAddr = "0.0.0.0:29536".parse().unwrap();
    let to_lo: std::net::SocketAddr = "127.0.0.1:42000".parse().unwrap();
    assert_eq!(
        beacon_url_addr(all, to_lo),
        "127.0.0.1:29536".parse().unwrap()
    );
    // A specific address is kept as it is.
    let one: std::net::SocketAddr = "127.0.0.2:5".parse().unwrap();
    assert_eq!(beacon_url_addr(one, to_lo), one);
}

#[test]
fn abort_gives_up_a_frame_nobody_acknowledges() {
    let s = server(500_000, 1024);
    let mut alone = client(&s);
    // Nobody else on the bus: no ACK, the chip would retry for ever.
    alone.send(&frame("123#11")).unwrap();
    alone.send(&frame("124#22")).unwrap();
    alone.abort().unwrap();
    let report = alone.flush(EVENT).unwrap();
    assert_eq!((report.sent, report.failed), (0, 2), "{report:?}");
    // The node is free again: with a listener, the next frame goes through.
    let mut listener = client(&s);
    alone.send(&frame("125#33")).unwrap();
    assert_eq!(recv(&mut listener), "125#33");
    s.shutdown();
}

#[test]
fn a_frame_sent_after_a_quiet_spell_enters_the_bus_at_the_wall_clock_time() {
    // Regression: the loop served clients before catching the idle bus up with the wall
    // clock, so a frame sent after a quiet spell entered the bus in the past (by as much as
    // the loop had slept): its timestamp was hundreds of milliseconds early, and a SLIO
    // calibrated every 40 ms saw gaps past its 8192-bit watchdog.
    let s = server(500_000, 1024);
    let mut a = client(&s);
    let mut b = client(&s);
    std::thread::sleep(Duration::from_millis(500));
    let before = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64();
    a.send(&frame("123#01")).unwrap();
    let m = b.recv(WAIT).unwrap().expect("the frame");
    // Virtual time never runs ahead of the wall clock, so the frame cannot be stamped later
    // than it really ended; and it entered the bus no earlier than it was sent (1 ms for the
    // two clocks' rounding).
    let at = m.at.as_secs_f64();
    assert!(at >= before - 0.001, "{at} < {before}");
    s.shutdown();
}

#[test]
fn at_max_speed_frames_sent_at_once_all_arrive_in_order() {
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 1_000_000);
    config.speed = Speed::Max;
    let s = spawn(config).unwrap();
    let mut rx = client(&s);
    let mut tx = client(&s);
    let frames: Vec<Frame> = (0..2000u32)
        .map(|i| Frame::data(buslab_can::Id::standard(0x123).unwrap(), &i.to_le_bytes()).unwrap())
        .collect();
    for batch in frames.chunks(64) {
        tx.send_all(batch).unwrap();
    }
    let report = tx.flush(EVENT).unwrap();
    assert_eq!((report.sent, report.failed), (2000, 0));
    for want in &frames {
        let got = rx.recv(WAIT).unwrap().expect("every frame arrives");
        assert_eq!(&got.record, want);
    }
    s.shutdown();
}

/// At `max`, a raw client reading with `pause` between small reads, after `quiet` without
/// traffic, while another client writes 5 000 frames at once: it gets every frame, in order,
/// and the server counts none dropped for it.
fn reader_at_max_gets_every_frame(client_queue: usize, quiet: Duration, pause: Duration) {
    let mut config = ServerConfig::new("127.0.0.1:0".parse().unwrap(), 1_000_000);
    config.speed = Speed::Max;
    config.client_queue = client_queue;
    let s = spawn(config).unwrap();
    let mut reader = raw(&s);
    read_until(&mut reader, "< hi >");
    reader.write_all(b"< open vcan0 >").unwrap();
    read_until(&mut reader, "< ok >");
    reader.write_all(b"< rawmode >").unwrap();
    read_until(&mut reader, "< ok >");
    let mut tx = client(&s);
    std::thread::sleep(quiet);
    let total = 5_000u32;
    let frames: Vec<Frame> = (0..total)
        .map(|i| Frame::data(buslab_can::Id::standard(0x123).unwrap(), &i.to_le_bytes()).unwrap())
        .collect();
    let sender = std::thread::spawn(move || {
        for batch in frames.chunks(64) {
            tx.send_all(batch).unwrap();
        }
        let report = tx.flush(EVENT).unwrap();
        assert_eq!((report.sent, report.failed), (u64::from(total), 0));
        tx
    });
    let mut text = String::new();
    let mut buf = [0u8; 512];
    // Until the last frame's element is whole, not only begun.
    while text.matches("< frame ").count() < total as usize || !text.ends_with('>') {
        std::thread::sleep(pause);
        let n = reader.read(&mut buf).expect("every frame arrives");
        assert!(
            n > 0,
            "closed after {} frames",
            text.matches("< frame ").count()
        );
        text.push_str(std::str::from_utf8(&buf[..n]).unwrap());
    }
    let mut tx = sender.join().unwrap();
    let data: Vec<String> = text
        .split("< frame ")
        .skip(1)
        .map(|f| f.split_whitespace().nth(2).unwrap().to_string())
        .collect();
    let want: Vec<String> = (0..total)
        .map(|i| i.to_le_bytes().iter().map(|b| format!("{b:02X}")).collect())
        .collect();
    assert_eq!(data, want, "every frame, in order");
    let st = tx.node_status(Some(&NodeRef::Number(1))).unwrap();
    assert_eq!(st.counters.rx_lost, 0, "{st}");
    s.shutdown();
}

/// At `max` the bus never hands a receiver that reads more than its queue takes: a slow
/// reader with a small `--client-queue` gets every frame, in order, however fast the sender.
/// (Before, a loop turn ran every frame the sender had queued, hundreds, into a queue of 64
/// and dropped the rest: 77 of 20 000 arrived.)
#[test]
fn at_max_speed_a_slow_reader_with_a_small_queue_loses_nothing() {
    reader_at_max_gets_every_frame(64, Duration::ZERO, Duration::from_micros(500));
}

/// A quiet spell longer than the server's 1 s stall limit does not make a reader that had
/// nothing to read look stalled when the traffic starts (it lost 391 of 3 000 frames so).
#[test]
fn at_max_speed_a_reader_quiet_for_a_while_loses_nothing() {
    reader_at_max_gets_every_frame(64, Duration::from_millis(1500), Duration::ZERO);
}

/// The loop wakes a little before a client's frame ends on the wire and spins the rest
/// (`buslab_pace::Punctual`): the frame still reaches the other client no earlier than its
/// end (virtual time never runs ahead of the wall clock), the sleep, the spin and a frame
/// short enough to be spun to at once alike.
#[test]
fn a_frame_reaches_its_receivers_no_earlier_than_its_end_on_the_wire() {
    // `123#`: 45 bits with its stuff bit; 360 µs at 125 kbit/s (a sleep, then a spin), 45 µs
    // at 1 Mbit/s (within the spin bound: spun to at once).
    for bitrate in [125_000u32, 1_000_000] {
        // The bus's clock is the wall clock rounded down to a bit: the frame may start up to
        // one bit-time before the server read it.
        let wire = Duration::from_nanos(44 * 1_000_000_000 / u64::from(bitrate));
        let s = server(bitrate, 1024);
        let mut a = client(&s);
        let mut b = client(&s);
        for _ in 0..20 {
            let sent = std::time::Instant::now();
            a.send(&frame("123#")).unwrap();
            assert_eq!(recv(&mut b), "123#");
            let took = sent.elapsed();
            assert!(
                took >= wire,
                "{bitrate} bit/s: {took:?} < {wire:?} on the wire, less a bit"
            );
        }
        s.shutdown();
    }
}
