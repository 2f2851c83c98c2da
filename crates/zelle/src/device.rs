//! The cell as a [`ByteDevice`] the link crate paces to the wall clock.

use std::collections::VecDeque;

use buslab_link::ByteDevice;

use crate::Cell;
use crate::timing::BYTE_NS;

impl ByteDevice for Cell {
    fn receive(&mut self, now_ns: u64, byte: u8) {
        Cell::receive(self, now_ns, byte);
    }

    fn poll(&mut self, now_ns: u64, out: &mut Vec<u8>) {
        Cell::poll(self, now_ns, out);
    }

    fn next_deadline(&self) -> Option<u64> {
        Cell::next_deadline(self)
    }
}

/// A [`Cell`] as `buslab_link::serve` should drive it today.
///
/// `serve` stamps a byte with the moment it read it from the PTY, spaced at least one
/// character time after the previous one: that is when the byte *starts* on the emulated
/// line. The cell needs the moment its stop bits end, one character time later; without that
/// a request would cost no line time and a stop-and-wait exchange would look nearly twice as
/// fast as on a real line. `LinkedCell` holds each byte for that character time. (Shifting
/// every stamp by one character time is exact: after an idle line the byte ends one character
/// after it was read, and back to back it ends one character after the previous one.)
#[derive(Debug, Default)]
pub struct LinkedCell {
    cell: Cell,
    on_the_line: VecDeque<(u64, u8)>,
}

impl LinkedCell {
    pub fn new(cell: Cell) -> LinkedCell {
        LinkedCell {
            cell,
            on_the_line: VecDeque::new(),
        }
    }

    /// The cell with every byte that has arrived by `now` delivered, for control work at
    /// `now` (key, power, inputs).
    pub fn at(&mut self, now: u64) -> &mut Cell {
        self.deliver(now);
        &mut self.cell
    }

    /// The cell as it is (bytes still on the line not yet delivered).
    pub fn cell(&self) -> &Cell {
        &self.cell
    }

    fn deliver(&mut self, now: u64) {
        while let Some(&(at, byte)) = self.on_the_line.front() {
            if at > now {
                break;
            }
            self.on_the_line.pop_front();
            self.cell.receive(at, byte);
        }
    }
}

impl ByteDevice for LinkedCell {
    fn receive(&mut self, now_ns: u64, byte: u8) {
        self.on_the_line.push_back((now_ns + BYTE_NS, byte));
    }

    fn poll(&mut self, now_ns: u64, out: &mut Vec<u8>) {
        self.deliver(now_ns);
        self.cell.poll(now_ns, out);
    }

    fn next_deadline(&self) -> Option<u64> {
        [
            self.cell.next_deadline(),
            self.on_the_line.front().map(|&(at, _)| at),
        ]
        .into_iter()
        .flatten()
        .min()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_byte_read_at_t_reaches_the_cell_one_character_later() {
        let mut linked = LinkedCell::default();
        let mut out = Vec::new();
        ByteDevice::receive(&mut linked, 1_000, 13);
        assert_eq!(linked.next_deadline(), Some(1_000 + BYTE_NS));
        ByteDevice::poll(&mut linked, 1_000 + BYTE_NS - 1, &mut out);
        assert_eq!(linked.cell().activity(), crate::Activity::Ready);
        ByteDevice::poll(&mut linked, 1_000 + BYTE_NS, &mut out);
        // The reply (key not pressed) ends one more character later.
        assert_eq!(linked.next_deadline(), Some(1_000 + 2 * BYTE_NS));
        ByteDevice::poll(&mut linked, 1_000 + 2 * BYTE_NS, &mut out);
        assert_eq!(out, [1]);
    }
}
