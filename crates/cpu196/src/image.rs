//! The board's persistent state (what survives a power cycle): boot configuration, serial
//! number, compression table, flash banks (with the configuration sets in blocks 28h/29h of
//! each bank), PIC program and EEPROM. Stored as TOML with hex strings
//! ([`Image::to_toml`], [`Image::from_toml`]); the host reads and writes the file.

use std::collections::BTreeMap;

use crate::acquisition::LogTable;
use crate::adconfig::{AdConfig, ChannelSetup, SampleFormat};
use crate::flash::Flash;
use crate::prginf::{self, ConfigSet};
use crate::program;
use crate::wire::{FLASH_BLOCK, PIC_BLOCK};

/// Link protocol of a serial port (`csboot.rs.Protocole196`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Protocol {
    Midi,
    Cpu196,
    None,
    Off,
}

/// Baud rates of the 3-bit `Bauds196` field; MIDI always runs at 31250.
pub const BAUD_RATES: [u32; 8] = [1200, 2400, 9600, 19200, 38400, 57600, 115200, 250000];

/// The boot configuration (`csboot`).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct BootConfig {
    pub protocol: Protocol,
    pub protocol_pic: Protocol,
    /// RS232 driver on (else TTL levels only).
    pub rs232: bool,
    /// Send and expect the watchdog (`FF`).
    pub watchdog: bool,
    pub watchdog_pic: bool,
    pub baud: u32,
    /// MIDI channel (0..16) or pipe address (0..63).
    pub address: u8,
    /// START word performed at boot (`8000h` bit set = no start).
    pub boot_start: u16,
    pub pwm196: [u8; 3],
    pub pic_pwm: u16,
    /// Battery thresholds on PIC channel 0 (8-bit, ascending); FFh disables.
    pub battery_thresholds: [u8; 3],
    pub pic_vref: u8,
    /// `c96inf.pwm[3]`: PWM speed and enables, clock out.
    #[serde(default)]
    pub pwm_flags: u8,
    /// `c96inf.p1masque`.
    #[serde(default)]
    pub p1_mask: u8,
    /// `picinf.cfg` (all ones: PIC not configured).
    #[serde(default = "unconfigured")]
    pub pic_cfg: [u8; 2],
    #[serde(default)]
    pub pic_cycle: [u8; 2],
    #[serde(default)]
    pub pic_adon: [u8; 2],
    #[serde(default)]
    pub pic_adrs: u8,
    #[serde(default)]
    pub pic_adr: u8,
}

fn unconfigured() -> [u8; 2] {
    [0xFF, 0xFF]
}

impl Default for BootConfig {
    fn default() -> Self {
        Self {
            protocol: Protocol::Cpu196,
            protocol_pic: Protocol::None,
            rs232: true,
            watchdog: true,
            watchdog_pic: false,
            baud: 115200,
            address: 0,
            boot_start: 0x8000,
            pwm196: [0; 3],
            pic_pwm: 0,
            battery_thresholds: [100, 140, 220],
            pic_vref: 0,
            pwm_flags: 0,
            p1_mask: 0xFF,
            pic_cfg: unconfigured(),
            pic_cycle: [0, 0],
            pic_adon: [0, 0],
            pic_adrs: 0,
            pic_adr: 0,
        }
    }
}

fn protocol_code(p: Protocol) -> u16 {
    match p {
        Protocol::Midi => 0,
        Protocol::Cpu196 => 1,
        Protocol::None => 2,
        Protocol::Off => 3,
    }
}

fn protocol_of(c: u16) -> Protocol {
    match c & 3 {
        0 => Protocol::Midi,
        1 => Protocol::Cpu196,
        2 => Protocol::None,
        _ => Protocol::Off,
    }
}

impl BootConfig {
    /// The `csboot` block (boot flash block 5): `info_valide` AA55h, the `rs` bit field (from
    /// bit 0: Protocole196:2, ProtocolePIC:2, Hardware, Watchdog196, WatchdogPIC, Bauds196:3,
    /// Adresse:6), `boot`, `c96inf {pwm[4], p1masque}`, `picinf {pwm[4], cfg[2], cycle[2],
    /// adon[2], adrs, seuil[3], adr, vref}`, then `user` bytes (`info_user`). Little-endian.
    pub fn to_csboot(&self, user: &[u8]) -> [u8; 256] {
        let mut b = [0u8; 256];
        b[0..2].copy_from_slice(&0xAA55u16.to_le_bytes());
        let baud = BAUD_RATES.iter().position(|&r| r == self.baud).unwrap_or(6) as u16;
        let rs = protocol_code(self.protocol)
            | protocol_code(self.protocol_pic) << 2
            | (self.rs232 as u16) << 4
            | (self.watchdog as u16) << 5
            | (self.watchdog_pic as u16) << 6
            | baud << 7
            | ((self.address & 0x3F) as u16) << 10;
        b[2..4].copy_from_slice(&rs.to_le_bytes());
        b[4..6].copy_from_slice(&self.boot_start.to_le_bytes());
        b[6..9].copy_from_slice(&self.pwm196);
        b[9] = self.pwm_flags;
        b[10] = self.p1_mask;
        b[11] = (self.pic_pwm >> 2) as u8;
        b[12] = ((self.pic_pwm & 3) as u8) << 6;
        b[15..17].copy_from_slice(&self.pic_cfg);
        b[17..19].copy_from_slice(&self.pic_cycle);
        b[19..21].copy_from_slice(&self.pic_adon);
        b[21] = self.pic_adrs;
        b[22..25].copy_from_slice(&self.battery_thresholds);
        b[25] = self.pic_adr;
        b[26] = self.pic_vref;
        let n = user.len().min(CSBOOT_USER);
        b[27..27 + n].copy_from_slice(&user[..n]);
        b
    }

    /// Decodes a `csboot` block; `None` if `info_valide` is not AA55h (the kernel then uses its
    /// defaults).
    pub fn from_csboot(b: &[u8; 256]) -> Option<(Self, Vec<u8>)> {
        if u16::from_le_bytes([b[0], b[1]]) != 0xAA55 {
            return None;
        }
        let rs = u16::from_le_bytes([b[2], b[3]]);
        let cfg = Self {
            protocol: protocol_of(rs),
            protocol_pic: protocol_of(rs >> 2),
            rs232: rs & 1 << 4 != 0,
            watchdog: rs & 1 << 5 != 0,
            watchdog_pic: rs & 1 << 6 != 0,
            baud: BAUD_RATES[((rs >> 7) & 7) as usize],
            address: (rs >> 10) as u8 & 0x3F,
            boot_start: u16::from_le_bytes([b[4], b[5]]),
            pwm196: [b[6], b[7], b[8]],
            pwm_flags: b[9],
            p1_mask: b[10],
            pic_pwm: ((b[11] as u16) << 2) | (b[12] >> 6) as u16,
            pic_cfg: [b[15], b[16]],
            pic_cycle: [b[17], b[18]],
            pic_adon: [b[19], b[20]],
            pic_adrs: b[21],
            battery_thresholds: [b[22], b[23], b[24]],
            pic_adr: b[25],
            pic_vref: b[26],
        };
        Some((cfg, b[27..].to_vec()))
    }
}

impl core::fmt::Display for BootConfig {
    /// The block `buslab cpu196 format boot` prints.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let start = if self.boot_start & 0x8000 != 0 {
            "none".to_string()
        } else {
            let s = crate::message::Start::from_word(self.boot_start & !0x6000);
            format!(
                "bank {} configuration {} (A/D {})",
                s.bank(),
                s.config(),
                if s.ad196() { "on" } else { "off" }
            )
        };
        writeln!(f, "boot configuration")?;
        writeln!(
            f,
            "  protocol        {:?} (PIC port {:?})",
            self.protocol, self.protocol_pic
        )?;
        writeln!(
            f,
            "  line            {} baud 8N1, {}",
            self.baud,
            if self.rs232 { "RS232" } else { "TTL" }
        )?;
        writeln!(
            f,
            "  watchdog        {}",
            if self.watchdog { "on" } else { "off" }
        )?;
        writeln!(f, "  address         {}", self.address)?;
        writeln!(f, "  boot START      {start}")?;
        writeln!(
            f,
            "  PWM             {:?} (PIC {})",
            self.pwm196, self.pic_pwm
        )?;
        write!(
            f,
            "  battery         thresholds {:?}",
            self.battery_thresholds
        )
    }
}

/// Changes to a boot configuration (`buslab cpu196 format boot-set`); `None` keeps a field.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BootEdit {
    pub baud: Option<u32>,
    pub watchdog: Option<bool>,
    pub thresholds: Option<[u8; 3]>,
    pub address: Option<u8>,
    /// The START word performed at boot (see [`crate::values::parse_boot_start`]).
    pub boot_start: Option<u16>,
}

/// A boot configuration value the board cannot hold.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum BootEditError {
    #[error("baud rate {0} is not one of {BAUD_RATES:?}")]
    Baud(u32),
    #[error("address {0} is out of range 0..63")]
    Address(u8),
}

impl BootConfig {
    /// Applies `edit`, checking every value first (nothing changes if one is refused).
    pub fn apply(&mut self, edit: &BootEdit) -> Result<(), BootEditError> {
        if let Some(b) = edit.baud.filter(|b| !BAUD_RATES.contains(b)) {
            return Err(BootEditError::Baud(b));
        }
        if let Some(a) = edit.address.filter(|&a| a > 63) {
            return Err(BootEditError::Address(a));
        }
        if let Some(b) = edit.baud {
            self.baud = b;
        }
        if let Some(w) = edit.watchdog {
            self.watchdog = w;
        }
        if let Some(t) = edit.thresholds {
            self.battery_thresholds = t;
        }
        if let Some(a) = edit.address {
            self.address = a;
        }
        if let Some(s) = edit.boot_start {
            self.boot_start = s;
        }
        Ok(())
    }
}

/// Bytes of `info_user` in the `csboot` block.
pub const CSBOOT_USER: usize = 256 - 27;

/// The persistent state.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    pub boot: BootConfig,
    pub serial: [u8; 8],
    pub compression: [u8; 8],
    pub log_table: LogTable,
    pub flash: Flash,
    pub pic_program: Vec<u8>,
    pub pic_eeprom: [u8; 256],
    /// The PIC's own kernel (CPUFORMAT `00`/`02`).
    pub pic_kernel: Vec<u8>,
    /// `csboot.info_user`.
    pub boot_user: Vec<u8>,
    /// Boot flash block 5 (`csboot`) erased: the kernel runs on its defaults until it is written.
    pub csboot_blank: bool,
}

/// buslab's stand-in for the lost serial-number cipher (`NSC`, CPUFORMAT's guard): byte i is
/// `serial[i]` rotated left by i, XOR A5h, XOR (i × 3Bh). It protects against accidents, not
/// attackers.
pub fn encrypt_serial(serial: &[u8; 8]) -> [u8; 8] {
    core::array::from_fn(|i| serial[i].rotate_left(i as u32) ^ 0xA5 ^ (i as u8).wrapping_mul(0x3B))
}

impl Default for Image {
    /// A board as shipped: bank 0 holds demo configuration sets (see `docs/cpu196.md`).
    fn default() -> Self {
        let mut flash = Flash::default();
        let (a, p) = prginf::encode(&demo_sets());
        flash
            .write(0, prginf::PRGINF_BLOCK, &a)
            .expect("blank at start");
        flash
            .write(0, prginf::PTRPRG_BLOCK, &p)
            .expect("blank at start");
        // Bank 1, set 0: the PWM playback of `pattern.bin` at 1 kHz.
        let mut bank1: [ConfigSet; 8] = Default::default();
        bank1[0].program = program::PWM_PLAYBACK;
        bank1[0].cycle1 = 1250;
        let (a, p) = prginf::encode(&bank1);
        flash
            .write(1, prginf::PRGINF_BLOCK, &a)
            .expect("blank at start");
        flash
            .write(1, prginf::PTRPRG_BLOCK, &p)
            .expect("blank at start");
        Self {
            boot: BootConfig::default(),
            serial: *b"BL196001",
            compression: [0x80, 0, 0, 0, 0, 0, 0, 0],
            log_table: LogTable::default(),
            flash,
            pic_program: vec![0xFF; 3 * PIC_BLOCK],
            pic_eeprom: [0xFF; 256],
            pic_kernel: vec![0xFF; PIC_BLOCK],
            boot_user: vec![0; CSBOOT_USER],
            csboot_blank: false,
        }
    }
}

/// The demo configuration sets of bank 0.
pub fn demo_sets() -> [ConfigSet; 8] {
    let mut sets: [ConfigSet; 8] = Default::default();
    // 1 kHz: T = 235 gives (75 + 5·235) × 0.8 µs = 1 ms.
    let set = |chs: &[u8], fmt, ratio| AdConfig::simple(chs, fmt, 235, ratio).encode();
    sets[0].ad_init = set(&[0, 1, 2, 3], SampleFormat::Bits10, 3);
    sets[1].ad_init = set(&[0, 1], SampleFormat::Bits10, 3);
    sets[1].program = program::LOGGER;
    sets[1].args[0] = 100;
    sets[2].ad_init = set(&[0], SampleFormat::Bits10, 3);
    sets[2].program = program::THRESHOLD_ALARM;
    sets[2].args = [0, 900, 0, 0, 0, 0, 0];
    sets[3].ad_init = set(&[0, 1], SampleFormat::Bits16, 3);
    sets[3].program = program::VIRTUAL_CHANNELS;
    sets[4].program = program::PULSE_TRAIN;
    sets[4].cycle1 = 1250;
    sets[4].args = [128, 10, 0, 0, 0, 0, 0];
    // 5: 4 channels in each format; 6: log8 of a centred input with a low-pass.
    let mut c5 = AdConfig::simple(&[0, 1, 2, 3], SampleFormat::Bits16, 235, 2);
    c5.channels[1] = ChannelSetup::from_byte(ChannelSetup::byte(true, SampleFormat::Bits10, 0));
    c5.channels[2] = ChannelSetup::from_byte(ChannelSetup::byte(true, SampleFormat::Bits8, 0));
    c5.channels[3] = ChannelSetup::from_byte(ChannelSetup::byte(true, SampleFormat::Log8, 0));
    sets[5].ad_init = c5.encode();
    let mut c6 = AdConfig::simple(&[0], SampleFormat::Log8, 235, 3);
    c6.channels[0] = ChannelSetup::from_byte(ChannelSetup::byte(true, SampleFormat::Log8, 2));
    sets[6].ad_init = c6.encode();
    // 7: PIC battery and channel 1 forwarded as FB samples at Fosc/(4096·2^3).
    sets[7].adon = [0x03, 0x03];
    sets[7].adrs = 0x03;
    sets
}

#[derive(serde::Serialize, serde::Deserialize)]
struct ImageFile {
    format: String,
    boot: BootConfig,
    serial: String,
    compression: String,
    log_table: String,
    blank_table: String,
    /// `"bank.block"` (hex) → 256 bytes in hex, for used blocks only.
    flash: BTreeMap<String, String>,
    pic_program: String,
    pic_eeprom: String,
    #[serde(default)]
    pic_kernel: Option<String>,
    #[serde(default)]
    boot_user: Option<String>,
    #[serde(default)]
    csboot_blank: bool,
}

const FORMAT: &str = "buslab-cpu196-image-1";

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

fn unhex(s: &str, want: usize, what: &str) -> Result<Vec<u8>, String> {
    let s = s.trim();
    if s.len() != want * 2 || !s.is_ascii() {
        return Err(format!(
            "{what} must be {want} bytes of hex, got {} characters",
            s.len()
        ));
    }
    // Hex digits only: `from_str_radix` would take a sign (`+f`).
    if !s.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(format!("{what} is not hex"));
    }
    (0..want)
        .map(|i| {
            u8::from_str_radix(&s[2 * i..2 * i + 2], 16).map_err(|_| format!("{what} is not hex"))
        })
        .collect()
}

impl Image {
    pub fn to_toml(&self) -> String {
        let file = ImageFile {
            format: FORMAT.into(),
            boot: self.boot.clone(),
            serial: hex(&self.serial),
            compression: hex(&self.compression),
            log_table: hex(&self
                .log_table
                .0
                .iter()
                .flat_map(|w| w.to_le_bytes())
                .collect::<Vec<_>>()),
            blank_table: hex(self.flash.blank_table()),
            flash: self
                .flash
                .used_blocks()
                .map(|(bank, block, d)| (format!("{bank}.{block:02x}"), hex(d)))
                .collect(),
            pic_program: hex(&self.pic_program),
            pic_eeprom: hex(&self.pic_eeprom),
            pic_kernel: Some(hex(&self.pic_kernel)),
            boot_user: Some(hex(&self.boot_user)),
            csboot_blank: self.csboot_blank,
        };
        toml::to_string(&file).expect("image serialises")
    }

    pub fn from_toml(text: &str) -> Result<Self, String> {
        let f: ImageFile = toml::from_str(text).map_err(|e| e.to_string())?;
        if f.format != FORMAT {
            return Err(format!("format is `{}`, expected `{FORMAT}`", f.format));
        }
        if f.boot.protocol != Protocol::Midi && !BAUD_RATES.contains(&f.boot.baud) {
            return Err(format!(
                "boot baud {} is not one of {BAUD_RATES:?}",
                f.boot.baud
            ));
        }
        let table = unhex(&f.log_table, 512, "log_table")?;
        let mut blocks = Vec::new();
        for (key, data) in &f.flash {
            let (bank, block) = key
                .split_once('.')
                .filter(|(a, b)| {
                    a.bytes().all(|c| c.is_ascii_digit())
                        && b.bytes().all(|c| c.is_ascii_hexdigit())
                })
                .and_then(|(a, b)| Some((a.parse::<u8>().ok()?, u8::from_str_radix(b, 16).ok()?)))
                .filter(|(bank, _)| *bank < 8)
                .ok_or_else(|| {
                    format!("flash key `{key}` is not BANK.BLOCK (bank 0..7, block hex)")
                })?;
            let d = unhex(data, FLASH_BLOCK, &format!("flash block {key}"))?;
            blocks.push((bank, block, d.try_into().expect("length checked")));
        }
        Ok(Self {
            boot: f.boot,
            serial: unhex(&f.serial, 8, "serial")?.try_into().expect("8"),
            compression: unhex(&f.compression, 8, "compression")?
                .try_into()
                .expect("8"),
            log_table: LogTable::from_bytes(&table.try_into().expect("512")),
            flash: Flash::restore(
                unhex(&f.blank_table, 256, "blank_table")?
                    .try_into()
                    .expect("256"),
                blocks,
            ),
            pic_program: unhex(&f.pic_program, 3 * PIC_BLOCK, "pic_program")?,
            pic_eeprom: unhex(&f.pic_eeprom, 256, "pic_eeprom")?
                .try_into()
                .expect("256"),
            pic_kernel: match &f.pic_kernel {
                Some(h) => unhex(h, PIC_BLOCK, "pic_kernel")?,
                None => vec![0xFF; PIC_BLOCK],
            },
            boot_user: match &f.boot_user {
                Some(h) => unhex(h, CSBOOT_USER, "boot_user")?,
                None => vec![0; CSBOOT_USER],
            },
            csboot_blank: f.csboot_blank,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_round_trips_through_toml() {
        let mut img = Image::default();
        img.flash.write(3, 0x61, &[7; 256]).unwrap();
        img.pic_eeprom[5] = 9;
        img.boot.baud = 250000;
        let text = img.to_toml();
        assert_eq!(Image::from_toml(&text).unwrap(), img);
    }

    #[test]
    fn csboot_round_trips() {
        let boot = BootConfig {
            baud: 19200,
            address: 42,
            watchdog: false,
            pic_pwm: 0x2A5,
            battery_thresholds: [1, 2, 0xFF],
            boot_start: 0x0041,
            ..Default::default()
        };
        let user: Vec<u8> = (0..CSBOOT_USER as u8).collect();
        let block = boot.to_csboot(&user);
        assert_eq!(BootConfig::from_csboot(&block), Some((boot, user)));
        assert_eq!(BootConfig::from_csboot(&[0xFF; 256]), None);
    }

    #[test]
    fn boot_edits_are_checked_before_anything_changes() {
        let mut boot = BootConfig::default();
        let edit = BootEdit {
            thresholds: Some([1, 2, 3]),
            address: Some(64),
            ..Default::default()
        };
        assert_eq!(boot.apply(&edit), Err(BootEditError::Address(64)));
        assert_eq!(boot, BootConfig::default());
        let edit = BootEdit {
            baud: Some(19200),
            watchdog: Some(false),
            boot_start: Some(0x0041),
            ..Default::default()
        };
        boot.apply(&edit).unwrap();
        assert_eq!(
            (boot.baud, boot.watchdog, boot.boot_start),
            (19200, false, 0x0041)
        );
        let shown = boot.to_string();
        assert!(
            shown.contains("line            19200 baud 8N1, RS232"),
            "{shown}"
        );
        assert!(
            shown.contains("boot START      bank 0 configuration 1 (A/D on)"),
            "{shown}"
        );
        assert!(
            BootConfig::default()
                .to_string()
                .ends_with("battery         thresholds [100, 140, 220]")
        );
        assert_eq!(
            boot.apply(&BootEdit {
                baud: Some(1234),
                ..Default::default()
            })
            .unwrap_err()
            .to_string(),
            "baud rate 1234 is not one of [1200, 2400, 9600, 19200, 38400, 57600, 115200, 250000]"
        );
    }

    #[test]
    fn bad_images_are_refused_with_the_reason() {
        assert!(Image::from_toml("garbage = [").is_err());
        let text = Image::default()
            .to_toml()
            .replace("baud = 115200", "baud = 1234");
        assert!(Image::from_toml(&text).unwrap_err().contains("1234"));
        let text = Image::default()
            .to_toml()
            .replace("[flash]", "[flash]\n\"9.60\" = \"00\"");
        assert!(Image::from_toml(&text).unwrap_err().contains("9.60"));
    }
}
