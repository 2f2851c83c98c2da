//! `buslab mail` against a real IMAP server: Dovecot (Debian's `dovecot-imapd`, installed by
//! scripts/setup-test-deps.sh) on loopback ports with a throwaway configuration, mailbox and
//! certificate authority. Dovecot's log marks each login made under TLS (`, TLS,`): the tests
//! check the password went under TLS, the certificate checked against the CA given with
//! `--ca-file` (Dovecot takes a loopback connection as secure, so it would accept a login in
//! clear text there too). A mail dropped into the mailbox must appear on the PowerPC
//! node's MoniCAN screen after Ctrl R, read through its pseudo-terminal by an independent
//! VT100 emulator (`vt100`).

#[path = "support/vt100_terminal.rs"]
mod vt100_terminal;

mod bus_common;
mod mail_support;

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use bus_common::Serve;
use mail_support::Certs;
use vt100_terminal::{CEILING, Terminal};

const DOVECOT: &str = "/usr/sbin/dovecot";

/// A Dovecot with its own configuration under a temporary folder; stopped when dropped.
struct Dovecot {
    config: PathBuf,
    /// IMAP with STARTTLS.
    port: u16,
    /// IMAPS: TLS from the first byte.
    imaps_port: u16,
    maildir: PathBuf,
    certs: Certs,
    log: PathBuf,
    _dir: tempfile::TempDir,
}

/// A free loopback port (released just before Dovecot binds it).
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

impl Dovecot {
    fn start() -> Self {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        for sub in ["run", "mail"] {
            std::fs::create_dir_all(root.join(sub)).unwrap();
        }
        let status = Command::new("chmod")
            .args(["755"])
            .arg(root)
            .arg(root.join("run"))
            .status()
            .unwrap();
        assert!(status.success());
        let (port, imaps_port) = (free_port(), free_port());
        let certs = Certs::generate(root);
        let d = root.display();
        std::fs::write(root.join("users"), "testuser:{PLAIN}secret\n").unwrap();
        let config = root.join("dovecot.conf");
        std::fs::write(
            &config,
            format!(
                "base_dir = {d}/run\nstate_dir = {d}/run\nlog_path = {d}/dovecot.log\n\
                 protocols = imap\nlisten = 127.0.0.1\n\
                 ssl = required\nssl_cert = <{cert}\nssl_key = <{key}\n\
                 disable_plaintext_auth = yes\nauth_mechanisms = plain login\n\
                 mail_location = maildir:{d}/mail/%u/Maildir\n\
                 passdb {{\n  driver = passwd-file\n  args = scheme=PLAIN username_format=%u {d}/users\n}}\n\
                 userdb {{\n  driver = static\n  args = uid=dovecot gid=dovecot home={d}/mail/%u\n}}\n\
                 service imap-login {{\n  inet_listener imap {{\n    address = 127.0.0.1\n    port = {port}\n  }}\n\
                 inet_listener imaps {{\n    address = 127.0.0.1\n    port = {imaps_port}\n    ssl = yes\n  }}\n}}\n\
                 default_login_user = dovenull\ndefault_internal_user = dovecot\n\
                 default_internal_group = dovecot\nfirst_valid_uid = 0\n",
                cert = certs.cert.display(),
                key = certs.key.display(),
            ),
        )
        .unwrap();
        let maildir = root.join("mail/testuser/Maildir");
        for sub in ["new", "cur", "tmp"] {
            std::fs::create_dir_all(maildir.join(sub)).unwrap();
        }
        let status = Command::new("chown")
            .args(["-R", "dovecot:dovecot"])
            .arg(root.join("mail"))
            .status()
            .unwrap();
        assert!(status.success());
        let status = Command::new(DOVECOT)
            .arg("-c")
            .arg(&config)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .unwrap();
        assert!(status.success(), "dovecot did not start");
        let start = Instant::now();
        for port in [port, imaps_port] {
            while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
                assert!(
                    start.elapsed() < CEILING,
                    "dovecot never listened on {port}"
                );
                std::thread::sleep(Duration::from_millis(50));
            }
        }
        Self {
            config,
            port,
            imaps_port,
            maildir,
            certs,
            log: root.join("dovecot.log"),
            _dir: dir,
        }
    }

    /// Delivers a mail the way a local delivery agent does (Maildir: tmp, then new).
    fn deliver(&self, name: &str, text: &str) {
        let tmp = self.maildir.join("tmp").join(name);
        std::fs::write(&tmp, text.replace('\n', "\r\n")).unwrap();
        let status = Command::new("chown")
            .args(["dovecot:dovecot"])
            .arg(&tmp)
            .status()
            .unwrap();
        assert!(status.success());
        std::fs::rename(&tmp, self.maildir.join("new").join(name)).unwrap();
    }
}

impl Dovecot {
    /// Dovecot's log lines of the logins so far (`Login: user=<testuser>, method=PLAIN, …,
    /// TLS, …` when the login was under TLS).
    fn logins(&self) -> Vec<String> {
        std::fs::read_to_string(&self.log)
            .unwrap_or_default()
            .lines()
            .filter(|l| l.contains("Login: user=<testuser>"))
            .map(str::to_string)
            .collect()
    }
}

/// Whether a login line of Dovecot's log says it was made under TLS.
fn under_tls(login: &str) -> bool {
    login.split(", ").any(|field| field == "TLS")
}

impl Drop for Dovecot {
    fn drop(&mut self) {
        let _ = Command::new(DOVECOT)
            .arg("-c")
            .arg(&self.config)
            .arg("stop")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status();
    }
}

struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Whether Dovecot is there (in CI it must be).
fn have_dovecot() -> bool {
    if Path::new(DOVECOT).exists() {
        return true;
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "dovecot is missing in CI (scripts/setup-test-deps.sh installs dovecot-imapd)"
    );
    eprintln!("SKIPPED: dovecot is missing; run scripts/setup-test-deps.sh");
    false
}

#[test]
fn a_mail_in_the_dovecot_mailbox_shows_on_monicans_screen_after_ctrl_r() {
    if !have_dovecot() {
        return;
    }
    let dovecot = Dovecot::start();
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("monican");
    let serve = Serve::start_with(125_000, &["--ppc", link.to_str().unwrap()]);
    let mut terminal = Terminal::open(&link);
    terminal.wait_for_text("MoniCAN");

    let mut notifier = serve
        .buslab()
        .args(["mail", "--bus", &serve.url, "--user", "testuser"])
        .arg("--imap")
        .arg(format!("127.0.0.1:{}", dovecot.port))
        .args(["--interval", "200ms", "--count", "1"])
        // --tls auto on a port other than 993: STARTTLS, required.
        .arg("--ca-file")
        .arg(&dovecot.certs.ca)
        .env("BUSLAB_MAIL_PASSWORD", "secret")
        .stdin(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut said = BufReader::new(notifier.stderr.take().unwrap());
    let notifier = Killed(notifier);
    // Mail that arrives while the notifier watches is new mail.
    let mut line = String::new();
    while !line.contains("watching INBOX of testuser") {
        line.clear();
        assert!(
            said.read_line(&mut line).unwrap() > 0,
            "the notifier stopped before it watched the mailbox"
        );
    }
    dovecot.deliver(
        "1700000000.M1P1.buslab",
        "From: Alice <alice@example.org>\nTo: testuser@localhost\nSubject: Dinner at eight\n\nThe table is booked.\nBring the CAN analyser.\n",
    );
    terminal.wait_for_text("you've got mail ! (press Ctrl R to read it)");
    terminal.type_keys(&[0x12]);
    terminal.wait_for_text("Subject: Dinner at eight");
    terminal.wait_for_text("From: Alice <alice@example.org>");
    terminal.wait_for_text("Bring the CAN analyser.");
    let mut rest = String::new();
    let mut notifier = notifier;
    let start = Instant::now();
    while notifier.0.try_wait().unwrap().is_none() {
        assert!(
            start.elapsed() < CEILING,
            "the notifier did not stop after its mail"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    said.read_to_string(&mut rest).unwrap();
    assert!(rest.contains("mail 1 asked for and sent"), "{rest}");
    let logins = dovecot.logins();
    assert!(
        !logins.is_empty() && logins.iter().all(|l| under_tls(l)),
        "{logins:#?}"
    );
}

/// Runs `buslab mail` against `port` with `args`; returns its stderr once it printed `until`
/// (then kills it) or ended.
fn notifier_says(serve: &Serve, port: u16, args: &[&str], until: &str) -> (String, bool) {
    let mut notifier = serve
        .buslab()
        .args([
            "mail",
            "--bus",
            &serve.url,
            "--user",
            "testuser",
            "--interval",
            "200ms",
        ])
        .arg("--imap")
        .arg(format!("127.0.0.1:{port}"))
        .args(args)
        .env("BUSLAB_MAIL_PASSWORD", "secret")
        .env_remove("SSL_CERT_FILE")
        .env_remove("SSL_CERT_DIR")
        .stdin(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut said = BufReader::new(notifier.stderr.take().unwrap());
    let notifier = Killed(notifier);
    let mut all = String::new();
    let mut line = String::new();
    loop {
        line.clear();
        if said.read_line(&mut line).unwrap() == 0 {
            return (all, false);
        }
        all.push_str(&line);
        if line.contains(until) {
            drop(notifier);
            return (all, true);
        }
    }
}

#[test]
fn the_notifier_logs_in_to_dovecot_over_imaps_and_refuses_a_certificate_it_cannot_check() {
    if !have_dovecot() {
        return;
    }
    let dovecot = Dovecot::start();
    let serve = Serve::start(125_000);
    let ca = dovecot.certs.ca.to_str().unwrap();
    let (said, seen) = notifier_says(
        &serve,
        dovecot.imaps_port,
        &["--tls", "tls", "--ca-file", ca],
        "watching INBOX of testuser",
    );
    assert!(seen, "{said}");
    // STARTTLS, the CA given: the same.
    let (said, seen) = notifier_says(&serve, dovecot.port, &["--ca-file", ca], "watching INBOX");
    assert!(seen, "{said}");
    let logins = dovecot.logins();
    assert!(
        logins.len() >= 2 && logins.iter().all(|l| under_tls(l)),
        "{logins:#?}"
    );
    // Without the CA, the system's certificates do not vouch for the server: no login.
    for (port, tls) in [(dovecot.imaps_port, "tls"), (dovecot.port, "auto")] {
        let (said, seen) = notifier_says(&serve, port, &["--tls", tls], "watching INBOX");
        assert!(!seen, "{said}");
        assert!(
            said.contains("TLS with 127.0.0.1") && said.contains("UnknownIssuer"),
            "{said}"
        );
    }
    assert_eq!(dovecot.logins().len(), logins.len(), "no login without TLS");
    // --tls plain, asked for: a login in clear text, warned about, and Dovecot's log tells it
    // from the others.
    let (said, seen) = notifier_says(&serve, dovecot.port, &["--tls", "plain"], "watching INBOX");
    assert!(seen, "{said}");
    assert!(said.contains("--tls plain: the password goes to"), "{said}");
    let plain = dovecot.logins();
    assert!(
        plain.len() > logins.len() && !under_tls(plain.last().unwrap()),
        "{plain:#?}"
    );
}
