//! The MCS-51 core running arbitrary programs with arbitrary serial input, pin changes,
//! resets, stalls, traps and run limits: no panic (overflow checks on), every run ends within
//! one instruction of its limit, time never goes back, and every event lies within the time
//! run so far.
#![no_main]

use buslab_mcs51::{Clocks, Event, FlatMemory, LineFrame, Mcs51, Pin, Port, Stop};
use libfuzzer_sys::fuzz_target;

/// The longest an instruction (MUL, DIV) runs past a limit, in clocks.
const OVERSHOOT: u64 = 4 * 12;

/// Input: 2 bytes of program length N (little-endian, taken modulo what follows), N program
/// bytes loaded at 0000h, then 2-byte operations (op, argument):
/// op % 8 = 0 run for argument × 50 + 1 cycles, 1 a frame on RxD now (bit time from the op's
/// upper bits), 2 a pin change (argument: port, bit, level), 3 port 1's outside levels,
/// 4 reset, 5 one step, 6 stall, 7 traps on a 256-byte page (then each trap returns as RET).
fn run(data: &[u8]) {
    let [lo, hi, rest @ ..] = data else { return };
    let len = usize::from(u16::from_le_bytes([*lo, *hi])) % (rest.len() + 1);
    let (program, ops) = rest.split_at(len);
    let mut mem = FlatMemory::new();
    mem.load(0, program);
    let mut cpu = Mcs51::new();
    let mut last = 0u64;
    for op in ops.chunks_exact(2) {
        let (op, arg) = (op[0], op[1]);
        let now = cpu.now().0;
        match op % 8 {
            0 => {
                let until = now + (u64::from(arg) * 50 + 1) * 12;
                drive(&mut cpu, &mut mem, until);
            }
            1 => {
                let bit_clocks = [1152, 576, 64, 12, 1][usize::from(op >> 3) % 5];
                let frame = LineFrame {
                    data: arg,
                    ninth: (op & 0x80 != 0).then_some(arg & 1 != 0),
                    bit_clocks: Clocks(bit_clocks),
                };
                let _ = cpu.send_rxd(Clocks(now), frame);
            }
            2 => {
                let port = Port::ALL[usize::from(arg >> 6)];
                let pin = Pin::new(port, (arg >> 3) & 7).expect("bit 0..7");
                let _ = cpu.set_pin(Clocks(now + u64::from(op >> 3)), pin, arg & 1 != 0);
            }
            3 => {
                let _ = cpu.set_port(Clocks(now), Port::P1, arg);
            }
            4 => cpu.reset(),
            5 => {
                let stop = cpu.step(&mut mem);
                drain(&mut cpu, stop);
            }
            6 => {
                let until = now + u64::from(arg) * 100;
                let stop = cpu.stall(Clocks(until));
                drain(&mut cpu, stop);
            }
            _ => {
                let page = u16::from(arg) << 8;
                cpu.set_traps(page..=page | 0xFF);
            }
        }
        let t = cpu.now().0;
        assert!(t >= last, "time went back from {last} to {t}");
        assert_eq!(t % 12, 0, "{t} is not a machine cycle boundary");
        assert!(
            cpu.instructions() <= t / 12,
            "more instructions than cycles"
        );
        last = t;
    }
}

/// Runs to `until`, taking events and answering traps with RET.
fn drive(cpu: &mut Mcs51, mem: &mut FlatMemory, until: u64) {
    // Each pass makes progress (an event taken, a trap returned from) or ends the run.
    for _ in 0..100_000 {
        let stop = cpu.run(mem, Clocks(until));
        drain(cpu, stop);
        match stop {
            Stop::Events => {}
            Stop::Trap { .. } => cpu.ret(),
            Stop::Limit | Stop::PowerDown => {
                let now = cpu.now().0;
                assert!(now >= until, "stopped at {now} before the limit {until}");
                assert!(
                    now < until + OVERSHOOT,
                    "ran to {now}, the limit was {until}"
                );
                return;
            }
        }
    }
}

fn drain(cpu: &mut Mcs51, _stop: Stop) {
    let now = cpu.now().0;
    while let Some(event) = cpu.poll_event() {
        match event {
            Event::Serial(f) => {
                assert!(f.start < f.end && f.end.0 <= now, "{f:?} at {now}");
                assert!(f.stop_end().0 > f.end.0 || f.bits() == 8);
            }
            Event::Port { at, .. } | Event::ReservedOpcode { at, .. } => {
                assert!(at.0 <= now, "{event:?} at {now}");
            }
        }
    }
}

fuzz_target!(|data: &[u8]| run(data));
