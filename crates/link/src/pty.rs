//! A pseudo-terminal for a device model: the model holds the master side, any serial program
//! opens the slave path (`/dev/pts/N`, or a symlink to it) as if it were the device's port.

use std::fs::{File, OpenOptions};
use std::io;
use std::os::fd::{AsFd, AsRawFd, BorrowedFd};
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

use nix::fcntl::{FcntlArg, OFlag, fcntl};
use nix::pty::{PtyMaster, grantpt, posix_openpt, ptsname_r, unlockpt};
use nix::sys::termios::{self, SetArg};

use buslab_device::{LineSettings, Parity};

/// The master side of a pseudo-terminal, non-blocking.
pub struct Pty {
    master: PtyMaster,
    /// Kept open so the master never reads EIO while no client has the port open.
    _slave: File,
    path: PathBuf,
    link: Option<PathBuf>,
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
        Ok(Self {
            master,
            _slave: slave,
            path,
            link: None,
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

    /// Reads what the client wrote; `Ok(0)` or `WouldBlock` when nothing is waiting.
    pub fn read(&self, buf: &mut [u8]) -> io::Result<usize> {
        nix::unistd::read(&self.master, buf).map_err(io::Error::from)
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
