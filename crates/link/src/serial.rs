//! Opening a serial port (or the slave side of a PTY) as a host tool does.

use std::path::Path;
use std::time::Duration;

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
    serialport::new(path.to_string_lossy(), line.baud)
        .data_bits(data_bits)
        .stop_bits(stop_bits)
        .parity(parity)
        .flow_control(FlowControl::None)
        .timeout(timeout)
        .open()
        .map_err(|source| SerialError::Open {
            path: path.display().to_string(),
            source,
        })
}
