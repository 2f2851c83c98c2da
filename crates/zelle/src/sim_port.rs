//! A serial port wired straight to a [`Cell`] in virtual time, so the host client runs against
//! the model as fast as the CPU allows, with the line's exact timing.

use std::collections::VecDeque;
use std::io;
use std::time::Duration;

use crate::Cell;
use crate::client::Port;
use crate::timing::BYTE_NS;

/// The host end of a 9600 8N2 line to a model cell, in virtual time. Writes queue bytes on the
/// line back to back (as a UART does); reads and pauses move time forward.
#[derive(Debug)]
pub struct SimPort {
    cell: Cell,
    now: u64,
    line_free: u64,
    to_cell: VecDeque<(u64, u8)>,
    from_cell: VecDeque<u8>,
    timeout_ns: u64,
    scratch: Vec<u8>,
}

impl SimPort {
    /// A port to `cell`, starting at the cell's current time.
    pub fn new(cell: Cell) -> SimPort {
        SimPort {
            now: cell.now(),
            cell,
            line_free: 0,
            to_cell: VecDeque::new(),
            from_cell: VecDeque::new(),
            timeout_ns: 100_000_000,
            scratch: Vec::new(),
        }
    }

    /// The virtual time.
    pub fn now(&self) -> u64 {
        self.now
    }

    /// The cell (advanced to [`now`](Self::now)).
    pub fn cell(&self) -> &Cell {
        &self.cell
    }

    /// The cell, to press keys, power-cycle or change inputs at [`now`](Self::now).
    pub fn cell_mut(&mut self) -> &mut Cell {
        &mut self.cell
    }

    /// Moves virtual time to `t`, delivering bytes and collecting replies on the way.
    pub fn run_to(&mut self, t: u64) {
        while let Some(&(at, byte)) = self.to_cell.front() {
            if at > t {
                break;
            }
            self.to_cell.pop_front();
            self.cell.receive(at, byte);
        }
        self.now = self.now.max(t);
        self.cell.poll(self.now, &mut self.scratch);
        self.from_cell.extend(self.scratch.drain(..));
    }

    fn next_event(&self) -> Option<u64> {
        [
            self.cell.next_deadline(),
            self.to_cell.front().map(|&(at, _)| at),
        ]
        .into_iter()
        .flatten()
        .min()
    }
}

impl io::Read for SimPort {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        let deadline = self.now + self.timeout_ns;
        while self.from_cell.is_empty() {
            match self.next_event() {
                Some(t) if t <= deadline => self.run_to(t.max(self.now)),
                _ => {
                    self.run_to(deadline);
                    if self.from_cell.is_empty() {
                        return Err(io::ErrorKind::TimedOut.into());
                    }
                }
            }
        }
        let n = buf.len().min(self.from_cell.len());
        for (slot, byte) in buf.iter_mut().zip(self.from_cell.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }
}

impl io::Write for SimPort {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        for &byte in buf {
            let arrival = self.now.max(self.line_free) + BYTE_NS;
            self.line_free = arrival;
            self.to_cell.push_back((arrival, byte));
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Port for SimPort {
    fn set_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        self.timeout_ns = timeout.as_nanos().min(u128::from(u64::MAX)) as u64;
        Ok(())
    }

    fn pause(&mut self, duration: Duration) {
        let t = self
            .now
            .saturating_add(duration.as_nanos().min(u128::from(u64::MAX)) as u64);
        self.run_to(t);
    }

    fn drain(&mut self) -> io::Result<()> {
        let t = self.line_free.max(self.now);
        self.pause(Duration::from_nanos(t - self.now));
        Ok(())
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.from_cell.clear();
        Ok(())
    }
}
