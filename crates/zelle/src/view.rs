//! What a person reads of a program's run: trace lines, the CPU, the internal RAM.
//!
//! One line each, so that they can go through a control socket or a log unchanged.

use std::fmt;

use buslab_device::Nanos;

use crate::chip::{CpuSnapshot, ProgramEnd, ProgramStop, TraceEvent};
use crate::memory::INTERNAL_RAM_SIZE;

/// The cell's time in seconds with nanosecond digits.
struct Seconds(Nanos);

impl fmt::Display for Seconds {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}.{:09}",
            self.0.get() / 1_000_000_000,
            self.0.get() % 1_000_000_000
        )
    }
}

/// `psw` as the flags set in it, e.g. `CY OV P` (`-` for none).
struct Flags(u8);

impl fmt::Display for Flags {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const NAMES: [(u8, &str); 5] = [
            (0x80, "CY"),
            (0x40, "AC"),
            (0x20, "F0"),
            (0x04, "OV"),
            (0x01, "P"),
        ];
        let mut any = false;
        for (bit, name) in NAMES {
            if self.0 & bit != 0 {
                write!(f, "{}{name}", if any { " " } else { "" })?;
                any = true;
            }
        }
        if !any {
            f.write_str("-")?;
        }
        Ok(())
    }
}

impl fmt::Display for TraceEvent {
    /// `0.001234567  0403  E5 90     MOV A,P1        A=00 PSW=00 SP=09`
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TraceEvent::Instruction {
                at_ns,
                instruction,
                a,
                psw,
                sp,
            } => {
                let bytes: Vec<String> = instruction.bytes[..usize::from(instruction.length())]
                    .iter()
                    .map(|b| format!("{b:02X}"))
                    .collect();
                write!(
                    f,
                    "{}  {:04X}  {:<9} {:<22} A={a:02X} PSW={psw:02X} SP={sp:02X}",
                    Seconds(*at_ns),
                    instruction.pc,
                    bytes.join(" "),
                    instruction.to_string(),
                )
            }
            TraceEvent::Interrupt { at_ns, vector } => {
                write!(f, "{}  interrupt: vector {vector:04X}h", Seconds(*at_ns))
            }
            TraceEvent::Os { at_ns, routine } => {
                write!(f, "{}  OS routine {routine}", Seconds(*at_ns))
            }
            TraceEvent::Skipped {
                instructions,
                until_ns,
            } => write!(
                f,
                "... {instructions} instructions not traced, until {}",
                Seconds(*until_ns)
            ),
        }
    }
}

impl fmt::Display for ProgramEnd {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ProgramEnd::Interrupted => f.write_str("interrupted by a 0 on RxD"),
            ProgramEnd::Returned => f.write_str("returned to the OS"),
            ProgramEnd::Restarted => f.write_str("jumped to 0000h (OS restart)"),
            ProgramEnd::Fault { pc } => {
                write!(
                    f,
                    "jumped into the OS area at {pc:04X}h (no entry point there)"
                )
            }
            ProgramEnd::Reset => f.write_str("RESET"),
            ProgramEnd::PowerOff => f.write_str("power off"),
        }
    }
}

/// A CPU snapshot with the register bank PSW selects, read from `iram`, on one line.
pub struct CpuLine<'a> {
    pub cpu: &'a CpuSnapshot,
    pub iram: &'a [u8; INTERNAL_RAM_SIZE],
}

impl fmt::Display for CpuLine<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = &self.cpu.registers;
        let s = &self.cpu.sfr;
        let bank = usize::from(r.psw >> 3 & 3);
        let regs: Vec<String> = self.iram[bank * 8..bank * 8 + 8]
            .iter()
            .map(|b| format!("{b:02X}"))
            .collect();
        write!(
            f,
            "PC={:04X} A={:02X} B={:02X} PSW={:02X} ({}) SP={:02X} DPTR={:04X} \
             bank {bank} R0-R7={} IE={:02X} IP={:02X} TCON={:02X} TMOD={:02X} \
             T0={:02X}{:02X} T1={:02X}{:02X} SCON={:02X} PCON={:02X} P1={:02X} P2={:02X} \
             P3={:02X}; {} instructions, t={} s",
            r.pc,
            r.a,
            r.b,
            r.psw,
            Flags(r.psw),
            r.sp,
            r.dptr,
            regs.join(" "),
            s.ie,
            s.ip,
            s.tcon,
            s.tmod,
            s.th0,
            s.tl0,
            s.th1,
            s.tl1,
            s.scon,
            s.pcon,
            s.p1,
            s.p2,
            s.p3,
            self.cpu.instructions,
            Seconds(self.cpu.at_ns),
        )
    }
}

/// What the control line `cpu` says: the running program's CPU, or the last one's at its
/// stop, or that none ran.
pub fn cpu_line(
    running: Option<&CpuSnapshot>,
    last_stop: Option<&ProgramStop>,
    routine: Option<&str>,
    iram: &[u8; INTERNAL_RAM_SIZE],
) -> String {
    match (running, last_stop) {
        (Some(cpu), _) => format!(
            "program running{}: {}",
            routine.map(|r| format!(" (in {r})")).unwrap_or_default(),
            CpuLine { cpu, iram }
        ),
        (None, Some(stop)) => format!(
            "program stopped ({}): {}",
            stop.why,
            CpuLine {
                cpu: &stop.cpu,
                iram
            }
        ),
        (None, None) => "no program has run since the model started".into(),
    }
}

/// The internal RAM on one line: `00: 12 34 …` (128 bytes, 16 a group).
pub fn iram_line(iram: &[u8; INTERNAL_RAM_SIZE]) -> String {
    iram.chunks(16)
        .enumerate()
        .map(|(i, row)| {
            let bytes: Vec<String> = row.iter().map(|b| format!("{b:02X}")).collect();
            format!("{:02X}: {}", i * 16, bytes.join(" "))
        })
        .collect::<Vec<_>>()
        .join(" | ")
}

#[cfg(test)]
mod tests {
    use buslab_mcs51::{Instruction, Registers};

    use super::*;
    use crate::chip::SfrSnapshot;

    #[test]
    fn a_trace_line_shows_time_address_bytes_mnemonic_and_registers() {
        let line = TraceEvent::Instruction {
            at_ns: Nanos::new(1_234_567),
            instruction: Instruction {
                pc: 0x0403,
                bytes: [0x75, 0x90, 0xFE],
            },
            a: 0x41,
            psw: 0x81,
            sp: 0x09,
        }
        .to_string();
        assert!(line.starts_with("0.001234567  0403  75 90 FE "), "{line}");
        assert!(line.contains("MOV P1,#FEh"), "{line}");
        assert!(line.ends_with("A=41 PSW=81 SP=09"), "{line}");
    }

    #[test]
    fn the_cpu_line_reads_the_bank_psw_selects() {
        let mut iram = [0u8; INTERNAL_RAM_SIZE];
        iram[0x10..0x18].copy_from_slice(&[1, 2, 3, 4, 5, 6, 7, 8]);
        let cpu = CpuSnapshot {
            at_ns: Nanos::new(2_000_000_000),
            registers: Registers {
                pc: 0x0412,
                a: 0,
                b: 7,
                psw: 0x10 | 0x80,
                sp: 0x0B,
                dptr: 0x0800,
            },
            sfr: SfrSnapshot::default(),
            instructions: 99,
        };
        let stop = ProgramStop {
            why: ProgramEnd::Interrupted,
            cpu,
        };
        let line = cpu_line(None, Some(&stop), None, &iram);
        assert!(
            line.starts_with("program stopped (interrupted by a 0 on RxD): PC=0412 A=00 B=07"),
            "{line}"
        );
        assert!(line.contains("PSW=90 (CY) SP=0B DPTR=0800 bank 2 R0-R7=01 02 03 04 05 06 07 08"));
        assert!(line.ends_with("99 instructions, t=2.000000000 s"), "{line}");
        assert_eq!(
            cpu_line(None, None, None, &iram),
            "no program has run since the model started"
        );
    }

    #[test]
    fn the_internal_ram_line_has_eight_rows_of_sixteen() {
        let mut iram = [0u8; INTERNAL_RAM_SIZE];
        iram[0x7F] = 0xAB;
        let line = iram_line(&iram);
        assert_eq!(line.split(" | ").count(), 8);
        assert!(line.starts_with("00: 00 00"));
        assert!(line.ends_with("70: 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 AB"));
    }
}
