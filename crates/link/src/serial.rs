//! Opening a serial port (or the slave side of a PTY) as a host tool does.

use std::io::{self, Read, Write};
use std::os::fd::{AsRawFd, BorrowedFd};
use std::path::Path;
use std::time::{Duration, Instant};

use buslab_device::{Human, LineSettings, Parity, Port};
use nix::fcntl::{FcntlArg, FdFlag, fcntl};
use serialport::{ClearBuffer, DataBits, FlowControl, SerialPort, StopBits, TTYPort};

/// Why a serial port could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum SerialError {
    #[error("cannot open serial port {path}: {source}")]
    Open {
        path: String,
        source: serialport::Error,
    },
    #[error("{data_bits} data bits are not supported; use 5, 6, 7 or 8")]
    DataBits { data_bits: u8 },
    #[error("{stop_bits} stop bits are not supported; use 1 or 2")]
    StopBits { stop_bits: u8 },
    #[error(
        "serial port {path} stayed in use by another program for {} (one client at a time: \
         stop the other one, or give a longer --timeout)",
        Human(*waited)
    )]
    Busy { path: String, waited: Duration },
}

/// How often a client waiting for a port held by another client tries again.
const BUSY_RETRY: Duration = Duration::from_millis(50);

/// Opens `path` with the given line settings, no flow control, and `timeout` for reads.
pub fn open_serial(
    path: &Path,
    line: LineSettings,
    timeout: Duration,
) -> Result<Box<dyn SerialPort>, SerialError> {
    Ok(Box::new(open_tty(path, line, timeout)?))
}

/// [`open_serial`], as the Unix port type (for a client that wants its descriptor: the SLCAN
/// host's `select`-free reads, `ClearBuffer`). Not inherited by child processes: one started
/// meanwhile would keep the port (and its exclusive lock) after it is closed here.
pub fn open_tty(
    path: &Path,
    line: LineSettings,
    timeout: Duration,
) -> Result<TTYPort, SerialError> {
    let data_bits = match line.data_bits {
        5 => DataBits::Five,
        6 => DataBits::Six,
        7 => DataBits::Seven,
        8 => DataBits::Eight,
        other => return Err(SerialError::DataBits { data_bits: other }),
    };
    let stop_bits = match line.stop_bits {
        1 => StopBits::One,
        2 => StopBits::Two,
        other => return Err(SerialError::StopBits { stop_bits: other }),
    };
    let parity = match line.parity {
        Parity::None => serialport::Parity::None,
        Parity::Even => serialport::Parity::Even,
        Parity::Odd => serialport::Parity::Odd,
    };
    let open_error = |source| SerialError::Open {
        path: path.display().to_string(),
        source,
    };
    let port = serialport::new(path.to_string_lossy(), line.baud)
        .data_bits(data_bits)
        .stop_bits(stop_bits)
        .parity(parity)
        .flow_control(FlowControl::None)
        .timeout(timeout)
        .open_native()
        .map_err(open_error)?;
    // serialport leaves the descriptor inheritable: a child process started meanwhile would
    // keep the port (and its exclusive lock) after we close it.
    fcntl(tty_fd(&port), FcntlArg::F_SETFD(FdFlag::FD_CLOEXEC))
        .map_err(|errno| open_error(serialport::Error::from(std::io::Error::from(errno))))?;
    Ok(port)
}

/// The descriptor of `port`, borrowed for as long as the port (serialport's Unix port has no
/// `AsFd`): to poll it beside others ([`crate::wait_readable`]).
pub fn tty_fd(port: &TTYPort) -> BorrowedFd<'_> {
    // SAFETY: the descriptor is owned by `port`, open until it drops, and the borrow cannot
    // outlive `port`.
    unsafe { BorrowedFd::borrow_raw(port.as_raw_fd()) }
}

/// A serial port (or the slave side of a PTY) as the [`Port`] host clients talk through,
/// keeping time by the wall clock.
pub struct SerialLine {
    port: Box<dyn SerialPort>,
    line: LineSettings,
    epoch: Instant,
}

impl SerialLine {
    /// Opens `path` at `line`, no flow control.
    pub fn open(path: &Path, line: LineSettings) -> Result<Self, SerialError> {
        Ok(Self {
            port: open_serial(path, line, Duration::from_millis(100))?,
            line,
            epoch: Instant::now(),
        })
    }

    /// Opens `path` as [`open`](Self::open) does; while another client holds the port (its
    /// exclusive lock: a dashboard reading the device, a second terminal), waits up to
    /// `patience` for it to let go.
    pub fn open_when_free(
        path: &Path,
        line: LineSettings,
        patience: Duration,
    ) -> Result<Self, SerialError> {
        let start = Instant::now();
        let mut said = false;
        loop {
            match Self::open(path, line) {
                // serialport reports the lock (EBUSY) as "no device"; the path being there
                // tells it from a device that is gone.
                Err(SerialError::Open { source, .. })
                    if source.kind() == serialport::ErrorKind::NoDevice && path.exists() =>
                {
                    let waited = start.elapsed();
                    if waited >= patience {
                        return Err(SerialError::Busy {
                            path: path.display().to_string(),
                            waited,
                        });
                    }
                    if !said {
                        tracing::info!("{} is in use; waiting for it", path.display());
                        said = true;
                    }
                    std::thread::sleep(BUSY_RETRY);
                }
                other => return other,
            }
        }
    }

    /// The settings the port was opened with.
    pub fn line(&self) -> LineSettings {
        self.line
    }
}

impl Port for SerialLine {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.write_all(bytes)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        self.port.set_timeout(timeout).map_err(io::Error::from)?;
        loop {
            match self.port.read(buf) {
                Err(e) if e.kind() == io::ErrorKind::TimedOut => return Ok(0),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                other => return other,
            }
        }
    }

    fn now(&self) -> Duration {
        self.epoch.elapsed()
    }

    fn pause(&mut self, duration: Duration) {
        std::thread::sleep(duration);
    }

    fn drain(&mut self) -> io::Result<()> {
        // serialport's flush waits for the output queue to empty (tcdrain).
        self.port.flush()
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.port.clear(ClearBuffer::Input).map_err(io::Error::from)
    }
}
