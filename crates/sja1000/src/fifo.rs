//! The 64-byte receive FIFO, seen through the receive window.

use crate::layout::{CanMode, stored_len};

/// Size of the FIFO RAM.
pub const FIFO_SIZE: usize = 64;

/// Circular RAM holding received messages back to back.
#[derive(Clone, Debug)]
pub struct RxFifo {
    ram: [u8; FIFO_SIZE],
    /// RBSA: RAM address of the message shown in the window.
    start: u8,
    /// Bytes occupied by stored messages, from `start`.
    used: usize,
    /// RMC: messages stored.
    count: u8,
}

impl Default for RxFifo {
    fn default() -> Self {
        Self {
            ram: [0; FIFO_SIZE],
            start: 0,
            used: 0,
            count: 0,
        }
    }
}

/// A message did not fit in the FIFO and was dropped whole.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Overrun;

impl RxFifo {
    /// Appends a message; errors (storing nothing) if it does not fit.
    pub fn store(&mut self, message: &[u8]) -> Result<(), Overrun> {
        if self.used + message.len() > FIFO_SIZE {
            return Err(Overrun);
        }
        let first = (self.start as usize + self.used) % FIFO_SIZE;
        let before_wrap = message.len().min(FIFO_SIZE - first);
        let (head, tail) = message.split_at(before_wrap);
        self.ram[first..first + before_wrap].copy_from_slice(head);
        if !tail.is_empty() {
            self.ram[..tail.len()].copy_from_slice(tail);
        }
        self.used += message.len();
        self.count += 1;
        Ok(())
    }

    /// RRB: drops the message in the window; no effect when empty.
    pub fn release(&mut self, mode: CanMode) {
        if self.count == 0 {
            return;
        }
        let len = stored_len(mode, self.window(0), self.window(1));
        self.start = ((self.start as usize + len) % FIFO_SIZE) as u8;
        self.used = self.used.saturating_sub(len);
        self.count -= 1;
    }

    /// RBSA moves past a message of `len` bytes stored and released at once, its bytes not
    /// written: for a message whose bytes later ones overwrite anyway.
    pub(crate) fn pass_over(&mut self, len: usize) {
        self.start = ((self.start as usize + len) % FIFO_SIZE) as u8;
    }

    /// Byte `k` of the receive window (may run into the next message).
    pub fn window(&self, k: usize) -> u8 {
        self.ram[(self.start as usize + k) % FIFO_SIZE]
    }

    /// Bytes `from..from + out.len()` of the receive window, as [`Self::window`] gives them
    /// (`out` no longer than the RAM: the chip copies at most the 13-byte window).
    pub(crate) fn copy_window(&self, from: usize, out: &mut [u8]) {
        let first = (self.start as usize + from) % FIFO_SIZE;
        let before_wrap = out.len().min(FIFO_SIZE - first);
        let (head, tail) = out.split_at_mut(before_wrap);
        head.copy_from_slice(&self.ram[first..first + before_wrap]);
        if !tail.is_empty() {
            tail.copy_from_slice(&self.ram[..tail.len()]);
        }
    }

    /// RMC.
    pub fn count(&self) -> u8 {
        self.count
    }

    /// RBSA.
    pub fn start(&self) -> u8 {
        self.start
    }

    /// Writing RBSA (reset mode only): the next message is stored from there.
    pub fn set_start(&mut self, rbsa: u8) {
        self.start = rbsa % FIFO_SIZE as u8;
    }

    /// Empties the FIFO; RBSA keeps its value (software reset, bus-off).
    pub fn clear(&mut self) {
        self.used = 0;
        self.count = 0;
    }

    /// Direct RAM access (CAN addresses 32..95).
    pub fn ram(&self, addr: usize) -> u8 {
        self.ram[addr % FIFO_SIZE]
    }

    /// Writing the RAM (reset mode only).
    pub fn set_ram(&mut self, addr: usize, value: u8) {
        self.ram[addr % FIFO_SIZE] = value;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_wrap_and_release_in_order() {
        let mut fifo = RxFifo::default();
        fifo.set_start(60);
        fifo.store(&[0x02, 0x24, 0x60, 0xAA, 0xBB]).unwrap();
        fifo.store(&[0x00, 0x20, 0x00]).unwrap();
        assert_eq!(fifo.count(), 2);
        assert_eq!(
            (0..5).map(|k| fifo.window(k)).collect::<Vec<_>>(),
            [2, 0x24, 0x60, 0xAA, 0xBB]
        );
        assert_eq!(
            fifo.window(5),
            0x00,
            "the window runs into the next message"
        );
        fifo.release(CanMode::Peli);
        assert_eq!(fifo.start(), 1);
        assert_eq!(fifo.window(1), 0x20);
        fifo.release(CanMode::Peli);
        assert_eq!(fifo.count(), 0);
        fifo.release(CanMode::Peli);
        assert_eq!((fifo.count(), fifo.start()), (0, 4));
    }

    #[test]
    fn the_window_copies_across_the_end_of_the_ram() {
        let mut fifo = RxFifo::default();
        fifo.set_start(60);
        fifo.store(&[0x08, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10]).unwrap();
        let mut window = [0u8; 13];
        fifo.copy_window(0, &mut window);
        let one_by_one: Vec<u8> = (0..13).map(|k| fifo.window(k)).collect();
        assert_eq!(window.to_vec(), one_by_one);
        assert_eq!(&window[..11], &[0x08, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10]);
        let mut tail = [0u8; 5];
        fifo.copy_window(8, &mut tail);
        assert_eq!(tail.to_vec(), one_by_one[8..]);
    }

    #[test]
    fn a_message_that_does_not_fit_is_dropped_whole() {
        let mut fifo = RxFifo::default();
        let full = [0x08u8, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10]; // SFF, 8 data bytes: 11 bytes
        for _ in 0..5 {
            fifo.store(&full).unwrap();
        }
        assert_eq!(fifo.store(&full), Err(Overrun));
        assert_eq!(fifo.count(), 5);
        fifo.store(&[0x40, 0x00, 0x10]).unwrap(); // 3 bytes still fit (55 + 3 <= 64)
        assert_eq!(fifo.count(), 6);
        fifo.clear();
        assert_eq!(fifo.count(), 0);
        assert_eq!(fifo.start(), 0, "RBSA kept across clear");
    }
}
