//! The PPC403GA's on-chip serial port (SPU): the line MoniCAN's VT100 terminal is on, the
//! running program's once it starts.
//!
//! Sans-IO in the CPU's cycles: the board reads and writes its registers at the cycle of each
//! access ([`Spu::read`], [`Spu::write`]), the terminal's keys come in with
//! [`Spu::key`], the bytes the transmitter shifted out go to the terminal through
//! [`Spu::take_output`]. The serial clock is the CPU clock: one bit lasts 16 × (BRD + 1)
//! cycles, so BRD = 80 gives 19290 baud at 25 MHz (the terminal's 19200 within 0.5 %).
//! A byte written to SPTB waits in the transmit buffer (TBR clear) until the shift register
//! is free, then is on the line for one character time (TSR clear) before the terminal has it.
//! A key is in the receive buffer one character time after it reached the port; a key that
//! arrives while the previous one waits unread is lost and sets OE.

use std::collections::VecDeque;

use buslab_ppc403::Cycles;
use tracing::warn;

/// SPLS, the line status (read; write 1s to clear RBR and the error bits).
pub const SPLS: u32 = 0;
/// SPHS, the handshake status (no handshake lines on the board: reads 0).
pub const SPHS: u32 = 2;
/// BRDH and BRDL, the baud-rate divisor (12 bits: BRDH's low 4 bits, then BRDL).
pub const BRDH: u32 = 4;
pub const BRDL: u32 = 5;
/// SPCTL, the line control (loopback, DTR, RTS, data bits, parity, stop bits).
pub const SPCTL: u32 = 6;
/// SPRC, the receiver command.
pub const SPRC: u32 = 7;
/// SPTC, the transmitter command.
pub const SPTC: u32 = 8;
/// SPRB (read) and SPTB (write), the receive and transmit buffers.
pub const SPRB: u32 = 9;
/// The registers' span from the port's base address.
pub const SPAN: u32 = 16;

/// SPLS bits.
pub const RBR: u8 = 0x80;
pub const FE: u8 = 0x40;
pub const OE: u8 = 0x20;
pub const PE: u8 = 0x10;
pub const LB: u8 = 0x08;
pub const TBR: u8 = 0x04;
pub const TSR: u8 = 0x02;
/// The SPLS bits a write of 1 clears.
const CLEARABLE: u8 = RBR | FE | OE | PE | LB;
const ERRORS: u8 = FE | OE | PE | LB;

/// SPCTL bits.
const LOOPBACK_MASK: u8 = 0xC0;
const INTERNAL_LOOPBACK: u8 = 0x40;
const EIGHT_BITS: u8 = 0x08;
const PARITY: u8 = 0x04;
const TWO_STOP_BITS: u8 = 0x01;

/// SPRC/SPTC bits: the enable, and the interrupt selections.
const ENABLE: u8 = 0x80;
const MODE_MASK: u8 = 0x60;
/// SPRC: interrupt when RBR is set; SPTC: when TBR is set.
const BUFFER_INTERRUPT: u8 = 0x20;
/// SPRC: interrupt on a receive error; SPTC: when the shift register is empty.
const SECOND_INTERRUPT: u8 = 0x10;

/// The CPU clock that drives the serial clock.
pub const CLOCK_HZ: u32 = crate::clocks::CPU_HZ;
/// The divisor the firmware programs for the terminal (19290 baud).
pub const FIRMWARE_BRD: u16 = 80;
/// SPCTL as the firmware leaves it: DTR and RTS on, 8 data bits, no parity, 1 stop bit.
pub const FIRMWARE_SPCTL: u8 = 0x20 | 0x10 | EIGHT_BITS;
/// Bytes transmitted and not yet taken by the terminal, at most; beyond, they are lost
/// (nobody reads the line) and counted.
pub const MAX_OUTPUT: usize = 64 * 1024;
/// Keys on their way to the receiver, at most (the terminal's line paces them anyway).
pub const MAX_INCOMING: usize = 256;

/// The serial port.
#[derive(Clone, Debug)]
pub struct Spu {
    /// RBR and the error bits (TBR and TSR follow the transmitter).
    status: u8,
    brd: u16,
    spctl: u8,
    sprc: u8,
    sptc: u8,
    received: u8,
    /// The byte written to SPTB, waiting for the shift register.
    tx_buffer: Option<u8>,
    /// Bytes the firmware's `write` service sends, ahead of the next byte written to SPTB.
    firmware: VecDeque<u8>,
    /// The byte on the line and the cycle its stop bit ends.
    shifting: Option<(u8, Cycles)>,
    /// Keys on the line towards the receiver, and when the first of them is complete.
    incoming: VecDeque<u8>,
    incoming_done: Cycles,
    output: Vec<u8>,
    output_lost: u64,
    keys_lost: u64,
    now: Cycles,
}

impl Spu {
    /// The port as the firmware leaves it to a program: the terminal's speed and format,
    /// receiver and transmitter enabled, no interrupts.
    pub fn new() -> Self {
        Self {
            status: 0,
            brd: FIRMWARE_BRD,
            spctl: FIRMWARE_SPCTL,
            sprc: ENABLE,
            sptc: ENABLE,
            received: 0,
            tx_buffer: None,
            firmware: VecDeque::new(),
            shifting: None,
            incoming: VecDeque::new(),
            incoming_done: Cycles::ZERO,
            output: Vec::new(),
            output_lost: 0,
            keys_lost: 0,
            now: Cycles::ZERO,
        }
    }

    /// Cycles one bit lasts.
    pub fn bit_cycles(&self) -> u64 {
        16 * (u64::from(self.brd) + 1)
    }

    /// The line's speed in bit/s.
    pub fn baud(&self) -> u32 {
        (u64::from(CLOCK_HZ) / self.bit_cycles()) as u32
    }

    /// Cycles one character lasts: start bit, data bits, parity, stop bits.
    pub fn character_cycles(&self) -> u64 {
        let data = if self.spctl & EIGHT_BITS != 0 { 8 } else { 7 };
        let parity = u64::from(self.spctl & PARITY != 0);
        let stop = if self.spctl & TWO_STOP_BITS != 0 {
            2
        } else {
            1
        };
        (1 + data + parity + stop) * self.bit_cycles()
    }

    fn data_mask(&self) -> u8 {
        if self.spctl & EIGHT_BITS != 0 {
            0xFF
        } else {
            0x7F
        }
    }

    fn loopback(&self) -> bool {
        self.spctl & LOOPBACK_MASK == INTERNAL_LOOPBACK
    }

    /// SPLS as the CPU reads it.
    pub fn line_status(&self) -> u8 {
        let mut s = self.status;
        if self.tx_buffer.is_none() {
            s |= TBR;
        }
        if self.shifting.is_none() {
            s |= TSR;
        }
        s
    }

    /// A key from the terminal at cycle `now`: in the receive buffer one character time after
    /// the line is free of the keys before it.
    pub fn key(&mut self, now: Cycles, byte: u8) {
        self.advance(now);
        if self.incoming.len() >= MAX_INCOMING {
            self.keys_lost += 1;
            return;
        }
        if self.incoming.is_empty() {
            self.incoming_done = self.incoming_done.max(now) + Cycles(self.character_cycles());
        }
        self.incoming.push_back(byte);
    }

    /// Keys lost before they reached the receive buffer (more than [`MAX_INCOMING`] waiting).
    pub fn keys_lost(&self) -> u64 {
        self.keys_lost
    }

    /// The bytes the transmitter shifted out since the last call.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.output)
    }

    /// Bytes lost because nobody took the output.
    pub fn output_lost(&self) -> u64 {
        self.output_lost
    }

    /// Bytes the firmware sends for the program (its `write` service), at cycle `now`: on the
    /// line after the byte in the transmit buffer, ahead of what the program writes next, at
    /// the line's pace (the firmware sends them in the background; TSR is clear meanwhile).
    /// Bounded as the output is: beyond [`MAX_OUTPUT`] waiting, bytes are lost.
    pub fn firmware_write(&mut self, now: Cycles, bytes: &[u8]) {
        self.advance(now);
        if let Some(byte) = self.tx_buffer.take() {
            self.firmware.push_back(byte);
        }
        let room = MAX_OUTPUT.saturating_sub(self.firmware.len());
        let take = bytes.len().min(room);
        self.firmware.extend(&bytes[..take]);
        self.lose_output((bytes.len() - take) as u64);
        self.start_shifting(now);
    }

    /// Everything still on its way to the terminal, in order, at once (the program ended: the
    /// firmware lets the port finish before it takes it back).
    pub fn flush(&mut self) -> Vec<u8> {
        let mut out = self.take_output();
        out.extend(self.shifting.take().map(|(b, _)| b));
        out.extend(self.firmware.drain(..));
        out.extend(self.tx_buffer.take());
        out
    }

    /// Bytes for the terminal that did not come through the transmitter.
    pub fn put_output(&mut self, bytes: &[u8]) {
        let room = MAX_OUTPUT.saturating_sub(self.output.len());
        let take = bytes.len().min(room);
        self.output.extend_from_slice(&bytes[..take]);
        self.lose_output((bytes.len() - take) as u64);
    }

    fn lose_output(&mut self, n: u64) {
        if n == 0 {
            return;
        }
        if self.output_lost == 0 {
            warn!(
                "the PowerPC node's serial output is not read: bytes beyond {MAX_OUTPUT} are lost"
            );
        }
        self.output_lost += n;
    }

    /// Brings the line up to cycle `now`: bytes shifted out, keys received.
    pub fn advance(&mut self, now: Cycles) {
        while let Some((byte, end)) = self.shifting
            && end <= now
        {
            self.shifting = None;
            if self.loopback() {
                self.receive(byte);
            } else {
                self.put_output(&[byte]);
            }
            self.start_shifting(end);
        }
        while !self.incoming.is_empty() && self.incoming_done <= now {
            let byte = self.incoming.pop_front().expect("a key waits");
            if !self.loopback() {
                self.receive(byte);
            }
            if !self.incoming.is_empty() {
                self.incoming_done = self.incoming_done + Cycles(self.character_cycles());
            }
        }
        self.now = self.now.max(now);
    }

    /// A complete character at the receiver.
    fn receive(&mut self, byte: u8) {
        if self.sprc & ENABLE == 0 {
            return;
        }
        if self.status & RBR != 0 {
            self.status |= OE;
        } else {
            self.received = byte & self.data_mask();
            self.status |= RBR;
        }
    }

    /// The transmit buffer's byte onto the line at cycle `at`, if the transmitter may.
    fn start_shifting(&mut self, at: Cycles) {
        if self.shifting.is_some() {
            return;
        }
        if let Some(byte) = self.firmware.pop_front() {
            self.shifting = Some((byte, at + Cycles(self.character_cycles())));
            return;
        }
        if self.sptc & ENABLE == 0 {
            return;
        }
        if let Some(byte) = self.tx_buffer.take() {
            self.shifting = Some((
                byte & self.data_mask(),
                at + Cycles(self.character_cycles()),
            ));
        }
    }

    /// The next cycle the port changes by itself (a byte shifted out, a key complete).
    pub fn next_event(&self) -> Option<Cycles> {
        let tx = self.shifting.map(|(_, end)| end);
        let rx = (!self.incoming.is_empty()).then_some(self.incoming_done);
        match (tx, rx) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// The levels of the receive and transmit interrupt lines.
    pub fn interrupts(&self) -> (bool, bool) {
        let status = self.line_status();
        let rx = (self.sprc & MODE_MASK == BUFFER_INTERRUPT && status & RBR != 0)
            || (self.sprc & SECOND_INTERRUPT != 0 && status & ERRORS != 0);
        let tx = (self.sptc & MODE_MASK == BUFFER_INTERRUPT && status & TBR != 0)
            || (self.sptc & SECOND_INTERRUPT != 0 && status & TSR != 0);
        (rx, tx)
    }

    /// A read of the register at `offset` from the port's base, at cycle `at`; `None`: no
    /// register there.
    pub fn read(&mut self, offset: u32, at: Cycles) -> Option<u8> {
        self.advance(at);
        Some(match offset {
            SPLS => self.line_status(),
            SPHS => 0,
            BRDH => (self.brd >> 8) as u8,
            BRDL => self.brd as u8,
            SPCTL => self.spctl,
            SPRC => self.sprc,
            SPTC => self.sptc,
            SPRB => {
                self.status &= !RBR;
                self.received
            }
            _ => return None,
        })
    }

    /// A write of the register at `offset` at cycle `at`; `false`: no register there.
    pub fn write(&mut self, offset: u32, value: u8, at: Cycles) -> bool {
        self.advance(at);
        match offset {
            SPLS => self.status &= !(value & CLEARABLE),
            SPHS => {}
            BRDH => self.brd = (self.brd & 0x00FF) | (u16::from(value & 0x0F) << 8),
            BRDL => self.brd = (self.brd & 0x0F00) | u16::from(value),
            SPCTL => self.spctl = value,
            SPRC => self.sprc = value,
            SPTC => {
                self.sptc = value;
                self.start_shifting(at);
            }
            SPRB => {
                self.tx_buffer = Some(value);
                self.start_shifting(at);
            }
            _ => return false,
        }
        true
    }
}

impl Default for Spu {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CHAR: u64 = 10 * 16 * 81;

    #[test]
    fn the_firmware_speed_is_the_terminals_within_half_a_percent() {
        let spu = Spu::new();
        assert_eq!(spu.baud(), 19_290);
        assert!((spu.baud() as f64 / 19_200.0 - 1.0).abs() < 0.005);
        assert_eq!(spu.character_cycles(), CHAR);
    }

    #[test]
    fn a_byte_is_on_the_line_one_character_time_then_at_the_terminal() {
        let mut spu = Spu::new();
        assert_eq!(spu.line_status(), TBR | TSR);
        assert!(spu.write(SPRB, b'A', Cycles(100)));
        // Straight into the shift register: the buffer is free again, the line is busy.
        assert_eq!(spu.read(SPLS, Cycles(100)), Some(TBR));
        spu.write(SPRB, b'B', Cycles(200));
        assert_eq!(spu.read(SPLS, Cycles(200)), Some(0), "both busy");
        assert_eq!(spu.next_event(), Some(Cycles(100 + CHAR)));
        spu.advance(Cycles(100 + CHAR - 1));
        assert!(spu.take_output().is_empty());
        spu.advance(Cycles(100 + CHAR));
        assert_eq!(spu.take_output(), b"A");
        assert_eq!(spu.line_status(), TBR, "B now shifts");
        spu.advance(Cycles(100 + 2 * CHAR));
        assert_eq!(spu.take_output(), b"B");
        assert_eq!(spu.line_status(), TBR | TSR);
    }

    #[test]
    fn a_key_not_read_in_time_is_lost_with_an_overrun() {
        let mut spu = Spu::new();
        spu.key(Cycles(0), b'x');
        spu.key(Cycles(0), b'y');
        assert_eq!(spu.read(SPLS, Cycles(CHAR - 1)).unwrap() & RBR, 0);
        assert_eq!(spu.read(SPLS, Cycles(CHAR)).unwrap() & RBR, RBR);
        assert_eq!(spu.read(SPLS, Cycles(2 * CHAR)).unwrap() & OE, OE);
        assert_eq!(spu.read(SPRB, Cycles(2 * CHAR)), Some(b'x'));
        spu.write(SPLS, OE, Cycles(2 * CHAR));
        assert_eq!(spu.line_status() & (RBR | OE), 0);
    }

    #[test]
    fn interrupt_lines_follow_the_enables() {
        let mut spu = Spu::new();
        assert_eq!(spu.interrupts(), (false, false));
        spu.write(SPTC, ENABLE | BUFFER_INTERRUPT, Cycles(0));
        assert_eq!(spu.interrupts(), (false, true));
        spu.write(SPRB, 1, Cycles(0));
        spu.write(SPRB, 2, Cycles(0));
        assert_eq!(spu.interrupts(), (false, false), "TBR clear");
        spu.write(SPRC, ENABLE | BUFFER_INTERRUPT, Cycles(0));
        spu.key(Cycles(0), b'k');
        spu.advance(Cycles(CHAR));
        assert_eq!(spu.interrupts(), (true, true));
    }

    #[test]
    fn internal_loopback_sends_the_transmitter_to_the_receiver() {
        let mut spu = Spu::new();
        spu.write(SPCTL, FIRMWARE_SPCTL | INTERNAL_LOOPBACK, Cycles(0));
        spu.write(SPRB, b'L', Cycles(0));
        spu.advance(Cycles(CHAR));
        assert!(spu.take_output().is_empty());
        assert_eq!(spu.read(SPRB, Cycles(CHAR)), Some(b'L'));
    }

    #[test]
    fn the_firmwares_bytes_go_after_the_buffers_and_before_what_follows() {
        let mut spu = Spu::new();
        spu.write(SPRB, b'a', Cycles(0));
        spu.write(SPRB, b'b', Cycles(0));
        spu.firmware_write(Cycles(0), b"cd");
        assert_eq!(spu.line_status() & (TBR | TSR), TBR);
        spu.write(SPRB, b'e', Cycles(0));
        spu.advance(Cycles(3 * CHAR));
        assert_eq!(spu.take_output(), b"abc");
        assert_eq!(spu.flush(), b"de");
        assert_eq!(spu.line_status(), TBR | TSR);
    }

    #[test]
    fn the_divisor_sets_the_speed() {
        let mut spu = Spu::new();
        spu.write(BRDH, 0x01, Cycles(0));
        spu.write(BRDL, 0x45, Cycles(0));
        assert_eq!(spu.read(BRDH, Cycles(0)), Some(1));
        assert_eq!(spu.bit_cycles(), 16 * 0x146);
        assert_eq!(spu.read(3, Cycles(0)), None);
    }
}
