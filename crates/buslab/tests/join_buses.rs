//! Two buses on two ports joined as two machines would be (`bus serve --join`), through a
//! real Mosquitto broker started here on a free loopback port with a throwaway configuration,
//! and through cannelloni over UDP and TCP; python-can (socketcand interface) sends on one bus
//! and receives on the other. PyPI's can-cannelloni talks to buslab's cannelloni TCP server
//! both ways.
//!
//! No timing margins: each wait is for an event (a line from a process, a counter reaching
//! the number of frames sent), under a deadline derived from the work (frames × the time a
//! frame takes on a 1 Mbit/s bus × a generous factor). The broker is stopped for 2 s because
//! that is the scenario (an outage), not a margin.

#[cfg(feature = "mqtt-tls")]
#[path = "mail_support/mod.rs"]
mod mail_support;
#[path = "support/outside_tools.rs"]
mod outside_tools;

use std::io::{BufRead, BufReader, Lines, Write};
use std::net::{TcpListener, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::time::{Duration, Instant};

use buslab_canbus::CanBus;
use outside_tools::{present, python_can, root};

const MOSQUITTO: &str = "/usr/sbin/mosquitto";
/// Frames the acceptance runs carry.
const FRAMES: u64 = 100_000;
/// The bus's bit rate: a frame of 8 bytes takes about 130 bit times with stuffing.
const BITRATE: u32 = 1_000_000;

/// A deadline for `frames` crossing two buses: their time on the wire × 20, plus a minute for
/// starting processes on a loaded machine.
fn deadline_for(frames: u64) -> Duration {
    Duration::from_micros(frames * 130 * 1_000_000 / u64::from(BITRATE) * 20)
        + Duration::from_secs(60)
}

fn free_tcp_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// The tools, or `None` (allowed outside CI only).
fn tools(with_mosquitto: bool) -> Option<PathBuf> {
    let python = python_can()?;
    if with_mosquitto && !present(Path::new(MOSQUITTO).exists(), "mosquitto") {
        return None;
    }
    Some(python)
}

/// Mosquitto on a loopback port of its own (the system's service, if any, stays on 1883).
struct Mosquitto {
    child: Option<Child>,
    port: u16,
    config: PathBuf,
    _dir: tempfile::TempDir,
}

impl Mosquitto {
    fn start() -> Self {
        Self::start_with(|_| "allow_anonymous true\n".into())
    }

    /// With `extra(dir)` in its configuration (`dir`: the broker's throwaway folder, for
    /// files the lines name); it runs as the user running the tests.
    fn start_with(extra: impl FnOnce(&Path) -> String) -> Self {
        let dir = tempfile::tempdir().unwrap();
        let port = free_tcp_port();
        let config = dir.path().join("mosquitto.conf");
        let user =
            String::from_utf8(Command::new("id").arg("-un").output().unwrap().stdout).unwrap();
        std::fs::write(
            &config,
            format!(
                "listener {port} 127.0.0.1\npersistence false\nuser {}\n{}",
                user.trim(),
                extra(dir.path())
            ),
        )
        .unwrap();
        let mut broker = Self {
            child: None,
            port,
            config,
            _dir: dir,
        };
        broker.run();
        broker
    }

    /// Starts the broker and waits until it listens.
    fn run(&mut self) {
        let child = Command::new(MOSQUITTO)
            .arg("-c")
            .arg(&self.config)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        self.child = Some(child);
        let start = Instant::now();
        while std::net::TcpStream::connect(("127.0.0.1", self.port)).is_err() {
            assert!(
                start.elapsed() < deadline_for(0),
                "mosquitto never listened on {}",
                self.port
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn stop(&mut self) {
        if let Some(mut c) = self.child.take() {
            c.kill().unwrap();
            c.wait().unwrap();
        }
    }

    fn url(&self, prefix: &str) -> String {
        format!("mqtt://127.0.0.1:{}/{prefix}", self.port)
    }
}

impl Drop for Mosquitto {
    fn drop(&mut self) {
        self.stop();
    }
}

/// `buslab bus serve --join URL`.
struct Joined {
    child: Child,
    port: u16,
    stdout: Lines<BufReader<ChildStdout>>,
}

/// `buslab [CONFIG…] bus serve --join URL` (`config`: `--no-config` or `--config FILE`), with
/// no credentials from this environment.
fn serve_command(config: &[&std::ffi::OsStr], join: &str) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_buslab"));
    command
        .args(config)
        .args(["bus", "serve", "--listen", "127.0.0.1:0", "--bitrate"])
        .arg(BITRATE.to_string())
        .args(["--join", join])
        .env_remove("BUSLAB_BUS")
        .env_remove("BUSLAB_MQTT_USERNAME")
        .env_remove("BUSLAB_MQTT_PASSWORD");
    command
}

impl Joined {
    fn start(join: &str) -> Self {
        Self::start_with(&["--no-config".as_ref()], join)
    }

    fn start_with(config: &[&std::ffi::OsStr], join: &str) -> Self {
        Self::spawn(serve_command(config, join))
    }

    fn spawn(mut command: Command) -> Self {
        let mut child = command
            // Every frame kept for slow readers: a frame dropped by the server would be lost
            // where no sequence number sees it.
            .args(["--client-queue", "1048576"])
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .unwrap();
        let mut stdout = BufReader::new(child.stdout.take().unwrap()).lines();
        let line = stdout.next().expect("bus serve said nothing").unwrap();
        let port = line
            .strip_prefix("socketcand://127.0.0.1:")
            .and_then(|r| r.split('/').next())
            .and_then(|p| p.parse().ok())
            .unwrap_or_else(|| panic!("no URL from bus serve: {line:?}"));
        Self {
            child,
            port,
            stdout,
        }
    }

    /// Stops the server as Ctrl-C would and returns its `joined …` line (the counters).
    fn stop(mut self) -> String {
        let status = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
        let line = self
            .stdout
            .by_ref()
            .map_while(Result::ok)
            .find(|l| l.starts_with("joined "))
            .expect("bus serve printed no counters");
        assert!(self.child.wait().unwrap().success());
        line
    }
}

impl Drop for Joined {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A python-can peer (tests/interop/join_peer.py) talking line by line.
struct Peer {
    child: Child,
    stdin: ChildStdin,
    stdout: Lines<BufReader<ChildStdout>>,
}

impl Peer {
    fn start(python: &Path, script: &str, args: &[String]) -> Self {
        let mut child = Command::new(python)
            .arg(root().join("tests/interop").join(script))
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        Self {
            stdin: child.stdin.take().unwrap(),
            stdout: BufReader::new(child.stdout.take().unwrap()).lines(),
            child,
        }
    }

    fn line(&mut self) -> String {
        self.stdout
            .next()
            .expect("the python-can peer ended early")
            .unwrap()
    }

    fn say(&mut self, line: &str) {
        writeln!(self.stdin, "{line}").unwrap();
        self.stdin.flush().unwrap();
    }

    fn finish(mut self) {
        assert!(
            self.child.wait().unwrap().success(),
            "python-can peer failed"
        );
    }
}

fn receiver(python: &Path, port: u16) -> Peer {
    let mut rx = Peer::start(python, "join_peer.py", &["recv".into(), port.to_string()]);
    assert_eq!(rx.line(), "ready");
    rx
}

fn sender(python: &Path, port: u16, count: u64, pauses: &str) -> Peer {
    let mut args = vec![
        "send".into(),
        port.to_string(),
        "0".into(),
        count.to_string(),
    ];
    if !pauses.is_empty() {
        args.push(pauses.into());
    }
    Peer::start(python, "join_peer.py", &args)
}

/// `received N in_order 1` from the receiver after `stop N`.
fn received(rx: &mut Peer, count: u64) -> u64 {
    rx.say(&format!("stop {count}"));
    let line = rx.line();
    let n = line
        .strip_prefix("received ")
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{line:?}"));
    assert!(line.ends_with("in_order 1"), "{line}");
    n
}

/// What `buslab status --bus mqtt://…` says: each member's online state and, for the one
/// that heard another, its `from` line's received and lost.
struct Members {
    online: usize,
    from: Vec<(u64, u64)>,
}

fn members(url: &str) -> Option<Members> {
    let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
        .args(["status", "--bus", url])
        .output()
        .unwrap();
    if !out.status.success() {
        return None;
    }
    let text = String::from_utf8(out.stdout).unwrap();
    let number = |line: &str, word: &str| -> u64 {
        let at = line.find(word).unwrap() + word.len();
        line[at..]
            .split(|c: char| !c.is_ascii_digit())
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    Some(Members {
        online: text.lines().filter(|l| l.ends_with(": online")).count(),
        from: text
            .lines()
            .filter(|l| l.starts_with("  from "))
            .map(|l| (number(l, "received "), number(l, "lost ")))
            .collect(),
    })
}

/// Waits until `done` holds for the members' status, within `deadline`.
fn wait_for(url: &str, deadline: Duration, what: &str, done: impl Fn(&Members) -> bool) {
    let start = Instant::now();
    loop {
        if members(url).is_some_and(|m| done(&m)) {
            return;
        }
        assert!(start.elapsed() < deadline, "{url}: never {what}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn buses_joined_through_mosquitto_carry_100k_frames_without_loss() {
    let Some(python) = tools(true) else {
        return;
    };
    let broker = Mosquitto::start();
    let url = broker.url("bench/zero-loss");
    let a = Joined::start(&url);
    let b = Joined::start(&url);
    let mut rx = receiver(&python, b.port);
    let mut tx = sender(&python, a.port, FRAMES, "");
    assert_eq!(tx.line(), format!("sent {FRAMES}"));
    tx.finish();
    assert_eq!(received(&mut rx, FRAMES), FRAMES);
    rx.finish();
    // B's gateway heard every frame of A's, none lost.
    wait_for(&url, deadline_for(FRAMES), "saw every frame", |m| {
        m.from == [(FRAMES, 0)]
    });
    let (a, b) = (a.stop(), b.stop());
    eprintln!("{a}\n{b}");
    assert!(a.contains(&format!("sent {FRAMES}, unsent 0")), "{a}");
    assert!(b.contains(&format!("received {FRAMES}, lost 0")), "{b}");
}

#[test]
fn the_gap_counter_equals_the_frames_lost_while_the_broker_is_stopped() {
    let Some(python) = tools(true) else {
        return;
    };
    let mut broker = Mosquitto::start();
    let url = broker.url("bench/outage");
    let a = Joined::start(&url);
    let b = Joined::start(&url);
    let mut rx = receiver(&python, b.port);
    // 40 000 frames with the broker up, 30 000 handed to bus A while it is down (a bus pushes
    // back, so most of them have crossed bus A by the time python-can has sent them all),
    // 30 000 after it is back.
    let mut tx = sender(&python, a.port, FRAMES, "40000,70000");
    assert_eq!(tx.line(), "paused 40000");
    broker.stop();
    let down = Instant::now();
    tx.say("go");
    assert_eq!(tx.line(), "paused 70000");
    // The outage lasts 2 s at least (the scenario), and until the 30 000 were handed over.
    std::thread::sleep(Duration::from_secs(2).saturating_sub(down.elapsed()));
    broker.run();
    wait_for(&url, deadline_for(0), "saw both members online", |m| {
        m.online == 2
    });
    tx.say("go");
    assert_eq!(tx.line(), format!("sent {FRAMES}"));
    tx.finish();
    // Every sequence number accounted for: received or counted lost.
    wait_for(
        &url,
        deadline_for(FRAMES),
        "accounted for every frame",
        |m| m.from.len() == 1 && m.from[0].0 + m.from[0].1 == FRAMES,
    );
    let (counted_received, lost) = members(&url).unwrap().from[0];
    let got = received(&mut rx, counted_received);
    rx.finish();
    eprintln!("broker stopped for 2 s: python-can received {got} of {FRAMES}, gap counter {lost}");
    assert!(lost > 0, "the outage lost nothing: the test did not test");
    assert_eq!(lost, FRAMES - got, "gap counter against python-can's count");
    let b = b.stop();
    assert!(b.contains(&format!("received {got}, lost {lost}")), "{b}");
    drop(a);
}

fn cannelloni_carries_100k_frames(a_join: &str, b_join: &str, python: &Path) -> (String, String) {
    let a = Joined::start(a_join);
    let b = Joined::start(b_join);
    let mut rx = receiver(python, b.port);
    let mut tx = sender(python, a.port, FRAMES, "");
    assert_eq!(tx.line(), format!("sent {FRAMES}"));
    tx.finish();
    assert_eq!(received(&mut rx, FRAMES), FRAMES);
    rx.finish();
    (a.stop(), b.stop())
}

#[test]
fn buses_joined_through_cannelloni_udp_carry_100k_frames_without_loss() {
    let Some(python) = tools(false) else {
        return;
    };
    let (pa, pb) = (free_udp_port(), free_udp_port());
    let (a, b) = cannelloni_carries_100k_frames(
        &format!("cannelloni://127.0.0.1:{pb}?listen=127.0.0.1:{pa}"),
        &format!("cannelloni://127.0.0.1:{pa}?listen=127.0.0.1:{pb}"),
        &python,
    );
    eprintln!("{a}\n{b}");
    assert!(a.contains(&format!("sent {FRAMES}, unsent 0")), "{a}");
    // Counted in packets: none lost, none out of order.
    assert!(b.contains("lost 0, reordered 0, duplicates 0"), "{b}");
}

#[test]
fn buses_joined_through_cannelloni_tcp_carry_100k_frames_without_loss() {
    let Some(python) = tools(false) else {
        return;
    };
    let port = free_tcp_port();
    let (a, b) = cannelloni_carries_100k_frames(
        &format!("cannelloni+tcp://127.0.0.1:{port}?role=server"),
        &format!("cannelloni+tcp://127.0.0.1:{port}"),
        &python,
    );
    eprintln!("{a}\n{b}");
    assert!(a.contains(&format!("sent {FRAMES}, unsent 0")), "{a}");
    assert!(b.contains(&format!("received {FRAMES}, lost 0")), "{b}");
}

#[test]
fn pypi_can_cannelloni_exchanges_frames_with_buslab_both_ways() {
    let Some(python) = tools(false) else {
        return;
    };
    let has = Command::new(&python)
        .args(["-c", "import can_cannelloni"])
        .status()
        .is_ok_and(|s| s.success());
    if !present(has, "can-cannelloni (PyPI)") {
        return;
    }
    let port = free_tcp_port();
    let serve = Joined::start(&format!("cannelloni+tcp://127.0.0.1:{port}?role=server"));
    let mut peer = Peer::start(
        &python,
        "can_cannelloni_peer.py",
        &[format!("127.0.0.1:{port}"), "1000".into()],
    );
    assert_eq!(peer.line(), "ready");
    let mut me =
        buslab_socketcand::SocketcandBus::connect(("127.0.0.1", serve.port), "vcan0").unwrap();
    // buslab's bus to can-cannelloni: numbered frames, every third extended.
    for k in 0u32..1000 {
        let id = if k % 3 == 0 {
            buslab_can::Id::extended(0x1000_0000 + k).unwrap()
        } else {
            buslab_can::Id::standard(0x100).unwrap()
        };
        me.send(&buslab_can::Frame::data(id, &k.to_le_bytes()).unwrap())
            .unwrap();
    }
    assert_eq!(peer.line(), "received 1000 in_order 1 ext 334 rtr 0");
    assert_eq!(peer.line(), "sent 1000");
    // can-cannelloni to buslab's bus.
    let wait = Some(deadline_for(1000));
    let got: Vec<buslab_can::Frame> = (0..1000)
        .map(|_| me.recv(wait).unwrap().expect("a frame").record)
        .collect();
    peer.say("done");
    peer.finish();
    for (k, f) in got[..999].iter().enumerate() {
        assert_eq!(f.is_extended(), k % 3 == 0, "{f}");
        assert_eq!(f.payload(), (k as u32).to_le_bytes(), "{f}");
    }
    // The remote frame arrives as its ID without data: socketcand's raw mode, which this
    // test's client speaks, has no remote frames (docs/bus.md).
    assert_eq!(got[999].to_string(), "7FF#");
    let line = serve.stop();
    assert!(line.contains("sent 1000, unsent 0"), "{line}");
    assert!(line.contains("received 1000, lost 0"), "{line}");
}

#[test]
fn buslab_send_to_mqtt_gets_its_frame_out_before_it_exits() {
    // `buslab send mqtt://…` exited before its batch was published: the frame never came.
    if !present(Path::new(MOSQUITTO).exists(), "mosquitto") {
        return;
    }
    let broker = Mosquitto::start();
    let url = broker.url("bench/send");
    let mut dump = buslab_backends::open_join(
        &url.parse().unwrap(),
        &buslab_backends::OpenOptions::default(),
    )
    .unwrap();
    for k in 0..5 {
        let text = format!("123#{k:02X}");
        let out = Command::new(env!("CARGO_BIN_EXE_buslab"))
            .args(["send", &url, &text])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let got = dump
            .recv(Some(deadline_for(1)))
            .unwrap()
            .expect("the frame sent");
        assert_eq!(got.record.to_string(), text);
    }
}

/// A broker that wants a password (mosquitto_passwd's file): buslab logs in with the
/// credentials of its configuration file; without them, or with a wrong password, it is
/// refused with a message saying where credentials come from, never repeating the password.
#[test]
fn a_broker_that_wants_a_password_accepts_the_credentials_of_the_configuration_file() {
    let Some(python) = tools(true) else {
        return;
    };
    if !present(
        Path::new("/usr/bin/mosquitto_passwd").exists(),
        "mosquitto_passwd",
    ) {
        return;
    }
    let broker = Mosquitto::start_with(|dir| {
        let passwords = dir.join("passwords");
        let made = Command::new("mosquitto_passwd")
            .args(["-c", "-b"])
            .arg(&passwords)
            .args(["bench", "s3cret-pw"])
            .status()
            .unwrap();
        assert!(made.success());
        format!(
            "allow_anonymous false\npassword_file {}\n",
            passwords.display()
        )
    });
    let url = broker.url("bench/login");
    let dir = tempfile::tempdir().unwrap();
    let config = |name: &str, password: &str| {
        let path = dir.path().join(name);
        std::fs::write(
            &path,
            format!("[mqtt]\nusername = \"bench\"\npassword = \"{password}\"\n"),
        )
        .unwrap();
        path
    };
    let good = config("good.toml", "s3cret-pw");
    let wrong = config("wrong.toml", "not-the-pw");

    // Refused: no credentials, then the wrong password.
    let refused = |config: &[&std::ffi::OsStr]| {
        let out = serve_command(config, &url)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        assert!(!out.status.success(), "joined without the right password");
        String::from_utf8(out.stderr).unwrap()
    };
    let err = refused(&["--no-config".as_ref()]);
    eprintln!("without credentials: {err}");
    assert!(
        err.contains("the broker refused a connection without user name and password")
            && err.contains("[mqtt]")
            && err.contains("$BUSLAB_MQTT_PASSWORD"),
        "{err}"
    );
    let err = refused(&["--config".as_ref(), wrong.as_os_str()]);
    eprintln!("wrong password: {err}");
    assert!(
        err.contains(&format!(
            "the broker refused user \"bench\" (from {}:2 and {}:3)",
            wrong.display(),
            wrong.display()
        )) && !err.contains("not-the-pw"),
        "{err}"
    );

    // Accepted: frames cross from one bus to the other.
    let login = ["--config".as_ref(), good.as_os_str()];
    let a = Joined::start_with(&login, &url);
    let b = Joined::start_with(&login, &url);
    let mut rx = receiver(&python, b.port);
    let mut tx = sender(&python, a.port, 1000, "");
    assert_eq!(tx.line(), "sent 1000");
    tx.finish();
    assert_eq!(received(&mut rx, 1000), 1000);
    rx.finish();
    let (a, b) = (a.stop(), b.stop());
    eprintln!("{a}\n{b}");
    assert!(b.contains("received 1000, lost 0"), "{b}");
}

/// `kill -SIGNAL pid`.
fn signal(child: &Child, signal: &str) {
    let status = Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
}

/// A member that stalls (SIGSTOP: a frozen process, a suspended laptop) while the others send
/// at full rate loses what the broker held for it, and counts exactly that. Mosquitto 2.0.11
/// never drops QoS 0 messages for a connected client because of `max_queued_messages` or
/// `max_queued_bytes` (set tiny here: it queues them without bound, docs/decisions.md); what
/// ends the stall is its keep-alive check: 1.5 × the member's 5 s keep-alive without a packet,
/// it disconnects the member and discards its queue. The test waits for that line in the
/// broker's log (an event, not a margin), continues the member, which connects again, and
/// sends the rest.
#[test]
fn the_gap_counter_equals_the_frames_the_broker_discards_for_a_stalled_member() {
    let Some(python) = tools(true) else {
        return;
    };
    let mut log = PathBuf::new();
    let broker = Mosquitto::start_with(|dir| {
        log = dir.join("mosquitto.log");
        format!(
            "allow_anonymous true\nmax_queued_messages 10\nmax_queued_bytes 16384\nlog_dest file {}\nlog_type error\nlog_type warning\nlog_type notice\n",
            log.display()
        )
    });
    let url = broker.url("bench/stall");
    let a = Joined::start(&url);
    let b = Joined::start(&url);
    let mut rx = receiver(&python, b.port);
    let mut tx = sender(&python, a.port, FRAMES, "20000,40000");
    assert_eq!(tx.line(), "paused 20000");
    signal(&b.child, "-STOP");
    tx.say("go");
    assert_eq!(tx.line(), "paused 40000");
    // The broker gives up on the stalled member.
    let start = Instant::now();
    let broker_log = || std::fs::read_to_string(&log).unwrap_or_default();
    while !broker_log().contains("has exceeded timeout") {
        assert!(
            start.elapsed() < deadline_for(0),
            "the broker never disconnected the stalled member: {}",
            broker_log()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    signal(&b.child, "-CONT");
    wait_for(&url, deadline_for(0), "saw both members online", |m| {
        m.online == 2
    });
    tx.say("go");
    assert_eq!(tx.line(), format!("sent {FRAMES}"));
    tx.finish();
    wait_for(
        &url,
        deadline_for(FRAMES),
        "accounted for every frame",
        |m| m.from.len() == 1 && m.from[0].0 + m.from[0].1 == FRAMES,
    );
    let (counted_received, lost) = members(&url).unwrap().from[0];
    let got = received(&mut rx, counted_received);
    rx.finish();
    let dropped = broker_log().contains("Outgoing messages are being dropped");
    eprintln!(
        "member stalled while 20 000 frames were sent: python-can received {got} of {FRAMES}, gap counter {lost}; the broker's log says 'being dropped' (queue limits): {dropped}"
    );
    assert!(lost > 0, "the stall lost nothing: the test did not test");
    assert_eq!(lost, FRAMES - got, "gap counter against python-can's count");
    let b = b.stop();
    assert!(b.contains(&format!("received {got}, lost {lost}")), "{b}");
    drop(a);
}

/// `mqtts://` to a Mosquitto TLS listener whose certificate a throwaway CA signed: with the CA
/// given as `$SSL_CERT_FILE` frames cross; without it (the system's roots) the broker's
/// certificate is refused.
#[cfg(feature = "mqtt-tls")]
#[test]
fn buses_joined_through_mqtts_check_the_broker_s_certificate() {
    let Some(python) = tools(true) else {
        return;
    };
    if !mail_support::have_openssl() {
        return;
    }
    let certs_dir = tempfile::tempdir().unwrap();
    let certs = mail_support::Certs::generate(certs_dir.path());
    let broker = Mosquitto::start_with(|_| {
        format!(
            "allow_anonymous true\ncafile {}\ncertfile {}\nkeyfile {}\n",
            certs.ca.display(),
            certs.cert.display(),
            certs.key.display()
        )
    });
    let url = format!("mqtts://127.0.0.1:{}/bench/tls", broker.port);
    let no_config: &[&std::ffi::OsStr] = &["--no-config".as_ref()];

    let out = serve_command(no_config, &url)
        .env_remove("SSL_CERT_FILE")
        .env_remove("SSL_CERT_DIR")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let err = String::from_utf8(out.stderr).unwrap();
    eprintln!("without the CA: {err}");
    assert!(!out.status.success(), "joined a broker it cannot check");
    assert!(err.to_lowercase().contains("certificate"), "{err}");

    let joined = || {
        let mut command = serve_command(no_config, &url);
        command.env("SSL_CERT_FILE", &certs.ca);
        Joined::spawn(command)
    };
    let (a, b) = (joined(), joined());
    let mut rx = receiver(&python, b.port);
    let mut tx = sender(&python, a.port, 1000, "");
    assert_eq!(tx.line(), "sent 1000");
    tx.finish();
    assert_eq!(received(&mut rx, 1000), 1000);
    rx.finish();
    let (a, b) = (a.stop(), b.stop());
    eprintln!("{a}\n{b}");
    assert!(b.contains("received 1000, lost 0"), "{b}");
}
