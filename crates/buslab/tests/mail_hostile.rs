//! `buslab mail` against a hostile IMAP server written for the purpose (on a loopback port, in
//! this file): each attack comes at the second look, after an honest first one. For each, the
//! notifier must not abort, must warn naming the problem, must try again and recover when the
//! server behaves (a mail delivered meanwhile is announced on the bus), and its peak memory
//! (VmHWM of /proc/PID/status) must stay within the framer's caps and an allowance for the
//! process itself. STARTTLS stripped: no login is ever sent in clear text.
//!
//! The waits are for events (a line printed, a frame on the bus), within the suite's
//! allowance; the timeout the silences are measured against is the notifier's `--timeout`.

mod bus_common;
mod mail_support;

use std::io::{self, BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::process::{Child, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use bus_common::Serve;
use buslab_canbus::CanBus;
use buslab_mail::imap::Limits;
use mail_support::Certs;
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use rustls::{ServerConfig, ServerConnection, StreamOwned};

/// How long an event may take on a loaded machine (the suite's event allowance, as
/// `vt100_terminal::CEILING`).
const ALLOWANCE: Duration = Duration::from_secs(60);

/// The notifier's `--timeout` where silence is the attack: the warning comes after it.
const SILENCE_TIMEOUT: &str = "3s";

/// Its `--timeout` elsewhere: long enough that an honest look on a loaded machine is never
/// taken for a silence.
const TIMEOUT: &str = "30s";

/// Memory the notifier may use besides what the framer holds: the binary, its threads, the
/// bus client, the TLS state (an honest run peaks at about 10 MiB).
const PROCESS_ALLOWANCE: u64 = 48 << 20;

/// The most a hostile server can make the notifier hold: one response at the framer's cap,
/// twice (the response and what is made of it), besides the process.
fn memory_bound() -> u64 {
    PROCESS_ALLOWANCE + 2 * Limits::DEFAULT.message as u64
}

/// The bytes an endless attack sends at most (the client stops it long before).
const ENDLESS: u64 = 3 << 30;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Attack {
    /// `* 1 FETCH (BODYSTRUCTURE (((…` 400 deep.
    DeepNesting,
    /// `* OK …` lines without end.
    EndlessLines,
    /// A line that never ends.
    LineWithoutLf,
    /// `{2147483648}` and the bytes to go with it.
    HugeLiteral,
    /// Connects, never greets.
    SilentAfterConnect,
    /// Starts the answer to EXAMINE, then says nothing more.
    SilentMidResponse,
    /// Greets without STARTTLS (a man in the middle removing it).
    StartTlsStripped,
    /// Random bytes instead of a greeting.
    Garbage,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Conduct {
    Honest,
    Hostile(Attack),
}

/// What the test and the server's connections share.
#[derive(Default)]
struct Shared {
    /// The mailbox: UID = index + 1.
    mails: Mutex<Vec<Vec<u8>>>,
    /// LOGIN commands received.
    logins: AtomicUsize,
    /// LOGIN commands received on a connection without TLS while the server offered TLS.
    logins_in_clear: AtomicUsize,
    connections: AtomicUsize,
    /// Bytes of mails sent in FETCH answers.
    mail_bytes_sent: AtomicUsize,
}

/// The fake IMAP server: each connection behaves as `script` says for its number (the last
/// entry for all later ones).
struct FakeImap {
    port: u16,
    shared: Arc<Shared>,
}

impl FakeImap {
    fn start(script: Vec<Conduct>, tls: Option<Arc<ServerConfig>>) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let shared = Arc::new(Shared::default());
        let for_server = shared.clone();
        std::thread::spawn(move || {
            for tcp in listener.incoming() {
                let Ok(tcp) = tcp else { continue };
                let n = for_server.connections.fetch_add(1, Ordering::SeqCst);
                let conduct = *script.get(n).unwrap_or(script.last().unwrap());
                let (shared, tls) = (for_server.clone(), tls.clone());
                std::thread::spawn(move || {
                    let _ = serve(tcp, conduct, &shared, tls);
                });
            }
        });
        Self { port, shared }
    }

    fn deliver(&self, mail: &str) {
        let mail = mail.replace('\n', "\r\n").into_bytes();
        self.shared.mails.lock().unwrap().push(mail);
    }
}

/// A connection, in clear text or after STARTTLS.
enum Conn {
    Plain(TcpStream),
    Tls(Box<StreamOwned<ServerConnection, TcpStream>>),
}

impl Read for Conn {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self {
            Conn::Plain(s) => s.read(buf),
            Conn::Tls(s) => s.read(buf),
        }
    }
}

impl Write for Conn {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self {
            Conn::Plain(s) => s.write(buf),
            Conn::Tls(s) => s.write(buf),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match self {
            Conn::Plain(s) => s.flush(),
            Conn::Tls(s) => s.flush(),
        }
    }
}

/// A command line from the client (without CRLF), `None` at its end.
fn read_line(conn: &mut Conn) -> io::Result<Option<String>> {
    let mut line = Vec::new();
    let mut byte = [0u8];
    loop {
        if conn.read(&mut byte)? == 0 {
            return Ok(None);
        }
        if byte[0] == b'\n' {
            return Ok(Some(String::from_utf8_lossy(&line).trim_end().to_string()));
        }
        line.push(byte[0]);
    }
}

/// Reads until the client leaves (it gives up on a silent server).
fn drain(mut conn: Conn) -> io::Result<()> {
    if let Conn::Plain(tcp) = &conn {
        tcp.set_read_timeout(Some(ALLOWANCE))?;
    }
    let mut buf = [0u8; 4096];
    while conn.read(&mut buf)? > 0 {}
    Ok(())
}

/// Writes `start`, then `chunk` again and again until the client stops taking them.
fn endless(conn: &mut Conn, start: &[u8], chunk: &[u8]) -> io::Result<()> {
    conn.write_all(start)?;
    let mut sent = 0u64;
    while sent < ENDLESS {
        conn.write_all(chunk)?;
        sent += chunk.len() as u64;
    }
    Ok(())
}

/// Deterministic garbage: bytes of every value, line ends among them.
fn garbage(len: usize) -> Vec<u8> {
    let mut x = 0x2545_f491_4f6c_dd1du64;
    (0..len)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 32) as u8
        })
        .collect()
}

fn serve(
    tcp: TcpStream,
    conduct: Conduct,
    shared: &Shared,
    tls: Option<Arc<ServerConfig>>,
) -> io::Result<()> {
    let mut conn = Conn::Plain(tcp);
    match conduct {
        Conduct::Hostile(Attack::SilentAfterConnect) => return drain(conn),
        Conduct::Hostile(Attack::Garbage) => {
            conn.write_all(&garbage(256 * 1024))?;
            return drain(conn);
        }
        _ => {}
    }
    let offers_tls = tls.is_some() && conduct != Conduct::Hostile(Attack::StartTlsStripped);
    let capabilities = if offers_tls {
        "IMAP4rev1 STARTTLS AUTH=PLAIN"
    } else {
        "IMAP4rev1 AUTH=PLAIN"
    };
    conn.write_all(format!("* OK [CAPABILITY {capabilities}] fake IMAP ready\r\n").as_bytes())?;
    while let Some(line) = read_line(&mut conn)? {
        let mut words = line.split(' ');
        let tag = words.next().unwrap_or("*").to_string();
        let command = words.next().unwrap_or("").to_ascii_uppercase();
        let reply = match command.as_str() {
            "CAPABILITY" => {
                format!("* CAPABILITY {capabilities}\r\n{tag} OK done\r\n").into_bytes()
            }
            "STARTTLS" if offers_tls => {
                conn.write_all(format!("{tag} OK begin TLS\r\n").as_bytes())?;
                let Conn::Plain(tcp) = conn else {
                    return Ok(());
                };
                let server =
                    ServerConnection::new(tls.clone().unwrap()).map_err(io::Error::other)?;
                conn = Conn::Tls(Box::new(StreamOwned::new(server, tcp)));
                continue;
            }
            "LOGIN" => {
                shared.logins.fetch_add(1, Ordering::SeqCst);
                if tls.is_some() && matches!(conn, Conn::Plain(_)) {
                    shared.logins_in_clear.fetch_add(1, Ordering::SeqCst);
                }
                format!("{tag} OK logged in\r\n").into_bytes()
            }
            "EXAMINE" => match conduct {
                Conduct::Hostile(attack) => return assault(conn, attack),
                Conduct::Honest => {
                    let n = shared.mails.lock().unwrap().len();
                    format!(
                        "* {n} EXISTS\r\n* OK [UIDVALIDITY 1] ok\r\n* OK [UIDNEXT {}] ok\r\n{tag} OK [READ-ONLY] done\r\n",
                        n + 1
                    )
                    .into_bytes()
                }
            },
            "UID" => {
                let what = words.next().unwrap_or("").to_ascii_uppercase();
                let arg = if what == "SEARCH" {
                    words.nth(1)
                } else {
                    words.next()
                };
                let mails = shared.mails.lock().unwrap();
                // BODY.PEEK[]<0.N>: the first N bytes.
                let part = line
                    .split_once("<0.")
                    .and_then(|(_, n)| n.split('>').next()?.parse().ok())
                    .unwrap_or(usize::MAX);
                let (reply, sent) = uid_command(&tag, &what, arg.unwrap_or(""), part, &mails);
                shared.mail_bytes_sent.fetch_add(sent, Ordering::SeqCst);
                reply
            }
            "LOGOUT" => {
                conn.write_all(format!("* BYE bye\r\n{tag} OK done\r\n").as_bytes())?;
                return Ok(());
            }
            _ => format!("{tag} BAD what is {command}?\r\n").into_bytes(),
        };
        conn.write_all(&reply)?;
    }
    Ok(())
}

/// UID SEARCH UID n:* and UID FETCH uid,… (… BODY.PEEK[]<0.part>) on `mails`; the reply and
/// the bytes of mails in it.
fn uid_command(
    tag: &str,
    what: &str,
    arg: &str,
    part: usize,
    mails: &[Vec<u8>],
) -> (Vec<u8>, usize) {
    let mut reply = Vec::new();
    let mut sent = 0;
    match what {
        "SEARCH" => {
            let from: usize = arg.split(':').next().unwrap().parse().unwrap();
            let mut line = "* SEARCH".to_string();
            for uid in from.max(1)..=mails.len() {
                line += &format!(" {uid}");
            }
            reply.extend(format!("{line}\r\n").as_bytes());
        }
        "FETCH" => {
            for uid in arg.split(',').map(|u| u.parse::<usize>().unwrap()) {
                let Some(mail) = mails.get(uid - 1) else {
                    continue;
                };
                let body = &mail[..mail.len().min(part)];
                reply.extend(
                    format!(
                        "* {uid} FETCH (UID {uid} RFC822.SIZE {} BODY[]<0> {{{}}}\r\n",
                        mail.len(),
                        body.len()
                    )
                    .as_bytes(),
                );
                reply.extend(body);
                sent += body.len();
                reply.extend(b")\r\n");
            }
        }
        _ => {}
    }
    reply.extend(format!("{tag} OK done\r\n").as_bytes());
    (reply, sent)
}

/// The attack, as the answer to EXAMINE.
fn assault(mut conn: Conn, attack: Attack) -> io::Result<()> {
    match attack {
        Attack::DeepNesting => {
            let mut line = b"* 1 FETCH (BODYSTRUCTURE ".to_vec();
            line.extend([b'('].repeat(400));
            line.extend(b"\"TEXT\" \"PLAIN\" NIL NIL NIL \"7BIT\" 1 1");
            line.extend([b')'].repeat(401));
            line.extend(b"\r\n");
            conn.write_all(&line)?;
        }
        Attack::EndlessLines => endless(&mut conn, b"", &b"* OK still here\r\n".repeat(4096))?,
        Attack::LineWithoutLf => endless(&mut conn, b"* OK ", &[b'x'; 64 * 1024])?,
        Attack::HugeLiteral => endless(
            &mut conn,
            b"* 1 FETCH (UID 1 BODY[] {2147483648}\r\n",
            &[b'a'; 64 * 1024],
        )?,
        Attack::SilentMidResponse => conn.write_all(b"* 3 EXISTS\r\n* OK [UIDVAL")?,
        Attack::SilentAfterConnect | Attack::StartTlsStripped | Attack::Garbage => {
            unreachable!("{attack:?} comes before EXAMINE")
        }
    }
    drain(conn)
}

/// `buslab mail` running, its stderr lines on a channel.
struct Notifier {
    child: Child,
    lines: mpsc::Receiver<String>,
    said: Vec<String>,
}

impl Notifier {
    fn spawn(serve: &Serve, port: u16, args: &[&str]) -> Self {
        let mut child = serve
            .buslab()
            .args(["mail", "--bus", &serve.url, "--user", "alice"])
            .args(["--interval", "200ms"])
            .arg("--imap")
            .arg(format!("127.0.0.1:{port}"))
            .args(args)
            .env("BUSLAB_MAIL_PASSWORD", "s3cret")
            .stdin(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stderr = BufReader::new(child.stderr.take().unwrap());
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in stderr.lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Self {
            child,
            lines,
            said: Vec::new(),
        }
    }

    /// The first line (from now) that contains `text`.
    fn wait_for(&mut self, text: &str) -> String {
        let start = Instant::now();
        loop {
            let left = ALLOWANCE.saturating_sub(start.elapsed());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    self.said.push(line.clone());
                    if line.contains(text) {
                        return line;
                    }
                }
                Err(_) => panic!(
                    "{text:?} never said within {ALLOWANCE:?} (exit: {:?}); it said:\n{}",
                    self.child.try_wait().unwrap(),
                    self.said.join("\n")
                ),
            }
        }
    }

    /// Peak resident memory so far, in bytes (VmHWM).
    fn peak_memory(&self) -> u64 {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).unwrap();
        let line = status
            .lines()
            .find(|l| l.starts_with("VmHWM:"))
            .expect("VmHWM in /proc/PID/status");
        let kib: u64 = line
            .split_whitespace()
            .nth(1)
            .and_then(|n| n.parse().ok())
            .unwrap();
        kib * 1024
    }

    /// Exit status, waiting for the end within the allowance.
    fn exit(&mut self) -> std::process::ExitStatus {
        let start = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status;
            }
            assert!(start.elapsed() < ALLOWANCE, "the notifier did not stop");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Notifier {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Waits for MoniCAN's mail announcement (a remote frame on 0x700, DLC 0) on the bus.
fn wait_for_announcement(bus: &mut impl CanBus) {
    let start = Instant::now();
    while start.elapsed() < ALLOWANCE {
        if let Some(message) = bus.recv(Some(Duration::from_millis(200))).unwrap() {
            let frame = message.record;
            if frame.is_remote() && frame.id().as_raw() == 0x700 {
                return;
            }
        }
    }
    panic!("no mail announced on 700 within {ALLOWANCE:?}");
}

/// The server's TLS set-up and the CA file the notifier is told to trust.
fn server_tls(dir: &Path) -> (Arc<ServerConfig>, Certs) {
    let certs = Certs::generate(dir);
    let chain: Vec<CertificateDer> = CertificateDer::pem_file_iter(&certs.cert)
        .unwrap()
        .map(Result::unwrap)
        .collect();
    let key = PrivateKeyDer::from_pem_file(&certs.key).unwrap();
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let config = ServerConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .unwrap()
        .with_no_client_auth()
        .with_single_cert(chain, key)
        .unwrap();
    (Arc::new(config), certs)
}

/// An honest look, the attack at the second, honest ones after: the warning names the
/// problem (`expect`), the notifier tries again, announces the mail delivered meanwhile, and
/// stays within the memory bound. Returns the warning and the peak memory.
fn attack_and_recover(attack: Attack, tls: bool, args: &[&str], expect: &[&str]) -> (String, u64) {
    let dir = tempfile::tempdir().unwrap();
    let (server_config, ca) = if tls {
        let (config, certs) = server_tls(dir.path());
        (Some(config), Some(certs))
    } else {
        (None, None)
    };
    let serve = Serve::start(125_000);
    let mut bus = serve.client();
    let imap = FakeImap::start(
        vec![Conduct::Honest, Conduct::Hostile(attack), Conduct::Honest],
        server_config,
    );
    imap.deliver("From: a@b\nSubject: old\n\nthere before\n");
    let mut args = args.to_vec();
    if let Some(certs) = &ca {
        args.extend(["--ca-file", certs.ca.to_str().unwrap()]);
    } else {
        args.extend(["--tls", "plain"]);
    }
    let mut notifier = Notifier::spawn(&serve, imap.port, &args);
    notifier.wait_for("watching INBOX of alice");
    let warning = notifier.wait_for("WARN IMAP server");
    for text in expect {
        assert!(
            warning.contains(text),
            "{attack:?}: {warning:?} lacks {text:?}"
        );
    }
    assert!(warning.contains("trying again in"), "{warning}");
    imap.deliver("From: Alice <alice@example.org>\nSubject: after the attack\n\nstill here\n");
    notifier.wait_for("answers again (after 1 failed looks)");
    wait_for_announcement(&mut bus);
    assert_eq!(notifier.child.try_wait().unwrap(), None, "still running");
    let peak = notifier.peak_memory();
    eprintln!(
        "{attack:?}: {warning}\n  peak RSS {:.1} MiB (bound {} MiB)",
        peak as f64 / (1 << 20) as f64,
        memory_bound() >> 20
    );
    assert!(
        peak < memory_bound(),
        "{attack:?}: peak memory {peak} bytes over {}",
        memory_bound()
    );
    assert_eq!(imap.shared.logins_in_clear.load(Ordering::SeqCst), 0);
    (warning, peak)
}

#[test]
fn imap_bodystructure_nested_400_deep_is_refused_not_a_stack_overflow() {
    attack_and_recover(
        Attack::DeepNesting,
        false,
        &["--timeout", TIMEOUT],
        &["parentheses nested deeper than 32", "the answer to EXAMINE"],
    );
}

#[test]
fn imap_endless_lines_are_cut_at_the_answer_cap() {
    attack_and_recover(
        Attack::EndlessLines,
        false,
        &["--timeout", TIMEOUT],
        &["the answer to EXAMINE exceeded 16777216 bytes"],
    );
}

#[test]
fn imap_line_without_lf_is_cut_at_the_line_cap() {
    attack_and_recover(
        Attack::LineWithoutLf,
        false,
        &["--timeout", TIMEOUT],
        &["a line longer than 1048576 bytes without a line end"],
    );
}

#[test]
fn imap_literal_announced_as_2_gb_is_refused_unread() {
    attack_and_recover(
        Attack::HugeLiteral,
        false,
        &["--timeout", TIMEOUT],
        &["a literal announced as 2147483648 bytes (at most 1048576 accepted)"],
    );
}

#[test]
fn imap_silence_after_connect_is_a_timeout() {
    attack_and_recover(
        Attack::SilentAfterConnect,
        false,
        &["--timeout", SILENCE_TIMEOUT],
        &[
            "the server sent nothing for 3s (waiting for its greeting)",
            "--timeout",
        ],
    );
}

#[test]
fn imap_silence_mid_response_is_a_timeout() {
    attack_and_recover(
        Attack::SilentMidResponse,
        false,
        &["--timeout", SILENCE_TIMEOUT],
        &[
            "the server did not finish the answer to EXAMINE within 3s (24 bytes received)",
            "--timeout",
        ],
    );
}

#[test]
fn imap_garbage_is_not_imap_and_says_so() {
    attack_and_recover(
        Attack::Garbage,
        false,
        &["--timeout", TIMEOUT],
        &["the server sent", "(in its greeting)"],
    );
}

#[test]
fn imap_starttls_stripped_later_is_warned_about_retried_and_no_login_goes_in_clear() {
    if !mail_support::have_openssl() {
        return;
    }
    attack_and_recover(
        Attack::StartTlsStripped,
        true,
        &["--timeout", TIMEOUT],
        &["does not offer STARTTLS", "--tls plain"],
    );
}

#[test]
fn imap_starttls_stripped_at_the_first_look_stops_with_the_reason_and_sends_no_login() {
    let serve = Serve::start(125_000);
    // A server that offers no STARTTLS at all; the notifier left at --tls auto.
    let imap = FakeImap::start(vec![Conduct::Honest], None);
    let mut notifier = Notifier::spawn(&serve, imap.port, &["--timeout", TIMEOUT]);
    let error = notifier.wait_for("does not offer STARTTLS");
    assert!(error.contains("--tls plain"), "{error}");
    assert!(error.contains("--tls tls"), "{error}");
    assert_eq!(notifier.exit().code(), Some(1), "an error, not an abort");
    assert_eq!(imap.shared.connections.load(Ordering::SeqCst), 1);
    assert_eq!(
        imap.shared.logins.load(Ordering::SeqCst),
        0,
        "no LOGIN, no password"
    );
}

#[test]
fn a_20_mb_mail_is_fetched_in_part_and_goes_on_the_bus_within_the_limit() {
    let serve = Serve::start(125_000);
    let mut bus = serve.client();
    let imap = FakeImap::start(vec![Conduct::Honest], None);
    let mut notifier = Notifier::spawn(
        &serve,
        imap.port,
        &["--tls", "plain", "--timeout", TIMEOUT, "--limit", "500"],
    );
    notifier.wait_for("watching INBOX of alice");
    let body = "twenty megabytes of text\n".repeat(20 << 20 >> 5);
    let mail = format!("From: Alice <alice@example.org>\nSubject: big\n\n{body}");
    imap.deliver(&mail);
    let size = mail.len() + mail.matches('\n').count();
    wait_for_announcement(&mut bus);
    // MoniCAN's Ctrl R: a remote frame on the mail ID; the text comes in 8-byte frames, the
    // last one shorter.
    let id = buslab_can::Id::standard(0x700).unwrap();
    bus.send(&buslab_can::Frame::remote(id, 0).unwrap())
        .unwrap();
    let mut text = Vec::new();
    let start = Instant::now();
    loop {
        assert!(
            start.elapsed() < ALLOWANCE,
            "the mail's frames did not come"
        );
        let Some(message) = bus.recv(Some(Duration::from_millis(200))).unwrap() else {
            continue;
        };
        let frame = message.record;
        if frame.id() != id || frame.is_remote() {
            continue;
        }
        text.extend_from_slice(frame.payload());
        if frame.payload().len() < 8 {
            break;
        }
    }
    notifier.wait_for("mail 1 asked for and sent");
    let text = String::from_utf8(text).unwrap();
    assert!(text.len() <= 500, "{} bytes", text.len());
    assert!(text.starts_with("From: Alice <alice@example.org>\nSubject: big\n\ntwenty megabytes"));
    let left: usize = text
        .rsplit_once("[... ")
        .and_then(|(_, n)| n.strip_suffix(" more bytes not sent]"))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no note of what was left out: {text:?}"));
    let shown = text
        .split("\n\n")
        .nth(1)
        .unwrap()
        .rsplit_once("\n[...")
        .unwrap()
        .0;
    let header = "From: Alice <alice@example.org>\r\nSubject: big\r\n\r\n".len();
    // Each shown line end was CRLF on the server.
    assert_eq!(
        left,
        size - header - shown.len() - shown.matches('\n').count()
    );
    let fetched = imap.shared.mail_bytes_sent.load(Ordering::SeqCst);
    assert!(
        fetched <= buslab_mail::imap::fetch_bytes(500) as usize,
        "{fetched} bytes of a {size}-byte mail fetched"
    );
    let peak = notifier.peak_memory();
    eprintln!(
        "20 MB mail: {fetched} bytes fetched, {} sent on the bus, peak RSS {:.1} MiB",
        text.len(),
        peak as f64 / (1 << 20) as f64
    );
    assert!(peak < memory_bound(), "peak memory {peak} bytes");
}
