//! The configuration as text: `config show` (every value and where it came from) and the file
//! the wizard writes. Both are valid TOML.

use std::fmt::Write;

use buslab_canbus::{CanMode, Sja1000Config};

use super::keys::{KEYS, Settings, Sources, controller_part, hidden};
use super::{ENV_MAIL_PASSWORD, Loaded, Source};

/// Where the `# source` comments start.
const COMMENT_COLUMN: usize = 44;

/// Every key with its effective value and, in a comment, where it came from; then the
/// registers the controller configuration programs. Secrets are not shown.
pub fn render_show(loaded: &Loaded) -> String {
    let mut out = String::new();
    match &loaded.file {
        Some((path, found)) => {
            let _ = writeln!(out, "# configuration file: {} ({found})", path.display());
        }
        None => out.push_str("# configuration file: none (defaults, environment, --set)\n"),
    }
    out.push_str(
        "# Each key with the commands that use it; the controller's keys apply to the node a\n\
         # command opens a bus with, each on the transports that have the setting.\n",
    );
    let applied = loaded.config.controller_settings.parts();
    body(&mut out, &loaded.settings, Some(&loaded.sources), &applied);
    let password = match &loaded.config.mail.password {
        Some(_) => format!("from ${ENV_MAIL_PASSWORD} (not shown)"),
        None => format!("not set: asked for when needed, or set ${ENV_MAIL_PASSWORD}"),
    };
    let _ = writeln!(out, "# mail password: {password}");
    out.push('\n');
    for line in registers(
        &loaded.config.controller,
        loaded.settings.timing().is_some(),
    )
    .lines()
    {
        let _ = writeln!(out, "# {line}");
    }
    if loaded.config.controller.filter != buslab_canbus::AcceptanceFilter::AcceptAll {
        for line in crate::filter::explain(&loaded.config.controller.filter).lines() {
            let _ = writeln!(out, "# {line}");
        }
    }
    let applied = &loaded.config.controller_settings;
    let _ = writeln!(
        out,
        "# applied when a command opens a bus: {}",
        if applied.is_empty() {
            "nothing (no [controller] key given: the bus's or the adapter's settings)".to_string()
        } else {
            applied.to_string()
        }
    );
    out
}

/// The file `buslab config wizard` writes: every key that has a value, each after its help.
pub fn render_file(settings: &Settings) -> String {
    let mut out = String::from(
        "# buslab configuration (docs/config.md), written by `buslab config wizard`.\n",
    );
    let defaults = Settings::default();
    let mut section = None;
    for key in KEYS.iter().filter(|k| settings.relevant(k.name)) {
        let Some(value) = key.show(settings) else {
            continue;
        };
        // A controller key in the file is applied where a command opens a bus: only what
        // differs from the chip's defaults is written, so the file asks for what was chosen.
        if key.section() == Some("controller") && key.show(&defaults).as_ref() == Some(&value) {
            continue;
        }
        if key.section() != section {
            section = key.section();
            let _ = write!(out, "\n[{}]\n", section.unwrap_or_default());
        }
        let _ = write!(out, "\n# {}\n{} = {value}\n", key.help, key.leaf());
    }
    out
}

fn body(
    out: &mut String,
    settings: &Settings,
    sources: Option<&Sources>,
    applied: &[buslab_canbus::ControllerPart],
) {
    let mut section = None;
    for (i, key) in KEYS.iter().enumerate() {
        if key.section() != section {
            section = key.section();
            let _ = write!(out, "\n[{}]\n", section.unwrap_or_default());
            if section == Some("controller") {
                out.push_str(
                    "# Applied to the node of every command that opens a bus (dump, send, gen,\n\
                     # monitor, web, regs, status, ...), each key where the transport has it.\n",
                );
            }
        }
        let source = sources.map_or(&Source::Default, |s| s.get(i));
        let _ = writeln!(out, "# {}: {}", key.leaf(), key.used_by);
        let line = match key.show(settings) {
            Some(_) if hidden(key.name) => format!("# {} = (set, not shown)", key.leaf()),
            Some(value) if !settings.relevant(key.name) => {
                format!("# {} = {value} (not used)", key.leaf())
            }
            // Not given: not applied, the bus's or the adapter's stays (as a comment, the text
            // read back applies the same).
            Some(value)
                if controller_part(key.name).is_some_and(|part| !applied.contains(&part)) =>
            {
                format!("# {} = {value} (not set: not applied)", key.leaf())
            }
            Some(value) => format!("{} = {value}", key.leaf()),
            None => format!("# {} (not set)", key.leaf()),
        };
        let pad = COMMENT_COLUMN.saturating_sub(line.chars().count()).max(1);
        let _ = writeln!(out, "{line}{:pad$}# {source}", "");
    }
}

/// What the controller configuration programs: MOD, CDR, OCR, BTR0/BTR1 with the bit rate
/// and sample point they give (when `timing_set`: else the bus's or adapter's stay), ACR/AMR.
pub fn registers(chip: &Sja1000Config, timing_set: bool) -> String {
    let mut out = String::new();
    let (acr, amr) = chip.filter.registers();
    let hex = |bytes: &[u8]| {
        bytes
            .iter()
            .map(|b| format!("{b:02X}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let (acr, amr) = match chip.mode {
        CanMode::Basic => (format!("{:02X}", acr[0]), format!("{:02X}", amr[0])),
        CanMode::Peli => (hex(&acr), hex(&amr)),
    };
    // BasicCAN has no MOD register (its CR bits are the driver's business).
    let mode = match chip.mode {
        CanMode::Peli => format!("MOD=0x{:02X} ", chip.mod_bits()),
        CanMode::Basic => String::new(),
    };
    let _ = writeln!(
        out,
        "registers: {mode}CDR=0x{:02X} OCR=0x{:02X} ACR={acr} AMR={amr}",
        chip.cdr(),
        chip.output_control
    );
    match chip.bit_timing() {
        _ if !timing_set => {
            out.push_str(
                "bit timing: not set: the bus's bit rate (buslab's bus) or the adapter's\n",
            );
        }
        Ok(t) => {
            let _ = writeln!(
                out,
                "bit timing: {} bit/s from a {} Hz crystal, {t}",
                t.bitrate(chip.can_clock_hz()),
                chip.crystal_hz
            );
        }
        Err(e) => {
            let _ = writeln!(out, "bit timing: {e}");
        }
    }
    out
}
