//! A port wired straight to a device model in virtual time, so a host client runs against the
//! model as fast as the CPU allows, with the line's exact timing.

use std::collections::VecDeque;
use std::io;
use std::time::Duration;

use buslab_can::Nanos;

use crate::{ByteDevice, LineSettings, Port};

/// The host end of a line to a model, in virtual time. Sends queue bytes on the line back to
/// back (as a UART does), each arriving one character time after the previous one; receiving
/// and pausing move time forward, running the device on the way.
///
/// The client's side may be set to other line settings
/// ([`with_client_line`](SimPort::with_client_line)): as on a real line, neither side then
/// understands the other, though the bytes still take their time on the wire.
#[derive(Debug)]
pub struct SimPort<D> {
    device: D,
    line: LineSettings,
    client_line: LineSettings,
    now: Nanos,
    line_free: Nanos,
    /// Bytes on their way to the device: arrival time, and the byte unless it is garbled.
    to_device: VecDeque<(Nanos, Option<u8>)>,
    from_device: VecDeque<u8>,
    scratch: Vec<u8>,
}

impl<D: ByteDevice> SimPort<D> {
    /// A port to `device` on a line at `line`, starting at virtual time `now_ns` (the device's
    /// current time).
    pub fn new(device: D, line: LineSettings, now_ns: Nanos) -> Self {
        SimPort {
            device,
            line,
            client_line: line,
            now: now_ns,
            line_free: now_ns,
            to_device: VecDeque::new(),
            from_device: VecDeque::new(),
            scratch: Vec::new(),
        }
    }

    /// The client's port set to `client_line` instead of the device's settings.
    pub fn with_client_line(mut self, client_line: LineSettings) -> Self {
        self.client_line = client_line;
        self
    }

    /// The virtual time.
    pub fn now_ns(&self) -> Nanos {
        self.now
    }

    /// The device (advanced to [`now_ns`](Self::now_ns)).
    pub fn device(&self) -> &D {
        &self.device
    }

    /// The device, to press keys, power-cycle or change inputs at [`now_ns`](Self::now_ns).
    pub fn device_mut(&mut self) -> &mut D {
        &mut self.device
    }

    /// Gives the device back.
    pub fn into_device(self) -> D {
        self.device
    }

    /// Moves virtual time to `t` (never back), delivering bytes and collecting replies on the
    /// way, every event in its order.
    pub fn run_to(&mut self, t: Nanos) {
        self.step(self.now);
        while let Some(at) = self.next_event().filter(|&at| at <= t) {
            self.step(at);
        }
        if t > self.now {
            self.step(t);
        }
    }

    /// The first event after now: a byte's arrival or a deadline of the device. (A device that
    /// keeps asking for a time already passed does not hold time still.)
    fn next_event(&self) -> Option<Nanos> {
        [
            self.device.next_deadline(),
            self.to_device.front().map(|&(at, _)| at),
        ]
        .into_iter()
        .flatten()
        .filter(|&at| at > self.now)
        .min()
    }

    /// Delivers the bytes arrived by `at`, then polls the device at `at`.
    fn step(&mut self, at: Nanos) {
        while let Some(&(arrival, byte)) = self.to_device.front() {
            if arrival > at {
                break;
            }
            self.to_device.pop_front();
            if let Some(byte) = byte {
                self.device.receive(arrival, byte);
            }
        }
        self.now = self.now.max(at);
        self.device.poll(self.now, &mut self.scratch);
        if self.client_line.understands(&self.line) {
            self.from_device.extend(self.scratch.drain(..));
        } else {
            // Framing errors on the client's side: nothing it can use.
            self.scratch.clear();
        }
    }
}

impl<D: ByteDevice> Port for SimPort<D> {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        let understood = self.client_line.understands(&self.line);
        let byte_ns = self.client_line.byte_time();
        for &byte in bytes {
            let arrival = self.now.max(self.line_free) + byte_ns;
            self.line_free = arrival;
            self.to_device
                .push_back((arrival, understood.then_some(byte)));
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        let deadline = self.now.saturating_add(Nanos::from(timeout));
        self.step(self.now);
        while self.from_device.is_empty() && self.now < deadline {
            let at = self.next_event().map_or(deadline, |t| t.min(deadline));
            self.step(at);
        }
        let n = buf.len().min(self.from_device.len());
        for (slot, byte) in buf.iter_mut().zip(self.from_device.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }

    fn now(&self) -> Duration {
        self.now.as_duration()
    }

    fn pause(&mut self, duration: Duration) {
        let t = self.now.saturating_add(Nanos::from(duration));
        self.run_to(t);
    }

    fn drain(&mut self) -> io::Result<()> {
        let t = self.line_free.max(self.now);
        self.run_to(t);
        Ok(())
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.from_device.clear();
        Ok(())
    }
}
