//! The host side of the seam: what a client needs from its line to a device.

use std::io;
use std::time::Duration;

/// A byte line to a device, with the clock the client keeps its time by: a serial port or a
/// pseudo-terminal (wall clock), or a model in virtual time ([`SimPort`](crate::SimPort)).
///
/// Clients never read the system clock or sleep themselves: they ask the port
/// ([`now`](Port::now), [`pause`](Port::pause), the `timeout` of [`recv`](Port::recv)), so the
/// same code runs against a device and, deterministically, against its model.
pub trait Port {
    /// Hands `bytes` to the line; returns once the port has taken all of them (they may still
    /// be on their way: see [`drain`](Port::drain)).
    fn send(&mut self, bytes: &[u8]) -> io::Result<()>;

    /// Waits at most `timeout` for bytes from the device and reads what is there; `Ok(0)` when
    /// nothing came in time, and then only once `timeout` has passed on the port's clock
    /// (clients loop on their deadline by [`now`](Port::now)).
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;

    /// The port's clock: it starts at an arbitrary point and only moves forward (the wall
    /// clock for a real port, the model's virtual time for a simulated one).
    fn now(&self) -> Duration;

    /// Lets `duration` pass on the port's clock (a real port sleeps; a simulated one moves
    /// virtual time, running the device meanwhile).
    fn pause(&mut self, duration: Duration);

    /// Waits until everything sent has left the port.
    fn drain(&mut self) -> io::Result<()>;

    /// Throws away received bytes not read yet.
    fn discard_input(&mut self) -> io::Result<()>;
}

impl<P: Port + ?Sized> Port for &mut P {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        (**self).send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        (**self).recv(buf, timeout)
    }
    fn now(&self) -> Duration {
        (**self).now()
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

impl<P: Port + ?Sized> Port for Box<P> {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        (**self).send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        (**self).recv(buf, timeout)
    }
    fn now(&self) -> Duration {
        (**self).now()
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
