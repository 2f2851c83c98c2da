//! A loaded program running on the PPC403 core, on the board, with the firmware's services.
//!
//! The loader jumps to the entry point with the registers the seed's routines expect (r18 and
//! r19 on the SJA1000 card's ports, r1 on a stack, LR into the loader in flash). While the
//! exception vectors are the firmware's (EVPR below 0x20000, or in the flash), the firmware
//! catches what the program does not handle itself: `sc` is a service call (Linux's numbers:
//! r0 = 1 exit(r3), r0 = 4 write(r3 = fd, r4 = buffer, r5 = length)), anything else stops
//! the program with a report. A program that points EVPR into its own memory handles its
//! exceptions itself. A branch into the flash (a top-level `blr`) returns to the firmware.

use buslab_ppc403::{Exception, Irq, Ppc403, Registers, Stop, WatchdogReset};
use buslab_sja1000::Sja1000;
use tracing::{debug, info};

use crate::board::{
    ADDRESS_PORT, Board, DATA_PORT, FLASH_BASE, LOADER_ENTRY, RAM_SIZE, Region, STACK_TOP, region,
};
pub use buslab_ppc403::Cycles;

/// The service calls (Linux's numbers, so a program can be tried under `qemu-ppc` first).
pub const SYS_EXIT: u32 = 1;
pub const SYS_WRITE: u32 = 4;
/// Bytes one `write` call takes at most (a longer one is a partial write: r3 says how many).
pub const MAX_WRITE: u32 = 4096;
/// The errors a service returns (r3, with `CR0[SO]` set, as Linux does).
pub const EBADF: u32 = 9;
pub const EFAULT: u32 = 14;
/// `CR0[SO]`.
const CR0_SO: u32 = 0x1000_0000;
/// How often the core may stop without its time moving before the board gives up on it
/// (a core that never advances would hang the bus).
const STALLS: u32 = 1000;

/// How a program ended.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Ending {
    /// exit(status), or a return into the firmware at `returned` with r3 = status.
    Exited { status: i32, returned: Option<u32> },
    /// The firmware caught an exception: `reason`, at the instruction at `pc`.
    Stopped { reason: String, pc: u32 },
    /// The watchdog's second time-out reset the core: the board restarts the firmware.
    WatchdogReset { by: WatchdogReset },
}

/// The program, the core it runs on and the board.
pub struct Running {
    core: Ppc403,
    board: Board,
}

impl core::fmt::Debug for Running {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Running")
            .field("pc", &format_args!("{:08X}", self.core.pc()))
            .field("cycles", &self.core.now())
            .finish_non_exhaustive()
    }
}

impl Running {
    /// The core at `entry` with the loader's registers, on `board` (its RAM loaded).
    pub fn start(board: Board, entry: u32) -> Self {
        let mut core = Ppc403::new();
        let r = core.registers_mut();
        r.pc = entry;
        r.gpr[1] = STACK_TOP;
        r.gpr[18] = ADDRESS_PORT;
        r.gpr[19] = DATA_PORT;
        r.lr = LOADER_ENTRY;
        r.msr = 0;
        r.evpr = 0;
        info!("the loader jumps to the program at {entry:08X}");
        Self { core, board }
    }

    pub fn registers(&self) -> &Registers {
        self.core.registers()
    }

    pub fn pc(&self) -> u32 {
        self.core.pc()
    }

    /// Cycles the core has run.
    pub fn cycles(&self) -> Cycles {
        self.core.now()
    }

    pub fn instructions(&self) -> u64 {
        self.core.instructions()
    }

    pub fn board(&self) -> &Board {
        &self.board
    }

    pub fn board_mut(&mut self) -> &mut Board {
        &mut self.board
    }

    /// Runs the program up to cycle `until` with `chip` on its card; `Some` when it ended.
    /// The interrupt lines are brought up to date before each slice, and a slice ends where
    /// the serial port changes by itself.
    pub fn run(&mut self, chip: &mut Sja1000, until: Cycles) -> Option<Ending> {
        let mut stalls = 0;
        while self.core.now() < until {
            let before = self.core.now();
            self.board.spu.advance(before);
            let (rx, tx) = self.board.spu.interrupts();
            self.core.set_irq(Irq::SerialReceive, rx);
            self.core.set_irq(Irq::SerialTransmit, tx);
            self.core.set_irq(Irq::External(0), chip.interrupt());
            let limit = self
                .board
                .spu
                .next_event()
                .filter(|&t| t > before)
                .map_or(until, |t| t.min(until));
            let stop = self.core.run(&mut self.board.wired(chip), limit);
            self.board.spu.advance(self.core.now());
            let ending = match stop {
                Stop::Limit | Stop::Wait => None,
                Stop::SystemCall { at } => self.service(at),
                Stop::Exception { kind, at } => self.exception(kind, at),
                Stop::Reset { by } => Some(Ending::WatchdogReset { by }),
            };
            if ending.is_some() {
                return ending;
            }
            if self.core.now() == before {
                stalls += 1;
                if stalls >= STALLS {
                    return Some(Ending::Stopped {
                        reason: format!("the core made no progress ({stop:?})"),
                        pc: self.core.pc(),
                    });
                }
            } else {
                stalls = 0;
            }
        }
        None
    }

    /// An exception was taken, its vector at the PC: the program's, or the firmware's.
    fn exception(&mut self, kind: Exception, at: u32) -> Option<Ending> {
        if let Some(addr) = self.board.returned() {
            let status = self.core.gpr(3) as i32;
            info!("the program returned to the firmware at {addr:08X} (r3 = {status})");
            return Some(Ending::Exited {
                status,
                returned: Some(addr),
            });
        }
        let vector = self.core.pc();
        match region(vector) {
            Region::ProgramRam => {
                debug!("{kind:?} at {at:08X}: the program's vector {vector:08X}");
                None
            }
            Region::FirmwareRam | Region::Flash => {
                if kind == Exception::SystemCall {
                    // The firmware serves the call and returns past the sc (rfi).
                    let r = self.core.registers_mut();
                    r.pc = r.srr0;
                    r.msr = r.srr1;
                    self.service(at)
                } else {
                    self.unvector(kind, at);
                    Some(Ending::Stopped {
                        reason: describe(kind),
                        pc: at,
                    })
                }
            }
            _ => {
                let evpr = self.core.registers().evpr;
                self.unvector(kind, at);
                Some(Ending::Stopped {
                    reason: format!(
                        "{}, and its vector {vector:08X} is outside memory (EVPR {evpr:08X})",
                        describe(kind),
                    ),
                    pc: at,
                })
            }
        }
    }

    /// The registers as the program left them at `at` (the report shows the program's state,
    /// not the firmware's vector): PC at the instruction, MSR from SRR1 (SRR3 for the
    /// critical class).
    fn unvector(&mut self, kind: Exception, at: u32) {
        let r = self.core.registers_mut();
        r.pc = at;
        r.msr = if kind.is_critical() { r.srr3 } else { r.srr1 };
    }

    /// The firmware's service call from the `sc` at `at`.
    fn service(&mut self, at: u32) -> Option<Ending> {
        let r = *self.core.registers();
        match r.gpr[0] {
            SYS_EXIT => Some(Ending::Exited {
                status: r.gpr[3] as i32,
                returned: None,
            }),
            SYS_WRITE => {
                let result = self.write(r.gpr[3], r.gpr[4], r.gpr[5]);
                let regs = self.core.registers_mut();
                match result {
                    Ok(n) => {
                        regs.gpr[3] = n;
                        regs.cr &= !CR0_SO;
                    }
                    Err(errno) => {
                        regs.gpr[3] = errno;
                        regs.cr |= CR0_SO;
                    }
                }
                None
            }
            n => Some(Ending::Stopped {
                reason: format!("unknown system call r0={n}"),
                pc: at,
            }),
        }
    }

    /// write(fd, buf, len) to the terminal: the bytes it took, or the errno.
    fn write(&mut self, fd: u32, buf: u32, len: u32) -> Result<u32, u32> {
        if fd != 1 && fd != 2 {
            return Err(EBADF);
        }
        let n = len.min(MAX_WRITE);
        let end = u64::from(buf) + u64::from(n);
        if end > u64::from(RAM_SIZE) {
            return Err(EFAULT);
        }
        let bytes = self.board.ram(buf, n as usize).ok_or(EFAULT)?.to_vec();
        let now = self.core.now();
        self.board.spu.firmware_write(now, &bytes);
        Ok(n)
    }
}

/// What an exception the firmware caught means, for the report.
pub fn describe(kind: Exception) -> String {
    match kind {
        Exception::MachineCheck { addr } if addr >= FLASH_BASE => {
            format!("machine check: a write to the flash at {addr:08X}")
        }
        Exception::MachineCheck { addr } => {
            format!("machine check: nothing answers at {addr:08X}")
        }
        Exception::External => {
            "external interrupt with the firmware's vectors (MSR[EE] set, no handler)".into()
        }
        Exception::Alignment { addr } => format!("alignment: {addr:08X}"),
        Exception::Illegal { word } => format!("illegal instruction {word:08X}"),
        Exception::Privileged { word } => format!("privileged instruction {word:08X}"),
        Exception::Trap => "trap".into(),
        Exception::SystemCall => "system call".into(),
        Exception::Pit => "PIT interrupt with the firmware's vectors".into(),
        Exception::Fit => "FIT interrupt with the firmware's vectors".into(),
        Exception::Watchdog => "watchdog time-out".into(),
        Exception::Critical => "critical interrupt with the firmware's vectors".into(),
    }
}

/// The registers, a line of four at a time (the crash report).
pub fn register_lines(r: &Registers) -> Vec<String> {
    let mut lines = vec![
        format!(
            "pc   {:08X}  msr  {:08X}  lr   {:08X}  ctr  {:08X}",
            r.pc, r.msr, r.lr, r.ctr
        ),
        format!(
            "cr   {:08X}  xer  {:08X}  srr0 {:08X}  srr1 {:08X}",
            r.cr, r.xer, r.srr0, r.srr1
        ),
        format!(
            "evpr {:08X}  esr  {:08X}  dear {:08X}  srr2 {:08X}  srr3 {:08X}",
            r.evpr, r.esr, r.dear, r.srr2, r.srr3
        ),
    ];
    for row in 0..8 {
        let cells: Vec<String> = (0..4)
            .map(|k| {
                let n = row * 4 + k;
                format!("{:<4} {:08X}", format!("r{n}"), r.gpr[n])
            })
            .collect();
        lines.push(cells.join("  "));
    }
    lines
}

/// The registers on one line, `name=value` (the control socket's `regs`).
pub fn registers_line(r: &Registers) -> String {
    let mut parts = vec![
        format!("pc={:08X}", r.pc),
        format!("msr={:08X}", r.msr),
        format!("lr={:08X}", r.lr),
        format!("ctr={:08X}", r.ctr),
        format!("cr={:08X}", r.cr),
        format!("xer={:08X}", r.xer),
    ];
    parts.extend((0..32).map(|n| format!("r{n}={:08X}", r.gpr[n])));
    parts.extend([
        format!("srr0={:08X}", r.srr0),
        format!("srr1={:08X}", r.srr1),
        format!("srr2={:08X}", r.srr2),
        format!("srr3={:08X}", r.srr3),
        format!("evpr={:08X}", r.evpr),
        format!("esr={:08X}", r.esr),
        format!("dear={:08X}", r.dear),
    ]);
    parts.join(" ")
}
