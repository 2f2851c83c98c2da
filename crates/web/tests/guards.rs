//! What keeps the web server to its own users: requests naming a foreign host are refused
//! (DNS rebinding), writes from other sites' pages too, every answer says what a browser may
//! do with it, and connections that stall cannot lock the others out.
//!
//! The timeouts are made short for these tests; every wait below is derived from them or
//! waits for an event (with [`HANG`] only as a guard against a hung server).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::mpsc::{self, Receiver, Sender};
use std::time::{Duration, Instant};

use buslab_bus::{BusError, CanBus, ErrorState, Filter, Message};
use buslab_can::Frame;
use buslab_web::{Timeouts, WebConfig, WebServer};

/// Only a guard against a hung server: every wait ends on an event first.
const HANG: Duration = Duration::from_secs(120);
const TOKEN: &str = "guard-test-token";

/// A bus whose frames the test feeds; frames sent to it are handed back to the test.
struct Feed {
    frames: Receiver<Frame>,
    sent: Sender<Frame>,
}

impl CanBus for Feed {
    fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
        let _ = self.sent.send(*frame);
        Ok(())
    }
    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
        match self.frames.recv_timeout(timeout.unwrap_or(HANG)) {
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

struct Bench {
    server: WebServer,
    frames: Sender<Frame>,
    sent: Receiver<Frame>,
}

fn bench(config: WebConfig) -> Bench {
    let (frames, frames_rx) = mpsc::channel();
    let (sent_tx, sent) = mpsc::channel();
    let server = WebServer::start(
        Box::new(Feed {
            frames: frames_rx,
            sent: sent_tx,
        }),
        WebConfig {
            listen: "127.0.0.1:0".parse().unwrap(),
            ..config
        },
    )
    .unwrap();
    Bench {
        server,
        frames,
        sent,
    }
}

/// An answer: status, headers (lower-case names), body.
struct Answer {
    status: u16,
    headers: Vec<(String, String)>,
    body: String,
}

impl Answer {
    fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
}

/// Reads one answer (by its Content-Length) from `reader`; `None` if the connection closed
/// first.
fn read_answer(reader: &mut impl BufRead) -> Option<Answer> {
    let mut line = String::new();
    if reader.read_line(&mut line).ok()? == 0 {
        return None;
    }
    let status = line.split_whitespace().nth(1)?.parse().ok()?;
    let mut headers = Vec::new();
    loop {
        let mut line = String::new();
        reader.read_line(&mut line).unwrap();
        let line = line.trim_end();
        if line.is_empty() {
            break;
        }
        let (name, value) = line.split_once(':').unwrap();
        headers.push((name.to_ascii_lowercase(), value.trim().to_string()));
    }
    let length = headers
        .iter()
        .find(|(n, _)| n == "content-length")
        .map_or(0, |(_, v)| v.parse().unwrap());
    let mut body = vec![0; length];
    reader.read_exact(&mut body).unwrap();
    Some(Answer {
        status,
        headers,
        body: String::from_utf8_lossy(&body).to_string(),
    })
}

/// Status 0: a connection over the limit closed without an answer (when even the polite
/// refusals are all busy).
const DROPPED: u16 = 0;

/// Sends `raw` on a new connection and reads the answer.
fn exchange(addr: SocketAddr, raw: &str) -> Answer {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(HANG)).unwrap();
    // A refused connection may be closed before it is read.
    let _ = s.write_all(raw.as_bytes());
    read_answer(&mut BufReader::new(s)).unwrap_or(Answer {
        status: DROPPED,
        headers: Vec::new(),
        body: String::new(),
    })
}

fn get(addr: SocketAddr, host: &str, path: &str) -> Answer {
    exchange(
        addr,
        &format!("GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"),
    )
}

fn assert_secured(answer: &Answer, what: &str) {
    let csp = answer
        .header("content-security-policy")
        .unwrap_or_else(|| panic!("{what}: no Content-Security-Policy"));
    for directive in [
        "default-src 'none'",
        "script-src 'self'",
        "frame-ancestors 'none'",
    ] {
        assert!(csp.contains(directive), "{what}: {csp}");
    }
    assert!(!csp.contains("unsafe-inline"), "{what}: {csp}");
    assert_eq!(answer.header("x-frame-options"), Some("DENY"), "{what}");
    assert_eq!(
        answer.header("x-content-type-options"),
        Some("nosniff"),
        "{what}"
    );
    assert_eq!(
        answer.header("referrer-policy"),
        Some("no-referrer"),
        "{what}"
    );
}

#[test]
fn a_foreign_host_gets_403_and_every_answer_carries_the_security_headers() {
    let b = bench(WebConfig {
        allowed_hosts: vec!["bench.lab".into()],
        ..WebConfig::default()
    });
    let addr = b.server.addr();
    // What a page of another site reaches after pointing its name at 127.0.0.1.
    for host in ["evil.example", &format!("evil.example:{}", addr.port())] {
        for path in ["/", "/api/state", "/api/events", "/dashboard"] {
            let a = get(addr, host, path);
            assert_eq!(a.status, 403, "{host} {path}: {}", a.body);
            assert!(
                a.body.contains(&format!(
                    "Host {host:?} is not a name this server answers to"
                )) && a.body.contains("--allow-host NAME"),
                "{}",
                a.body
            );
            assert!(!a.body.contains("\"delta\""), "nothing of the bus leaks");
            assert_secured(&a, "403");
        }
    }
    let a = exchange(addr, "GET / HTTP/1.1\r\nConnection: close\r\n\r\n");
    assert_eq!(a.status, 400, "{}", a.body);
    assert!(a.body.contains("needs a Host header"), "{}", a.body);
    // Absolute-form targets name their host too.
    let a = exchange(
        addr,
        "GET http://evil.example/ HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n",
    );
    assert_eq!(a.status, 403, "{}", a.body);

    // The loopback names, IP addresses and the allowed name are served.
    let port = addr.port();
    for host in [
        format!("127.0.0.1:{port}"),
        format!("localhost:{port}"),
        "LocalHost".to_string(),
        format!("[::1]:{port}"),
        format!("bench.lab:{port}"),
    ] {
        let a = get(addr, &host, "/");
        assert_eq!(a.status, 200, "{host}: {}", a.body);
        assert_secured(&a, "a page");
    }
    let host = format!("127.0.0.1:{port}");
    for (path, status) in [
        ("/dashboard", 200),
        ("/assets/dashboard.js", 200),
        ("/assets/style.css", 200),
        ("/api/state", 200),
        ("/nowhere", 404),
        ("/frames?filter=zzz", 400),
    ] {
        let a = get(addr, &host, path);
        assert_eq!(a.status, status, "{path}: {}", a.body);
        assert_secured(&a, path);
    }
    // The live updates too (read up to the head only).
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(HANG)).unwrap();
    write!(s, "GET /api/events HTTP/1.1\r\nHost: {host}\r\n\r\n").unwrap();
    let mut head = String::new();
    let mut reader = BufReader::new(s);
    while !head.ends_with("\r\n\r\n") {
        assert!(reader.read_line(&mut head).unwrap() > 0, "{head}");
    }
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert!(
        head.to_ascii_lowercase().contains("x-frame-options: deny"),
        "{head}"
    );
}

#[test]
fn writes_from_a_page_of_another_origin_are_refused() {
    let b = bench(WebConfig {
        token: Some(TOKEN.into()),
        ..WebConfig::default()
    });
    let addr = b.server.addr();
    let post = |origin: Option<&str>| {
        let origin = origin.map_or(String::new(), |o| format!("Origin: {o}\r\n"));
        let body = r#"{"frame":"123#11"}"#;
        exchange(
            addr,
            &format!(
                "POST /api/send HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nConnection: close\r\n\
                 {origin}X-Buslab-Token: {TOKEN}\r\nContent-Length: {}\r\n\r\n{body}",
                addr.port(),
                body.len()
            ),
        )
    };
    for origin in ["http://evil.example", "null", "http://evil.example:8080"] {
        let a = post(Some(origin));
        assert_eq!(a.status, 403, "{origin}: {}", a.body);
        assert!(
            a.body.contains("a write from a page of origin"),
            "{}",
            a.body
        );
        assert_secured(&a, "403");
    }
    assert!(b.sent.try_recv().is_err(), "nothing reached the bus");
    // The server's own page, and a client that is no page at all (curl), may write.
    let own = format!("http://127.0.0.1:{}", addr.port());
    for origin in [Some(own.as_str()), None] {
        let a = post(origin);
        assert_eq!(a.status, 202, "{origin:?}: {}", a.body);
        assert_eq!(
            b.sent.recv_timeout(HANG).unwrap(),
            "123#11".parse::<Frame>().unwrap()
        );
    }
}

/// The request timeout of the attack tests: short, so they are quick.
const TIMEOUT: Duration = Duration::from_millis(1500);

/// Reads `conn` until the server closes it: what it said, and when it closed.
fn until_closed(mut conn: TcpStream) -> (String, Instant) {
    conn.set_read_timeout(Some(HANG)).unwrap();
    let mut said = Vec::new();
    // A reset counts as closed.
    let _ = conn.read_to_end(&mut said);
    (String::from_utf8_lossy(&said).to_string(), Instant::now())
}

#[test]
fn stalled_bodies_and_idle_connections_cannot_lock_everyone_out() {
    // Regression: a POST whose body never came held its connection slot forever (hyper's
    // timer covers only the head), so --max-connections of them locked everyone out with
    // 503, no token needed.
    const MAX: usize = 6;
    let b = bench(WebConfig {
        max_connections: MAX,
        timeouts: Timeouts {
            request: TIMEOUT,
            ..Timeouts::default()
        },
        ..WebConfig::default()
    });
    let addr = b.server.addr();
    let host = format!("127.0.0.1:{}", addr.port());

    // A live dashboard holds one place while all this happens, and keeps it.
    let viewer = TcpStream::connect(addr).unwrap();
    viewer.set_read_timeout(Some(HANG)).unwrap();
    write!(&viewer, "GET /api/events HTTP/1.1\r\nHost: {host}\r\n\r\n").unwrap();
    let (updates_tx, updates) = mpsc::channel();
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(viewer).lines() {
            let Ok(line) = line else { break };
            if line.starts_with("data: ") && updates_tx.send(Instant::now()).is_err() {
                break;
            }
        }
    });
    updates
        .recv_timeout(HANG)
        .expect("the viewer got no update");

    // The attack: every other place held by a connection that does not do its part.
    let started = Instant::now();
    let mut attackers = Vec::new();
    for i in 0..MAX - 1 {
        let mut c = TcpStream::connect(addr).unwrap();
        match i % 4 {
            // A write's head announcing a body that never comes (no token needed).
            0 => write!(
                c,
                "POST /api/send HTTP/1.1\r\nHost: {host}\r\nContent-Length: 100\r\n\r\n"
            )
            .unwrap(),
            // Half the body, then nothing.
            1 => write!(
                c,
                "POST /api/fault HTTP/1.1\r\nHost: {host}\r\nContent-Length: 100\r\n\r\n{{\"kind\":"
            )
            .unwrap(),
            // A connection that says nothing.
            2 => {}
            // A kept-alive connection, idle after one answer.
            _ => {
                write!(c, "GET /api/state?n=0 HTTP/1.1\r\nHost: {host}\r\n\r\n").unwrap();
                let mut r = BufReader::new(c.try_clone().unwrap());
                let a = read_answer(&mut r).expect("the first answer");
                assert_eq!(a.status, 200);
            }
        }
        attackers.push((i % 4, c));
    }
    // While they hold every place, a newcomer is refused (unless the machine was so slow
    // that the timeout already freed them).
    let a = get(addr, &host, "/");
    assert!(
        a.status == 503 || started.elapsed() >= TIMEOUT,
        "{} {}",
        a.status,
        a.body
    );
    if a.status == 503 {
        assert!(a.body.contains("too many connections"), "{}", a.body);
        assert_secured(&a, "503");
    }

    // Each is cut by the server once the timeout has passed, never before; a stalled body
    // is told why.
    for (kind, conn) in attackers {
        let (said, closed) = until_closed(conn);
        assert!(
            closed - started >= TIMEOUT,
            "kind {kind} cut after {:?}, before the timeout {TIMEOUT:?}",
            closed - started
        );
        if kind < 2 {
            assert!(said.starts_with("HTTP/1.1 408"), "kind {kind}: {said}");
            assert!(said.contains("did not arrive within 1500 ms"), "{said}");
        }
    }
    // A legitimate client is served again.
    let served = loop {
        let a = get(addr, &host, "/");
        if a.status == 200 {
            break Instant::now();
        }
        assert_eq!(a.status, 503, "{}", a.body);
        assert!(started.elapsed() < HANG, "never served again");
    };
    eprintln!(
        "attack with {} connections, request timeout {TIMEOUT:?}: a legitimate client was \
         served {:?} after the attack began",
        MAX - 1,
        served - started
    );
    assert!(b.sent.try_recv().is_err(), "no write reached the bus");

    // The live dashboard was never cut: it still gets updates, more than twice the timeout
    // after the attack began.
    let mut last = started;
    while last - started <= TIMEOUT * 2 {
        last = updates
            .recv_timeout(HANG)
            .expect("the live viewer's stream ended");
    }
    drop(b);
    reader.join().unwrap();
}

#[test]
fn an_answer_nobody_reads_frees_its_place_after_the_stall_limit() {
    // A client that asks and never reads held its connection's place for ever (with one
    // place: everyone locked out); now it holds it for the stall limit.
    let stall = TIMEOUT;
    let b = bench(WebConfig {
        max_connections: 1,
        timeouts: Timeouts {
            stalled_write: stall,
            ..Timeouts::default()
        },
        ..WebConfig::default()
    });
    let addr = b.server.addr();
    let host = format!("127.0.0.1:{}", addr.port());
    // Frames with IDs of their own make the answer larger than every buffer on the way
    // (the server's send buffer is 64 KiB, the client's receive buffer is made small).
    const IDS: u16 = 2048;
    for id in 0..IDS {
        let frame = Frame::data(buslab_can::Id::standard(id).unwrap(), &[0xAA; 8]).unwrap();
        b.frames.send(frame).unwrap();
    }
    // (With one place, a connection may come before the last one has let go of it: 503.)
    let size = loop {
        let a = get(addr, &host, "/api/state?n=1000");
        assert!([200, 503, DROPPED].contains(&a.status), "{}", a.body);
        if a.body.contains(&format!("\"frames\":{IDS},")) {
            break a.body.len();
        }
    };
    assert!(size > 1 << 18, "the answer is only {size} bytes");
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let stalled = loop {
        let stalled = rt.block_on(async {
            let socket = tokio::net::TcpSocket::new_v4().unwrap();
            socket.set_recv_buffer_size(4096).unwrap();
            socket.connect(addr).await.unwrap().into_std().unwrap()
        });
        stalled.set_nonblocking(false).unwrap();
        stalled.set_read_timeout(Some(HANG)).unwrap();
        write!(
            &stalled,
            "GET /api/state?n=1000 HTTP/1.1\r\nHost: {host}\r\n\r\n"
        )
        .unwrap();
        // The answer has begun (looked at, not read).
        let mut head = [0u8; 12];
        let mut seen = 0;
        while seen < head.len() {
            seen = stalled.peek(&mut head).unwrap();
        }
        match &head {
            b"HTTP/1.1 200" => break stalled,
            b"HTTP/1.1 503" => continue,
            other => panic!("{}", String::from_utf8_lossy(other)),
        }
    };
    let started = Instant::now();
    // It holds the only place until the server gives up on it; then others are served.
    let served = loop {
        let a = get(addr, &host, "/");
        if a.status == 200 {
            break Instant::now();
        }
        assert!([503, DROPPED].contains(&a.status), "{}", a.body);
        assert!(started.elapsed() < HANG, "never served again");
    };
    assert!(
        served - started >= stall,
        "served after {:?}, before the stall limit",
        served - started
    );
    // What the stalled client can still read is less than the answer.
    let (said, _) = until_closed(stalled);
    assert!(
        said.len() < size,
        "the whole answer arrived ({} bytes): nothing was cut",
        said.len()
    );
    eprintln!(
        "a {size}-byte answer nobody read: the place was free again {:?} after the answer \
         began (stall limit {stall:?}); {} bytes of it had been sent",
        served - started,
        said.len()
    );
}
