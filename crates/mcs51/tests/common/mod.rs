//! A board for the behaviour tests: the core on 64 KiB of flat memory, with hand-assembled
//! programs (bytes with their mnemonics beside them).

#![allow(dead_code)] // each test file uses a different part

use buslab_mcs51::{Clocks, Event, FlatMemory, Mcs51, SerialFrame, Stop};

/// One machine cycle in clocks.
pub const CYCLE: u64 = 12;

pub struct Board {
    pub cpu: Mcs51,
    pub mem: FlatMemory,
    pub events: Vec<Event>,
}

impl Board {
    /// A fresh core with `program` at 0000h.
    pub fn new(program: &[u8]) -> Board {
        let mut mem = FlatMemory::new();
        mem.load(0, program);
        Board {
            cpu: Mcs51::new(),
            mem,
            events: Vec::new(),
        }
    }

    pub fn load(&mut self, addr: u16, bytes: &[u8]) {
        self.mem.load(addr, bytes);
    }

    /// Runs to `until` (clocks), collecting events; returns the last stop (Limit, a trap or
    /// power-down).
    pub fn run_to(&mut self, until: u64) -> Stop {
        loop {
            let stop = self.cpu.run(&mut self.mem, Clocks(until));
            self.drain();
            if stop != Stop::Events {
                return stop;
            }
        }
    }

    /// Runs for `cycles` machine cycles from now.
    pub fn run_cycles(&mut self, cycles: u64) -> Stop {
        let until = self.cpu.now().0 + cycles * CYCLE;
        self.run_to(until)
    }

    /// Runs until the program counter is `pc` at an instruction boundary (stepping), at most
    /// `max_steps` steps.
    pub fn run_until_pc(&mut self, pc: u16, max_steps: usize) {
        for _ in 0..max_steps {
            if self.cpu.pc() == pc {
                return;
            }
            self.step();
        }
        panic!("PC never reached {pc:04X}h (at {:04X}h)", self.cpu.pc());
    }

    /// One instruction (or interrupt entry); returns (start time, PC after).
    pub fn step(&mut self) -> (u64, u16) {
        let start = self.cpu.now().0;
        loop {
            let stop = self.cpu.step(&mut self.mem);
            self.drain();
            if stop != Stop::Events || self.cpu.now().0 > start {
                break;
            }
        }
        (start, self.cpu.pc())
    }

    pub fn drain(&mut self) {
        while let Some(e) = self.cpu.poll_event() {
            self.events.push(e);
        }
    }

    pub fn frames(&self) -> Vec<SerialFrame> {
        self.events
            .iter()
            .filter_map(|e| match e {
                Event::Serial(f) => Some(*f),
                _ => None,
            })
            .collect()
    }

    pub fn now(&self) -> u64 {
        self.cpu.now().0
    }

    pub fn iram(&self, addr: u8) -> u8 {
        self.cpu.iram()[usize::from(addr)]
    }

    pub fn sfr(&mut self, addr: u8) -> u8 {
        self.cpu.read_direct(addr)
    }
}
