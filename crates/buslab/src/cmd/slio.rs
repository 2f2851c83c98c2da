//! `buslab slio`: P82C150 SLIOs on any bus — calibrate them, list them, read and write their
//! registers, drive an output, convert an input, set a DPM output.

use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_canbus::slio::SlioHost;
use buslab_slio::board::{CONVERT_ADC1, CONVERT_ADC2, VDD};
use buslab_slio::registers::TEN_BITS;
use buslab_slio::{Register, Request, SlioId};

use super::busopt::{BusOpt, open};
use crate::units::Human;

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub bus: BusOpt,
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
    let url = args.bus.bus.clone();
    let mut bus = open(&url)?;
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

/// With --calibrate, the start-up calibration before a request.
fn prepare(host: &mut SlioHost<'_>, calibrate: bool) -> anyhow::Result<()> {
    if calibrate {
        host.settle()?;
    }
    Ok(())
}
