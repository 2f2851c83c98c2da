//! A pseudo-terminal for a device model: the model holds the master side, any serial program
//! opens the slave path (`/dev/pts/N`, or a symlink to it) as if it were the device's port.
//!
//! Two things a real port's owner learns from its line the master side also tells: a client
//! opened the port (an inotify watch on the slave path: the device may greet a terminal that
//! arrives late), and a client threw away what the device sent before it read it (`tcflush`,
//! as terminal programs do when they start; the master then runs in packet mode, where the
//! kernel reports such a flush): the device's output never reached the client.

use std::fs::{File, OpenOptions};
use std::io;
use std::os::fd::{AsFd, AsRawFd, BorrowedFd};
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use nix::fcntl::{FcntlArg, OFlag, fcntl};
use nix::pty::{PtyMaster, grantpt, posix_openpt, ptsname_r, unlockpt};
use nix::sys::inotify::{AddWatchFlags, InitFlags, Inotify};
use nix::sys::termios::{self, SetArg};

use buslab_device::{LineSettings, Parity};

/// What Linux's pseudo-terminal hands over in one read at most (its line discipline's buffer,
/// `N_TTY_BUF_SIZE` 4096, keeps one byte free), plus packet mode's status byte.
const PACKET_MAX: usize = 4096;

/// Packet mode's status bytes (Linux `<asm-generic/ioctls.h>`; the libc crate lacks them): a
/// packet of data, and the slave's input queue flushed.
const TIOCPKT_DATA: u8 = 0;
const TIOCPKT_FLUSHREAD: u8 = 1;

/// The master side of a pseudo-terminal, non-blocking.
pub struct Pty {
    master: PtyMaster,
    /// Kept open so the master never reads EIO while no client has the port open.
    _slave: File,
    path: PathBuf,
    link: Option<PathBuf>,
    /// Opens of the slave path; `None` where inotify is not available (its limits reached):
    /// the device is then not told of a client's arrival.
    opens: Option<Inotify>,
    /// The master is in packet mode ([`report_flushes`](Pty::report_flushes)).
    packet: AtomicBool,
    /// The kernel reported that the client flushed what it had not read yet.
    flushed: AtomicBool,
}

impl Pty {
    /// Opens a new pseudo-terminal in raw mode (no echo, no line editing, 8 bits).
    pub fn open() -> io::Result<Self> {
        // Close-on-exec: a child process must not keep the device's side of the line open.
        let master = posix_openpt(OFlag::O_RDWR | OFlag::O_NOCTTY | OFlag::O_CLOEXEC)?;
        grantpt(&master)?;
        unlockpt(&master)?;
        let path = PathBuf::from(ptsname_r(&master)?);
        let slave = OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_NOCTTY)
            .open(&path)?;
        let mut attrs = termios::tcgetattr(&slave)?;
        termios::cfmakeraw(&mut attrs);
        termios::tcsetattr(&slave, SetArg::TCSANOW, &attrs)?;
        let flags = OFlag::from_bits_truncate(fcntl(&master, FcntlArg::F_GETFL)?);
        fcntl(&master, FcntlArg::F_SETFL(flags | OFlag::O_NONBLOCK))?;
        // After our own open of the slave: only clients' opens are seen.
        let opens = watch_opens(&path)
            .inspect_err(|e| {
                tracing::warn!(
                    "{}: cannot watch for clients opening the port ({e}); a device that \
                     draws a screen will not redraw it for a terminal opened late",
                    path.display()
                )
            })
            .ok();
        Ok(Self {
            master,
            _slave: slave,
            path,
            link: None,
            opens,
            packet: AtomicBool::new(false),
            flushed: AtomicBool::new(false),
        })
    }

    /// The slave device path clients open, e.g. `/dev/pts/3`.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Makes `link` a symlink to the slave path (replacing an old symlink there); it is removed
    /// when the `Pty` is dropped, unless it points elsewhere by then. Refuses to replace
    /// anything that is not a symlink.
    pub fn link_at(&mut self, link: &Path) -> io::Result<()> {
        match std::fs::symlink_metadata(link) {
            Ok(meta) if meta.file_type().is_symlink() => std::fs::remove_file(link)?,
            Ok(_) => {
                return Err(io::Error::new(
                    io::ErrorKind::AlreadyExists,
                    format!(
                        "{} exists and is not a symlink; not replacing it",
                        link.display()
                    ),
                ));
            }
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(e) => return Err(e),
        }
        std::os::unix::fs::symlink(&self.path, link)?;
        self.link = Some(link.to_path_buf());
        Ok(())
    }

    /// The line settings the client last set on its side (baud rate, data bits, parity, stop
    /// bits). On Linux the master sees the slave's termios.
    pub fn peer_settings(&self) -> io::Result<LineSettings> {
        peer_settings(self.master.as_fd())
    }

    /// From now on the kernel reports when the client flushes its input
    /// ([`take_flushed`](Pty::take_flushed)): the master runs in packet mode, which only
    /// [`read`](Pty::read) understands (not a raw `read` of the file descriptor).
    pub fn report_flushes(&self) -> io::Result<()> {
        set_packet_mode(self.master.as_fd())?;
        self.packet.store(true, Ordering::Relaxed);
        Ok(())
    }

    /// Reads what the client wrote (in packet mode at most 4095 bytes at once, the line
    /// discipline's buffer); `Ok(0)` or `WouldBlock` when nothing is waiting. A flush the
    /// kernel reports on the way is noted for [`take_flushed`](Pty::take_flushed).
    pub fn read(&self, buf: &mut [u8]) -> io::Result<usize> {
        if !self.packet.load(Ordering::Relaxed) {
            return nix::unistd::read(&self.master, buf).map_err(io::Error::from);
        }
        let mut packet = [0u8; PACKET_MAX];
        let want = buf.len().min(PACKET_MAX - 1) + 1;
        loop {
            let n =
                nix::unistd::read(&self.master, &mut packet[..want]).map_err(io::Error::from)?;
            let Some((&status, data)) = packet[..n].split_first() else {
                return Ok(0);
            };
            if status == TIOCPKT_DATA {
                buf[..data.len()].copy_from_slice(data);
                return Ok(data.len());
            }
            // A status packet carries no data; the data (if any) comes in the next read.
            if status & TIOCPKT_FLUSHREAD != 0 {
                self.flushed.store(true, Ordering::Relaxed);
            }
        }
    }

    /// Whether the client threw away bytes sent to it before reading them (`tcflush` of its
    /// input, as `screen` and `picocom` do when they start) since the last call: they never
    /// reached it. Never before [`report_flushes`](Pty::report_flushes).
    pub fn take_flushed(&self) -> bool {
        self.flushed.swap(false, Ordering::Relaxed)
    }

    /// Whether a client opened the port since the last call (never, where it cannot be
    /// watched).
    pub fn take_opened(&self) -> bool {
        let Some(opens) = &self.opens else {
            return false;
        };
        let mut opened = false;
        // Non-blocking: EAGAIN once every waiting event is read.
        while let Ok(events) = opens.read_events() {
            opened |= events
                .iter()
                .any(|e| e.mask.contains(AddWatchFlags::IN_OPEN));
            if events.is_empty() {
                break;
            }
        }
        opened
    }

    /// What becomes readable when a client opens the port, for `poll` beside the master.
    pub fn opens_fd(&self) -> Option<BorrowedFd<'_>> {
        self.opens.as_ref().map(|opens| opens.as_fd())
    }

    /// Writes toward the client; may write less than asked (non-blocking).
    pub fn write(&self, buf: &[u8]) -> io::Result<usize> {
        nix::unistd::write(&self.master, buf).map_err(io::Error::from)
    }
}

impl AsFd for Pty {
    fn as_fd(&self) -> BorrowedFd<'_> {
        self.master.as_fd()
    }
}

impl Drop for Pty {
    fn drop(&mut self) {
        // Only our own link: another server may have taken the name over meanwhile.
        if let Some(link) = &self.link
            && std::fs::read_link(link).is_ok_and(|to| to == self.path)
        {
            let _ = std::fs::remove_file(link);
        }
    }
}

/// Packet mode: the kernel tells the master when the slave flushes its queues.
#[allow(unsafe_code)]
fn set_packet_mode(fd: BorrowedFd<'_>) -> io::Result<()> {
    let on: libc::c_int = 1;
    // SAFETY: TIOCPKT reads an int we own; the fd is valid for the call.
    if unsafe { libc::ioctl(fd.as_raw_fd(), libc::TIOCPKT, &on) } != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

/// An inotify watch for opens of the slave device (through any link to it).
fn watch_opens(path: &Path) -> io::Result<Inotify> {
    let opens = Inotify::init(InitFlags::IN_NONBLOCK | InitFlags::IN_CLOEXEC)?;
    opens.add_watch(path, AddWatchFlags::IN_OPEN)?;
    Ok(opens)
}

/// Reads termios2 so rates outside the classic `Bxxx` set (31250, 250000) come back exactly.
#[allow(unsafe_code)]
fn peer_settings(fd: BorrowedFd<'_>) -> io::Result<LineSettings> {
    // SAFETY: TCGETS2 fills a `termios2` we own; the fd is valid for the call.
    let t = unsafe {
        let mut t: libc::termios2 = std::mem::zeroed();
        if libc::ioctl(fd.as_raw_fd(), libc::TCGETS2, &mut t) != 0 {
            return Err(io::Error::last_os_error());
        }
        t
    };
    let data_bits = match t.c_cflag & libc::CSIZE {
        libc::CS5 => 5,
        libc::CS6 => 6,
        libc::CS7 => 7,
        _ => 8,
    };
    let parity = if t.c_cflag & libc::PARENB == 0 {
        Parity::None
    } else if t.c_cflag & libc::PARODD != 0 {
        Parity::Odd
    } else {
        Parity::Even
    };
    Ok(LineSettings {
        baud: t.c_ospeed,
        data_bits,
        parity,
        stop_bits: if t.c_cflag & libc::CSTOPB != 0 { 2 } else { 1 },
    })
}
