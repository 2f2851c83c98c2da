//! The cell as a [`ByteDevice`] the link crate paces to the wall clock.

use buslab_link::ByteDevice;

use crate::Cell;

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
