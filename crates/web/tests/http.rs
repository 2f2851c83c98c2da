//! The web server over real TCP: pages without JavaScript, the token rule, reasons for
//! refusals, live updates, and 10 000 bad requests survived. The bus is a stand-in whose
//! frames and node the test controls.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use buslab_bus::{
    BusAdmin, BusError, BusSummary, CanBus, ErrorRegisters, ErrorState, Filter, Message,
    NodeCounters, NodeInfo, NodeRef, NodeRegisters, NodeStatus, Status, TxReport, WireFault,
};
use buslab_can::Frame;
use buslab_web::{WebConfig, WebServer};

/// Only a guard against a hung server: every wait below ends on an event first.
const HANG: Duration = Duration::from_secs(120);
const TOKEN: &str = "test-token-123";

/// What the stand-in bus's node 2 ("sender") goes through; shared with the test.
#[derive(Default)]
struct Wire {
    faults: Vec<String>,
    tec: u8,
}

struct FakeBus {
    frames: Receiver<Frame>,
    sent: Sender<Frame>,
    wire: Arc<Mutex<Wire>>,
}

impl CanBus for FakeBus {
    fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
        let _ = self.sent.send(*frame);
        Ok(())
    }
    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
        match self.frames.recv_timeout(timeout.unwrap_or(HANG)) {
            Ok(f) => Ok(Some(Message::rx(
                buslab_bus::Timestamp::from_secs(1),
                "fake",
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
        "fake bus".into()
    }
    fn admin(&mut self) -> Option<&mut dyn BusAdmin> {
        Some(self)
    }
}

impl BusAdmin for FakeBus {
    fn nodes(&mut self) -> Result<Vec<NodeInfo>, BusError> {
        Ok(vec![
            NodeInfo {
                number: 1,
                name: "web".into(),
            },
            NodeInfo {
                number: 2,
                name: "<sender>".into(),
            },
        ])
    }
    fn node_status(&mut self, node: Option<&NodeRef>) -> Result<NodeStatus, BusError> {
        let (number, name, tec) = match node {
            None | Some(NodeRef::Number(1)) => (1, "web", 0),
            Some(NodeRef::Number(2)) => (2, "<sender>", self.wire.lock().unwrap().tec),
            Some(other) => return Err(BusError::Other(format!("no node {other}").into())),
        };
        Ok(NodeStatus {
            number,
            name: name.into(),
            state: if tec >= 128 {
                ErrorState::Passive
            } else {
                ErrorState::Active
            },
            errors: Some(ErrorRegisters {
                alc: None,
                ecc: None,
                rxerr: 0,
                txerr: tec,
            }),
            sr: Some(Status(0x0C)),
            timing: None,
            counters: NodeCounters::default(),
            tx_queued: 0,
            bus: BusSummary {
                bitrate: 125_000,
                load_percent: 12.5,
                frames: 0,
                errors: 0,
            },
        })
    }
    fn register_dump(&mut self, _: Option<&NodeRef>) -> Result<NodeRegisters, BusError> {
        Err(BusError::Other("no registers".into()))
    }
    fn set_name(&mut self, _: &str) -> Result<(), BusError> {
        Ok(())
    }
    fn set_btr(&mut self, _: u8, _: u8) -> Result<(), BusError> {
        Ok(())
    }
    fn flush(&mut self, _: Duration) -> Result<TxReport, BusError> {
        Err(BusError::Other("no flush".into()))
    }
    fn abort(&mut self) -> Result<(), BusError> {
        Ok(())
    }
    fn inject_fault(&mut self, fault: &WireFault, _: Option<Duration>) -> Result<(), BusError> {
        let mut wire = self.wire.lock().unwrap();
        wire.faults.push(fault.name().to_string());
        wire.tec = 136;
        Ok(())
    }
    fn repair(&mut self) -> Result<(), BusError> {
        let mut wire = self.wire.lock().unwrap();
        wire.faults.push("repair".into());
        wire.tec = 0;
        Ok(())
    }
}

struct Bench {
    server: WebServer,
    frames: Sender<Frame>,
    sent: Receiver<Frame>,
    wire: Arc<Mutex<Wire>>,
}

fn bench(token: Option<&str>, max_connections: usize) -> Bench {
    bench_with(token, max_connections, buslab_web::DeviceConfig::default())
}

fn bench_with(
    token: Option<&str>,
    max_connections: usize,
    devices: buslab_web::DeviceConfig,
) -> Bench {
    bench_config(WebConfig {
        token: token.map(str::to_string),
        max_connections,
        devices,
        ..WebConfig::default()
    })
}

/// A server on a free loopback port with `config` otherwise.
fn bench_config(config: WebConfig) -> Bench {
    let (frames, frames_rx) = mpsc::channel();
    let (sent_tx, sent) = mpsc::channel();
    let wire = Arc::new(Mutex::new(Wire::default()));
    let bus = FakeBus {
        frames: frames_rx,
        sent: sent_tx,
        wire: wire.clone(),
    };
    let server = WebServer::start(
        Box::new(bus),
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
        wire,
    }
}

/// Sends `raw` on a new connection and reads the answer to the end: (status, whole text).
fn exchange(addr: SocketAddr, raw: &[u8]) -> (u16, String) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(HANG)).unwrap();
    // The server may answer (and close) before it read a request it refuses.
    let _ = s.write_all(raw);
    let mut bytes = Vec::new();
    let _ = s.read_to_end(&mut bytes);
    let text = String::from_utf8_lossy(&bytes).to_string();
    let status = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (status, text)
}

fn get(addr: SocketAddr, path: &str) -> (u16, String) {
    exchange(
        addr,
        format!("GET {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n").as_bytes(),
    )
}

fn post(addr: SocketAddr, path: &str, token: Option<&str>, body: &str) -> (u16, String) {
    let header = token.map_or(String::new(), |t| format!("X-Buslab-Token: {t}\r\n"));
    exchange(
        addr,
        format!(
            "POST {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n{header}\
             Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
            body.len()
        )
        .as_bytes(),
    )
}

/// Reads a page until `done` says it shows what is expected (the view catches up with the
/// bus on its own threads: a node's page is a 404 until the view has seen the node).
fn until(addr: SocketAddr, path: &str, done: impl Fn(&str) -> bool) -> String {
    let deadline = std::time::Instant::now() + HANG;
    loop {
        let (status, text) = get(addr, path);
        if status == 200 && done(&text) {
            return text;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "{path} never showed it (status {status}):\n{text}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn pages_without_javascript_show_nodes_load_frames_and_ids() {
    let b = bench(None, 64);
    let addr = b.server.addr();
    b.frames.send("123#1122".parse().unwrap()).unwrap();
    b.frames.send("123#1133".parse().unwrap()).unwrap();
    b.frames.send("18FF0010#AA".parse().unwrap()).unwrap();
    let page = until(addr, "/", |t| {
        t.contains("18FF0010") && t.contains("&lt;sender&gt;")
    });
    assert!(
        !page.contains("<script"),
        "the overview needs no JavaScript"
    );
    assert!(page.contains("123#1133"), "last frames: {page}");
    assert!(page.contains("error-active"), "node state: {page}");
    // The node's name is escaped, never markup.
    assert!(!page.contains("<sender>"));
    let ids = until(addr, "/ids", |t| t.contains("<code>123</code>"));
    // Byte 1 changed (22 → 33), byte 0 did not.
    assert!(ids.contains("11 <mark>33</mark>"), "{ids}");
    assert!(ids.contains("<td>2</td>"), "count 2 for 123: {ids}");
    let frames = until(addr, "/frames?filter=18FF0010", |t| {
        t.contains("18FF0010#AA")
    });
    assert!(
        !frames.contains("123#1122"),
        "the filter lets only 18FF0010 through"
    );
    let node = until(addr, "/nodes/2", |t| t.contains("TEC and REC"));
    assert!(node.contains("0x0C"), "{node}");
    let (status, text) = get(addr, "/nodes/9");
    assert_eq!(status, 404, "{text}");
    assert!(text.contains("node 9 is not on the bus"));
    let (status, text) = get(addr, "/frames?filter=zzz");
    assert_eq!(status, 400);
    assert!(text.contains("filter \"zzz\""), "{text}");
}

#[test]
fn without_a_token_every_write_is_refused() {
    let b = bench(None, 64);
    let addr = b.server.addr();
    for (path, body) in [
        ("/api/send", r#"{"frame":"123#11"}"#),
        ("/api/fault", r#"{"kind":"cut","nodes":["2"]}"#),
        ("/api/repair", ""),
        (
            "/api/slio",
            r#"{"action":"output","slio":"3","pin":7,"on":true}"#,
        ),
        ("/api/zelle", r#"{"action":"stop"}"#),
        ("/api/cpu196", r#"{"action":"identify"}"#),
    ] {
        let (status, text) = post(addr, path, Some(TOKEN), body);
        assert_eq!(status, 403, "{path}: {text}");
        assert!(text.contains("read-only"), "{text}");
    }
    assert!(b.sent.try_recv().is_err(), "nothing reached the bus");
    assert!(b.wire.lock().unwrap().faults.is_empty());
}

#[test]
fn writes_need_the_right_token_in_the_header() {
    let b = bench(Some(TOKEN), 64);
    let addr = b.server.addr();
    let frame = r#"{"frame":"123#11"}"#;
    let (status, text) = post(addr, "/api/send", None, frame);
    assert_eq!(status, 401, "{text}");
    assert!(text.contains("X-Buslab-Token"), "{text}");
    let (status, _) = post(addr, "/api/send", Some("wrong-token-1"), frame);
    assert_eq!(status, 403);
    // A cookie is no token.
    let (status, _) = exchange(
        addr,
        format!(
            "POST /api/send HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\nCookie: \
             x-buslab-token={TOKEN}\r\nContent-Length: {}\r\n\r\n{frame}",
            frame.len()
        )
        .as_bytes(),
    );
    assert_eq!(status, 401);
    assert!(b.sent.try_recv().is_err());
    let (status, text) = post(addr, "/api/send", Some(TOKEN), frame);
    assert_eq!(status, 202, "{text}");
    assert_eq!(
        b.sent.recv_timeout(HANG).unwrap(),
        "123#11".parse::<Frame>().unwrap()
    );
    let (status, text) = post(addr, "/api/send", Some(TOKEN), r#"{"frame":"800#11"}"#);
    assert_eq!(status, 400, "{text}");
    assert!(
        text.contains("800#11"),
        "the reason names the frame: {text}"
    );
}

#[test]
fn a_cut_from_the_api_shows_the_node_going_error_passive_and_back() {
    let b = bench(Some(TOKEN), 64);
    let addr = b.server.addr();
    let (status, text) = post(
        addr,
        "/api/fault",
        Some(TOKEN),
        r#"{"kind":"cut","nodes":["<sender>"],"rate":0.05}"#,
    );
    assert_eq!(status, 200, "{text}");
    until(addr, "/nodes/2", |t| t.contains("error-passive"));
    let (status, text) = post(addr, "/api/repair", Some(TOKEN), "");
    assert_eq!(status, 200, "{text}");
    until(addr, "/nodes/2", |t| t.contains("error-active"));
    assert_eq!(b.wire.lock().unwrap().faults, ["cut", "repair"]);
    for (body, reason) in [
        (r#"{"kind":"cut"}"#, "name the nodes"),
        (r#"{"kind":"noise"}"#, "give \"rate\""),
        (r#"{"kind":"noise","rate":2}"#, "rate"),
        (r#"{"kind":"melt"}"#, "expected cut, noise"),
        (r#"{"kind":"flip","for_ms":0}"#, "for_ms 0"),
        (r#"{"kind":"flip","colour":1}"#, "unknown field"),
        ("not json", "expected JSON"),
    ] {
        let (status, text) = post(addr, "/api/fault", Some(TOKEN), body);
        assert_eq!(status, 400, "{body}: {text}");
        assert!(text.contains(reason), "{body}: {text}");
    }
}

#[test]
fn live_updates_carry_new_frames_and_node_states() {
    let b = bench(None, 64);
    let addr = b.server.addr();
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(HANG)).unwrap();
    s.write_all(b"GET /api/events?filter=321 HTTP/1.1\r\nHost: localhost\r\n\r\n")
        .unwrap();
    let mut lines = BufReader::new(s).lines();
    let first = lines.next().unwrap().unwrap();
    assert!(first.contains("200"), "{first}");
    b.frames.send("321#CAFE".parse().unwrap()).unwrap();
    b.frames.send("111#00".parse().unwrap()).unwrap();
    let mut saw_node = false;
    loop {
        let line = lines.next().expect("the stream ended").unwrap();
        let Some(json) = line.strip_prefix("data: ") else {
            continue;
        };
        let update: serde_json::Value = serde_json::from_str(json).unwrap();
        saw_node |= update["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .any(|n| n["name"] == "<sender>" && n["state"] == "error-active");
        let log = update["log"].as_array().unwrap();
        assert!(
            log.iter().all(|e| e["frame"] != "111#00"),
            "the viewer's filter holds: {json}"
        );
        if log.iter().any(|e| e["frame"] == "321#CAFE") && saw_node {
            assert_eq!(update["lost"], 0);
            break;
        }
    }
}

#[test]
fn ten_thousand_bad_requests_then_a_good_one() {
    let b = bench(Some(TOKEN), 64);
    let addr = b.server.addr();
    let big_header = format!(
        "GET / HTTP/1.1\r\nHost: localhost\r\nX-Big: {}\r\n\r\n",
        "a".repeat(20_000)
    );
    let big_body = format!(
        "POST /api/send HTTP/1.1\r\nHost: localhost\r\nX-Buslab-Token: {TOKEN}\r\nConnection: close\r\n\
         Content-Length: 5000\r\n\r\n{}",
        "x".repeat(5000)
    );
    let kinds: Vec<(Vec<u8>, u16)> = vec![
        (b"\x00\x01\x02 garbage\r\n\r\n".to_vec(), 400),
        (
            b"GET /no/such/page HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n".to_vec(),
            404,
        ),
        (
            b"DELETE /api/send HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n".to_vec(),
            405,
        ),
        (
            b"POST /api/send HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\nContent-Length: 2\r\n\r\n{}"
                .to_vec(),
            401,
        ),
        (
            format!(
                "POST /api/send HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\nX-Buslab-Token: \
                 {TOKEN}\r\nContent-Length: 3\r\n\r\n{{x}}"
            )
            .into_bytes(),
            400,
        ),
        (
            b"GET /frames?n=-1 HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n".to_vec(),
            400,
        ),
        (big_header.into_bytes(), 431),
        (big_body.into_bytes(), 413),
    ];
    let kinds = Arc::new(kinds);
    let threads: Vec<_> = (0..4)
        .map(|t| {
            let kinds = kinds.clone();
            std::thread::spawn(move || {
                for i in 0..2500 {
                    let (raw, want) = &kinds[(i + t) % kinds.len()];
                    let (status, text) = exchange(addr, raw);
                    assert_eq!(status, *want, "{}", String::from_utf8_lossy(&raw[..40]));
                    if *want != 431 && *want != 400 {
                        // Every refusal says why.
                        let body = text.split("\r\n\r\n").nth(1).unwrap_or("");
                        assert!(!body.trim().is_empty(), "no reason: {text}");
                    }
                }
            })
        })
        .collect();
    for t in threads {
        t.join().unwrap();
    }
    assert!(b.sent.try_recv().is_err(), "no bad request reached the bus");
    let (status, text) = post(addr, "/api/send", Some(TOKEN), r#"{"frame":"7FF#01"}"#);
    assert_eq!(status, 202, "{text}");
    let (status, _) = get(addr, "/");
    assert_eq!(status, 200);
}

#[test]
fn connections_beyond_the_limit_get_503_and_the_server_recovers() {
    let b = bench(None, 2);
    let addr = b.server.addr();
    // Two connections that say nothing hold both places.
    let idle: Vec<TcpStream> = (0..2).map(|_| TcpStream::connect(addr).unwrap()).collect();
    let deadline = std::time::Instant::now() + HANG;
    // The server takes them in order; the third is refused once both are held.
    loop {
        let (status, text) = get(addr, "/");
        if status == 503 {
            assert!(text.contains("too many connections"), "{text}");
            break;
        }
        assert!(std::time::Instant::now() < deadline, "never refused");
    }
    drop(idle);
    loop {
        let (status, _) = get(addr, "/");
        if status == 200 {
            break;
        }
        assert!(std::time::Instant::now() < deadline, "never served again");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn the_dashboard_and_its_files_are_served_from_the_binary() {
    let b = bench(None, 64);
    let addr = b.server.addr();
    let (status, page) = get(addr, "/dashboard");
    assert_eq!(status, 200);
    assert!(page.contains("<script src=/assets/dashboard.js"), "{page}");
    let (status, js) = get(addr, "/assets/dashboard.js");
    assert_eq!(status, 200);
    assert!(js.contains("text/javascript") && js.contains("EventSource"));
    let (status, css) = get(addr, "/assets/style.css");
    assert_eq!(status, 200);
    assert!(css.contains("text/css"));
    let (status, text) = get(addr, "/assets/../Cargo.toml");
    assert!(status == 404 || status == 400, "{status}: {text}");
}

#[test]
fn a_slio_led_set_over_the_api_shows_only_once_the_slio_answers() {
    let slio3 = buslab_chips::slio::SlioId::new(3).unwrap();
    let b = bench_with(
        Some(TOKEN),
        64,
        buslab_web::DeviceConfig {
            slios: vec![slio3],
            ..Default::default()
        },
    );
    let addr = b.server.addr();
    let led = r#"{"action":"output","slio":"3","pin":7,"on":true}"#;
    let (status, text) = post(addr, "/api/slio", None, led);
    assert_eq!(status, 401, "{text}");
    // The SLIO has not told its outputs yet: nothing to build the write on.
    let (status, text) = post(addr, "/api/slio", Some(TOKEN), led);
    assert_eq!(status, 409, "{text}");
    for (body, why) in [
        (
            r#"{"action":"output","slio":"3","pin":13,"on":true}"#,
            "not an LED",
        ),
        (
            r#"{"action":"output","slio":"G","pin":7,"on":true}"#,
            "0..F",
        ),
        (
            r#"{"action":"dpm","slio":"3","output":1,"duty":4000}"#,
            "0..1023",
        ),
        (r#"{"action":"blink","slio":"3"}"#, "unknown variant"),
    ] {
        let (status, text) = post(addr, "/api/slio", Some(TOKEN), body);
        assert_eq!(status, 400, "{body}: {text}");
        assert!(text.contains(why), "{body}: {text}");
    }
    // No ZELLE cell or CPU196 board on this server.
    let (status, _) = post(addr, "/api/zelle", Some(TOKEN), r#"{"action":"stop"}"#);
    assert_eq!(status, 404);
    let (status, _) = post(addr, "/api/cpu196", Some(TOKEN), r#"{"action":"identify"}"#);
    assert_eq!(status, 404);

    // The SLIO answers (DATA_OUTPUT 0x2000): the click is sent, the LED stays off until the
    // SLIO confirms the new value.
    b.frames.send("29D#232000".parse().unwrap()).unwrap();
    until(addr, "/api/devices", |t| t.contains("\"outputs\":8192"));
    let (status, text) = post(addr, "/api/slio", Some(TOKEN), led);
    assert_eq!(status, 202, "{text}");
    let write: Frame = "29C#032080".parse().unwrap();
    while b.sent.recv_timeout(HANG).unwrap() != write {}
    let p7 = |t: &str| -> serde_json::Value {
        let v: serde_json::Value = serde_json::from_str(t).unwrap();
        v["slio"][0]["leds"][0].clone()
    };
    let (_, text) = get(addr, "/api/devices");
    let body = text.split("\r\n\r\n").nth(1).unwrap();
    assert_eq!(
        p7(body),
        serde_json::json!({"pin":7,"on":false,"pending":true})
    );
    b.frames.send("29D#232080".parse().unwrap()).unwrap();
    let text = until(addr, "/api/devices", |t| t.contains("\"outputs\":8320"));
    let body = text.split("\r\n\r\n").nth(1).unwrap();
    assert_eq!(
        p7(body),
        serde_json::json!({"pin":7,"on":true,"pending":false})
    );
    // The page without JavaScript shows it too.
    let page = until(addr, "/devices", |t| t.contains("SLIO boards"));
    assert!(page.contains("class=\"led on\""), "{page}");
}

#[test]
fn a_joined_bus_shows_its_counters_per_peer_on_the_overview() {
    use buslab_backends::{OpenOptions, open_join};
    let port = |_| {
        std::net::UdpSocket::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
    };
    let (a, b) = (port(0), port(1));
    let mut peer = open_join(
        &format!("cannelloni://{b}?listen={a}").parse().unwrap(),
        &OpenOptions::default(),
    )
    .unwrap();
    let joined = open_join(
        &format!("cannelloni://{a}?listen={b}").parse().unwrap(),
        &OpenOptions::default(),
    )
    .unwrap();
    let join = joined.sender();
    let server = WebServer::start(
        Box::new(joined),
        WebConfig {
            listen: "127.0.0.1:0".parse().unwrap(),
            join: Some(join),
            ..WebConfig::default()
        },
    )
    .unwrap();
    for k in 0..3u8 {
        buslab_bus::CanBus::send(
            &mut peer,
            &Frame::data(buslab_can::Id::standard(0x100).unwrap(), &[k]).unwrap(),
        )
        .unwrap();
    }
    let page = until(server.addr(), "/", |t| {
        t.contains("<h2>Joined buses</h2>") && t.contains("<td id=frames>3</td>")
    });
    // cannelloni counts packets: the 3 frames came in 1 to 3 of them, none lost.
    assert!(
        page.contains(&format!("<td>cannelloni {a} (packets)</td>")),
        "{page}"
    );
    assert!(page.contains("<td class=ok>0</td>"), "{page}");
}
