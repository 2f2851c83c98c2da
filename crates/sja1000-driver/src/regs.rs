//! Register access: the only way the driver talks to a chip (the seed's `MemoryMappedDevice`).

use std::sync::{Arc, Mutex, MutexGuard};

use buslab_can::Frame;
use buslab_sja1000::{CanMode, Sja1000, layout};

/// Byte-wide registers at 8-bit addresses, as a CPU sees a memory-mapped SJA1000.
pub trait RegisterAccess {
    /// A read, with the chip's side effects (reading IR clears it, ALC/ECC re-arm).
    fn read(&mut self, addr: u8) -> u8;
    /// A write, with the chip's side effects.
    fn write(&mut self, addr: u8, value: u8);
    /// A read without side effects, if the device can do that (a model can, real hardware
    /// cannot). The default says it cannot.
    fn peek(&mut self, addr: u8) -> Option<u8> {
        let _ = addr;
        None
    }
    /// Reads `buf.len()` consecutive registers from `addr` on (the receive window), each with
    /// the side effects of [`read`](Self::read). The default reads them one by one; a model
    /// can copy them at once.
    fn read_block(&mut self, addr: u8, buf: &mut [u8]) {
        for (k, byte) in buf.iter_mut().enumerate() {
            *byte = self.read(addr.wrapping_add(k as u8));
        }
    }
    /// The frame in the receive window at `base` in `mode`'s layout: its first two bytes, then
    /// the rest of the message as its length says, read with [`read_block`](Self::read_block)
    /// and decoded. A model that kept the frames it stored hands the frame over instead.
    fn read_received_frame(&mut self, mode: CanMode, base: u8) -> Frame {
        read_frame_bytes(self, mode, base)
    }
    /// Writes `bytes` to consecutive registers from `addr` on (the transmit buffer), each
    /// with the side effects of [`write`](Self::write). The default writes them one by one.
    fn write_block(&mut self, addr: u8, bytes: &[u8]) {
        for (k, &byte) in bytes.iter().enumerate() {
            self.write(addr.wrapping_add(k as u8), byte);
        }
    }
}

impl RegisterAccess for Sja1000 {
    fn read(&mut self, addr: u8) -> u8 {
        Sja1000::read(self, addr)
    }
    fn write(&mut self, addr: u8, value: u8) {
        Sja1000::write(self, addr, value)
    }
    fn peek(&mut self, addr: u8) -> Option<u8> {
        Some(Sja1000::peek(self, addr))
    }
    fn read_block(&mut self, addr: u8, buf: &mut [u8]) {
        Sja1000::read_block(self, addr, buf)
    }
    fn write_block(&mut self, addr: u8, bytes: &[u8]) {
        Sja1000::write_block(self, addr, bytes)
    }
    fn read_received_frame(&mut self, mode: CanMode, base: u8) -> Frame {
        match self.received_frame(mode, base) {
            Some(frame) => frame,
            None => read_frame_bytes(self, mode, base),
        }
    }
}

/// [`RegisterAccess::read_received_frame`] from the window's bytes.
fn read_frame_bytes<R: RegisterAccess + ?Sized>(regs: &mut R, mode: CanMode, base: u8) -> Frame {
    let mut buf = [0u8; 13];
    regs.read_block(base, &mut buf[..2]);
    let len = layout::stored_len(mode, buf[0], buf[1]);
    regs.read_block(base.wrapping_add(2), &mut buf[2..len]);
    layout::decode_tx(mode, &buf)
}

impl<T: RegisterAccess + ?Sized> RegisterAccess for &mut T {
    fn read(&mut self, addr: u8) -> u8 {
        (**self).read(addr)
    }
    fn write(&mut self, addr: u8, value: u8) {
        (**self).write(addr, value)
    }
    fn peek(&mut self, addr: u8) -> Option<u8> {
        (**self).peek(addr)
    }
    fn read_block(&mut self, addr: u8, buf: &mut [u8]) {
        (**self).read_block(addr, buf)
    }
    fn write_block(&mut self, addr: u8, bytes: &[u8]) {
        (**self).write_block(addr, bytes)
    }
    fn read_received_frame(&mut self, mode: CanMode, base: u8) -> Frame {
        (**self).read_received_frame(mode, base)
    }
}

impl<T: RegisterAccess + ?Sized> RegisterAccess for Box<T> {
    fn read(&mut self, addr: u8) -> u8 {
        (**self).read(addr)
    }
    fn write(&mut self, addr: u8, value: u8) {
        (**self).write(addr, value)
    }
    fn peek(&mut self, addr: u8) -> Option<u8> {
        (**self).peek(addr)
    }
    fn read_block(&mut self, addr: u8, buf: &mut [u8]) {
        (**self).read_block(addr, buf)
    }
    fn write_block(&mut self, addr: u8, bytes: &[u8]) {
        (**self).write_block(addr, bytes)
    }
    fn read_received_frame(&mut self, mode: CanMode, base: u8) -> Frame {
        (**self).read_received_frame(mode, base)
    }
}

/// A chip shared between the thread that steps the bus and the thread that owns the driver.
/// Each register access takes the lock once, like one bus cycle of a CPU.
pub type SharedChip = Arc<Mutex<Sja1000>>;

/// A new chip (after hardware reset) ready to share.
pub fn shared_chip() -> SharedChip {
    Arc::new(Mutex::new(Sja1000::new()))
}

/// A poisoned lock still holds a consistent chip (every register access is atomic), so it is
/// used as is.
fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl<T: RegisterAccess> RegisterAccess for Arc<Mutex<T>> {
    fn read(&mut self, addr: u8) -> u8 {
        lock(self).read(addr)
    }
    fn write(&mut self, addr: u8, value: u8) {
        lock(self).write(addr, value)
    }
    fn peek(&mut self, addr: u8) -> Option<u8> {
        lock(self).peek(addr)
    }
    // A block takes the lock once, as one burst of bus cycles.
    fn read_block(&mut self, addr: u8, buf: &mut [u8]) {
        lock(self).read_block(addr, buf)
    }
    fn write_block(&mut self, addr: u8, bytes: &[u8]) {
        lock(self).write_block(addr, bytes)
    }
    fn read_received_frame(&mut self, mode: CanMode, base: u8) -> Frame {
        lock(self).read_received_frame(mode, base)
    }
}

/// A data bus with nothing on it: every read returns 0xFF (pulled-up lines), writes vanish.
/// Probing it must fail with "no chip".
#[derive(Clone, Copy, Debug, Default)]
pub struct NoChip;

impl RegisterAccess for NoChip {
    fn read(&mut self, _addr: u8) -> u8 {
        0xFF
    }
    fn write(&mut self, _addr: u8, _value: u8) {}
}
