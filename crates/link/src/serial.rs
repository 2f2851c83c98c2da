//! Opening a serial port (or the slave side of a PTY) as a host tool does.

use std::os::fd::{AsRawFd, BorrowedFd};
use std::path::Path;
use std::time::Duration;

use nix::fcntl::{FcntlArg, FdFlag, fcntl};
use serialport::{DataBits, FlowControl, SerialPort, StopBits};

use crate::{LineSettings, Parity};

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
}

/// Opens `path` with the given line settings, no flow control, and `timeout` for reads.
pub fn open_serial(
    path: &Path,
    line: LineSettings,
    timeout: Duration,
) -> Result<Box<dyn SerialPort>, SerialError> {
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
    // SAFETY: the descriptor is owned by `port`, which outlives this borrow.
    let fd = unsafe { BorrowedFd::borrow_raw(port.as_raw_fd()) };
    fcntl(fd, FcntlArg::F_SETFD(FdFlag::FD_CLOEXEC))
        .map_err(|errno| open_error(serialport::Error::from(std::io::Error::from(errno))))?;
    Ok(Box::new(port))
}
