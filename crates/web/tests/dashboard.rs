//! What the live dashboard's charts, log and result line get from the server, over real TCP on
//! a stand-in bus: the time window of a whole view (not the server's age), error frames in
//! the log and the live updates with their class and meaning, writes answered with what was
//! done in words, faults marked on the time charts, a rate-limited fault answered 429 with
//! `Retry-After`; with a DBC database, each message's signals and the values of the signal a
//! viewer plots. (How the page draws them: crates/buslab/tests/web_browser.rs.)

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use buslab_bus::admin::FaultLimit;
use buslab_bus::{
    BusAdmin, BusError, BusSummary, CanBus, ErrorFrame, ErrorRegisters, ErrorState, Filter,
    Message, NodeCounters, NodeInfo, NodeRef, NodeRegisters, NodeStatus, Timestamp, TxReport,
    WireFault,
};
use buslab_can::Frame;
use buslab_web::{WebConfig, WebServer};
use serde_json::Value;

/// Only a guard against a hung server: every wait below ends on an event first.
const HANG: Duration = Duration::from_secs(120);
const TOKEN: &str = "dashboard-token";

/// What the test controls of the stand-in bus.
#[derive(Default)]
struct Control {
    /// Whether the server asked for error frames.
    error_frames: AtomicBool,
    /// Node 2's status answers given: its TEC counts them from 100 to 119 and again (so no
    /// two samples in a row are equal, and the axis for them is 0 to 128).
    polls: AtomicU32,
    /// The refusal of the next faults, if any.
    refuse: Mutex<Option<FaultLimit>>,
    /// The bus's load figure, in tenths of a per cent.
    load_tenths: AtomicU32,
}

struct FakeBus {
    events: Receiver<Message>,
    control: Arc<Control>,
}

impl CanBus for FakeBus {
    fn send(&mut self, _: &Frame) -> Result<(), BusError> {
        Ok(())
    }
    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
        loop {
            match self.recv_event(timeout)? {
                Some(m) => match m.into_frame() {
                    Some(frame) => return Ok(Some(frame)),
                    None => continue,
                },
                None => return Ok(None),
            }
        }
    }
    fn recv_event(&mut self, timeout: Option<Duration>) -> Result<Option<Message>, BusError> {
        match self.events.recv_timeout(timeout.unwrap_or(HANG)) {
            Ok(e) => Ok(Some(e)),
            Err(mpsc::RecvTimeoutError::Timeout) => Ok(None),
            Err(mpsc::RecvTimeoutError::Disconnected) => Err(BusError::Closed),
        }
    }
    fn set_error_frames(&mut self, on: bool) -> Result<(), BusError> {
        self.control.error_frames.store(on, Ordering::SeqCst);
        Ok(())
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
                name: "sender".into(),
            },
        ])
    }
    fn node_status(&mut self, node: Option<&NodeRef>) -> Result<NodeStatus, BusError> {
        let (number, name) = match node {
            None | Some(NodeRef::Number(1)) => (1, "web"),
            Some(NodeRef::Number(2)) => (2, "sender"),
            Some(other) => return Err(BusError::Other(format!("no node {other}").into())),
        };
        let tec = if number == 2 {
            100 + (self.control.polls.fetch_add(1, Ordering::SeqCst) % 20) as u8
        } else {
            0
        };
        Ok(NodeStatus {
            number,
            name: name.into(),
            state: ErrorState::Active,
            errors: Some(ErrorRegisters {
                alc: None,
                ecc: None,
                rxerr: 0,
                txerr: tec,
            }),
            sr: None,
            timing: None,
            counters: NodeCounters::default(),
            tx_queued: 0,
            bus: BusSummary {
                bitrate: 125_000,
                load_percent: f64::from(self.control.load_tenths.load(Ordering::SeqCst)) / 10.0,
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
    fn inject_fault(&mut self, _: &WireFault, _: Option<Duration>) -> Result<(), BusError> {
        match *self.control.refuse.lock().unwrap() {
            Some(limit) => Err(BusError::FaultRefused(limit)),
            None => Ok(()),
        }
    }
    fn repair(&mut self) -> Result<(), BusError> {
        Ok(())
    }
}

struct Bench {
    server: WebServer,
    events: Sender<Message>,
    control: Arc<Control>,
}

impl Bench {
    fn start() -> Self {
        Self::start_with(None)
    }

    /// With a DBC database, for the signals.
    fn start_with(dbc: Option<Arc<buslab_dbc::Database>>) -> Self {
        let (events, rx) = mpsc::channel();
        let control = Arc::new(Control::default());
        control.load_tenths.store(31, Ordering::SeqCst);
        let bus = FakeBus {
            events: rx,
            control: control.clone(),
        };
        let server = WebServer::start(
            Box::new(bus),
            WebConfig {
                listen: "127.0.0.1:0".parse().unwrap(),
                token: Some(TOKEN.into()),
                // Many TEC/REC samples quickly.
                status_every: Duration::from_millis(20),
                dbc,
                ..WebConfig::default()
            },
        )
        .unwrap();
        Self {
            server,
            events,
            control,
        }
    }

    fn addr(&self) -> SocketAddr {
        self.server.addr()
    }

    fn error(&self, class: u32, data: &[u8]) {
        let error = ErrorFrame::decode(class, data).unwrap();
        self.events
            .send(Message::error(
                Timestamp::from_micros(1_700_000_000_250_000),
                "fake",
                error,
            ))
            .unwrap();
    }

    fn frame(&self, text: &str) {
        self.events
            .send(
                Message::rx(
                    Timestamp::from_micros(1_700_000_000_125_000),
                    "fake",
                    text.parse().unwrap(),
                )
                .into_record(),
            )
            .unwrap();
    }
}

/// (status, head, body).
fn exchange(addr: SocketAddr, raw: &str) -> (u16, String, String) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(HANG)).unwrap();
    s.write_all(raw.as_bytes()).unwrap();
    let mut text = String::new();
    let _ = s.read_to_string(&mut text);
    let status = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    (status, head.to_string(), body.to_string())
}

fn get(addr: SocketAddr, path: &str) -> (u16, String) {
    let (status, _, body) = exchange(
        addr,
        &format!("GET {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n"),
    );
    (status, body)
}

fn post(addr: SocketAddr, path: &str, body: &str) -> (u16, String, String) {
    exchange(
        addr,
        &format!(
            "POST {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\
             X-Buslab-Token: {TOKEN}\r\nContent-Type: application/json\r\n\
             Content-Length: {}\r\n\r\n{body}",
            body.len()
        ),
    )
}

fn json(addr: SocketAddr, path: &str) -> Value {
    let (status, body) = get(addr, path);
    assert_eq!(status, 200, "{path}: {body}");
    serde_json::from_str(&body).unwrap()
}

/// Reads `path` (JSON) until `done` holds for it.
fn until(addr: SocketAddr, path: &str, done: impl Fn(&Value) -> bool) -> Value {
    let deadline = Instant::now() + HANG;
    loop {
        let v = json(addr, path);
        if done(&v) {
            return v;
        }
        assert!(Instant::now() < deadline, "{path} never showed it: {v}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The server's own clock (seconds since it started) as its views give it.
fn server_time(v: &Value) -> f64 {
    v["delta"]["t"].as_f64().unwrap()
}

/// The sender node's TEC/REC history in a view (the server's own node is not shown).
fn history(delta: &Value) -> &[Value] {
    let nodes = delta["nodes"].as_array().unwrap();
    let sender = nodes.iter().find(|n| n["name"] == "sender");
    sender.unwrap_or_else(|| panic!("no sender: {nodes:?}"))["history"]
        .as_array()
        .unwrap()
}

/// Checks that `samples` (each with `t`) are the window [now - window, now] and the one before
/// it, and that there was history before the window to leave out.
fn holds_the_window(samples: &[Value], now: f64, window: f64) {
    let t: Vec<f64> = samples.iter().map(|s| s["t"].as_f64().unwrap()).collect();
    assert!(t.len() >= 2, "{t:?}");
    let from = now - window;
    assert!(
        t[0] < from,
        "the sample before the window comes first: {t:?}"
    );
    assert!(t[1..].iter().all(|&x| x >= from), "nothing older: {t:?}");
}

#[test]
fn a_whole_view_carries_the_chart_window_not_the_servers_age() {
    let b = Bench::start();
    let addr = b.addr();
    // Wait for the server's own clock to pass 3 s and for the sender's history to reach more
    // than 2 s back, so that a 1-s window leaves most out. (On a loaded machine the first
    // status sample may come seconds after the server's clock started: CI saw the whole
    // history one sample at 4.56 s, nothing before the window.)
    let whole = until(addr, "/api/state?n=0&window=600", |v| {
        let now = server_time(v);
        now > 3.0
            && v["delta"]["nodes"].as_array().is_some_and(|nodes| {
                nodes.iter().any(|n| {
                    n["name"] == "sender"
                        && n["history"][0]["t"].as_f64().is_some_and(|t| t < now - 2.0)
                })
            })
    });
    let v = json(addr, "/api/state?n=0&window=1");
    let now = server_time(&v);
    holds_the_window(history(&v["delta"]), now, 1.0);
    let load = v["delta"]["load"].as_array().unwrap();
    assert!(
        load.iter().all(|l| l["t"].as_f64().unwrap() >= now - 1.0),
        "{load:?}"
    );
    // The whole kept history when the window is longer than the server's age: from the
    // first sample on.
    let first_sample = history(&whole["delta"])[0]["t"].as_f64().unwrap();
    let all = json(addr, "/api/state?n=0&window=600");
    let first = history(&all["delta"])[0]["t"].as_f64().unwrap();
    assert_eq!(first, first_sample);

    // The live updates' first, whole, view is the window too.
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(HANG)).unwrap();
    s.write_all(b"GET /api/events?window=1 HTTP/1.1\r\nHost: localhost\r\n\r\n")
        .unwrap();
    let update = BufReader::new(s)
        .lines()
        .map(|l| l.unwrap())
        .find_map(|l| l.strip_prefix("data: ").map(str::to_string))
        .unwrap();
    let update: Value = serde_json::from_str(&update).unwrap();
    assert_eq!(update["full"], true);
    let now = update["t"].as_f64().unwrap();
    holds_the_window(history(&update), now, 1.0);

    // A window the server does not keep is refused with the range.
    for bad in ["0", "601"] {
        for path in ["/api/state", "/api/events", "/", "/nodes/2"] {
            let (status, body) = get(addr, &format!("{path}?window={bad}"));
            assert_eq!(status, 400, "{path}?window={bad}: {body}");
            assert!(body.contains("from 1 to 600 seconds"), "{body}");
        }
    }
}

#[test]
fn the_node_page_charts_the_window_on_an_axis_that_fits_and_the_load_is_autoscaled() {
    let b = Bench::start();
    let addr = b.addr();
    until(addr, "/api/state?n=0&window=600", |v| {
        server_time(v) > 3.0 && v["delta"]["load"].as_array().unwrap().len() >= 2
    });
    let (status, page) = get(addr, "/nodes/2?window=2&refresh=0");
    assert_eq!(status, 200, "{page}");
    assert!(page.contains(">−2 s<") && page.contains(">now<"), "{page}");
    // TEC from 100 to 119: the axis goes to the power of two above (not to 256).
    assert!(
        page.contains("TEC (red) and REC (blue) over the last 2 s (scale 0 to 128)"),
        "{page}"
    );
    // The load, 3.1 %, on a 0..5 % axis (not a flat line at the bottom of 0..100 %).
    let (_, overview) = get(addr, "/?refresh=0");
    assert!(
        overview.contains("bus load over the last 60 s (scale 0 to 5 %)"),
        "{overview}"
    );
    assert!(overview.contains(">5 %<") && overview.contains(">2.5 %<"));
}

#[test]
fn error_frames_reach_the_log_and_the_live_updates_with_their_class_and_meaning() {
    let b = Bench::start();
    let addr = b.addr();
    // The server asks for error frames when it joins the bus.
    until(addr, "/api/state?n=0", |_| {
        b.control.error_frames.load(Ordering::SeqCst)
    });
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(HANG)).unwrap();
    s.write_all(b"GET /api/events?filter=123,%23080 HTTP/1.1\r\nHost: localhost\r\n\r\n")
        .unwrap();
    let mut lines = BufReader::new(s).lines();
    b.frame("123#11");
    b.frame("124#22");
    // Linux's SJA1000 frame for a stuff error in the data field, with the counters; then a
    // bus-off, which the viewer's filter (#080: bus errors) leaves out.
    b.error(0x288, &[0, 0, 0x04, 0x0A, 0, 0, 8, 0]);
    b.error(0x040, &[]);
    b.frame("123#33");
    let mut seen = Vec::new();
    while !seen.iter().any(|e: &Value| e["frame"] == "123#33") {
        let line = lines.next().expect("the stream ended").unwrap();
        let Some(data) = line.strip_prefix("data: ") else {
            continue;
        };
        let update: Value = serde_json::from_str(data).unwrap();
        seen.extend(update["log"].as_array().unwrap().iter().cloned());
    }
    let frames: Vec<&str> = seen.iter().map(|e| e["frame"].as_str().unwrap()).collect();
    assert_eq!(
        frames,
        ["123#11", "20000288#0000040A00000800", "123#33"],
        "{seen:?}"
    );
    let error = &seen[1]["error"];
    assert_eq!(error["class"], 0x288);
    assert_eq!(
        error["classes"],
        serde_json::json!([
            "protocol-violation{{bit-stuffing-error}{data-field}}",
            "bus-error"
        ])
    );
    assert_eq!(
        (&error["tec"], &error["rec"]),
        (&Value::from(8), &Value::from(0))
    );
    assert!(seen[0].get("error").is_none(), "a frame is no error frame");

    // Without a filter every error frame is in the log; error frames are counted apart.
    let v = json(addr, "/api/state?n=100");
    let log = v["delta"]["log"].as_array().unwrap();
    assert_eq!(log.iter().filter(|e| e.get("error").is_some()).count(), 2);
    assert_eq!(
        (&v["delta"]["frames"], &v["delta"]["error_frames"]),
        (&Value::from(3), &Value::from(2))
    );
    // The pages without JavaScript show them too, with a readable time.
    let (_, page) = get(addr, "/frames?refresh=0");
    assert!(
        page.contains("<code>20000040#</code> <b>ERRORFRAME</b> bus-off"),
        "{page}"
    );
    assert!(page.contains("<td>22:13:20.125</td>"), "{page}");
    let (status, bad) = get(addr, "/api/state?filter=%23XYZ");
    assert_eq!(status, 400);
    assert!(bad.contains("#MASK"), "{bad}");
}

#[test]
fn writes_answer_what_was_done_in_words_and_faults_are_marked_on_the_charts() {
    let b = Bench::start();
    let addr = b.addr();
    let done = |body: &str| -> String {
        let v: Value = serde_json::from_str(body).unwrap();
        v["done"].as_str().unwrap().to_string()
    };
    let (status, _, body) = post(addr, "/api/send", r#"{"frame":"123#1122"}"#);
    assert_eq!(status, 202, "{body}");
    assert_eq!(done(&body), "123#1122 is queued for the bus");
    let (status, _, body) = post(
        addr,
        "/api/fault",
        r#"{"kind":"cut","nodes":["sender"],"for_ms":3000}"#,
    );
    assert_eq!(status, 200, "{body}");
    assert_eq!(
        done(&body),
        "the wire cut: sender on the far side, 5 % of the bits read there wrong, for 3.00 s"
    );
    let (_, _, body) = post(addr, "/api/fault", r#"{"kind":"noise","rate":0.001}"#);
    assert_eq!(
        done(&body),
        "noise on the whole bus: 0.1 % of the bits read wrong, until repaired"
    );
    let v = json(addr, "/api/state?n=0");
    let faults = v["delta"]["faults"].as_array().unwrap();
    assert_eq!(faults.len(), 2, "{faults:?}");
    assert_eq!(faults[0]["label"], "cut at sender");
    let (t, until) = (
        faults[0]["t"].as_f64().unwrap(),
        faults[0]["until"].as_f64().unwrap(),
    );
    assert!((until - t - 3.0).abs() < 1e-6, "{faults:?}");
    assert_eq!(
        (&faults[1]["label"], &faults[1]["until"]),
        (&Value::from("noise 0.1 %"), &Value::Null)
    );
    let (status, _, body) = post(addr, "/api/repair", "{}");
    assert_eq!(status, 200);
    assert_eq!(done(&body), "the wire is repaired: every fault on it ended");
    let v = json(addr, "/api/state?n=0");
    assert!(
        v["delta"]["faults"][1]["until"].is_f64(),
        "the repair ended it: {v}"
    );
}

#[test]
fn a_fault_over_the_rate_limit_is_429_with_retry_after_and_the_limit_in_words() {
    let b = Bench::start();
    let addr = b.addr();
    *b.control.refuse.lock().unwrap() = Some(FaultLimit::Rate {
        max: 20,
        per: Duration::from_secs(1),
        retry_after: Duration::from_millis(1500),
    });
    let (status, head, body) = post(addr, "/api/fault", r#"{"kind":"stuck","for_ms":10}"#);
    assert_eq!(status, 429, "{head}\n{body}");
    assert!(
        head.to_ascii_lowercase().contains("retry-after: 2\r\n"),
        "{head}"
    );
    assert!(
        body.contains("too many faults from this client: at most 20 per 1.00 s"),
        "{body}"
    );
    // A wait under a second is still asked for as 1 s (the header counts whole seconds).
    *b.control.refuse.lock().unwrap() = Some(FaultLimit::Rate {
        max: 20,
        per: Duration::from_secs(1),
        retry_after: Duration::from_millis(50),
    });
    let (_, head, _) = post(addr, "/api/fault", r#"{"kind":"stuck","for_ms":10}"#);
    assert!(
        head.to_ascii_lowercase().contains("retry-after: 1\r\n"),
        "{head}"
    );
    // Too many faults on the wire at once: no use waiting a given time, 400 and the reason.
    *b.control.refuse.lock().unwrap() = Some(FaultLimit::Active { max: 1024 });
    let (status, head, body) = post(addr, "/api/fault", r#"{"kind":"stuck"}"#);
    assert_eq!(status, 400, "{body}");
    assert!(!head.to_ascii_lowercase().contains("retry-after"), "{head}");
    assert!(body.contains("at most 1024 at once"), "{body}");
    // A refused fault is not marked.
    let v = json(addr, "/api/state?n=0");
    assert_eq!(v["delta"]["faults"], serde_json::json!([]));
}

const DBC: &str = r#"
BO_ 192 Engine: 8 engine
 SG_ EngineSpeed : 7|16@0+ (1,0) [0|65535] "rpm" Vector__XXX
 SG_ Gear : 16|8@1+ (1,0) [0|8] "" Vector__XXX
VAL_ 192 Gear 0 "neutral" 1 "first" ;
"#;

/// The next SSE update from `lines` for which `done` holds.
fn next_update(
    lines: &mut impl Iterator<Item = std::io::Result<String>>,
    done: impl Fn(&Value) -> bool,
) -> Value {
    loop {
        let line = lines.next().expect("the stream ended").unwrap();
        let Some(data) = line.strip_prefix("data: ") else {
            continue;
        };
        let update: Value = serde_json::from_str(data).unwrap();
        if done(&update) {
            return update;
        }
    }
}

#[test]
fn with_a_dbc_the_updates_carry_each_messages_signals_and_the_plotted_values() {
    let db = buslab_dbc::Database::parse(DBC).unwrap();
    let b = Bench::start_with(Some(Arc::new(db)));
    let addr = b.addr();
    let state = json(addr, "/api/state?n=0");
    assert_eq!(state["dbc_messages"], 1, "{state}");
    b.frame("0C0#0FA000");
    b.frame("0C0#100001");
    let state = until(addr, "/api/state?n=0&plot=Engine.EngineSpeed", |v| {
        v["delta"]["messages"][0]["count"] == 2
    });
    let engine = &state["delta"]["messages"][0];
    assert_eq!(
        (&engine["id"], &engine["name"]),
        (&json_str("0C0"), &json_str("Engine"))
    );
    let signals = engine["signals"].as_array().unwrap();
    assert_eq!(
        signals
            .iter()
            .map(|s| (
                s["name"].as_str().unwrap(),
                s["number"].as_str().unwrap(),
                s["unit"].as_str().unwrap()
            ))
            .collect::<Vec<_>>(),
        [("EngineSpeed", "4096", "rpm"), ("Gear", "1", "")]
    );
    assert_eq!(signals[1]["label"], "first");
    let plot = &state["plot"];
    assert_eq!(
        (&plot["full"], &plot["unit"]),
        (&Value::from(true), &json_str("rpm"))
    );
    let values: Vec<f64> = plot["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p[1].as_f64().unwrap())
        .collect();
    assert_eq!(values, [4000.0, 4096.0]);

    // Live: the whole series first, then the new values only.
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(HANG)).unwrap();
    s.write_all(b"GET /api/events?plot=Engine.EngineSpeed HTTP/1.1\r\nHost: localhost\r\n\r\n")
        .unwrap();
    let mut lines = BufReader::new(s).lines();
    let first = next_update(&mut lines, |_| true);
    assert_eq!(first["plot"]["full"], true);
    assert_eq!(first["plot"]["points"].as_array().unwrap().len(), 2);
    assert_eq!(first["messages"].as_array().unwrap().len(), 1);
    b.frame("0C0#110001");
    let later = next_update(&mut lines, |u| u.get("plot").is_some());
    assert_eq!(later["plot"]["full"], false);
    assert_eq!(
        later["plot"]["points"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p[1].as_f64().unwrap())
            .collect::<Vec<_>>(),
        [4352.0]
    );
    assert_eq!(later["messages"][0]["signals"][0]["number"], "4352");

    // The page without JavaScript: the table, and the plot as steps on its own axis.
    let (status, page) = get(addr, "/signals?plot=Engine.EngineSpeed&refresh=0&window=60");
    assert_eq!(status, 200, "{page}");
    assert!(page.contains("<td>0C0</td><td>Engine</td>"), "{page}");
    assert!(
        page.contains(">4352 rpm<") && page.contains(">first<"),
        "{page}"
    );
    assert!(
        page.contains("href=\"/signals?plot=Engine.Gear&amp;window=60&amp;refresh=0\""),
        "{page}"
    );
    assert!(
        page.contains("Engine.EngineSpeed over the last 60 s (scale 0 to 5000 rpm;"),
        "{page}"
    );
    // Three values: each held until the next (two steps), the last until now.
    let line = page
        .split("<polyline class=signal points=\"")
        .nth(1)
        .and_then(|r| r.split('"').next())
        .unwrap_or_else(|| panic!("no line: {page}"));
    assert_eq!(line.split(' ').count(), 6, "{line}");

    // A signal the database does not have is refused, naming what it has.
    for path in ["/api/events", "/api/state", "/signals"] {
        let (status, body) = get(addr, &format!("{path}?plot=Engine.Rpm"));
        assert_eq!(status, 400, "{path}: {body}");
        assert_eq!(
            body.trim(),
            "plot: message Engine has no signal \"Rpm\" (it has EngineSpeed, Gear)"
        );
    }
    // Without a database there is nothing to plot.
    let plain = Bench::start();
    let (status, page) = get(plain.addr(), "/signals?refresh=0");
    assert_eq!(status, 200);
    assert!(page.contains("No DBC database"), "{page}");
    assert_eq!(
        json(plain.addr(), "/api/state?n=0")["dbc_messages"],
        Value::Null
    );
    let (status, body) = get(plain.addr(), "/api/events?plot=Engine.EngineSpeed");
    assert_eq!(status, 400, "{body}");
    assert!(body.contains("no DBC database"), "{body}");
}

fn json_str(s: &str) -> Value {
    Value::from(s)
}
