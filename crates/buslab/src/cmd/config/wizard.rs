//! `buslab config wizard`: JerryCAN's configuration assistant (seed 002 §5.4.2) on a
//! terminal. It asks for the controller mode, the acceptance filter, the bit timing, the
//! output control and the clock out, then the bus, the identifiers and the mail server; every
//! answer is checked as the file's value would be, and a step is finished only when the
//! controller accepts it. The file is written atomically at the end.
//!
//! The questions go through [`Prompter`] so that the steps can be tested with scripted answers;
//! [`Terminal`] asks the choices with `inquire` and the text with [`line`] (readline's editing
//! keys).
//!
//! A filter is shown as the IDs it lets through, and can be derived from the IDs wanted
//! (`buslab_config::filter`).

mod line;

use std::path::Path;
use std::rc::Rc;

use anyhow::{Context, bail};
use buslab_canbus::{AcceptanceFilter, CanMode, ControllerMode};

use super::WizardArgs;
use crate::config::filter::{self as filters, Kind};
use crate::config::{self, FilterKind, KEYS, MODE_NAMES, Raw, Settings};

/// Checks one answer; the error says what is allowed.
pub type Check = Rc<dyn Fn(&str) -> Result<(), String>>;

/// Asks questions.
pub trait Prompter {
    /// One of `options`, the cursor on `start`; returns its index.
    fn select(&mut self, question: &str, options: &[&str], start: usize) -> anyhow::Result<usize>;
    /// Text, `default` when the answer is empty; asked again until `check` accepts it.
    fn text(
        &mut self,
        question: &str,
        default: &str,
        help: &str,
        check: Check,
    ) -> anyhow::Result<String>;
    fn confirm(&mut self, question: &str, default: bool) -> anyhow::Result<bool>;
    /// Tells the user something (a computed register, a refused step).
    fn say(&mut self, text: &str);
}

pub fn run(args: WizardArgs) -> anyhow::Result<()> {
    let (start, in_use) = match config::loaded() {
        Some(Ok(loaded)) => {
            let mut settings = loaded.settings.clone();
            // The MQTT credentials are written back only as the file gave them: one from the
            // environment never lands in a file.
            for key in config::SECRET_KEYS {
                if !matches!(loaded.source(key), Some(config::Source::File { .. })) {
                    settings.unset(key);
                }
            }
            (settings, loaded.file.clone().map(|(p, _)| p))
        }
        Some(Err(e)) => {
            tracing::warn!("the configuration in use is refused ({e}); starting from the defaults");
            (Settings::default(), None)
        }
        None => (Settings::default(), None),
    };
    let path = match args.out.or(in_use).or_else(config::user_file) {
        Some(path) => path,
        None => bail!("no file to write: give --out FILE"),
    };
    if !std::io::IsTerminal::is_terminal(&std::io::stdin()) {
        bail!(
            "the wizard asks its questions on a terminal; edit {} instead (docs/config.md)",
            path.display()
        );
    }
    let mut terminal = Terminal;
    let settings = ask_all(&mut terminal, start)?;
    write(&mut terminal, &settings, &path)
}

/// Every step, in the seed's order, then the keys JerryCAN kept in its properties file.
pub fn ask_all(p: &mut dyn Prompter, mut s: Settings) -> anyhow::Result<Settings> {
    p.say("buslab configuration assistant: press Enter to keep the value shown.");
    ask_mode(p, &mut s)?;
    ask_filter(p, &mut s)?;
    ask_timing(p, &mut s)?;
    ask_key(
        p,
        &mut s,
        "controller.output_control",
        "Output control register (OCR)",
    )?;
    ask_clock_out(p, &mut s)?;
    ask_key(p, &mut s, "bus", "Bus CAN commands use by default")?;
    ask_identifiers(p, &mut s)?;
    ask_optional(p, &mut s, "mail.host", "IMAP server of the mail notifier")?;
    ask_key(p, &mut s, "mail.port", "Its port")?;
    ask_optional(
        p,
        &mut s,
        "mail.user",
        "Mailbox user (the password is asked when needed)",
    )?;
    ask_key(
        p,
        &mut s,
        "mail.interval",
        "How often the mailbox is checked",
    )?;
    ask_key(
        p,
        &mut s,
        "manager.poll_interval",
        "Manager's pause between polls of the chip",
    )?;
    ask_optional(p, &mut s, "log_file", "Log file of received frames")?;
    Ok(s)
}

fn ask_mode(p: &mut dyn Prompter, s: &mut Settings) -> anyhow::Result<()> {
    let start = ControllerMode::ALL
        .iter()
        .position(|&m| m == s.mode)
        .unwrap_or(0);
    let i = p.select("Controller mode", &MODE_NAMES, start)?;
    s.mode = ControllerMode::ALL[i];
    Ok(())
}

/// The ways to give a filter.
const FILTER_FROM: [&str; 2] = ["the IDs to let through", "ACR and AMR registers"];

/// The filter's kind, then its code and mask (from the IDs wanted, or the registers), shown
/// as the IDs it lets through; asked again until the user keeps it.
fn ask_filter(p: &mut dyn Prompter, s: &mut Settings) -> anyhow::Result<()> {
    let kinds: &[FilterKind] = match s.mode.can_mode() {
        CanMode::Basic => &[FilterKind::AcceptAll, FilterKind::Basic],
        CanMode::Peli => &[FilterKind::AcceptAll, FilterKind::Single, FilterKind::Dual],
    };
    let names: Vec<&str> = kinds.iter().map(|k| k.name()).collect();
    loop {
        let start = kinds.iter().position(|&k| k == s.filter).unwrap_or(0);
        s.filter = kinds[p.select("Acceptance filter", &names, start)?];
        if s.filter == FilterKind::AcceptAll {
            s.acceptance_code = 0;
            s.acceptance_mask = None;
            return Ok(());
        }
        let max = s.filter.max_code();
        s.acceptance_code &= max;
        s.acceptance_mask = Some(s.mask() & max);
        if p.select("Acceptance filter from", &FILTER_FROM, 0)? == 0 {
            ask_wanted_ids(p, s)?;
        } else {
            ask_registers(p, s, max)?;
        }
        p.say(&filters::explain(&s.controller().filter));
        if p.confirm("Keep this filter?", true)? {
            return Ok(());
        }
    }
}

/// The IDs wanted; the code and mask that let them through, and what else passes.
fn ask_wanted_ids(p: &mut dyn Prompter, s: &mut Settings) -> anyhow::Result<()> {
    let kind = match s.filter {
        FilterKind::Basic => Kind::Basic,
        FilterKind::Dual => Kind::Dual,
        _ => Kind::Single,
    };
    let check: Check =
        Rc::new(move |answer| filters::derive(kind, &filters::parse_wanted(answer)?).map(drop));
    let answer = p.text(
        "IDs to let through",
        "",
        "hex as candump writes them: 123, 100-1FF, 18FEF100 (8 digits: extended)",
        check,
    )?;
    let derived = filters::derive(
        kind,
        &filters::parse_wanted(&answer).map_err(anyhow::Error::msg)?,
    )
    .map_err(anyhow::Error::msg)?;
    let (code, mask) = derived.filter.registers();
    (s.acceptance_code, s.acceptance_mask) = match derived.filter {
        AcceptanceFilter::Basic { code, mask } => (code.into(), Some(mask.into())),
        _ => (u32::from_be_bytes(code), Some(u32::from_be_bytes(mask))),
    };
    let (acr, amr) = (
        key_of("controller.acceptance_code").show(s),
        key_of("controller.acceptance_mask").show(s),
    );
    p.say(&format!(
        "ACR={} AMR={}: {}",
        acr.unwrap_or_default(),
        amr.unwrap_or_default(),
        match derived.extra {
            0 => format!("exactly the {} IDs asked for", derived.wanted),
            n => format!(
                "the {} IDs asked for and {n} others the filter cannot tell apart",
                derived.wanted
            ),
        }
    ));
    Ok(())
}

/// ACR and AMR as numbers.
fn ask_registers(p: &mut dyn Prompter, s: &mut Settings, max: u32) -> anyhow::Result<()> {
    let width = if max == 0xFF { "8" } else { "32" };
    for (key, question) in [
        (
            "controller.acceptance_code",
            format!("Acceptance code ({width} bits, ACR)"),
        ),
        (
            "controller.acceptance_mask",
            format!("Acceptance mask ({width} bits, AMR; 1 = don't care)"),
        ),
    ] {
        ask_key_with(p, s, key, &question, Some(u64::from(max)))?;
    }
    Ok(())
}

/// The ways to give the bit timing.
const TIMING_FROM: [&str; 3] = [
    "the bus's (buslab's bus) or the adapter's: leave it",
    "bit rate and sample point",
    "BTR0 and BTR1 registers",
];

fn ask_timing(p: &mut dyn Prompter, s: &mut Settings) -> anyhow::Result<()> {
    loop {
        let start = match (s.btr0, s.bitrate) {
            (Some(_), _) => 2,
            (None, Some(_)) => 1,
            (None, None) => 0,
        };
        let way = p.select("Bus timing", &TIMING_FROM, start)?;
        if way == 0 {
            (s.btr0, s.btr1, s.bitrate, s.sample_point) = (None, None, None, None);
            return Ok(());
        }
        ask_key(p, s, "controller.crystal_hz", "Crystal frequency in Hz")?;
        if way == 1 {
            s.btr0 = None;
            s.btr1 = None;
            ask_key(
                p,
                s,
                "controller.bitrate",
                "Bit rate (e.g. 125000, 125k, 500 kbit/s, 1M)",
            )?;
            ask_optional(
                p,
                s,
                "controller.sample_point",
                "Sample point in % (- for CiA's)",
            )?;
        } else {
            let timing = s.controller().bit_timing();
            let (btr0, btr1) = timing.map_or((0x00, 0x14), |t| t.registers());
            s.btr0.get_or_insert(btr0);
            s.btr1.get_or_insert(btr1);
            ask_key(p, s, "controller.btr0", "BTR0 (SJW, prescaler)")?;
            ask_key(p, s, "controller.btr1", "BTR1 (SAM, TSEG2, TSEG1)")?;
        }
        let chip = s.controller();
        match chip.bit_timing() {
            Ok(t) => {
                p.say(&format!("{} bit/s: {t}", t.bitrate(chip.can_clock_hz())));
                return Ok(());
            }
            Err(e) => p.say(&format!("This timing cannot be used: {e}. Again:")),
        }
    }
}

fn ask_clock_out(p: &mut dyn Prompter, s: &mut Settings) -> anyhow::Result<()> {
    s.clock_out = p.confirm("Clock output (CLKOUT pin) on?", s.clock_out)?;
    if s.clock_out {
        ask_key(
            p,
            s,
            "controller.clock_divider",
            "CLKOUT divider (crystal / N)",
        )?;
    }
    Ok(())
}

/// The loader's and the mail notifier's identifiers, until the pair is accepted.
fn ask_identifiers(p: &mut dyn Prompter, s: &mut Settings) -> anyhow::Result<()> {
    loop {
        ask_key(p, s, "loader_id", "Identifier of the loader (idloader)")?;
        ask_key(p, s, "mail_id", "Identifier of the mail notifier (idmail)")?;
        match s.check() {
            Ok(_) => return Ok(()),
            Err(e) => p.say(&format!("{e}. Again:")),
        }
    }
}

fn ask_key(
    p: &mut dyn Prompter,
    s: &mut Settings,
    key: &str,
    question: &str,
) -> anyhow::Result<()> {
    ask_key_with(p, s, key, question, None)
}

/// Asks for `key`, keeping its value on an empty answer; `max` bounds an integer further.
fn ask_key_with(
    p: &mut dyn Prompter,
    s: &mut Settings,
    key: &str,
    question: &str,
    max: Option<u64>,
) -> anyhow::Result<()> {
    let k = key_of(key);
    let default = k.show(s).map(|v| unquote(&v)).unwrap_or_default();
    let probe = s.clone();
    let check: Check = Rc::new(move |answer| {
        let mut trial = probe.clone();
        k.apply(&mut trial, &Raw::Text(answer.to_string()))?;
        match (max, crate::config::integer_text(answer)) {
            (Some(max), Some(n)) if n > i128::from(max) => {
                Err(format!("must be at most 0x{max:X} here"))
            }
            _ => Ok(()),
        }
    });
    let answer = p.text(question, &default, k.allowed, check)?;
    k.apply(s, &Raw::Text(answer)).map_err(anyhow::Error::msg)
}

/// Like [`ask_key`] for a key that may be unset: `-` unsets it.
fn ask_optional(
    p: &mut dyn Prompter,
    s: &mut Settings,
    key: &str,
    question: &str,
) -> anyhow::Result<()> {
    let k = key_of(key);
    let default = k.show(s).map_or_else(|| "-".to_string(), |v| unquote(&v));
    let probe = s.clone();
    let check: Check = Rc::new(move |answer| match answer.trim() {
        "-" => Ok(()),
        _ => k.apply(&mut probe.clone(), &Raw::Text(answer.to_string())),
    });
    let help = format!("{}; - for none", k.allowed);
    let answer = p.text(question, &default, &help, check)?;
    if answer.trim() == "-" {
        s.unset(k.name);
        Ok(())
    } else {
        k.apply(s, &Raw::Text(answer)).map_err(anyhow::Error::msg)
    }
}

fn key_of(name: &str) -> &'static config::Key {
    KEYS.iter()
        .find(|k| k.name == name)
        .expect("the wizard asks for known keys")
}

/// A TOML string literal's text (`"vcan0"` → `vcan0`); other literals as they are.
fn unquote(literal: &str) -> String {
    match literal.parse::<toml::Value>() {
        Ok(toml::Value::String(s)) => s,
        _ => literal.to_string(),
    }
}

/// Shows the registers and writes the file after a last confirmation.
pub fn write(p: &mut dyn Prompter, settings: &Settings, path: &Path) -> anyhow::Result<()> {
    let checked = settings.check()?;
    p.say(config::registers(&checked.controller, settings.timing().is_some()).trim_end());
    if !p.confirm(&format!("Write {}?", path.display()), true)? {
        p.say("Nothing written.");
        return Ok(());
    }
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    buslab_link::fs::write_atomic(path, config::render_file(settings).as_bytes())?;
    p.say(&format!("Wrote {}.", path.display()));
    Ok(())
}

/// The questions on the terminal, with `inquire`.
struct Terminal;

fn asked(e: inquire::InquireError) -> anyhow::Error {
    match e {
        inquire::InquireError::OperationCanceled | inquire::InquireError::OperationInterrupted => {
            anyhow::anyhow!("cancelled; nothing written")
        }
        other => anyhow::anyhow!("cannot ask on the terminal: {other}"),
    }
}

impl Prompter for Terminal {
    fn select(&mut self, question: &str, options: &[&str], start: usize) -> anyhow::Result<usize> {
        inquire::Select::new(question, options.to_vec())
            .with_starting_cursor(start)
            .raw_prompt()
            .map(|o| o.index)
            .map_err(asked)
    }

    fn text(
        &mut self,
        question: &str,
        default: &str,
        help: &str,
        check: Check,
    ) -> anyhow::Result<String> {
        line::ask(question, default, help, &*check).map_err(|e| match e {
            line::AskError::Cancelled => anyhow::anyhow!("cancelled; nothing written"),
            line::AskError::Io(e) => anyhow::anyhow!("cannot ask on the terminal: {e}"),
        })
    }

    fn confirm(&mut self, question: &str, default: bool) -> anyhow::Result<bool> {
        inquire::Confirm::new(question)
            .with_default(default)
            .prompt()
            .map_err(asked)
    }

    fn say(&mut self, text: &str) {
        println!("{text}");
    }
}

#[cfg(test)]
mod tests;
