//! `< buslab_controller KEY=VALUE… >`: a client reprograms its own SJA1000 on buslab's bus with
//! the parts of its controller configuration it gives (docs/bus.md):
//!
//! | key | value |
//! |---|---|
//! | `mode` | `PeliCAN`, `BasicCAN`, `listen-only`, `self-test` |
//! | `crystal`, `btr0`, `btr1` | together: the crystal in Hz (decimal), BTR0 and BTR1 (hex) |
//! | `filter` | `accept-all`, `basic`, `single`, `dual`; the last three with `acr` and `amr` |
//! | `acr`, `amr` | hex: 2 digits with `basic`, else 8 (ACR0/AMR0 the first byte) |
//! | `ocr` | OCR, hex |
//! | `clkout` | `off`, or the divider 1, 2, 4, …, 14 (decimal) |
//!
//! Each key at most once, at least one; the server answers `< ok >` or `< error … >`.

use std::fmt;

use buslab_bus::{AcceptanceFilter, ClockOut, ControllerMode, ControllerSettings, TimingSetting};

use crate::ProtocolError;

/// The command's name.
pub const NAME: &str = "buslab_controller";

const KEYS: [&str; 9] = [
    "mode", "crystal", "btr0", "btr1", "filter", "acr", "amr", "ocr", "clkout",
];

fn bad(expected: &'static str, got: &str) -> ProtocolError {
    ProtocolError::Arguments {
        command: NAME,
        expected,
        got: got.to_string(),
    }
}

/// Reads the `KEY=VALUE` arguments.
pub fn parse(args: &[&str]) -> Result<ControllerSettings, ProtocolError> {
    let mut values: [Option<&str>; KEYS.len()] = [None; KEYS.len()];
    if args.is_empty() {
        return Err(bad(
            "KEY=VALUE… with keys mode, crystal btr0 btr1, filter acr amr, ocr, clkout",
            "",
        ));
    }
    for arg in args {
        let (key, value) = arg
            .split_once('=')
            .ok_or_else(|| bad("KEY=VALUE arguments", arg))?;
        let i = KEYS.iter().position(|k| *k == key).ok_or_else(|| {
            bad(
                "keys mode, crystal, btr0, btr1, filter, acr, amr, ocr, clkout",
                arg,
            )
        })?;
        if values[i].replace(value).is_some() {
            return Err(bad("each key once", arg));
        }
    }
    let get = |key: &str| values[KEYS.iter().position(|k| *k == key).unwrap_or(0)];
    let mut settings = ControllerSettings::default();
    if let Some(mode) = get("mode") {
        settings.mode = Some(
            ControllerMode::from_name(mode)
                .ok_or_else(|| bad("mode=PeliCAN, BasicCAN, listen-only or self-test", mode))?,
        );
    }
    settings.timing = match (get("crystal"), get("btr0"), get("btr1")) {
        (None, None, None) => None,
        (Some(crystal), Some(btr0), Some(btr1)) => Some(TimingSetting {
            crystal_hz: decimal(crystal)
                .filter(|hz| (1_000_000..=24_000_000).contains(hz))
                .ok_or_else(|| bad("crystal=HZ, 1000000..=24000000", crystal))?,
            btr0: hex(btr0, 2).ok_or_else(|| bad("btr0=HH (hex)", btr0))? as u8,
            btr1: hex(btr1, 2).ok_or_else(|| bad("btr1=HH (hex)", btr1))? as u8,
        }),
        _ => return Err(bad("crystal, btr0 and btr1 together", &args.join(" "))),
    };
    settings.filter = match (get("filter"), get("acr"), get("amr")) {
        (None, None, None) => None,
        (Some("accept-all"), None, None) => Some(AcceptanceFilter::AcceptAll),
        (Some("basic"), Some(acr), Some(amr)) => {
            let byte = |t: &str| hex(t, 2).map(|v| v as u8);
            Some(AcceptanceFilter::Basic {
                code: byte(acr).ok_or_else(|| bad("acr=HH with filter=basic", acr))?,
                mask: byte(amr).ok_or_else(|| bad("amr=HH with filter=basic", amr))?,
            })
        }
        (Some(kind @ ("single" | "dual")), Some(acr), Some(amr)) => {
            let code = hex(acr, 8)
                .ok_or_else(|| bad("acr=HHHHHHHH (8 hex digits)", acr))?
                .to_be_bytes();
            let mask = hex(amr, 8)
                .ok_or_else(|| bad("amr=HHHHHHHH (8 hex digits)", amr))?
                .to_be_bytes();
            Some(if kind == "single" {
                AcceptanceFilter::Single { code, mask }
            } else {
                AcceptanceFilter::Dual { code, mask }
            })
        }
        _ => {
            return Err(bad(
                "filter=accept-all, or filter=basic|single|dual with acr and amr",
                &args.join(" "),
            ));
        }
    };
    if let Some(ocr) = get("ocr") {
        settings.output_control = Some(hex(ocr, 2).ok_or_else(|| bad("ocr=HH (hex)", ocr))? as u8);
    }
    if let Some(clkout) = get("clkout") {
        let clock = match clkout {
            "off" => Some(ClockOut::Off),
            d => decimal(d)
                .and_then(|d| u8::try_from(d).ok())
                .map(ClockOut::Divider)
                .filter(|c| c.cdr_bits().is_some()),
        };
        settings.clock_out =
            Some(clock.ok_or_else(|| bad("clkout=off, 1, 2, 4, 6, 8, 10, 12 or 14", clkout))?);
    }
    Ok(settings)
}

/// Exactly `digits` hex digits.
fn hex(text: &str, digits: usize) -> Option<u32> {
    (text.len() == digits && text.bytes().all(|b| b.is_ascii_hexdigit()))
        .then(|| u32::from_str_radix(text, 16).ok())
        .flatten()
}

/// Decimal digits only.
fn decimal(text: &str) -> Option<u32> {
    (!text.is_empty() && text.len() <= 9 && text.bytes().all(|b| b.is_ascii_digit()))
        .then(|| text.parse().ok())
        .flatten()
}

/// The arguments as [`parse`] reads them.
pub struct Args<'a>(pub &'a ControllerSettings);

impl fmt::Display for Args<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.0;
        let mut sep = "";
        let mut put = |f: &mut fmt::Formatter<'_>, text: fmt::Arguments<'_>| {
            let r = write!(f, "{sep}{text}");
            sep = " ";
            r
        };
        if let Some(mode) = s.mode {
            put(f, format_args!("mode={}", mode.name()))?;
        }
        if let Some(t) = s.timing {
            put(
                f,
                format_args!(
                    "crystal={} btr0={:02X} btr1={:02X}",
                    t.crystal_hz, t.btr0, t.btr1
                ),
            )?;
        }
        if let Some(filter) = s.filter {
            let (code, mask) = filter.registers();
            match filter {
                AcceptanceFilter::AcceptAll => put(f, format_args!("filter=accept-all"))?,
                AcceptanceFilter::Basic { code, mask } => put(
                    f,
                    format_args!("filter=basic acr={code:02X} amr={mask:02X}"),
                )?,
                _ => put(
                    f,
                    format_args!(
                        "filter={} acr={:08X} amr={:08X}",
                        filter.kind_name(),
                        u32::from_be_bytes(code),
                        u32::from_be_bytes(mask)
                    ),
                )?,
            }
        }
        if let Some(ocr) = s.output_control {
            put(f, format_args!("ocr={ocr:02X}"))?;
        }
        match s.clock_out {
            Some(ClockOut::Off) => put(f, format_args!("clkout=off"))?,
            Some(ClockOut::Divider(d)) => put(f, format_args!("clkout={d}"))?,
            None => {}
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::command::Command;

    fn round_trip(settings: ControllerSettings) {
        let text = Command::Controller(settings).to_string();
        let inner = text.trim_start_matches('<').trim_end_matches('>');
        assert_eq!(
            Command::parse(inner),
            Ok(Command::Controller(settings)),
            "{text}"
        );
    }

    #[test]
    fn every_part_goes_over_and_back() {
        round_trip(ControllerSettings {
            mode: Some(ControllerMode::BasicCan),
            timing: Some(TimingSetting {
                crystal_hz: 16_000_000,
                btr0: 0x03,
                btr1: 0x1C,
            }),
            filter: Some(AcceptanceFilter::Basic {
                code: 0xE0,
                mask: 0x0F,
            }),
            output_control: Some(0x1A),
            clock_out: Some(ClockOut::Off),
        });
        round_trip(ControllerSettings {
            mode: Some(ControllerMode::ListenOnly),
            filter: Some(AcceptanceFilter::Dual {
                code: [0x20, 0x05, 0x40, 0x00],
                mask: [0x00, 0x00, 0x00, 0x1F],
            }),
            clock_out: Some(ClockOut::Divider(14)),
            ..ControllerSettings::default()
        });
        round_trip(ControllerSettings {
            filter: Some(AcceptanceFilter::AcceptAll),
            ..ControllerSettings::default()
        });
    }

    #[test]
    fn garbage_is_refused_with_what_is_expected() {
        for (inner, expected) in [
            ("buslab_controller", "KEY=VALUE"),
            ("buslab_controller mode", "KEY=VALUE"),
            ("buslab_controller colour=red", "keys mode"),
            (
                "buslab_controller mode=PeliCAN mode=BasicCAN",
                "each key once",
            ),
            ("buslab_controller mode=CAN-FD", "mode=PeliCAN"),
            ("buslab_controller btr0=03 btr1=1C", "together"),
            (
                "buslab_controller crystal=99 btr0=03 btr1=1C",
                "1000000..=24000000",
            ),
            (
                "buslab_controller crystal=16000000 btr0=+3 btr1=1C",
                "btr0=HH",
            ),
            (
                "buslab_controller filter=single acr=123",
                "filter=accept-all",
            ),
            (
                "buslab_controller filter=single acr=123 amr=001FFFFF",
                "8 hex digits",
            ),
            (
                "buslab_controller filter=basic acr=E0 amr=0F0",
                "amr=HH with filter=basic",
            ),
            (
                "buslab_controller filter=accept-all acr=00",
                "filter=accept-all",
            ),
            ("buslab_controller ocr=xyz", "ocr=HH"),
            ("buslab_controller clkout=3", "clkout=off"),
            ("buslab_controller clkout=99999999999", "clkout=off"),
        ] {
            let e = Command::parse(inner).unwrap_err().to_string();
            assert!(e.contains(expected), "{inner}: {e}");
        }
    }
}
