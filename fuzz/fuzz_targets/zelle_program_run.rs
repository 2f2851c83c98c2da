//! The ZELLE cell running arbitrary program bytes from 0400h (started with command 6), with
//! arbitrary line bytes at arbitrary gaps, the START key, RESET and power cycles: no panic
//! (overflow checks on), at most a few hundred ms of cell time per input, the cell never sends
//! faster than 9600 baud allows and never asks to be woken in the past.
#![no_main]

use buslab_device::Nanos;
use buslab_zelle::{BatteryRam, Cell, PROGRAM_AREA};
use libfuzzer_sys::fuzz_target;

const US: Nanos = Nanos::from_micros(1);
const MS: Nanos = Nanos::from_millis(1);
/// The cell time an input may spend (the run after the last op included).
const CAP_NS: Nanos = Nanos::from_millis(300);

/// Input: 1 byte of flags and program length N (low 7 bits, taken modulo what follows; bit 7
/// turns the instruction trace on), N program bytes at 0400h, then 2-byte operations (op,
/// argument): op % 8 = 0..3 the byte `argument` on the line after (op >> 3)² × 100 µs,
/// 4 a pause of argument × 100 µs, 5 the START key for argument × 20 ms, 6 RESET, 7 a power
/// cycle (off for argument × 100 µs).
fn run(data: &[u8]) {
    let [flags, rest @ ..] = data else { return };
    let len = usize::from(flags & 0x7F) % (rest.len() + 1);
    let (program, ops) = rest.split_at(len);
    let mut cell = Cell::new(BatteryRam::default());
    cell.write_ram(PROGRAM_AREA, program);
    if flags & 0x80 != 0 {
        cell.set_trace(Some(1_000));
    }
    let byte_ns = cell.line().byte_time();
    let mut line = Line {
        now: Nanos::ZERO,
        rx_free_at: Nanos::ZERO,
        sent: 0,
        byte_ns,
        out: Vec::new(),
    };
    line.byte(&mut cell, Nanos::ZERO, 6);
    for op in ops.chunks_exact(2) {
        if line.now >= CAP_NS {
            break;
        }
        let (op, arg) = (op[0], op[1]);
        let arg_ns = u64::from(arg) * 100 * US;
        match op % 8 {
            0..=3 => {
                let gap = u64::from(op >> 3).pow(2) * 100 * US;
                line.byte(&mut cell, gap, arg);
            }
            4 => line.run_to(&mut cell, line.now + arg_ns),
            5 => cell.press_key_for(line.now, u64::from(arg) * 20 * MS),
            6 => cell.reset(line.now),
            _ => {
                cell.power_off(line.now);
                line.run_to(&mut cell, line.now + arg_ns);
                cell.power_on(line.now);
            }
        }
        let mut trace = Vec::new();
        cell.take_trace(&mut trace);
    }
    let end = line.now.max(CAP_NS - 20 * MS) + 20 * MS;
    line.run_to(&mut cell, end.min(CAP_NS + 20 * MS));
}

struct Line {
    now: Nanos,
    rx_free_at: Nanos,
    sent: u64,
    byte_ns: Nanos,
    out: Vec<u8>,
}

impl Line {
    /// A byte arriving `gap` after the line is free, the cell run to its arrival first.
    fn byte(&mut self, cell: &mut Cell, gap: Nanos, byte: u8) {
        let at = self.now.max(self.rx_free_at) + gap + self.byte_ns;
        self.run_to(cell, at);
        self.rx_free_at = at;
        cell.receive(at, byte);
    }

    /// Runs the cell through its deadlines to `end`.
    fn run_to(&mut self, cell: &mut Cell, end: Nanos) {
        loop {
            self.poll(cell, self.now);
            match cell.next_deadline() {
                Some(t) if t <= end => {
                    assert!(t > self.now, "deadline {t} at {} after a poll", self.now);
                    self.now = t;
                }
                _ => break,
            }
        }
        self.now = self.now.max(end);
        self.poll(cell, self.now);
    }

    fn poll(&mut self, cell: &mut Cell, now: Nanos) {
        cell.poll(now, &mut self.out);
        self.sent += self.out.len() as u64;
        self.out.clear();
        // A program may send 8N1 (10 bits), which a host at 8N2 reads too.
        let frame_ns = self.byte_ns * 10 / 11;
        assert!(
            self.sent <= now / frame_ns + 1,
            "{} bytes sent by {now} ns, faster than the line",
            self.sent
        );
    }
}

fuzz_target!(|data: &[u8]| run(data));
