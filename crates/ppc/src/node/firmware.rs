//! The firmware's side of a loaded program: the jump to its entry point, running it on the
//! core through each bit-time, its end (exit, a return into the flash, a crash report, the
//! watchdog's reset) and the board's reset, after which the resident firmware (the SJA1000
//! initialised by its driver, MoniCAN) has the board again.

use buslab_can::{BitTime, Nanos};
use buslab_monican::MoniCan;
use buslab_ppc403::Registers;
use buslab_sja1000::Sja1000;
use buslab_sja1000_driver::Sja1000Driver;
use tracing::{info, warn};

use super::{CLEAR, LOADER_TITLE, PRESS_ANY_KEY, PROGRAM_TITLE, PpcNode, Program};
use crate::board::Board;
use crate::clocks::CPU_HZ;
use crate::program::{Ending, Running, register_lines};
use crate::sampling::Sampling;
use crate::spu::MAX_OUTPUT;

impl PpcNode {
    /// The registers of the running program, or of the last one (`None`: none ran yet).
    pub fn registers(&self) -> Option<Registers> {
        match &self.program {
            Program::Running { run, .. } => Some(*run.registers()),
            _ => self.last_registers,
        }
    }

    /// The running program's RAM (`None` when no program runs, or past the RAM's end).
    pub fn ram(&self, address: u32, len: usize) -> Option<Vec<u8>> {
        match &self.program {
            Program::Running { run, .. } => run.board().ram(address, len).map(<[u8]>::to_vec),
            _ => None,
        }
    }

    /// The running program (its core and board), to look at.
    pub fn running(&self) -> Option<&Running> {
        match &self.program {
            Program::Running { run, .. } => Some(run),
            _ => None,
        }
    }

    /// A power cycle: a fresh SJA1000 initialised by the resident firmware's driver and
    /// MoniCAN started; a running program, a transfer and waiting keys are gone (the memory
    /// image is kept: it is the loader's, saved by the host).
    pub fn reset(&mut self) {
        info!("the PowerPC node is reset");
        if let Program::Running { run, .. } = &self.program {
            self.last_registers = Some(*run.registers());
        }
        self.driver = Sja1000Driver::new(Sja1000::new());
        self.keys.clear();
        self.pending_output.clear();
        self.exited = None;
        let ns = self.now.at_bitrate(self.bitrate);
        self.firmware(ns);
    }

    /// The resident firmware takes the board back: the SJA1000 initialised by its driver,
    /// MoniCAN started.
    pub(super) fn firmware(&mut self, ns: Nanos) {
        self.in_flight = None;
        self.next = None;
        self.restart_at = None;
        if let Err(e) = self.driver.init(&self.chip_config) {
            warn!("the PowerPC node's SJA1000 did not initialise: {e}");
        }
        match MoniCan::new(self.config.clone(), ns) {
            Ok(app) => self.app = app,
            Err(e) => warn!("MoniCAN cannot start again: {e}"),
        }
        self.program = Program::MoniCan;
    }

    /// Bytes for the terminal ahead of what comes next, the oldest lost beyond
    /// [`MAX_OUTPUT`] (nobody reads the line).
    pub(super) fn say(&mut self, bytes: &[u8]) {
        self.pending_output.extend_from_slice(bytes);
        if self.pending_output.len() > MAX_OUTPUT {
            let excess = self.pending_output.len() - MAX_OUTPUT;
            self.pending_output.drain(..excess);
        }
    }

    /// The loader prints its report and jumps to `entry`: the memory image in the board's
    /// RAM, the SJA1000 the program's (the firmware's driver no longer touches it).
    pub(super) fn start_program(&mut self, entry: u32, report: &[String]) {
        let mut text = CLEAR.to_vec();
        for line in std::iter::once(LOADER_TITLE).chain(report.iter().map(String::as_str)) {
            text.extend_from_slice(line.as_bytes());
            text.extend_from_slice(b"\r\n");
        }
        text.extend_from_slice(b"\r\n");
        self.say(&text);
        let mut board = Board::new();
        for (address, bytes) in self.memory.runs() {
            board.load(address, bytes);
        }
        self.in_flight = None;
        self.next = None;
        self.restart_at = None;
        self.exited = None;
        self.sampling = Sampling::default();
        self.program = Program::Running {
            run: Box::new(Running::start(board, entry)),
            start: None,
        };
    }

    /// Runs the program through bit-time `now`: the cycles of this bit-time at 25 MHz.
    pub(super) fn run_program(&mut self, now: BitTime) {
        let chip = self.driver.registers();
        let Program::Running { run, start } = &mut self.program else {
            return;
        };
        let start = *start.get_or_insert(now);
        let bits = u128::from(now.get() - start.get().min(now.get()) + 1);
        let until = buslab_ppc403::Cycles(
            (bits * u128::from(CPU_HZ) / u128::from(self.bitrate.max(1))) as u64,
        );
        let at = run.cycles();
        for key in self.keys.drain(..) {
            run.board_mut().spu.key(at, key);
        }
        let Some(ending) = run.run(chip, until) else {
            return;
        };
        let registers = *run.registers();
        let output = run.board_mut().spu.flush();
        let ns = now.at_bitrate(self.bitrate);
        self.last_registers = Some(registers);
        self.say(&output);
        self.end_program(ns, ending, &registers);
    }

    /// The program ended: MoniCAN with its status, or the crash report until a key.
    pub(super) fn end_program(&mut self, ns: Nanos, ending: Ending, registers: &Registers) {
        match ending {
            Ending::Exited { status, returned } => {
                info!("the program exited with status {status}");
                self.firmware(ns);
                let how = match returned {
                    Some(at) => format!(
                        "The program returned to the firmware (blr to {at:08X}) with r3 = {status}."
                    ),
                    None => format!("The program exited with status {status}."),
                };
                self.app.show_page(PROGRAM_TITLE, vec![how]);
                self.exited = Some(status);
            }
            Ending::WatchdogReset { by } => {
                warn!("the program's watchdog reset the board ({by:?} reset)");
                self.firmware(ns);
                self.app.show_page(
                    PROGRAM_TITLE,
                    vec![format!(
                        "The watchdog reset the board ({by:?} reset): MoniCAN started again."
                    )],
                );
            }
            Ending::Stopped { reason, pc } => {
                warn!("the program stopped: {reason} at {pc:08X}");
                let mut lines = vec![
                    String::new(),
                    format!("*** the program stopped: {reason} at {pc:08X} ***"),
                ];
                lines.extend(register_lines(registers));
                lines.push(PRESS_ANY_KEY.to_string());
                let report: Vec<u8> = lines
                    .iter()
                    .flat_map(|l| l.bytes().chain(*b"\r\n"))
                    .collect();
                self.say(&report);
                self.program = Program::Stopped { reason, pc, report };
            }
        }
    }
}
