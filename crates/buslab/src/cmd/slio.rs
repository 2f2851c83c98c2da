//! `buslab slio`: P82C150 SLIOs on any bus — calibrate them, list them, read and write their
//! registers, drive an output, convert an input, set a DPM output — and, on a buslab virtual
//! bus, the demo boards' switches and potentiometer (`board`).

use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_backends::{BusUrl, resolve};
use buslab_canbus::admin::{BoardInput, BoardSwitch, BoardVolts};
use buslab_canbus::slio::SlioHost;
use buslab_slio::board::{CONVERT_ADC1, CONVERT_ADC2, VDD};
use buslab_slio::registers::TEN_BITS;
use buslab_slio::{Register, Request, SlioId};

use super::busopt::{self, open};
use crate::units::Human;

#[derive(clap::Args)]
pub struct Args {
    /// The bus: vcan0 (buslab's bus on this machine), an interface (can0: SocketCAN), an
    /// SLCAN adapter's path (/dev/ttyACM0), or a URL: socketcand://HOST[:PORT][/CHANNEL],
    /// socketcan:IFACE, slcan:DEVICE[@BAUD][?bitrate=N&listen_only=1] (docs/transports.md).
    /// Default: the configuration's `bus` (docs/config.md), else vcan0. Before or after the
    /// subcommand.
    #[arg(long, global = true, value_name = "BUS",
          default_value = crate::config::get().bus_name.as_str(), value_parser = resolve)]
    pub bus: BusUrl,
    /// The bus's bit rate in bit/s, for the calibration rhythm (a buslab bus says it itself;
    /// SLIOs follow 20000..125000).
    #[arg(long, global = true, value_name = "BIT/S")]
    pub bitrate: Option<u32>,
    /// Send the 48 start-up calibration frames first (SLIOs after reset or after losing
    /// their calibration need them; a host such as the lab's PowerPC node may already keep
    /// them calibrated).
    #[arg(long, global = true)]
    pub calibrate: bool,
    /// How long to wait for a SLIO's answer (`500ms`, `2s`); `list` takes that long for the
    /// numbers nobody answers.
    #[arg(long, global = true, default_value = "2s", value_parser = crate::units::duration)]
    pub timeout: Duration,
    #[command(subcommand)]
    pub command: SlioCommand,
}

#[derive(clap::Subcommand)]
pub enum SlioCommand {
    /// Calibrate every SLIO on the bus (48 calibration frames) and list those that sign on;
    /// with --keep, go on sending a calibration frame every 5000 bit-times until Ctrl-C.
    Calibrate {
        /// Keep the SLIOs calibrated until stopped.
        #[arg(long)]
        keep: bool,
    },
    /// Ask all 16 SLIO numbers for their inputs and list those that answer.
    List,
    /// Read a read-only register of a SLIO: DATA_INPUT (the 16 pin levels) or ADC (converts
    /// again). A writable register has no read on a P82C150 (every frame to it has 3 bytes
    /// and writes): `write` shows what it stored.
    Read {
        /// The SLIO: 0..F.
        slio: SlioId,
        /// The register: DATA_INPUT, ADC (or 0, 8).
        register: Register,
    },
    /// Write a register of a SLIO and show what it confirmed.
    Write {
        /// The SLIO: 0..F.
        slio: SlioId,
        /// The register: a name (DATA_OUTPUT, OUTPUT_ENABLE, DPM1, …) or 0..8.
        register: Register,
        /// The value: 0x2000, 2000h or decimal; 16 bits.
        #[arg(value_parser = parse_u16)]
        value: u16,
    },
    /// Drive one output pin high or low: DATA_OUTPUT takes the pin levels (DATA_INPUT) with
    /// this one changed, so the other outputs keep theirs; the pin must then read the level
    /// (it must be an output: OUTPUT_ENABLE, 0x3F90 on the demo board).
    Set {
        /// The SLIO: 0..F.
        slio: SlioId,
        /// The pin, P0..P15 (the demo board's LEDs are 7, 8, 9, 11, 12).
        #[arg(value_parser = clap::value_parser!(u8).range(0..=15))]
        pin: u8,
        /// on/off, 1/0, high/low.
        #[arg(action = clap::ArgAction::Set, value_parser = parse_level)]
        level: bool,
    },
    /// Convert an analog input of a demo board: 1 = ADC1 (P5), 2 = ADC2 (P6, the
    /// potentiometer); prints the 10-bit result and the voltage.
    Adc {
        /// The SLIO: 0..F.
        slio: SlioId,
        /// 1 or 2.
        #[arg(value_parser = clap::value_parser!(u8).range(1..=2))]
        input: u8,
    },
    /// A demo board on a buslab virtual bus (`buslab lab`, `bus serve --slio`) as a person at
    /// the bench sees it: its input switches, potentiometer, LEDs and DPM outputs; with a
    /// change, flip a switch or turn the potentiometer first. The SLIO sees the new levels at
    /// once (`read SLIO DATA_INPUT`, MoniCAN's `3I0`; edges its edge registers ask for are
    /// reported), and the next conversion of ADC2 reads the potentiometer.
    Board {
        /// The board's SLIO number: 0..F.
        slio: SlioId,
        #[command(subcommand)]
        change: Option<BoardChange>,
    },
    /// Set a quasi-analog output: 1 = DPM1 (P10), 2 = DPM2 (P4), a duty of 0..1023 (/1024).
    Dpm {
        /// The SLIO: 0..F.
        slio: SlioId,
        /// 1 or 2.
        #[arg(value_parser = clap::value_parser!(u8).range(1..=2))]
        output: u8,
        /// The duty, 0..1023.
        #[arg(value_parser = clap::value_parser!(u16).range(0..=1023))]
        duty: u16,
    },
}

/// A change to a demo board's inputs.
#[derive(clap::Subcommand)]
pub enum BoardChange {
    /// Flip one input switch (0..3, on P0..P3): `switch 2 on`.
    Switch {
        /// 0..3.
        #[arg(value_parser = parse_switch)]
        switch: BoardSwitch,
        /// on/off, 1/0, high/low.
        #[arg(action = clap::ArgAction::Set, value_parser = parse_level)]
        level: bool,
    },
    /// Set the four input switches at once, as the board shows them from P3 to P0 (`0101`),
    /// or as a number (`0x5`).
    Switches {
        /// Four binary digits P3..P0 (`0101`) or a number 0..15 (`0x5`).
        #[arg(value_parser = parse_switches)]
        switches: u8,
    },
    /// Turn the potentiometer (P6, ADC2) to a level, 0..5 V (`2.5V`, `2500mV`, `2.5`); it
    /// stays there (the lab's slow turn stops).
    Pot {
        /// 0..5 V: `2.5V`, `2500mV` or `2.5`.
        #[arg(value_parser = parse_volts)]
        level: BoardVolts,
    },
}

impl BoardChange {
    fn input(&self) -> BoardInput {
        match *self {
            BoardChange::Switch { switch, level } => BoardInput::Switch { switch, on: level },
            BoardChange::Switches { switches } => BoardInput::Switches(switches),
            BoardChange::Pot { level } => BoardInput::Potentiometer(level),
        }
    }
}

fn parse_switch(text: &str) -> Result<BoardSwitch, String> {
    let n = text
        .parse::<u8>()
        .ok()
        .filter(|_| text.bytes().all(|b| b.is_ascii_digit()))
        .unwrap_or(u8::MAX);
    BoardSwitch::new(n)
        .map_err(|_| format!("switch {text:?}: a demo board has input switches 0..3 (on P0..P3)"))
}

/// `0101` (P3..P0) or `0x5`.
fn parse_switches(text: &str) -> Result<u8, String> {
    let t = text.trim();
    let parsed = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        Some(hex) if hex.len() == 1 => u8::from_str_radix(hex, 16).ok(),
        Some(_) => None,
        None if t.len() == 4 && t.bytes().all(|b| b == b'0' || b == b'1') => {
            u8::from_str_radix(t, 2).ok()
        }
        None => None,
    };
    parsed.ok_or_else(|| {
        format!(
            "switches {text:?}: four 0/1 digits from P3 to P0 (0101: switches 0 and 2 on) or 0x0..0xF"
        )
    })
}

/// `2.5V`, `2500mV`, `2.5` (volts), 0..5.
fn parse_volts(text: &str) -> Result<BoardVolts, String> {
    let t = text.trim();
    let (number, scale) = if let Some(n) = t.strip_suffix("mV") {
        (n, 1e-3)
    } else if let Some(n) = t.strip_suffix(['V', 'v']) {
        (n, 1.0)
    } else {
        (t, 1.0)
    };
    // Digits and one point: `f64::from_str` would take `inf`, `NaN`, `1e3`, `-0`.
    let plain = !number.is_empty()
        && number.bytes().all(|b| b.is_ascii_digit() || b == b'.')
        && number.bytes().filter(|&b| b == b'.').count() <= 1;
    plain
        .then(|| number.parse::<f64>().ok())
        .flatten()
        .and_then(|v| BoardVolts::new(v * scale).ok())
        .ok_or_else(|| format!("potentiometer level {text:?}: 0..5 V, as 2.5V, 2500mV or 2.5"))
}

/// `0x2000`, `2000h`, `8192`.
fn parse_u16(text: &str) -> Result<u16, String> {
    let t = text.trim();
    // Digits only: `from_str_radix` and `parse` would take a sign (`+f`, `+5`).
    let parsed = if !t.bytes().all(|b| b.is_ascii_alphanumeric()) {
        "-".parse::<u16>()
    } else if let Some(hex) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        u16::from_str_radix(hex, 16)
    } else if let Some(hex) = t.strip_suffix(['h', 'H']) {
        u16::from_str_radix(hex, 16)
    } else {
        t.parse()
    };
    parsed
        .map_err(|_| format!("value {text:?} must be 16 bits: 0..65535, 0x0..0xFFFF or 0h..FFFFh"))
}

fn parse_level(text: &str) -> Result<bool, String> {
    match text.to_ascii_lowercase().as_str() {
        "1" | "on" | "high" => Ok(true),
        "0" | "off" | "low" => Ok(false),
        _ => Err(format!("level {text:?} must be on/off, 1/0 or high/low")),
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let url = args.bus.clone();
    let mut bus = open(&url)?;
    if let SlioCommand::Board { slio, change } = &args.command {
        return board(&mut bus, &url, *slio, change.as_ref());
    }
    let bitrate = match (args.bitrate, bus.admin()) {
        (Some(b), _) => b,
        (None, Some(admin)) => admin.node_status(None)?.bus.bitrate,
        (None, None) => bail!("{url}: say the bus's bit rate with --bitrate (20000..125000)"),
    };
    if !(20_000..=125_000).contains(&bitrate) {
        bail!("{url} runs at {bitrate} bit/s: SLIOs follow 20000..125000 bit/s only");
    }
    let calibrate = args.calibrate || matches!(args.command, SlioCommand::Calibrate { .. });
    let mut host = SlioHost::new(&mut *bus, bitrate, calibrate);
    let wait = args.timeout;
    host.set_answer_within(wait);
    match args.command {
        SlioCommand::Calibrate { keep } => {
            let signed = host.settle()?;
            if signed.is_empty() {
                println!(
                    "no SLIO signed on (already calibrated ones do not: try `buslab slio list`)"
                );
            }
            for (slio, inputs) in signed {
                println!("SLIO {slio} signed on: inputs 0x{inputs:04X}");
            }
            if keep {
                eprintln!("keeping the SLIOs calibrated; Ctrl-C to stop");
                let stop = crate::cmd::interrupted()?;
                while !stop.load(std::sync::atomic::Ordering::SeqCst) {
                    host.run(Instant::now() + Duration::from_millis(100), |_| false)?;
                }
            }
        }
        SlioCommand::List => {
            if calibrate {
                host.settle()?;
            }
            let found = host.scan(wait)?;
            if found.is_empty() {
                bail!(
                    "no SLIO answered within {} (none on the bus, or not calibrated: add --calibrate)",
                    Human(wait)
                );
            }
            for (slio, inputs) in found {
                println!(
                    "SLIO {slio}: id {:03X}/{:03X}, inputs 0x{inputs:04X}",
                    slio.command_id().as_raw(),
                    slio.reply_id().as_raw()
                );
            }
        }
        SlioCommand::Read { slio, register } => {
            if let Err(e) = Request::read(register) {
                bail!(
                    "SLIO {slio}: {e} (`buslab slio write {slio} {register} VALUE` sets it and shows what the SLIO stored)"
                );
            }
            prepare(&mut host, calibrate)?;
            let value = host.read(slio, register, wait)?;
            println!("SLIO {slio} {register} = 0x{value:04X}");
        }
        SlioCommand::Write {
            slio,
            register,
            value,
        } => {
            prepare(&mut host, calibrate)?;
            let confirmed = host.write(slio, register, value, wait)?;
            println!("SLIO {slio} {register} = 0x{confirmed:04X}");
        }
        SlioCommand::Set { slio, pin, level } => {
            prepare(&mut host, calibrate)?;
            // A P82C150 cannot be asked for DATA_OUTPUT or OUTPUT_ENABLE without writing them:
            // the pin levels stand in for the outputs (an output reads back its level).
            let levels = host.read(slio, Register::DataInput, wait)?;
            let new = if level {
                levels | 1 << pin
            } else {
                levels & !(1 << pin)
            };
            let confirmed = host
                .write(slio, Register::DataOutput, new, wait)
                .context("writing DATA_OUTPUT")?;
            let after = host.read(slio, Register::DataInput, wait)?;
            let word = |high: bool| if high { "high" } else { "low" };
            if (after & 1 << pin != 0) != level {
                bail!(
                    "SLIO {slio}: P{pin} is not an output: it reads {} after DATA_OUTPUT drove it {} (DATA_INPUT = 0x{after:04X}); OUTPUT_ENABLE makes it one (the demo board uses 0x3F90: buslab slio write {slio} OUTPUT_ENABLE 0x3F90){}",
                    word(!level),
                    word(level),
                    if pin == 10 || pin == 4 {
                        ", unless it is a DPM output"
                    } else {
                        ""
                    }
                );
            }
            println!(
                "SLIO {slio} P{pin} {} (DATA_OUTPUT = 0x{confirmed:04X})",
                word(level)
            );
        }
        SlioCommand::Adc { slio, input } => {
            prepare(&mut host, calibrate)?;
            let config = if input == 1 {
                CONVERT_ADC1
            } else {
                CONVERT_ADC2
            };
            let code = host.write(slio, Register::AnalogConfig, config, wait)? & TEN_BITS;
            println!(
                "SLIO {slio} ADC{input} = {code} ({:.3} V)",
                f64::from(code) / 1023.0 * VDD
            );
        }
        // The board, not its SLIO: answered above.
        SlioCommand::Board { .. } => {}
        SlioCommand::Dpm { slio, output, duty } => {
            prepare(&mut host, calibrate)?;
            let register = if output == 1 {
                Register::Dpm1
            } else {
                Register::Dpm2
            };
            let confirmed = host.write(slio, register, duty, wait)?;
            println!(
                "SLIO {slio} {register} = {confirmed} ({:.3} V mean while its pin is an output)",
                f64::from(confirmed) / 1024.0 * VDD
            );
        }
    }
    Ok(())
}

/// `board`: the demo board as the server sees it, after the change; nothing goes on the bus
/// (the board's SLIO tells the change itself, as the chip does).
fn board(
    bus: &mut buslab_backends::DynBus,
    url: &BusUrl,
    slio: SlioId,
    change: Option<&BoardChange>,
) -> anyhow::Result<()> {
    let admin = busopt::admin(bus, url, "demo boards")?;
    let board = admin
        .demo_board(slio, change.map(BoardChange::input))
        .with_context(|| format!("{url}: SLIO {slio}'s demo board"))?;
    println!("{board}");
    Ok(())
}

/// With --calibrate, the start-up calibration before a request.
fn prepare(host: &mut SlioHost<'_>, calibrate: bool) -> anyhow::Result<()> {
    if calibrate {
        host.settle()?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn board_inputs_are_read_as_a_person_writes_them() {
        assert_eq!(parse_switch("2").map(BoardSwitch::number), Ok(2));
        assert!(parse_switch("4").unwrap_err().contains("0..3"));
        assert!(parse_switch("+1").is_err());
        assert_eq!(parse_switches("0101"), Ok(0b0101));
        assert_eq!(parse_switches("0xF"), Ok(0xF));
        assert!(parse_switches("5").unwrap_err().contains("four 0/1 digits"));
        assert!(parse_switches("0x10").is_err());
        for (text, volts) in [
            ("2.5V", 2.5),
            ("2500mV", 2.5),
            ("2.5", 2.5),
            ("5V", 5.0),
            ("0", 0.0),
        ] {
            assert_eq!(parse_volts(text).map(BoardVolts::get), Ok(volts), "{text}");
        }
        for text in ["5.1V", "-1V", "NaN", "inf", "1e0", "V", "2.5 V", "2.5.1"] {
            let e = parse_volts(text).unwrap_err();
            assert!(e.contains("0..5 V"), "{text}: {e}");
        }
    }
}
