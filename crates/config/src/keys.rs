//! Every key of `buslab.toml`: its name, what it accepts, how it is read and shown, and the
//! checks between keys once all are read.

use std::time::Duration;

use buslab_backends::mqtt::Credentials;
use buslab_backends::resolve;
use buslab_canbus::{
    AcceptanceFilter, CanMode, ClockOut, ConfigError as ChipError, ControllerMode,
    ControllerSettings, ManagerConfig, Sja1000Config, Timing, TimingSetting,
};

use super::value::{self, Raw, quoted};
use super::{Config, ConfigError, MailSettings, Password, Source, expand_home};

/// The acceptance filter's kind (`controller.filter`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FilterKind {
    AcceptAll,
    /// BasicCAN: 8 bits on ID.10..3.
    Basic,
    /// PeliCAN single 32-bit filter.
    Single,
    /// PeliCAN dual filter.
    Dual,
}

impl FilterKind {
    pub const NAMES: [&'static str; 4] = ["accept-all", "basic", "single", "dual"];
    const ALL: [FilterKind; 4] = [Self::AcceptAll, Self::Basic, Self::Single, Self::Dual];

    pub fn name(self) -> &'static str {
        Self::NAMES[Self::ALL.iter().position(|&k| k == self).unwrap_or(0)]
    }

    /// The largest acceptance code or mask: 8 bits for BasicCAN's filter, else 32.
    pub fn max_code(self) -> u32 {
        match self {
            FilterKind::Basic => 0xFF,
            _ => u32::MAX,
        }
    }
}

/// The controller modes as the file names them.
pub const MODE_NAMES: [&str; 4] = ["PeliCAN", "BasicCAN", "listen-only", "self-test"];

/// Every value of the file, typed, before the checks between keys.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// As written (`vcan0`, a URL).
    pub bus: String,
    pub log_file: Option<String>,
    pub loader_id: u16,
    pub mail_id: u16,
    pub mail_host: Option<String>,
    pub mail_port: u16,
    pub mail_user: Option<String>,
    pub mail_interval: Duration,
    pub mqtt_username: Option<String>,
    pub mqtt_password: Option<Password>,
    pub poll_interval: Duration,
    pub mode: ControllerMode,
    pub crystal_hz: u32,
    /// `None`: the bus's (buslab's bus) or the adapter's, left as it is.
    pub bitrate: Option<u32>,
    /// Per mille; `None`: CiA's for the bit rate.
    pub sample_point: Option<u32>,
    pub btr0: Option<u8>,
    pub btr1: Option<u8>,
    pub filter: FilterKind,
    pub acceptance_code: u32,
    /// `None`: every bit "don't care" (0xFF or 0xFFFFFFFF).
    pub acceptance_mask: Option<u32>,
    pub output_control: u8,
    pub clock_out: bool,
    pub clock_divider: u8,
}

/// Defaults: buslab's bus, the bit rate left to the bus or the adapter, the seed's loader
/// identifier 0, MoniCAN's mail identifier 0x700, the host library's manager and SJA1000
/// defaults otherwise (docs/decisions.md).
impl Default for Settings {
    fn default() -> Self {
        let chip = Sja1000Config::default();
        Self {
            bus: buslab_backends::DEFAULT_NAME.to_string(),
            log_file: None,
            loader_id: 0,
            mail_id: buslab_monican::DEFAULT_MAIL_ID,
            mail_host: None,
            mail_port: 143,
            mail_user: None,
            mail_interval: Duration::from_secs(60),
            mqtt_username: None,
            mqtt_password: None,
            poll_interval: ManagerConfig::default().poll_interval,
            mode: ControllerMode::PeliCan,
            crystal_hz: chip.crystal_hz,
            bitrate: None,
            sample_point: None,
            btr0: None,
            btr1: None,
            filter: FilterKind::AcceptAll,
            acceptance_code: 0,
            acceptance_mask: None,
            output_control: chip.output_control,
            clock_out: chip.clock_out != ClockOut::Off,
            clock_divider: match chip.clock_out {
                ClockOut::Divider(d) => d,
                ClockOut::Off => 2,
            },
        }
    }
}

/// One key of the file.
pub struct Key {
    /// `mail.host`: the section, a dot, the name.
    pub name: &'static str,
    /// What is accepted, as the error says it.
    pub allowed: &'static str,
    /// What it is for.
    pub help: &'static str,
    /// JerryCAN's name for it in `jerrycan.properties`, if it had one.
    pub jerrycan: Option<&'static str>,
    /// Which commands use it; for the controller's keys, which transports apply it.
    pub used_by: &'static str,
    apply: fn(&mut Settings, &Raw, &str) -> Result<(), String>,
    show: fn(&Settings) -> Option<String>,
}

impl Key {
    /// The environment variable that overrides it: `BUSLAB_MAIL_HOST`.
    pub fn env(&self) -> String {
        format!(
            "BUSLAB_{}",
            self.name.replace('.', "_").to_ascii_uppercase()
        )
    }

    /// Reads `raw` into `settings`; the error says what is allowed.
    pub fn apply(&self, settings: &mut Settings, raw: &Raw) -> Result<(), String> {
        (self.apply)(settings, raw, self.allowed)
    }

    /// The value in `settings` as a TOML literal; `None` when unset.
    pub fn show(&self, settings: &Settings) -> Option<String> {
        (self.show)(settings)
    }

    /// The section (`mail`), or `None` at the top.
    pub fn section(&self) -> Option<&'static str> {
        self.name.split_once('.').map(|(s, _)| s)
    }

    /// The name inside its section (`host`).
    pub fn leaf(&self) -> &'static str {
        self.name.rsplit_once('.').map_or(self.name, |(_, l)| l)
    }
}

const ID_ALLOWED: &str =
    "must be an 11-bit identifier 0x000..=0x7EF (CAN 2.0A forbids 0x7F0..=0x7FF)";

fn id(raw: &Raw) -> Result<u16, String> {
    value::integer(raw, 0, u64::from(buslab_can::SFF_MAX_CAN20A), ID_ALLOWED).map(|n| n as u16)
}

fn hex_id(id: u16) -> Option<String> {
    Some(format!("0x{id:03X}"))
}

fn byte(raw: &Raw, allowed: &str) -> Result<u8, String> {
    value::integer(raw, 0, 0xFF, allowed).map(|n| n as u8)
}

fn duration_text(d: Duration) -> Option<String> {
    Some(quoted(&humantime::format_duration(d).to_string()))
}

/// Text without control characters, `1..=max` bytes.
fn plain(raw: &Raw, max: usize, allowed: &str) -> Result<String, String> {
    let t = value::text(raw)?;
    if t.is_empty() || t.len() > max || t.chars().any(char::is_control) {
        return Err(allowed.to_string());
    }
    Ok(t.to_string())
}

/// The keys, in the order `config show` prints them.
pub static KEYS: &[Key] = &[
    Key {
        name: "bus",
        allowed: "must be a bus as --bus takes it: vcan0 (buslab's bus on this machine), an interface (can0), an SLCAN adapter's path (/dev/ttyACM0), socketcand://HOST[:PORT][/CHANNEL], socketcan:IFACE or slcan:DEVICE",
        help: "the bus a CAN command uses when none is given (--bus, IFACE)",
        jerrycan: None,
        used_by: "every CAN command given no --bus or IFACE: dump, send, gen, regs, status, monitor, web, slio, monican, play, load, sendfile, recvfile, mail, bridge, slcan serve",
        apply: |s, raw, allowed| {
            let t = value::text(raw)?;
            resolve(t).map_err(|e| format!("{}; {}", e.problem, allowed))?;
            s.bus = t.to_string();
            Ok(())
        },
        show: |s| Some(quoted(&s.bus)),
    },
    Key {
        name: "log_file",
        allowed: "must be a file path (relative to the current directory; ~/ is the home folder)",
        help: "the log `buslab dump -w` writes every frame to (its format from the extension, as with -l)",
        jerrycan: Some("logfile"),
        used_by: "buslab dump -w",
        apply: |s, raw, allowed| {
            let t = plain(raw, 4096, allowed)?;
            s.log_file = Some(t);
            Ok(())
        },
        show: |s| s.log_file.as_deref().map(quoted),
    },
    Key {
        name: "loader_id",
        allowed: ID_ALLOWED,
        help: "the identifier of the loader handshake's remote frame (buslab load)",
        jerrycan: Some("idloader"),
        used_by: "buslab load",
        apply: |s, raw, _| {
            s.loader_id = id(raw)?;
            Ok(())
        },
        show: |s| hex_id(s.loader_id),
    },
    Key {
        name: "mail_id",
        allowed: ID_ALLOWED,
        help: "the identifier the mail notifier announces and sends mail on (buslab mail, MoniCAN)",
        jerrycan: Some("idmail"),
        used_by: "buslab mail, buslab monican",
        apply: |s, raw, _| {
            s.mail_id = id(raw)?;
            Ok(())
        },
        show: |s| hex_id(s.mail_id),
    },
    Key {
        name: "mail.host",
        allowed: "must be a host name or address, 1..=253 characters without spaces or /",
        help: "the IMAP server the mail notifier polls",
        jerrycan: Some("host"),
        used_by: "buslab mail",
        apply: |s, raw, allowed| {
            let t = plain(raw, 253, allowed)?;
            if t.contains(|c: char| c.is_whitespace() || c == '/') {
                return Err(allowed.to_string());
            }
            s.mail_host = Some(t);
            Ok(())
        },
        show: |s| s.mail_host.as_deref().map(quoted),
    },
    Key {
        name: "mail.port",
        allowed: "must be a TCP port 1..=65535",
        help: "the IMAP server's port",
        jerrycan: None,
        used_by: "buslab mail",
        apply: |s, raw, allowed| {
            s.mail_port = value::integer(raw, 1, 65535, allowed)? as u16;
            Ok(())
        },
        show: |s| Some(s.mail_port.to_string()),
    },
    Key {
        name: "mail.user",
        allowed: "must be a user name, 1..=256 characters without control characters",
        help: "the mailbox's user name",
        jerrycan: None,
        used_by: "buslab mail",
        apply: |s, raw, allowed| {
            s.mail_user = Some(plain(raw, 256, allowed)?);
            Ok(())
        },
        show: |s| s.mail_user.as_deref().map(quoted),
    },
    Key {
        name: "mail.interval",
        allowed: "must be a duration with its unit from 1s to 1day, e.g. \"60s\" or \"5min\"",
        help: "how often the mailbox is checked for new mail",
        jerrycan: Some("mailsleepingtime"),
        used_by: "buslab mail",
        apply: |s, raw, allowed| {
            let max = Duration::from_secs(86_400);
            s.mail_interval = value::duration(raw, Duration::from_secs(1), max, allowed)?;
            Ok(())
        },
        show: |s| duration_text(s.mail_interval),
    },
    Key {
        name: "mqtt.username",
        allowed: "must be a user name, 1..=256 characters without control characters",
        help: "the user name mqtt:// buses log in to the broker with (never on the command line)",
        jerrycan: None,
        used_by: "every command given an mqtt:// or mqtts:// bus, bus serve --join, status --bus",
        apply: |s, raw, allowed| {
            s.mqtt_username = Some(plain(raw, 256, allowed)?);
            Ok(())
        },
        show: |s| s.mqtt_username.as_deref().map(quoted),
    },
    Key {
        name: "mqtt.password",
        allowed: "must be a password, 1..=1024 characters without control characters",
        help: "the password with mqtt.username (never on the command line; keep the file readable by you only)",
        jerrycan: None,
        used_by: "every command given an mqtt:// or mqtts:// bus, bus serve --join, status --bus",
        apply: |s, raw, allowed| {
            s.mqtt_password = Some(Password::new(plain(raw, 1024, allowed)?));
            Ok(())
        },
        show: |s| s.mqtt_password.as_ref().map(|p| quoted(p.expose())),
    },
    Key {
        name: "manager.poll_interval",
        allowed: "must be a duration with its unit from 0s (poll without pause) to 10s, e.g. \"1ms\"",
        help: "the host library's manager: the pause between polls of the chip when no request arrives",
        jerrycan: Some("managersleepingtime"),
        used_by: "no buslab command: the host library's Manager (Config::manager_config)",
        apply: |s, raw, allowed| {
            let max = Duration::from_secs(10);
            s.poll_interval = value::duration(raw, Duration::ZERO, max, allowed)?;
            Ok(())
        },
        show: |s| duration_text(s.poll_interval),
    },
    Key {
        name: "controller.mode",
        allowed: "must be \"PeliCAN\", \"BasicCAN\", \"listen-only\" or \"self-test\" (the last two PeliCAN)",
        help: "the SJA1000's mode: PeliCAN (CAN 2.0B), BasicCAN (PCA82C200, 11-bit IDs), or PeliCAN listen-only (receives, never acknowledges) or self-test (no acknowledge needed)",
        jerrycan: None,
        used_by: "buslab's bus: the client's SJA1000; SLCAN: listen-only as L, the others not; SocketCAN: not (netlink)",
        apply: |s, raw, allowed| {
            let i = value::choice(raw, &MODE_NAMES, allowed)?;
            s.mode = ControllerMode::ALL[i];
            Ok(())
        },
        show: |s| Some(quoted(s.mode.name())),
    },
    Key {
        name: "controller.crystal_hz",
        allowed: "must be the crystal frequency in Hz, 1000000..=24000000",
        help: "the SJA1000's crystal (the CAN clock is half of it)",
        jerrycan: None,
        used_by: "buslab's bus: the client's SJA1000 crystal; SLCAN and SocketCAN: only to compute the bit rate",
        apply: |s, raw, allowed| {
            let (min, max) = (
                buslab_canbus::config::MIN_CRYSTAL_HZ.into(),
                buslab_canbus::config::MAX_CRYSTAL_HZ.into(),
            );
            s.crystal_hz = value::integer(raw, min, max, allowed)? as u32;
            Ok(())
        },
        show: |s| Some(s.crystal_hz.to_string()),
    },
    Key {
        name: "controller.bitrate",
        allowed: "must be a bit rate 1..=1000000 bit/s: 125000, 125k, \"500 kbit/s\" or 1M",
        help: "the bit rate; BTR0/BTR1 are chosen as Linux does (or give btr0 and btr1); unset: the bus's or the adapter's",
        jerrycan: None,
        used_by: "buslab's bus: the client's BTR0/BTR1; SLCAN: S/s; SocketCAN: not (netlink: ip link … bitrate)",
        apply: |s, raw, allowed| {
            s.bitrate = Some(value::bitrate(raw, allowed)?);
            Ok(())
        },
        show: |s| s.bitrate.map(|b| b.to_string()),
    },
    Key {
        name: "controller.sample_point",
        allowed: "must be a sample point in per cent, 50..=95 (e.g. 87.5)",
        help: "the sample point with bitrate; default CiA's: 87.5 % up to 500 kbit/s, 80 % up to 800 kbit/s, 75 % above",
        jerrycan: None,
        used_by: "buslab's bus: the client's BTR0/BTR1; SLCAN: through s; SocketCAN: not (netlink)",
        apply: |s, raw, allowed| {
            let percent = value::number(raw, 50.0, 95.0, allowed)?;
            s.sample_point = Some((percent * 10.0).round() as u32);
            Ok(())
        },
        show: |s| {
            s.sample_point
                .map(|p| format!("{:.1}", f64::from(p) / 10.0))
        },
    },
    Key {
        name: "controller.btr0",
        allowed: "must be a register value 0x00..=0xFF",
        help: "BTR0 (SJW, prescaler), with btr1 instead of bitrate",
        jerrycan: None,
        used_by: "buslab's bus: the client's BTR0; SLCAN: s (or S for a standard rate); SocketCAN: not (netlink)",
        apply: |s, raw, allowed| {
            s.btr0 = Some(byte(raw, allowed)?);
            Ok(())
        },
        show: |s| s.btr0.map(|b| format!("0x{b:02X}")),
    },
    Key {
        name: "controller.btr1",
        allowed: "must be a register value 0x00..=0xFF",
        help: "BTR1 (SAM, TSEG2, TSEG1), with btr0 instead of bitrate",
        jerrycan: None,
        used_by: "buslab's bus: the client's BTR1; SLCAN: s (or S for a standard rate); SocketCAN: not (netlink)",
        apply: |s, raw, allowed| {
            s.btr1 = Some(byte(raw, allowed)?);
            Ok(())
        },
        show: |s| s.btr1.map(|b| format!("0x{b:02X}")),
    },
    Key {
        name: "controller.filter",
        allowed: "must be \"accept-all\", \"basic\" (BasicCAN), \"single\" or \"dual\" (PeliCAN)",
        help: "the acceptance filter: every frame, BasicCAN's 8 bits on ID.10..3, or PeliCAN's single or dual filter",
        jerrycan: None,
        used_by: "buslab's bus: the client's SJA1000; SLCAN: M/m (Lawicel) and checked by buslab; SocketCAN: kernel filters and checked by buslab",
        apply: |s, raw, allowed| {
            let i = value::choice(raw, &FilterKind::NAMES, allowed)?;
            s.filter = FilterKind::ALL[i];
            Ok(())
        },
        show: |s| Some(quoted(s.filter.name())),
    },
    Key {
        name: "controller.acceptance_code",
        allowed: "must be 0x00..=0xFF (filter \"basic\") or 0x00000000..=0xFFFFFFFF (ACR0..ACR3, ACR0 the high byte)",
        help: "ACR: the bits a frame must have where the mask says \"care\"",
        jerrycan: None,
        used_by: "buslab's bus: the client's ACR; SLCAN: M (Lawicel) and checked by buslab; SocketCAN: kernel filters and checked by buslab",
        apply: |s, raw, allowed| {
            s.acceptance_code = value::integer(raw, 0, u32::MAX.into(), allowed)? as u32;
            Ok(())
        },
        show: |s| Some(code_text(s.filter, s.acceptance_code)),
    },
    Key {
        name: "controller.acceptance_mask",
        allowed: "must be 0x00..=0xFF (filter \"basic\") or 0x00000000..=0xFFFFFFFF (AMR0..AMR3, AMR0 the high byte)",
        help: "AMR: bit 1 = \"don't care\"; default all 1 (every frame passes)",
        jerrycan: None,
        used_by: "buslab's bus: the client's AMR; SLCAN: m (Lawicel) and checked by buslab; SocketCAN: kernel filters and checked by buslab",
        apply: |s, raw, allowed| {
            let mask = value::integer(raw, 0, u32::MAX.into(), allowed)? as u32;
            s.acceptance_mask = Some(mask);
            Ok(())
        },
        show: |s| Some(code_text(s.filter, s.mask())),
    },
    Key {
        name: "controller.output_control",
        allowed: "must be an OCR value 0x00..=0xFF whose OCMODE (bits 1..0) is not 01, the test mode",
        help: "OCR: how TX0 and TX1 drive the bus (default 0xDA: normal mode, TX0 push-pull)",
        jerrycan: None,
        used_by: "buslab's bus only (the client's OCR); SLCAN, SocketCAN: not (no such command)",
        apply: |s, raw, allowed| {
            let ocr = byte(raw, allowed)?;
            if ocr & 0x03 == 0x01 {
                return Err(allowed.to_string());
            }
            s.output_control = ocr;
            Ok(())
        },
        show: |s| Some(format!("0x{:02X}", s.output_control)),
    },
    Key {
        name: "controller.clock_out",
        allowed: "must be true or false",
        help: "whether the CLKOUT pin runs (CDR.3 clear)",
        jerrycan: None,
        used_by: "buslab's bus only (the client's CDR); SLCAN, SocketCAN: not (no such command)",
        apply: |s, raw, _| {
            s.clock_out = value::boolean(raw)?;
            Ok(())
        },
        show: |s| Some(s.clock_out.to_string()),
    },
    Key {
        name: "controller.clock_divider",
        allowed: "must be 1, 2, 4, 6, 8, 10, 12 or 14",
        help: "CLKOUT = crystal / this divider",
        jerrycan: None,
        used_by: "buslab's bus only (the client's CDR); SLCAN, SocketCAN: not (no such command)",
        apply: |s, raw, allowed| {
            let d = value::integer(raw, 1, 14, allowed)? as u8;
            if ClockOut::Divider(d).cdr_bits().is_none() {
                return Err(allowed.to_string());
            }
            s.clock_divider = d;
            Ok(())
        },
        show: |s| Some(s.clock_divider.to_string()),
    },
];

/// The bit rate the library's checks assume when none is set (buslab's bus by default).
pub const DEFAULT_BUS_BITRATE: u32 = 500_000;

/// The part of the controller settings a `[controller]` key belongs to.
pub fn controller_part(name: &str) -> Option<buslab_canbus::ControllerPart> {
    use buslab_canbus::ControllerPart as P;
    Some(match name.strip_prefix("controller.")? {
        "mode" => P::Mode,
        "crystal_hz" | "bitrate" | "sample_point" | "btr0" | "btr1" => P::Timing,
        "filter" | "acceptance_code" | "acceptance_mask" => P::Filter,
        "output_control" => P::OutputControl,
        _ => P::ClockOut,
    })
}

/// The sections (tables) of the file.
pub const SECTIONS: [&str; 4] = ["mail", "mqtt", "manager", "controller"];

/// The keys `--set` refuses (`ps` shows a command line to every user) and `config show` and
/// error messages do not print.
pub const SECRET_KEYS: [&str; 2] = ["mqtt.username", "mqtt.password"];

/// Keys whose value is never printed.
pub fn hidden(name: &str) -> bool {
    name == "mqtt.password"
}

/// A key's index in [`KEYS`].
pub fn index(name: &str) -> Option<usize> {
    KEYS.iter().position(|k| k.name == name)
}

fn code_text(filter: FilterKind, value: u32) -> String {
    match filter {
        FilterKind::Basic => format!("0x{value:02X}"),
        _ => format!("0x{value:08X}"),
    }
}

/// Where each key's value came from, in [`KEYS`]' order.
#[derive(Clone, Debug, PartialEq)]
pub struct Sources(Vec<Source>);

impl Sources {
    pub fn defaults() -> Self {
        Self(vec![Source::Default; KEYS.len()])
    }

    pub fn get(&self, i: usize) -> &Source {
        &self.0[i]
    }

    pub fn set(&mut self, i: usize, source: Source) {
        self.0[i] = source;
    }

    fn given(&self, name: &str) -> bool {
        index(name).is_some_and(|i| self.0[i] != Source::Default)
    }

    fn of(&self, name: &str) -> Source {
        index(name).map_or(Source::Default, |i| self.0[i].clone())
    }
}

impl Settings {
    /// The acceptance mask in effect: every bit "don't care" unless given.
    pub fn mask(&self) -> u32 {
        self.acceptance_mask.unwrap_or(self.filter.max_code())
    }

    /// The timing: the registers if given, else the bit rate and sample point; `None` when
    /// neither is (the bus's or the adapter's bit rate).
    pub fn timing(&self) -> Option<Timing> {
        match (self.btr0, self.btr1, self.bitrate) {
            (Some(btr0), Some(btr1), _) => Some(Timing::Registers { btr0, btr1 }),
            (_, _, Some(bitrate)) => Some(Timing::Bitrate {
                bitrate,
                sample_point_permille: self.sample_point,
            }),
            _ => None,
        }
    }

    /// The SJA1000 configuration these settings describe (not yet validated).
    pub fn controller(&self) -> Sja1000Config {
        let code = self.acceptance_code;
        let mask = self.mask();
        let filter = match self.filter {
            FilterKind::AcceptAll => AcceptanceFilter::AcceptAll,
            FilterKind::Basic => AcceptanceFilter::Basic {
                code: code as u8,
                mask: mask as u8,
            },
            FilterKind::Single => AcceptanceFilter::Single {
                code: code.to_be_bytes(),
                mask: mask.to_be_bytes(),
            },
            FilterKind::Dual => AcceptanceFilter::Dual {
                code: code.to_be_bytes(),
                mask: mask.to_be_bytes(),
            },
        };
        let base = match self.mode.can_mode() {
            CanMode::Basic => Sja1000Config::basic_can(),
            CanMode::Peli => Sja1000Config::peli_can(),
        };
        Sja1000Config {
            mode: self.mode.can_mode(),
            listen_only: self.mode == ControllerMode::ListenOnly,
            self_test: self.mode == ControllerMode::SelfTest,
            // Unset: what buslab's bus runs at by default (only for the library's checks).
            timing: self.timing().unwrap_or(Timing::Bitrate {
                bitrate: DEFAULT_BUS_BITRATE,
                sample_point_permille: None,
            }),
            crystal_hz: self.crystal_hz,
            filter,
            output_control: self.output_control,
            clock_out: if self.clock_out {
                ClockOut::Divider(self.clock_divider)
            } else {
                ClockOut::Off
            },
            ..base
        }
    }

    /// A key's value as a [`ConfigError::Value`] for `allowed`.
    fn invalid(&self, sources: &Sources, name: &'static str, allowed: String) -> ConfigError {
        let i = index(name).expect("a known key");
        ConfigError::Value {
            origin: sources.get(i).clone(),
            key: name,
            value: KEYS[i].show(self).unwrap_or_else(|| "(unset)".into()),
            allowed,
        }
    }

    /// Checks the keys together, as the wizard sets them (each key once, no contradiction
    /// between what was given and what was left).
    pub fn check(&self) -> Result<Config, ConfigError> {
        self.finish(&Sources::defaults())
    }

    /// Unsets an optional key (`mail.host`, `log_file`, `controller.sample_point`).
    pub fn unset(&mut self, name: &str) {
        match name {
            "log_file" => self.log_file = None,
            "mail.host" => self.mail_host = None,
            "mail.user" => self.mail_user = None,
            "mqtt.username" => self.mqtt_username = None,
            "mqtt.password" => self.mqtt_password = None,
            "controller.sample_point" => self.sample_point = None,
            "controller.bitrate" => self.bitrate = None,
            _ => {}
        }
    }

    /// Whether `name` says something in these settings: the bit rate is not written beside
    /// the registers, nor a code or mask beside the filter that accepts everything.
    pub fn relevant(&self, name: &str) -> bool {
        let registers = self.btr0.is_some() && self.btr1.is_some();
        match name {
            "controller.bitrate" => !registers,
            "controller.sample_point" => !registers && self.bitrate.is_some(),
            "controller.crystal_hz" => self.timing().is_some(),
            "controller.acceptance_code" | "controller.acceptance_mask" => {
                self.filter != FilterKind::AcceptAll
            }
            "controller.clock_divider" => self.clock_out,
            _ => true,
        }
    }

    /// Checks the keys together and gives the configuration.
    pub fn finish(&self, sources: &Sources) -> Result<Config, ConfigError> {
        let conflict = |first, second, problem| ConfigError::Conflict {
            first,
            first_source: sources.of(first),
            second,
            second_source: sources.of(second),
            problem,
        };
        let bus =
            resolve(&self.bus).map_err(|e| self.invalid(sources, "bus", e.problem.to_string()))?;
        self.check_timing(sources, &conflict)?;
        self.check_filter(sources, &conflict)?;
        if self.mail_id == self.loader_id {
            return Err(conflict(
                "mail_id",
                "loader_id",
                "are the same identifier: the mail notifier and the loader need their own",
            ));
        }
        let monican = buslab_monican::Config {
            mail_id: self.mail_id,
            ..buslab_monican::Config::default()
        };
        if let Err(e) = monican.validate() {
            return Err(self.invalid(sources, "mail_id", format!("MoniCAN refuses it: {e}")));
        }
        let controller = self.controller();
        controller
            .validate()
            .map_err(|e| self.chip_error(sources, e))?;
        let controller_settings = self.controller_settings(&controller, sources);
        let mqtt_credentials = match (&self.mqtt_username, &self.mqtt_password) {
            (Some(user), Some(password)) => {
                let (u, p) = (sources.of("mqtt.username"), sources.of("mqtt.password"));
                let from = if u == p {
                    u.to_string()
                } else {
                    format!("{u} and {p}")
                };
                Some(Credentials::new(user.clone(), password.expose(), from))
            }
            (None, None) => None,
            (Some(_), None) => {
                return Err(conflict(
                    "mqtt.username",
                    "mqtt.password",
                    "go together: the password is missing",
                ));
            }
            (None, Some(_)) => {
                return Err(conflict(
                    "mqtt.password",
                    "mqtt.username",
                    "go together: the user name is missing",
                ));
            }
        };
        Ok(Config {
            bus,
            bus_name: self.bus.clone(),
            log_file: self.log_file.as_deref().map(expand_home),
            loader_id: self.loader_id,
            mail_id: self.mail_id,
            mail: MailSettings {
                host: self.mail_host.clone(),
                port: self.mail_port,
                user: self.mail_user.clone(),
                password: None,
                interval: self.mail_interval,
            },
            mqtt_credentials,
            manager_poll_interval: self.poll_interval,
            controller,
            controller_settings,
        })
    }

    /// The parts of the controller configuration that were given (file, environment,
    /// `--set`), to apply where a command opens a bus; the bit timing when a bit rate or the
    /// registers are set.
    fn controller_settings(&self, chip: &Sja1000Config, sources: &Sources) -> ControllerSettings {
        let given = |keys: &[&str]| keys.iter().any(|k| sources.given(k));
        let timing = self.timing().and_then(|_| chip.bit_timing().ok()).map(|t| {
            let (btr0, btr1) = t.registers();
            TimingSetting {
                crystal_hz: chip.crystal_hz,
                btr0,
                btr1,
            }
        });
        ControllerSettings {
            mode: given(&["controller.mode"]).then_some(self.mode),
            timing,
            filter: given(&[
                "controller.filter",
                "controller.acceptance_code",
                "controller.acceptance_mask",
            ])
            .then_some(chip.filter),
            output_control: given(&["controller.output_control"]).then_some(chip.output_control),
            clock_out: given(&["controller.clock_out", "controller.clock_divider"])
                .then_some(chip.clock_out),
        }
    }

    fn check_timing(
        &self,
        sources: &Sources,
        conflict: &dyn Fn(&'static str, &'static str, &'static str) -> ConfigError,
    ) -> Result<(), ConfigError> {
        let rate_key = ["controller.bitrate", "controller.sample_point"]
            .into_iter()
            .find(|k| sources.given(k));
        let btr_key = ["controller.btr0", "controller.btr1"]
            .into_iter()
            .find(|k| sources.given(k));
        if let (Some(rate), Some(btr)) = (rate_key, btr_key) {
            return Err(conflict(
                rate,
                btr,
                "both set the bit timing: give bitrate (and sample_point) or btr0 and btr1",
            ));
        }
        match (self.btr0, self.btr1) {
            (Some(_), None) => Err(conflict(
                "controller.btr0",
                "controller.btr1",
                "go together: btr1 is missing",
            )),
            (None, Some(_)) => Err(conflict(
                "controller.btr1",
                "controller.btr0",
                "go together: btr0 is missing",
            )),
            _ => Ok(()),
        }
    }

    fn check_filter(
        &self,
        sources: &Sources,
        conflict: &dyn Fn(&'static str, &'static str, &'static str) -> ConfigError,
    ) -> Result<(), ConfigError> {
        const FILTER: &str = "controller.filter";
        const MODE: &str = "controller.mode";
        match (self.filter, self.mode.can_mode()) {
            (FilterKind::AcceptAll, _) => {
                for key in ["controller.acceptance_code", "controller.acceptance_mask"] {
                    if sources.given(key) {
                        return Err(conflict(
                            key,
                            FILTER,
                            "do not go together: \"accept-all\" has no code or mask; set filter to \"basic\", \"single\" or \"dual\"",
                        ));
                    }
                }
            }
            (FilterKind::Basic, CanMode::Peli) => {
                return Err(conflict(
                    FILTER,
                    MODE,
                    "do not go together: the \"basic\" 8-bit filter is BasicCAN's; PeliCAN has \"single\" and \"dual\"",
                ));
            }
            (FilterKind::Single | FilterKind::Dual, CanMode::Basic) => {
                return Err(conflict(
                    FILTER,
                    MODE,
                    "do not go together: BasicCAN has only the \"basic\" 8-bit filter",
                ));
            }
            _ => {}
        }
        let max = self.filter.max_code();
        for (key, value) in [
            ("controller.acceptance_code", self.acceptance_code),
            ("controller.acceptance_mask", self.mask()),
        ] {
            if value > max {
                return Err(self.invalid(
                    sources,
                    key,
                    "must be 0x00..=0xFF with filter \"basic\" (8 bits on ID.10..3)".into(),
                ));
            }
        }
        Ok(())
    }

    /// The library's verdict, told against the key it concerns.
    fn chip_error(&self, sources: &Sources, e: ChipError) -> ConfigError {
        let timing_key = if self.btr0.is_some() {
            "controller.btr0"
        } else if sources.given("controller.sample_point") {
            "controller.sample_point"
        } else {
            "controller.bitrate"
        };
        let key = match e {
            ChipError::Crystal { .. } => "controller.crystal_hz",
            ChipError::Timing(_) => timing_key,
            ChipError::ClockDivider { .. } => "controller.clock_divider",
            ChipError::OutputTestMode { .. } => "controller.output_control",
            ChipError::FilterMode { .. } => "controller.filter",
            _ => "controller.mode",
        };
        let allowed = match &e {
            ChipError::Timing(t) => format!("{t} (crystal {} Hz)", self.crystal_hz),
            other => other.to_string(),
        };
        self.invalid(sources, key, allowed)
    }
}
