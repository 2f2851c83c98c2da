//! The serial port, in its four modes.
//!
//! Modes 1 and 3 take their baud clock from timer 1's overflows (halved unless SMOD), mode 2
//! from the oscillator (fosc/64, or fosc/32 with SMOD), each divided by 16 per bit; mode 0
//! shifts one bit per machine cycle. Like the timers, the baud clock is counted lazily: the
//! UART only wakes at the instants something visible happens (a start bit, TI, each of the
//! three samples of a received bit).
//!
//! Sending (modes 1..3): a write to SBUF starts the frame at the next rollover of the
//! free-running divide-by-16 counter; TI is set at the start of the stop bit (the 10th
//! rollover in mode 1, the 11th in modes 2 and 3) and the frame is reported then. A write
//! while a frame is still going out is ignored (the manual leaves it undefined).
//!
//! Receiving (modes 1..3, REN set): a falling edge on RxD resets the receive divide-by-16
//! counter at the next baud tick; each bit is sampled at its ticks 7, 8 and 9 and taken by
//! majority. A start bit read as 1 is a false start. After the last bit (the stop bit in mode
//! 1, the 9th data bit in modes 2 and 3) SBUF and RB8 are loaded and RI set only if RI is clear
//! and SM2 is clear or that bit is 1; otherwise the byte is lost.
//!
//! Mode 0: a write to SBUF shifts 8 bits out from the next cycle on, TI at the start of the
//! 10th cycle after the write; writing SCON with REN set and RI clear samples RxD in the 2nd to
//! 9th cycles after the write, RI at the start of the 10th.

use crate::Clocks;
use crate::event::{SerialFrame, SerialMode};
use crate::pins::S5P2;
use crate::pins::p3;
use crate::sfr::scon;
use crate::timers::Timers;

/// Baud ticks per bit.
const TICKS_PER_BIT: u64 = 16;

#[derive(Clone, Copy, Debug)]
struct Outgoing {
    data: u8,
    ninth: Option<bool>,
    mode: SerialMode,
}

#[derive(Clone, Copy, Debug)]
enum Tx {
    Idle,
    /// Waiting for the rollover at tick `at_tick`, where the start bit begins.
    Rollover {
        out: Outgoing,
        at_tick: u64,
    },
    /// The start bit began at `start`; TI at tick `ti_tick`.
    Sending {
        out: Outgoing,
        start: Clocks,
        ti_tick: u64,
    },
    /// Mode 0: shifting since `start`; TI at `ti_at`.
    Shifting {
        out: Outgoing,
        start: Clocks,
        ti_at: Clocks,
    },
}

#[derive(Clone, Copy, Debug)]
enum Rx {
    Idle,
    /// Bit `bit` (0 = start bit) of a frame whose counter was reset at tick `origin`: `sample`
    /// (0..3) samples taken of it, `ones` of them high.
    Frame {
        origin: u64,
        bit: u8,
        sample: u8,
        ones: u8,
        shift: u8,
    },
    /// Mode 0: bit `bit` (0..8; 8 = done) of a reception started by the SCON write at `start`.
    Shift {
        start: Clocks,
        bit: u8,
        shift: u8,
    },
}

#[derive(Clone, Debug)]
pub(crate) struct Uart {
    pub scon: u8,
    /// The receive buffer (what reading SBUF gives).
    pub sbuf: u8,
    pub since_ri: Clocks,
    pub since_ti: Clocks,
    synced: Clocks,
    /// Baud ticks counted up to `synced`.
    ticks: u64,
    /// Timer 1 overflows already turned into ticks.
    t1_seen: u64,
    /// One overflow of the divide-by-2 (SMOD clear) counted towards the next tick.
    half: bool,
    smod: bool,
    tx: Tx,
    rx: Rx,
}

impl Uart {
    pub fn new(now: Clocks, t1_overflows: u64) -> Uart {
        Uart {
            scon: 0,
            sbuf: 0,
            since_ri: Clocks::ZERO,
            since_ti: Clocks::ZERO,
            synced: now,
            ticks: 0,
            t1_seen: t1_overflows,
            half: false,
            smod: false,
            tx: Tx::Idle,
            rx: Rx::Idle,
        }
    }

    pub fn mode(&self) -> SerialMode {
        SerialMode::from_scon(self.scon)
    }

    /// Whether a frame is on its way out (SBUF written, TI not set yet).
    pub fn sending(&self) -> bool {
        !matches!(self.tx, Tx::Idle)
    }

    /// Mode 2's tick length in clocks.
    fn mode2_tick(&self) -> Clocks {
        Clocks(if self.smod { 2 } else { 4 })
    }

    /// Counts baud ticks up to `to` (timers synced to `to` first).
    pub fn sync(&mut self, to: Clocks, t1_overflows: u64) {
        let new = t1_overflows - self.t1_seen;
        self.t1_seen = t1_overflows;
        if to <= self.synced {
            return;
        }
        match self.mode() {
            SerialMode::Mode1 | SerialMode::Mode3 => {
                if self.smod {
                    self.ticks += new;
                } else {
                    let total = new + u64::from(self.half);
                    self.ticks += total / 2;
                    self.half = total % 2 == 1;
                }
            }
            SerialMode::Mode2 => {
                let len = self.mode2_tick();
                self.ticks += to / len - self.synced / len;
            }
            SerialMode::Mode0 => {}
        }
        self.synced = to;
    }

    /// Moves on to `to` without counting (the oscillator stood still).
    pub fn skip_to(&mut self, to: Clocks) {
        self.synced = self.synced.max(to);
    }

    /// SMOD changed (synced first).
    pub fn set_smod(&mut self, smod: bool) {
        self.smod = smod;
    }

    /// When baud tick `n` happens; `None` while timer 1 does not count machine cycles.
    fn tick_time(&self, n: u64, timers: &Timers, p3_pins: u8) -> Option<Clocks> {
        if n <= self.ticks {
            return Some(self.synced);
        }
        let ahead = n - self.ticks;
        match self.mode() {
            SerialMode::Mode2 => {
                let len = self.mode2_tick();
                Some(len * (self.synced / len + ahead))
            }
            SerialMode::Mode1 | SerialMode::Mode3 => {
                let overflows = if self.smod {
                    ahead
                } else {
                    2 * ahead - u64::from(self.half)
                };
                timers.t1_overflow_time(self.t1_seen + overflows, p3_pins)
            }
            SerialMode::Mode0 => None,
        }
    }

    /// When the UART next has something to do.
    pub fn next_time(&self, timers: &Timers, p3_pins: u8) -> Clocks {
        let tick = |n| self.tick_time(n, timers, p3_pins).unwrap_or(Clocks::NEVER);
        let tx = match self.tx {
            Tx::Idle => Clocks::NEVER,
            Tx::Rollover { at_tick, .. } => tick(at_tick),
            Tx::Sending { ti_tick, .. } => tick(ti_tick),
            Tx::Shifting { ti_at, .. } => ti_at,
        };
        let rx = match self.rx {
            Rx::Idle => Clocks::NEVER,
            Rx::Frame {
                origin,
                bit,
                sample,
                ..
            } => tick(sample_tick(origin, bit, sample)),
            Rx::Shift { start, bit, .. } => shift_time(start, bit),
        };
        tx.min(rx)
    }

    /// Does what is due at `now` (synced to `now`, `p3_pins` the pins now); returns a frame
    /// whose TI was set.
    pub fn process(&mut self, now: Clocks, p3_pins: u8) -> Option<SerialFrame> {
        self.receive(now, p3_pins);
        self.transmit(now)
    }

    fn transmit(&mut self, now: Clocks) -> Option<SerialFrame> {
        match self.tx {
            Tx::Rollover { out, at_tick } if self.ticks >= at_tick => {
                let bits = if out.ninth.is_some() { 10 } else { 9 };
                self.tx = Tx::Sending {
                    out,
                    start: now,
                    ti_tick: at_tick + bits * TICKS_PER_BIT,
                };
                None
            }
            Tx::Sending {
                out,
                start,
                ti_tick,
            } if self.ticks >= ti_tick => Some(self.sent(out, start, now)),
            Tx::Shifting { out, start, ti_at } if now >= ti_at => Some(self.sent(out, start, now)),
            _ => None,
        }
    }

    fn sent(&mut self, out: Outgoing, start: Clocks, now: Clocks) -> SerialFrame {
        self.tx = Tx::Idle;
        self.set_flag(scon::TI, now);
        SerialFrame {
            mode: out.mode,
            data: out.data,
            ninth: out.ninth,
            start,
            end: now,
        }
    }

    fn receive(&mut self, now: Clocks, p3_pins: u8) {
        let level = p3_pins & p3::RXD != 0;
        loop {
            match self.rx {
                Rx::Frame {
                    origin,
                    bit,
                    sample,
                    ones,
                    shift,
                } if self.ticks >= sample_tick(origin, bit, sample) => {
                    let ones = ones + u8::from(level);
                    if sample < 2 {
                        self.rx = Rx::Frame {
                            origin,
                            bit,
                            sample: sample + 1,
                            ones,
                            shift,
                        };
                        continue;
                    }
                    let value = ones >= 2;
                    self.rx = match bit {
                        // A start bit that reads 1 was noise.
                        0 if value => Rx::Idle,
                        1..=8 => Rx::Frame {
                            origin,
                            bit: bit + 1,
                            sample: 0,
                            ones: 0,
                            shift: shift | u8::from(value) << (bit - 1),
                        },
                        9 => {
                            self.load(shift, value, now);
                            Rx::Idle
                        }
                        // A good start bit.
                        _ => Rx::Frame {
                            origin,
                            bit: bit + 1,
                            sample: 0,
                            ones: 0,
                            shift,
                        },
                    };
                }
                Rx::Shift { start, bit, shift } if now >= shift_time(start, bit) => {
                    if bit == 8 {
                        self.sbuf = shift;
                        self.set_flag(scon::RI, now);
                        self.rx = Rx::Idle;
                    } else {
                        self.rx = Rx::Shift {
                            start,
                            bit: bit + 1,
                            shift: shift | u8::from(level) << bit,
                        };
                    }
                }
                _ => return,
            }
        }
    }

    /// The last bit of a frame is in: load SBUF if the rules let it.
    fn load(&mut self, data: u8, last: bool, now: Clocks) {
        if self.scon & scon::RI == 0 && (self.scon & scon::SM2 == 0 || last) {
            self.sbuf = data;
            self.scon = (self.scon & !scon::RB8) | if last { scon::RB8 } else { 0 };
            self.set_flag(scon::RI, now);
        }
    }

    fn set_flag(&mut self, flag: u8, now: Clocks) {
        if self.scon & flag == 0 {
            self.scon |= flag;
            let since = now.cycle_start();
            if flag == scon::RI {
                self.since_ri = since;
            } else {
                self.since_ti = since;
            }
        }
    }

    /// The program wrote SCON at `at` (synced to `at`).
    pub fn write_scon(&mut self, value: u8, at: Clocks) {
        let old = self.scon;
        self.scon = value;
        for flag in [scon::RI, scon::TI] {
            if value & flag != 0 && old & flag == 0 {
                self.scon &= !flag;
                self.set_flag(flag, at);
            }
        }
        let mode_changed = (old ^ value) & (scon::SM0 | scon::SM1) != 0;
        if mode_changed || value & scon::REN == 0 {
            self.rx = Rx::Idle;
        }
        let mode0_ready =
            self.mode() == SerialMode::Mode0 && value & scon::REN != 0 && value & scon::RI == 0;
        if mode0_ready && matches!(self.rx, Rx::Idle) {
            self.rx = Rx::Shift {
                start: at,
                bit: 0,
                shift: 0,
            };
        }
    }

    /// The program wrote SBUF at `at` (synced to `at`).
    pub fn write_sbuf(&mut self, data: u8, at: Clocks) {
        if !matches!(self.tx, Tx::Idle) {
            return;
        }
        let mode = self.mode();
        let ninth = matches!(mode, SerialMode::Mode2 | SerialMode::Mode3)
            .then_some(self.scon & scon::TB8 != 0);
        let out = Outgoing { data, ninth, mode };
        self.tx = if mode == SerialMode::Mode0 {
            Tx::Shifting {
                out,
                start: at + Clocks::CYCLE,
                ti_at: at + Clocks::from_cycles(10),
            }
        } else {
            Tx::Rollover {
                out,
                at_tick: (self.ticks / TICKS_PER_BIT + 1) * TICKS_PER_BIT,
            }
        };
    }

    /// RxD fell (sampled at `at`, synced to `at`).
    pub fn rxd_fell(&mut self) {
        if self.mode() != SerialMode::Mode0
            && self.scon & scon::REN != 0
            && matches!(self.rx, Rx::Idle)
        {
            self.rx = Rx::Frame {
                origin: self.ticks + 1,
                bit: 0,
                sample: 0,
                ones: 0,
                shift: 0,
            };
        }
    }
}

/// The tick of sample `sample` (0..3, at counter states 7, 8, 9) of bit `bit`.
fn sample_tick(origin: u64, bit: u8, sample: u8) -> u64 {
    origin + TICKS_PER_BIT * u64::from(bit) + 7 + u64::from(sample)
}

/// Mode 0 reception: bit `bit` (0..8) is sampled at S5P2 of the (bit + 2)th cycle after the
/// write at `start`; "bit 8" is RI, at the start of the 10th.
fn shift_time(start: Clocks, bit: u8) -> Clocks {
    if bit == 8 {
        start + Clocks::from_cycles(10)
    } else {
        start + Clocks::from_cycles(u64::from(bit) + 2) + S5P2
    }
}
