//! Scripted SLCAN adapters on a pseudo-terminal, each answering as its firmware does (the
//! facts are in `docs/decisions.md`, "SLCAN open"):
//!
//! | kind | answers |
//! |---|---|
//! | `Lawicel` | CANUSB/CAN232 manual: CR or BEL to every command (BEL to `C` while closed), `V1013`, `NA123`, `z`/`Z` for frames |
//! | `Canable` | normaldotcom/canable-fw and canable2-fw: **nothing** but `V` (`<git describe> <repository>`); an empty line runs the previous command again; `M1` silent mode, no `L`, `S7` = 750k |
//! | `CanableAcking` | the same firmware with its CR/BEL answers on (a 2019 variant): CR or BEL to every line, `V`'s text then CR |
//! | `Canable2Fork` | Nakakiyo092/canable2-fw: Lawicel-like, `V` answered `VL2K0 <describe> <repository>`, CR to an empty line, `N1A2B` |
//! | `Model` | buslab's own `buslab_slcan::Adapter` (with CAN FD after `speak_fd`) |
//!
//! A fake can hold its answer to `C` (and a frame queued before it) until the host writes
//! again, as an adapter whose output was still queued when the session closed the port: the
//! next session reads them first.

use std::os::fd::{AsFd, OwnedFd};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use buslab_can::Frame;
use buslab_slcan::{Adapter, AdapterEvent, Command, STANDARD_BITRATES, Timing, parse_command};
use nix::poll::{PollFd, PollFlags, PollTimeout, poll};
use nix::sys::termios;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Lawicel,
    Canable,
    CanableAcking,
    Canable2Fork,
    Model,
}

pub const ALL: [Kind; 5] = [
    Kind::Lawicel,
    Kind::Canable,
    Kind::CanableAcking,
    Kind::Canable2Fork,
    Kind::Model,
];

pub const CANABLE_VERSION: &str = "8ca5d39 https://github.com/normaldotcom/canable-fw.git";
pub const FORK_VERSION: &str = "VL2K0 v2.0.0-16-g1a2b3c4 github.com/Nakakiyo092/canable2-fw.git";

/// What the fake did, for the test to check.
#[derive(Debug, Default)]
pub struct Seen {
    /// Every line the host sent, as text.
    pub lines: Vec<String>,
    /// Frames put on the bus (can-utils syntax).
    pub transmitted: Vec<String>,
    pub open: bool,
    /// CANable's silent mode (`M1`), or Lawicel's `L`.
    pub silent: bool,
    /// The last `S` code set.
    pub bitrate_code: Option<u8>,
}

struct Firmware {
    kind: Kind,
    line: Vec<u8>,
    /// CANable: the command an empty line runs again.
    previous: Vec<u8>,
    model: Adapter,
    seen: Seen,
    /// Output held back until the host writes again.
    held: Vec<u8>,
    /// Hold the answer to every `C` until the host writes again.
    hold_close: bool,
    /// Write each answer on its own, a little apart, as a USB adapter sends them in separate
    /// packets (the host then reads them one by one).
    paced: bool,
}

impl Firmware {
    /// One byte from the host; the answer to a line it ends.
    fn byte(&mut self, b: u8, out: &mut Vec<u8>) {
        if self.kind == Kind::Model {
            self.model.receive(&[b]);
            while let Some(event) = self.model.poll_event() {
                match event {
                    AdapterEvent::Opened {
                        listen_only,
                        timing,
                        ..
                    } => {
                        self.seen.open = true;
                        self.seen.silent = listen_only;
                        if let Some(Timing::Bitrate(rate)) = timing {
                            self.seen.bitrate_code = STANDARD_BITRATES
                                .iter()
                                .position(|&r| r == rate)
                                .map(|i| i as u8);
                        }
                    }
                    AdapterEvent::Closed => self.seen.open = false,
                    AdapterEvent::Transmit(f) => self.seen.transmitted.push(f.to_string()),
                    AdapterEvent::TransmitFd(f) => self.seen.transmitted.push(f.to_string()),
                    _ => {}
                }
            }
            let answer = self.model.take_output();
            if b == b'\r' {
                let line = std::mem::take(&mut self.line);
                self.seen
                    .lines
                    .push(String::from_utf8_lossy(&line).into_owned());
                self.answered(&line, answer, out);
            } else {
                self.line.push(b);
                out.extend(answer);
            }
            return;
        }
        if b != b'\r' {
            if self.line.len() < 64 {
                self.line.push(b);
            }
            return;
        }
        let line = std::mem::take(&mut self.line);
        self.seen
            .lines
            .push(String::from_utf8_lossy(&line).into_owned());
        let mut answer = Vec::new();
        match self.kind {
            Kind::Lawicel => self.lawicel(&line, &mut answer),
            Kind::Canable | Kind::CanableAcking => {
                // The firmware parses its buffer as it stands: an empty line finds the
                // previous command there.
                let run = if line.is_empty() {
                    self.previous.clone()
                } else {
                    line.clone()
                };
                self.previous = run.clone();
                let ok = self.canable(&run, &mut answer);
                if self.kind == Kind::CanableAcking {
                    answer.push(if ok { b'\r' } else { 0x07 });
                }
            }
            Kind::Canable2Fork => self.fork(&line, &mut answer),
            Kind::Model => unreachable!(),
        }
        self.answered(&line, answer, out);
    }

    fn answered(&mut self, line: &[u8], answer: Vec<u8>, out: &mut Vec<u8>) {
        if self.hold_close && line == b"C" {
            // A frame received before the close, queued before the answer to C; the next
            // session reads them.
            self.held.extend_from_slice(b"t1232AABB\r");
            self.held.extend(answer);
        } else {
            out.extend(answer);
        }
    }

    /// A frame for the bus: its answer (`z`/`Z` CR), or `None` when refused (closed, silent).
    fn transmit(&mut self, frame: Frame) -> Option<&'static [u8]> {
        if !self.seen.open || self.seen.silent {
            return None;
        }
        self.seen.transmitted.push(frame.to_string());
        Some(if frame.is_extended() { b"Z\r" } else { b"z\r" })
    }

    fn lawicel(&mut self, line: &[u8], out: &mut Vec<u8>) {
        let open = self.seen.open;
        let ok = match parse_command(line) {
            Ok(Command::Close) if open => {
                self.seen.open = false;
                true
            }
            Ok(Command::Bitrate(code)) if !open => {
                self.seen.bitrate_code = Some(code);
                true
            }
            Ok(Command::Btr { .. }) => !open,
            Ok(Command::Open | Command::ListenOnly) if !open => {
                self.seen.open = true;
                self.seen.silent = line == b"L";
                true
            }
            Ok(Command::Timestamps(_)) => true,
            Ok(Command::Version) => {
                out.extend_from_slice(b"V1013\r");
                return;
            }
            Ok(Command::SerialNumber) => {
                out.extend_from_slice(b"NA123\r");
                return;
            }
            Ok(Command::Status) if open => {
                out.extend_from_slice(b"F00\r");
                return;
            }
            Ok(Command::Transmit(frame)) => match self.transmit(frame) {
                Some(answer) => {
                    out.extend_from_slice(answer);
                    return;
                }
                None => false,
            },
            _ => false,
        };
        out.push(if ok { b'\r' } else { 0x07 });
    }

    /// Runs a line as CANable's firmware does; whether it "succeeded".
    fn canable(&mut self, line: &[u8], out: &mut Vec<u8>) -> bool {
        let Some((&letter, arg)) = line.split_first() else {
            return false;
        };
        match letter {
            b'O' => self.seen.open = true,
            b'C' => self.seen.open = false,
            b'S' => match arg.first() {
                Some(d @ b'0'..=b'8') => self.seen.bitrate_code = Some(d - b'0'),
                _ => return false,
            },
            b'M' | b'm' => self.seen.silent = arg.first() == Some(&b'1'),
            b'A' | b'a' => {}
            b'V' | b'v' => {
                out.extend_from_slice(CANABLE_VERSION.as_bytes());
                out.push(b'\r');
            }
            b't' | b'T' | b'r' | b'R' => {
                // can_tx() puts it in the queue whatever the channel's state; the parser
                // accepts it.
                if let Ok(Command::Transmit(frame)) = parse_command(line)
                    && self.seen.open
                    && !self.seen.silent
                {
                    self.seen.transmitted.push(frame.to_string());
                }
            }
            _ => return false,
        }
        true
    }

    fn fork(&mut self, line: &[u8], out: &mut Vec<u8>) {
        let open = self.seen.open;
        let ok = match parse_command(line) {
            Ok(Command::Empty) => true,
            Ok(Command::Open | Command::ListenOnly) => {
                self.seen.open = true;
                self.seen.silent = line == b"L";
                true
            }
            Ok(Command::Close) => {
                self.seen.open = false;
                true
            }
            Ok(Command::Bitrate(code)) if !open => {
                self.seen.bitrate_code = Some(code);
                true
            }
            Ok(Command::Timestamps(_)) => !open,
            Ok(Command::Version) => {
                out.extend_from_slice(FORK_VERSION.as_bytes());
                out.push(b'\r');
                return;
            }
            Ok(Command::SerialNumber) => {
                out.extend_from_slice(b"N1A2B\r");
                return;
            }
            Ok(Command::Status) if open => {
                out.extend_from_slice(b"F00\r");
                return;
            }
            Ok(Command::Transmit(frame)) => match self.transmit(frame) {
                Some(answer) => {
                    out.extend_from_slice(answer);
                    return;
                }
                None => false,
            },
            _ => false,
        };
        out.push(if ok { b'\r' } else { 0x07 });
    }
}

/// A fake adapter on a PTY; the test holds the PTY's slave open, as a plugged-in adapter
/// stays plugged in between sessions.
pub struct FakeAdapter {
    path: PathBuf,
    firmware: Arc<Mutex<Firmware>>,
    master: Arc<OwnedFd>,
    _slave: OwnedFd,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl FakeAdapter {
    pub fn start(kind: Kind) -> Self {
        let pty = nix::pty::openpty(None, None).expect("openpty");
        let mut attrs = termios::tcgetattr(&pty.slave).unwrap();
        termios::cfmakeraw(&mut attrs);
        termios::tcsetattr(&pty.slave, termios::SetArg::TCSANOW, &attrs).unwrap();
        let path = nix::unistd::ttyname(&pty.slave).expect("ttyname");
        let firmware = Arc::new(Mutex::new(Firmware {
            kind,
            line: Vec::new(),
            previous: Vec::new(),
            model: Adapter::default(),
            seen: Seen::default(),
            held: Vec::new(),
            hold_close: false,
            paced: false,
        }));
        let master = Arc::new(pty.master);
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (firmware, master, stop) = (firmware.clone(), master.clone(), stop.clone());
            std::thread::spawn(move || serve(&master, &firmware, &stop))
        };
        Self {
            path,
            firmware,
            master,
            _slave: pty.slave,
            stop,
            thread: Some(thread),
        }
    }

    pub fn path(&self) -> &str {
        self.path.to_str().unwrap()
    }

    /// Holds the answer to every `C` (and a frame before it) until the host writes again:
    /// the session that closes the channel leaves them for the next one.
    pub fn hold_close_answers(&self) {
        self.firmware.lock().unwrap().hold_close = true;
    }

    /// The model speaks CAN FD (a CANable 2.0's kind) from now on.
    #[allow(dead_code)] // not every test file has an FD adapter
    pub fn speak_fd(&self) {
        let mut fw = self.firmware.lock().unwrap();
        assert_eq!(fw.kind, Kind::Model, "only the model speaks FD");
        fw.model = Adapter::default().with_fd(true);
    }

    /// Each answer written on its own, a millisecond apart.
    pub fn pace_answers(&self, paced: bool) {
        self.firmware.lock().unwrap().paced = paced;
    }

    /// Bytes the firmware got before this session (a half-typed line, a previous command).
    pub fn already_typed(&self, bytes: &[u8]) {
        let mut fw = self.firmware.lock().unwrap();
        let mut ignored = Vec::new();
        for &b in bytes {
            fw.byte(b, &mut ignored);
        }
        fw.seen.lines.clear();
        fw.seen.transmitted.clear();
        fw.held.clear();
    }

    /// A frame from the bus, printed to the host if the channel is open.
    pub fn deliver(&self, line: &str) {
        let open = self.firmware.lock().unwrap().seen.open;
        if open {
            write_all(&self.master, format!("{line}\r").as_bytes());
        }
    }

    pub fn seen<T>(&self, f: impl FnOnce(&Seen) -> T) -> T {
        f(&self.firmware.lock().unwrap().seen)
    }

    /// Waits until what the fake saw satisfies `done` (it works through the host's bytes in
    /// its own thread); panics after `deadline` with what it saw.
    pub fn wait_for(&self, deadline: std::time::Duration, done: impl Fn(&Seen) -> bool) {
        let end = std::time::Instant::now() + deadline;
        loop {
            if self.seen(&done) {
                return;
            }
            if std::time::Instant::now() > end {
                panic!(
                    "the fake adapter never got there: {:?}",
                    self.seen(|s| format!("{s:?}"))
                );
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
    }
}

impl Drop for FakeAdapter {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn write_all(fd: &OwnedFd, mut bytes: &[u8]) {
    while !bytes.is_empty() {
        match nix::unistd::write(fd, bytes) {
            Ok(n) => bytes = &bytes[n..],
            Err(nix::errno::Errno::EAGAIN | nix::errno::Errno::EINTR) => std::thread::yield_now(),
            Err(e) => panic!("writing to the PTY: {e}"),
        }
    }
}

fn serve(master: &OwnedFd, firmware: &Mutex<Firmware>, stop: &AtomicBool) {
    let mut buf = [0u8; 1024];
    while !stop.load(Ordering::SeqCst) {
        let mut fds = [PollFd::new(master.as_fd(), PollFlags::POLLIN)];
        match poll(&mut fds, PollTimeout::from(50u8)) {
            Ok(0) | Err(nix::errno::Errno::EINTR) => continue,
            Ok(_) => {}
            Err(e) => panic!("poll: {e}"),
        }
        let n = match nix::unistd::read(master, &mut buf) {
            Ok(0) | Err(nix::errno::Errno::EAGAIN | nix::errno::Errno::EINTR) => continue,
            // Nobody has the slave open: not while the test holds it.
            Err(nix::errno::Errno::EIO) => continue,
            Ok(n) => n,
            Err(e) => panic!("read: {e}"),
        };
        let mut out = Vec::new();
        for &b in &buf[..n] {
            let paced = {
                let mut fw = firmware.lock().unwrap();
                // Whatever was held goes out before anything the host's next byte causes.
                if fw.paced && !fw.held.is_empty() {
                    write_all(master, &std::mem::take(&mut fw.held));
                    std::thread::sleep(std::time::Duration::from_millis(1));
                }
                out.append(&mut fw.held);
                fw.byte(b, &mut out);
                fw.paced
            };
            if paced && !out.is_empty() {
                write_all(master, &std::mem::take(&mut out));
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
        }
        write_all(master, &out);
    }
}
