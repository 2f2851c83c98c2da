//! What the client needs from a serial line.

use std::io;
use std::time::Duration;

use serialport::{ClearBuffer, SerialPort};

/// A byte stream to a cell: a serial port, a pseudo-terminal, or a model in virtual time.
pub trait Port: io::Read + io::Write {
    /// How long a `read` waits for the first byte before failing with `TimedOut`.
    fn set_timeout(&mut self, timeout: Duration) -> io::Result<()>;

    /// Lets `duration` pass (a real port sleeps; a simulated one moves virtual time).
    fn pause(&mut self, duration: Duration) {
        std::thread::sleep(duration);
    }

    /// Waits until everything written has left the port.
    fn drain(&mut self) -> io::Result<()> {
        self.flush()
    }

    /// Throws away received bytes not read yet.
    fn discard_input(&mut self) -> io::Result<()>;
}

impl Port for Box<dyn SerialPort> {
    fn set_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        SerialPort::set_timeout(self.as_mut(), timeout).map_err(io::Error::from)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.clear(ClearBuffer::Input).map_err(io::Error::from)
    }
}

impl<P: Port + ?Sized> Port for &mut P {
    fn set_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        (**self).set_timeout(timeout)
    }

    fn pause(&mut self, duration: Duration) {
        (**self).pause(duration)
    }

    fn drain(&mut self) -> io::Result<()> {
        (**self).drain()
    }

    fn discard_input(&mut self) -> io::Result<()> {
        (**self).discard_input()
    }
}
