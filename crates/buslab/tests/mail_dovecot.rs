//! `buslab mail` against a real IMAP server: Dovecot (Debian's `dovecot-imapd`, installed by
//! scripts/setup-test-deps.sh) on a loopback port with a throwaway configuration and mailbox.
//! A mail dropped into the mailbox must appear on the PowerPC node's MoniCAN screen after
//! Ctrl R, read through its pseudo-terminal by an independent VT100 emulator (`vt100`).

#[path = "support/vt100_terminal.rs"]
mod vt100_terminal;

mod bus_common;

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use bus_common::Serve;
use vt100_terminal::{CEILING, Terminal};

const DOVECOT: &str = "/usr/sbin/dovecot";

/// A Dovecot with its own configuration under a temporary folder; stopped when dropped.
struct Dovecot {
    config: PathBuf,
    port: u16,
    maildir: PathBuf,
    _dir: tempfile::TempDir,
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
        // A free loopback port (released just before Dovecot binds it).
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let d = root.display();
        std::fs::write(root.join("users"), "testuser:{PLAIN}secret\n").unwrap();
        let config = root.join("dovecot.conf");
        std::fs::write(
            &config,
            format!(
                "base_dir = {d}/run\nstate_dir = {d}/run\nlog_path = {d}/dovecot.log\n\
                 protocols = imap\nlisten = 127.0.0.1\nssl = no\n\
                 disable_plaintext_auth = no\nauth_mechanisms = plain login\n\
                 mail_location = maildir:{d}/mail/%u/Maildir\n\
                 passdb {{\n  driver = passwd-file\n  args = scheme=PLAIN username_format=%u {d}/users\n}}\n\
                 userdb {{\n  driver = static\n  args = uid=dovecot gid=dovecot home={d}/mail/%u\n}}\n\
                 service imap-login {{\n  inet_listener imap {{\n    address = 127.0.0.1\n    port = {port}\n  }}\n}}\n\
                 default_login_user = dovenull\ndefault_internal_user = dovecot\n\
                 default_internal_group = dovecot\nfirst_valid_uid = 0\n"
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
        while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(
                start.elapsed() < CEILING,
                "dovecot never listened on {port}"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        Self {
            config,
            port,
            maildir,
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

#[test]
fn a_mail_in_the_dovecot_mailbox_shows_on_monicans_screen_after_ctrl_r() {
    if !Path::new(DOVECOT).exists() {
        assert!(
            std::env::var_os("CI").is_none(),
            "dovecot is missing in CI (scripts/setup-test-deps.sh installs dovecot-imapd)"
        );
        eprintln!("SKIPPED: dovecot is missing; run scripts/setup-test-deps.sh");
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
}
