//! The served cell's control language: one command a line, from stdin or a control socket.
//!
//! ```text
//! key press 1.2s | key down | key up      the START key
//! power off | power on | power cycle      the supply
//! reset                                   the RESET key
//! analog CH SOURCE                        feed A/D input CH (1..4), e.g. analog 2 sine:1Hz:2V:2.5V
//! p1 pull MASK                            port 1 pins pulled low from outside (bit set = low)
//! p26 pull 0|1                            P2.6 pulled low from outside
//! bus ADDR VALUE                          what the parallel-bus peripheral at ADDR answers
//! status                                  mode, activity, value count, bytes lost
//! cpu                                     the program's CPU: running, or at its last stop
//! iram                                    the internal RAM (128 bytes)
//! save                                    write the state file now
//! ```

use buslab_device::Nanos;

use crate::analog::{SourceError, SourceSpec};
pub use crate::number::{NumberError, parse_duration_ns, parse_number, parse_number_in};
use crate::{Activity, Cell, view};

/// Help text for the control language.
pub const HELP: &str = "key press DURATION | key down | key up | power off | power on | \
     power cycle | reset | analog CH SOURCE | p1 pull MASK | p26 pull 0|1 | bus ADDR VALUE | \
     status | cpu | iram | save | help";

/// One control line, parsed.
#[derive(Clone, Debug, PartialEq)]
pub enum ControlCommand {
    KeyPress { hold_ns: Nanos },
    KeyDown,
    KeyUp,
    PowerOff,
    PowerOn,
    PowerCycle,
    Reset,
    Analog { channel: u8, source: SourceSpec },
    Port1Pull(u8),
    P26Pull(bool),
    Bus { addr: u8, value: u8 },
    Status,
    Cpu,
    Iram,
    Save,
    Help,
}

/// Why a control line was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ControlError {
    #[error("`{line}`: {why}; commands: {HELP}")]
    Syntax { line: String, why: String },
    #[error(transparent)]
    Source(#[from] SourceError),
}

impl ControlCommand {
    /// Parses one line (blank lines and `#` comments give `None`).
    pub fn parse(line: &str) -> Result<Option<ControlCommand>, ControlError> {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            return Ok(None);
        }
        let bad = |why: &str| ControlError::Syntax {
            line: line.to_owned(),
            why: why.to_owned(),
        };
        let words: Vec<&str> = line.split_whitespace().collect();
        use ControlCommand::*;
        let cmd = match words[..] {
            ["key", "press", d] => KeyPress {
                hold_ns: parse_duration_ns(d)
                    .ok_or_else(|| bad("the hold time must look like 1.2s or 500ms"))?,
            },
            ["key", "press"] => KeyPress {
                hold_ns: Nanos::from_millis(200),
            },
            ["key", "down"] => KeyDown,
            ["key", "up"] => KeyUp,
            ["power", "off"] => PowerOff,
            ["power", "on"] => PowerOn,
            ["power", "cycle"] => PowerCycle,
            ["reset"] => Reset,
            ["analog", ch, ref rest @ ..] if !rest.is_empty() => {
                let channel = parse_number(ch)
                    .filter(|c| (1..=4).contains(c))
                    .ok_or_else(|| bad("the channel must be 1..4"))?
                    as u8;
                Analog {
                    channel,
                    source: SourceSpec::parse(&rest.join(" "))?,
                }
            }
            ["p1", "pull", mask] => Port1Pull(
                parse_number(mask)
                    .filter(|&m| m <= 0xFF)
                    .ok_or_else(|| bad("the mask must be a byte, e.g. 0x30"))?
                    as u8,
            ),
            ["p26", "pull", v] => P26Pull(match v {
                "0" => false,
                "1" => true,
                _ => return Err(bad("p26 pull takes 0 or 1")),
            }),
            ["bus", addr, value] => Bus {
                addr: parse_number(addr)
                    .filter(|&a| a < 128)
                    .ok_or_else(|| bad("the bus address must be 0..127"))?
                    as u8,
                value: parse_number(value)
                    .filter(|&v| v <= 0xFF)
                    .ok_or_else(|| bad("the value must be a byte 0..255"))?
                    as u8,
            },
            ["status"] => Status,
            ["cpu"] => Cpu,
            ["iram"] => Iram,
            ["save"] => Save,
            ["help"] => Help,
            _ => return Err(bad("unknown command")),
        };
        Ok(Some(cmd))
    }
}

/// Applies `cmd` to `cell` at `now` and says what happened. A [`SourceSpec::CsvFile`] must be
/// loaded by the caller first; [`ControlCommand::Save`] is the caller's to do.
pub fn apply(cell: &mut Cell, now: Nanos, cmd: &ControlCommand) -> String {
    use ControlCommand::*;
    match cmd {
        KeyPress { hold_ns } => {
            cell.press_key_for(now, *hold_ns);
            format!("START pressed for {:.3} s", hold_ns.get() as f64 * 1e-9)
        }
        KeyDown => {
            cell.key_down(now);
            "START down".into()
        }
        KeyUp => {
            cell.key_up(now);
            "START up".into()
        }
        PowerOff => {
            cell.power_off(now);
            "power off".into()
        }
        PowerOn => {
            cell.power_on(now);
            format!("power on: {}", status(cell))
        }
        PowerCycle => {
            cell.power_off(now);
            cell.power_on(now);
            format!("power cycled: {}", status(cell))
        }
        Reset => {
            cell.reset(now);
            format!("reset: {}", status(cell))
        }
        Analog { channel, source } => match source {
            SourceSpec::Ready(s) => match cell.set_analog(*channel, s.clone()) {
                Ok(()) => format!("analog {channel} = {s}"),
                Err(e) => format!("error: {e}"),
            },
            SourceSpec::CsvFile(p) => format!("error: {} must be loaded first", p.display()),
        },
        Port1Pull(mask) => {
            cell.set_port1_pulled_low(*mask);
            format!("port 1 pins pulled low: {mask:#04x}")
        }
        P26Pull(low) => {
            cell.set_p26_pulled_low(*low);
            format!("P2.6 pulled low: {low}")
        }
        Bus { addr, value } => match cell.set_bus(*addr, *value) {
            Ok(()) => format!("bus {addr} = {value:#04x}"),
            Err(e) => format!("error: {e}"),
        },
        Status | Save => status(cell),
        Cpu => {
            let running = cell.program_cpu();
            view::cpu_line(
                running.as_ref(),
                cell.last_program_stop().as_ref(),
                cell.program_routine(),
                cell.internal_ram(),
            )
        }
        Iram => view::iram_line(cell.internal_ram()),
        Help => HELP.into(),
    }
}

/// One line about the cell's state.
pub fn status(cell: &Cell) -> String {
    let activity = match cell.activity() {
        Activity::Off => "off",
        Activity::TimingKey => "timing the START key",
        Activity::Ready => "ready",
        Activity::Exchange => "in a command",
        Activity::MeasureWaiting => "series armed, waiting for START",
        Activity::Measuring => "measuring",
        Activity::ProgramRunning => "program running",
    };
    let s = cell.stats();
    format!(
        "mode {:?}, {activity}, {} values, key {}, lost {} (set-up {}, overrun {}, off {}), \
         kept in set-up {}",
        cell.mode(),
        cell.value_count(),
        if cell.key_is_down() { "down" } else { "up" },
        s.lost_in_setup + s.lost_overrun + s.lost_off,
        s.lost_in_setup,
        s.lost_overrun,
        s.lost_off,
        s.kept_in_setup,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Mode;
    use crate::analog::Source;

    fn parse(line: &str) -> ControlCommand {
        ControlCommand::parse(line).unwrap().unwrap()
    }

    #[test]
    fn parses_the_documented_lines() {
        assert_eq!(
            parse("key press 1.2s"),
            ControlCommand::KeyPress {
                hold_ns: Nanos::new(1_200_000_000)
            }
        );
        assert_eq!(parse("  power off "), ControlCommand::PowerOff);
        assert_eq!(
            parse("analog 2 sine:1Hz:2V:2.5V"),
            ControlCommand::Analog {
                channel: 2,
                source: SourceSpec::parse("sine:1Hz:2V:2.5V").unwrap()
            }
        );
        assert_eq!(parse("p1 pull 0x30"), ControlCommand::Port1Pull(0x30));
        assert_eq!(
            parse("bus 7Fh 255"),
            ControlCommand::Bus {
                addr: 127,
                value: 255
            }
        );
        assert_eq!(ControlCommand::parse("# note"), Ok(None));
    }

    #[test]
    fn numbers_in_range_in_three_spellings() {
        assert_eq!(parse_number_in("0x1F", "value", 255), Ok(31));
        assert_eq!(parse_number_in("1Fh", "value", 255), Ok(31));
        assert_eq!(parse_number_in("31", "value", 255), Ok(31));
        assert_eq!(
            parse_number_in("0x10000", "address", 0xFFFF)
                .unwrap_err()
                .to_string(),
            "address `0x10000` is not a number in 0..65535 (decimal, 0x1F or 1Fh)"
        );
    }

    #[test]
    fn a_sign_is_not_a_digit() {
        for bad in ["+5", "+0x1F", "0x+1F", "+1Fh", "-1"] {
            assert_eq!(parse_number(bad), None, "{bad}");
        }
        assert_eq!(parse_number("0x1F"), Some(31));
        assert_eq!(parse_number("1Fh"), Some(31));
    }

    #[test]
    fn garbage_lines_are_refused_with_the_line() {
        for line in [
            "key press soon",
            "analog 5 1V",
            "analog 1 wobble:3",
            "analog 1",
            "p1 pull 256",
            "p26 pull 2",
            "bus 128 0",
            "bus 1 300",
            "launch",
            "\u{0}\u{1b}[A",
        ] {
            let err = ControlCommand::parse(line).unwrap_err().to_string();
            let last = line.split_whitespace().last().unwrap();
            assert!(err.contains(line.trim()) || err.contains(last), "{err}");
        }
    }

    #[test]
    fn cpu_shows_the_running_program_then_its_stop() {
        let mut cell = Cell::default();
        let mut out = Vec::new();
        assert_eq!(
            apply(&mut cell, Nanos::ZERO, &parse("cpu")),
            "no program has run since the model started"
        );
        // MOV A,#55h; MOV R3,#0AAh; SJMP $
        cell.write_ram(crate::PROGRAM_AREA, &[0x74, 0x55, 0x7B, 0xAA, 0x80, 0xFE]);
        let ms = Nanos::from_millis(1);
        cell.receive(ms, 6);
        cell.poll(20 * ms, &mut out);
        let running = apply(&mut cell, 20 * ms, &parse("cpu"));
        assert!(
            running.starts_with("program running: PC=0404 A=55"),
            "{running}"
        );
        assert!(running.contains("bank 0 R0-R7=00 00 00 AA"), "{running}");
        cell.receive(21 * ms, 0);
        cell.poll(40 * ms, &mut out);
        let stopped = apply(&mut cell, 40 * ms, &parse("cpu"));
        assert!(
            stopped.starts_with("program stopped (interrupted by a 0 on RxD): PC=0404 A=55"),
            "{stopped}"
        );
        let iram = apply(&mut cell, 40 * ms, &parse("iram"));
        assert!(iram.starts_with("00: 00 00 00 AA"), "{iram}");
    }

    #[test]
    fn power_cycle_resumes_the_stored_mode() {
        let mut cell = Cell::default();
        cell.write_ram(crate::START_BYTE, &[129]);
        let out = apply(&mut cell, Nanos::new(1_000), &parse("power cycle"));
        assert!(out.contains("waiting for START"), "{out}");
        assert_eq!(cell.mode(), Mode::Measure);
        apply(&mut cell, Nanos::new(2_000), &parse("analog 3 4V"));
        assert_eq!(cell.analog(3), Some(&Source::Constant(4.0)));
    }
}
