//! `buslab mail` against a real IMAP server: Dovecot (Debian's `dovecot-imapd`, installed by
//! scripts/setup-test-deps.sh) on a loopback port with a throwaway configuration and mailbox.
//! A mail dropped into the mailbox must appear on the PowerPC node's MoniCAN screen after
//! Ctrl R, read through its pseudo-terminal by an independent VT100 emulator (`vt100`).

mod bus_common;

use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, Read, Write};
use std::os::fd::AsFd;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

use bus_common::Serve;
use nix::sys::termios::{BaudRate, SetArg, cfmakeraw, cfsetspeed, tcgetattr, tcsetattr};

/// The ceiling for what the test waits for (it returns as soon as the screen shows it).
const CEILING: Duration = Duration::from_secs(60);
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

struct Terminal {
    keys: File,
    output: Receiver<Vec<u8>>,
    screen: vt100::Parser,
}

impl Terminal {
    fn open(path: &Path) -> Self {
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
            .unwrap();
        let mut t = tcgetattr(file.as_fd()).unwrap();
        cfmakeraw(&mut t);
        cfsetspeed(&mut t, BaudRate::B19200).unwrap();
        tcsetattr(file.as_fd(), SetArg::TCSANOW, &t).unwrap();
        let mut reader = file.try_clone().unwrap();
        let (tx, output) = mpsc::channel();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = reader.read(&mut buf) {
                if n == 0 || tx.send(buf[..n].to_vec()).is_err() {
                    break;
                }
            }
        });
        Self {
            keys: file,
            output,
            screen: vt100::Parser::new(24, 80, 0),
        }
    }

    fn wait_for(&mut self, text: &str) {
        let start = Instant::now();
        while !self.screen.screen().contents().contains(text) {
            let left = CEILING.saturating_sub(start.elapsed());
            match self.output.recv_timeout(left) {
                Ok(bytes) => self.screen.process(&bytes),
                Err(_) => panic!(
                    "{text:?} never showed within {CEILING:?}; the screen:\n{}",
                    self.screen.screen().contents()
                ),
            }
        }
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
    terminal.wait_for("MoniCAN");

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
    terminal.wait_for("you've got mail ! (press Ctrl R to read it)");
    terminal.keys.write_all(&[0x12]).unwrap();
    terminal.wait_for("Subject: Dinner at eight");
    terminal.wait_for("From: Alice <alice@example.org>");
    terminal.wait_for("Bring the CAN analyser.");
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
