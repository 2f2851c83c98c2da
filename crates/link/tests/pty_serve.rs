//! A toy device served on a real pseudo-terminal, driven through `open_serial` like a host tool.

use std::io::{Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use buslab_device::Nanos;
use buslab_link::{ByteDevice, Control, LineSettings, Pty, open_serial, serve};

/// How long a test waits for what must come: far above any scheduling delay on a loaded
/// machine (a wait ends as soon as the bytes are there). Waits for silence are shorter.
const ALLOWANCE: Duration = Duration::from_secs(30);

/// Answers every byte with byte + 1, each answer finishing one character time after the
/// request arrived; records arrival times.
#[derive(Default)]
struct Echo {
    byte_ns: Nanos,
    pending: Vec<(Nanos, u8)>,
    arrivals: Vec<Nanos>,
    offset: u8,
}

impl ByteDevice for Echo {
    fn receive(&mut self, now_ns: Nanos, byte: u8) {
        self.arrivals.push(now_ns);
        self.pending
            .push((now_ns + self.byte_ns, byte.wrapping_add(1 + self.offset)));
    }
    fn poll(&mut self, now_ns: Nanos, out: &mut Vec<u8>) {
        while let Some(&(at, byte)) = self.pending.first() {
            if at > now_ns {
                break;
            }
            out.push(byte);
            self.pending.remove(0);
        }
    }
    fn next_deadline(&self) -> Option<Nanos> {
        self.pending.first().map(|&(at, _)| at)
    }
}

struct Served {
    path: std::path::PathBuf,
    stop: Arc<AtomicBool>,
    control: mpsc::Sender<Control<Echo>>,
    thread: std::thread::JoinHandle<Echo>,
}

fn start(line: LineSettings) -> Served {
    let pty = Pty::open().unwrap();
    let path = pty.path().to_path_buf();
    let stop = Arc::new(AtomicBool::new(false));
    let (control, rx) = mpsc::channel();
    let flag = stop.clone();
    let thread = std::thread::spawn(move || {
        let mut dev = Echo {
            byte_ns: line.byte_time(),
            ..Echo::default()
        };
        serve(&mut dev, &pty, line, &rx, &flag).unwrap();
        dev
    });
    Served {
        path,
        stop,
        control,
        thread,
    }
}

fn read_exact(port: &mut dyn Read, n: usize) -> Vec<u8> {
    let mut got = vec![0; n];
    port.read_exact(&mut got).unwrap();
    got
}

#[test]
fn bytes_cross_the_pty_paced_at_the_line_rate() {
    let line = LineSettings::n82(115_200);
    let served = start(line);
    let mut port = open_serial(&served.path, line, ALLOWANCE).unwrap();
    port.write_all(&[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    assert_eq!(read_exact(&mut port, 8), [2, 3, 4, 5, 6, 7, 8, 9]);

    // Control work runs on the device between steps; the byte goes once it has run.
    let (ran, done) = mpsc::channel();
    served
        .control
        .send(Box::new(move |dev: &mut Echo, _now| {
            dev.offset = 10;
            let _ = ran.send(());
        }))
        .unwrap();
    done.recv_timeout(ALLOWANCE).unwrap();
    port.write_all(&[1]).unwrap();
    assert_eq!(read_exact(&mut port, 1), [12]);

    served.stop.store(true, Ordering::Relaxed);
    let dev = served.thread.join().unwrap();
    // The burst of 8 arrived no faster than the line allows: one character time apart, the
    // first one a whole character after the serve loop started (nothing arrives instantly).
    assert!(dev.arrivals[0] >= line.byte_time());
    let gaps: Vec<Nanos> = dev.arrivals[..8].windows(2).map(|w| w[1] - w[0]).collect();
    assert!(
        gaps.iter().all(|&g| g >= line.byte_time()),
        "arrival gaps {gaps:?} shorter than {} ns",
        line.byte_time()
    );
}

#[test]
fn a_client_at_the_wrong_baud_rate_is_not_understood() {
    let served = start(LineSettings::n82(9600));
    let mut port = open_serial(
        &served.path,
        LineSettings::n81(19_200),
        Duration::from_millis(300),
    )
    .unwrap();
    port.write_all(&[1, 2, 3]).unwrap();
    let mut buf = [0u8; 4];
    let err = port.read(&mut buf).unwrap_err();
    assert_eq!(err.kind(), std::io::ErrorKind::TimedOut);
    served.stop.store(true, Ordering::Relaxed);
    assert!(served.thread.join().unwrap().arrivals.is_empty());
}

#[test]
fn the_pty_reports_what_the_client_set_even_nonstandard_rates() {
    let pty = Pty::open().unwrap();
    let _port = open_serial(pty.path(), LineSettings::n82(250_000), ALLOWANCE).unwrap();
    assert_eq!(pty.peer_settings().unwrap(), LineSettings::n82(250_000));
}

#[test]
fn link_at_makes_and_removes_a_symlink_and_never_replaces_a_file() {
    let dir = std::env::temp_dir().join(format!("buslab-link-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("ttyZELLE");
    {
        let mut pty = Pty::open().unwrap();
        pty.link_at(&link).unwrap();
        assert_eq!(std::fs::read_link(&link).unwrap(), pty.path());
    }
    assert!(std::fs::symlink_metadata(&link).is_err());
    // A second server takes the name over: the first one leaves it alone when it ends.
    {
        let mut first = Pty::open().unwrap();
        first.link_at(&link).unwrap();
        let mut second = Pty::open().unwrap();
        second.link_at(&link).unwrap();
        drop(first);
        assert_eq!(std::fs::read_link(&link).unwrap(), second.path());
    }
    assert!(std::fs::symlink_metadata(&link).is_err());
    let file = dir.join("plain");
    std::fs::write(&file, b"keep me").unwrap();
    let mut pty = Pty::open().unwrap();
    assert!(pty.link_at(&file).is_err());
    assert_eq!(std::fs::read(&file).unwrap(), b"keep me");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn ports_and_ptys_are_not_inherited_by_child_processes() {
    let pty = Pty::open().unwrap();
    let _port = open_serial(pty.path(), LineSettings::n81(9600), Duration::from_secs(1)).unwrap();
    let mut checked = 0;
    for entry in std::fs::read_dir("/proc/self/fd").unwrap() {
        let entry = entry.unwrap();
        let Ok(fd) = entry.file_name().to_string_lossy().parse::<i32>() else {
            continue;
        };
        let Ok(target) = std::fs::read_link(entry.path()) else {
            continue; // closed meanwhile by another test
        };
        let target = target.to_string_lossy();
        if fd <= 2 || !(target.starts_with("/dev/pts/") || target == "/dev/ptmx") {
            continue;
        }
        // SAFETY: only queried; an fd closed meanwhile just gives EBADF.
        let flags = nix::fcntl::fcntl(
            unsafe { std::os::fd::BorrowedFd::borrow_raw(fd) },
            nix::fcntl::FcntlArg::F_GETFD,
        );
        if let Ok(flags) = flags {
            assert_ne!(
                flags & libc::FD_CLOEXEC,
                0,
                "fd {fd} ({target}) is inheritable"
            );
            checked += 1;
        }
    }
    assert!(
        checked >= 3,
        "expected master, kept slave and port; saw {checked}"
    );
}

/// Wants a look every `period_ns` and counts how often it is polled.
struct Ticker {
    period_ns: Nanos,
    next: Nanos,
    polls: u64,
    last_now: Nanos,
}

impl ByteDevice for Ticker {
    fn receive(&mut self, _now_ns: Nanos, _byte: u8) {}
    fn poll(&mut self, now_ns: Nanos, _out: &mut Vec<u8>) {
        self.polls += 1;
        self.last_now = now_ns;
        while self.next <= now_ns {
            self.next += self.period_ns;
        }
    }
    fn next_deadline(&self) -> Option<Nanos> {
        Some(self.next)
    }
}

#[test]
fn deadlines_shorter_than_a_millisecond_are_slept_not_spun() {
    // 700 µs between deadlines (a byte at 115200 baud is 87 µs): a poll timeout in whole
    // milliseconds would round each wait down to 0 and spin the loop at 100 % CPU.
    let pty = Pty::open().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let (_control, rx) = mpsc::channel::<Control<Ticker>>();
    let flag = stop.clone();
    let thread = std::thread::spawn(move || {
        let mut dev = Ticker {
            period_ns: Nanos::new(700_000),
            next: Nanos::new(700_000),
            polls: 0,
            last_now: Nanos::ZERO,
        };
        serve(&mut dev, &pty, LineSettings::n81(115_200), &rx, &flag).unwrap();
        dev
    });
    std::thread::sleep(Duration::from_millis(300));
    stop.store(true, Ordering::Relaxed);
    let dev = thread.join().unwrap();
    let deadlines = dev.last_now / dev.period_ns;
    assert!(
        dev.polls <= 2 * deadlines + 20,
        "{} polls for {deadlines} deadlines: the loop spins",
        dev.polls
    );
}

#[test]
fn a_client_writing_faster_than_the_line_is_held_back() {
    // 1 MiB takes 91 s at 115200 8N1: the serve loop must not swallow it at once (it would
    // pile up in memory; `cat /dev/zero > PTY` grew it by gigabytes), the writer must wait.
    let line = LineSettings::n81(115_200);
    let served = start(line);
    // A blocked write must stay blocked (not time out) until the server goes.
    let mut port = open_serial(&served.path, line, ALLOWANCE).unwrap();
    let (done_tx, done) = mpsc::channel();
    let writer = std::thread::spawn(move || {
        let result = port.write_all(&vec![0u8; 1 << 20]);
        let _ = done_tx.send(());
        result
    });
    assert_eq!(
        done.recv_timeout(Duration::from_secs(1)),
        Err(mpsc::RecvTimeoutError::Timeout),
        "1 MiB went into the PTY at once"
    );
    served.stop.store(true, Ordering::Relaxed);
    served.thread.join().unwrap();
    // The master is gone: the blocked write fails now.
    assert!(writer.join().unwrap().is_err());
}

#[test]
fn a_client_at_the_wrong_rate_cannot_outrun_the_line_either() {
    // Its bytes are framing errors, but they still take line time: before, the server read
    // and dropped them as fast as the client wrote (hundreds of MB/s, a core busy).
    let served = start(LineSettings::n82(9600));
    let mut port = open_serial(&served.path, LineSettings::n81(19_200), ALLOWANCE).unwrap();
    let (done_tx, done) = mpsc::channel();
    let writer = std::thread::spawn(move || {
        let result = port.write_all(&vec![0x55u8; 1 << 20]);
        let _ = done_tx.send(());
        result
    });
    assert_eq!(
        done.recv_timeout(Duration::from_secs(1)),
        Err(mpsc::RecvTimeoutError::Timeout),
        "1 MiB at the wrong rate went into the PTY at once"
    );
    served.stop.store(true, Ordering::Relaxed);
    assert!(served.thread.join().unwrap().arrivals.is_empty());
    assert!(writer.join().unwrap().is_err());
}

/// Sends `len` bytes as soon as it is first polled.
struct Flood {
    len: usize,
}

impl ByteDevice for Flood {
    fn receive(&mut self, _now_ns: Nanos, _byte: u8) {}
    fn poll(&mut self, _now_ns: Nanos, out: &mut Vec<u8>) {
        out.resize(std::mem::take(&mut self.len), 0x55);
    }
    fn next_deadline(&self) -> Option<Nanos> {
        None
    }
}

#[test]
fn output_to_a_client_that_does_not_read_is_bounded() {
    let pty = Pty::open().unwrap();
    let path = pty.path().to_path_buf();
    let stop = Arc::new(AtomicBool::new(false));
    let (_control, rx) = mpsc::channel::<Control<Flood>>();
    let flag = stop.clone();
    let line = LineSettings::n81(115_200);
    let thread = std::thread::spawn(move || {
        let mut dev = Flood { len: 4 << 20 };
        serve(&mut dev, &pty, line, &rx, &flag).unwrap();
    });
    let mut port = open_serial(&path, line, ALLOWANCE).unwrap();
    let mut buf = [0u8; 65536];
    // The flood has begun once the first bytes are here; then read until it dries up.
    let mut total = port.read(&mut buf).unwrap();
    port.set_timeout(Duration::from_millis(300)).unwrap();
    loop {
        match port.read(&mut buf) {
            Ok(n) => total += n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => break,
            Err(e) => panic!("{e}"),
        }
    }
    stop.store(true, Ordering::Relaxed);
    thread.join().unwrap();
    assert!(total > 0);
    assert!(
        total < 1 << 20,
        "{total} bytes were kept for a client that did not read"
    );
}

/// A screen device: it sends its whole screen whenever a client opens the port or loses what
/// was sent to it, and tells the test each time.
struct Screen {
    heard: mpsc::Sender<&'static str>,
    out: Vec<u8>,
    /// Bytes handed to the line so far.
    sent: Arc<std::sync::atomic::AtomicUsize>,
}

impl ByteDevice for Screen {
    fn receive(&mut self, _now_ns: Nanos, _byte: u8) {}
    fn poll(&mut self, _now_ns: Nanos, out: &mut Vec<u8>) {
        if !self.out.is_empty() {
            self.sent.fetch_add(self.out.len(), Ordering::SeqCst);
            out.append(&mut self.out);
            let _ = self.heard.send("sent");
        }
    }
    fn next_deadline(&self) -> Option<Nanos> {
        None
    }
    fn output_lost(&mut self, _now_ns: Nanos) {
        self.out.extend_from_slice(b"[whole screen]");
        let _ = self.heard.send("lost");
    }
    fn port_opened(&mut self, _now_ns: Nanos) {
        self.out.extend_from_slice(b"[whole screen]");
        let _ = self.heard.send("opened");
    }
}

/// A terminal program's start, as screen and picocom do it: open, raw at the line's rate,
/// throw away what waits unread.
fn open_like_a_terminal(path: &std::path::Path) -> std::fs::File {
    use nix::sys::termios::{BaudRate, FlushArg, SetArg, cfmakeraw, cfsetspeed, tcflush};
    use std::os::fd::AsFd;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(path)
        .unwrap();
    let mut t = nix::sys::termios::tcgetattr(file.as_fd()).unwrap();
    cfmakeraw(&mut t);
    cfsetspeed(&mut t, BaudRate::B19200).unwrap();
    nix::sys::termios::tcsetattr(file.as_fd(), SetArg::TCSANOW, &t).unwrap();
    tcflush(file.as_fd(), FlushArg::TCIFLUSH).unwrap();
    file
}

/// Issue 28 (4): a terminal opened on the served MoniCAN port stayed blank until its user
/// pressed Ctrl L: the device never heard that a client had arrived, and the screen it had
/// sent before waited in the PTY, where the terminal program's start-up flush threw it away.
#[test]
fn a_client_opening_the_port_and_flushing_it_gets_the_whole_screen() {
    let pty = Pty::open().unwrap();
    let path = pty.path().to_path_buf();
    let stop = Arc::new(AtomicBool::new(false));
    let (control, rx) = mpsc::channel::<Control<Screen>>();
    let (heard_tx, heard) = mpsc::channel();
    let flag = stop.clone();
    let line = LineSettings::n81(19_200);
    let sent = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let device_sent = sent.clone();
    let thread = std::thread::spawn(move || {
        let mut dev = Screen {
            heard: heard_tx,
            out: Vec::new(),
            sent: device_sent,
        };
        serve(&mut dev, &pty, line, &rx, &flag).unwrap();
    });
    // Something on the screen before anyone looks: it waits in the PTY, unread.
    control
        .send(Box::new(|d: &mut Screen, _| {
            d.out.extend_from_slice(b"[stale update]")
        }))
        .unwrap();
    hear(&heard, "sent");
    let mut file = open_like_a_terminal(&path);
    // The open is heard. Whether the terminal's flush threw away the stale update alone or
    // the screen sent for the open too (then the flush is heard and the screen sent again),
    // the last thing the client gets is the whole screen.
    hear(&heard, "opened");
    read_until(&mut file, b"[whole screen]");
    // Later: an update sent, not read, then flushed by the client: the device hears it lost.
    const UPDATE: &[u8] = b"[update nobody read]";
    control
        .send(Box::new(|d: &mut Screen, _| {
            d.sent.store(0, Ordering::SeqCst);
            d.out.extend_from_slice(UPDATE)
        }))
        .unwrap();
    // Flushed once the update waits in the client's queue (what came before it may wait
    // there too: a second screen from the start).
    let start = std::time::Instant::now();
    while sent.load(Ordering::SeqCst) < UPDATE.len() || unread(&file) < UPDATE.len() {
        assert!(start.elapsed() < ALLOWANCE, "the update never came");
        std::thread::sleep(Duration::from_millis(1));
    }
    while heard.try_recv().is_ok() {}
    nix::sys::termios::tcflush(
        std::os::fd::AsFd::as_fd(&file),
        nix::sys::termios::FlushArg::TCIFLUSH,
    )
    .unwrap();
    hear(&heard, "lost");
    let got = String::from_utf8(read_until(&mut file, b"[whole screen]")).unwrap();
    assert!(!got.contains("[update nobody read]"), "{got}");
    stop.store(true, Ordering::Relaxed);
    thread.join().unwrap();
}

/// Waits for the device to tell `what`, skipping its other news; fails after the allowance.
fn hear(heard: &mpsc::Receiver<&'static str>, what: &str) {
    loop {
        match heard.recv_timeout(ALLOWANCE) {
            Ok(news) if news == what => return,
            Ok(_) => {}
            Err(e) => panic!("the device never told {what:?}: {e}"),
        }
    }
}

/// Bytes waiting unread in the client's input queue (`FIONREAD`).
#[allow(unsafe_code)]
fn unread(file: &std::fs::File) -> usize {
    use std::os::fd::AsRawFd;
    let mut n: libc::c_int = 0;
    // SAFETY: FIONREAD writes one int we own; the fd is open for the call.
    assert_eq!(
        unsafe { libc::ioctl(file.as_raw_fd(), libc::FIONREAD, &mut n) },
        0
    );
    n as usize
}

/// Whether `file` has something to read within the allowance.
fn readable(file: &std::fs::File) -> bool {
    use nix::poll::{PollFd, PollFlags, PollTimeout, poll};
    let mut fds = [PollFd::new(
        std::os::fd::AsFd::as_fd(file),
        PollFlags::POLLIN,
    )];
    poll(&mut fds, PollTimeout::try_from(ALLOWANCE).unwrap()).unwrap() > 0
}

/// What the client reads until it ends with `end`; fails if nothing more comes within the
/// allowance.
fn read_until(file: &mut std::fs::File, end: &[u8]) -> Vec<u8> {
    let mut got = Vec::new();
    let mut buf = [0u8; 256];
    while !got.ends_with(end) {
        assert!(
            readable(file),
            "{:?} never came; read {:?}",
            String::from_utf8_lossy(end),
            String::from_utf8_lossy(&got)
        );
        let n = file.read(&mut buf).unwrap();
        got.extend_from_slice(&buf[..n]);
    }
    got
}
