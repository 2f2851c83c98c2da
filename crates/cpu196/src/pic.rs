//! The PIC16F877A slave (SPEC C5): the 80C196 ↔ PIC command set and a model of the PIC's
//! answers. Commands `1x` read (and execute at once), `0x` write; 0..2 parameters.
//!
//! Every event read (`10`) returns two bytes `event, data` (data 00h when the event has none).

use std::collections::VecDeque;

use buslab_device::Nanos;

/// A command from the 80C196 to the PIC.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PicCommand {
    ReadEvent,
    ReadPortD,
    ReadEeprom,
    /// 5-bit reference (D/A).
    WriteVref(u8),
    WriteConfig([u8; 2]),
    /// PWM `n` (0/1) to the 10-bit `value`; sent as `(dd00 000n) high8`.
    WritePwm {
        n: u8,
        value: u16,
    },
    StopTimer,
    StopAd,
    /// 16-bit cycle in steps of 800 ns × 1/2/4/8 (`pp`).
    StartTimer {
        cycle: u16,
        prescale: u8,
    },
    /// `(0000 pfff) mask`.
    StartAd {
        rate: u8,
        mask: u8,
    },
    IoAddress(u8),
    EepromAddress(u8),
    SciWrite(u8),
    Spi {
        cmd: u8,
        data: u8,
    },
    PortDWrite(u8),
    EepromWrite(u8),
    User(u8),
}

impl PicCommand {
    pub fn encode(self) -> Vec<u8> {
        match self {
            Self::ReadEvent => vec![0x10],
            Self::ReadPortD => vec![0x11],
            Self::ReadEeprom => vec![0x12],
            Self::WriteVref(v) => vec![0x02, v & 0x1F],
            Self::WriteConfig(c) => vec![0x03, c[0], c[1]],
            Self::WritePwm { n, value } => vec![
                0x04,
                (((value & 3) as u8) << 6) | (n & 1),
                (value >> 2) as u8,
            ],
            Self::StopTimer => vec![0x15],
            Self::StopAd => vec![0x16],
            Self::StartTimer { cycle, prescale } => {
                vec![
                    0x07,
                    (cycle >> 8) as u8,
                    (cycle as u8 & 0xFC) | (prescale & 3),
                ]
            }
            Self::StartAd { rate, mask } => vec![0x08, rate & 0x0F, mask],
            Self::IoAddress(a) => vec![0x09, a],
            Self::EepromAddress(a) => vec![0x0A, a],
            Self::SciWrite(d) => vec![0x0B, d],
            Self::Spi { cmd, data } => vec![0x0C, cmd, data],
            Self::PortDWrite(d) => vec![0x0D, d],
            Self::EepromWrite(d) => vec![0x0E, d],
            Self::User(d) => vec![0x0F, d],
        }
    }

    /// Parses one command; `Err` names the offending byte.
    pub fn parse(b: &[u8]) -> Result<Self, String> {
        let need = |n: usize| -> Result<(), String> {
            if b.len() == n {
                Ok(())
            } else {
                Err(format!(
                    "PIC command {:02X}h takes {} parameter bytes, got {}",
                    b[0],
                    n - 1,
                    b.len() - 1
                ))
            }
        };
        let Some(&c) = b.first() else {
            return Err("empty PIC command".into());
        };
        let cmd = match c {
            0x10 | 0x11 | 0x12 | 0x15 | 0x16 => {
                need(1)?;
                match c {
                    0x10 => Self::ReadEvent,
                    0x11 => Self::ReadPortD,
                    0x12 => Self::ReadEeprom,
                    0x15 => Self::StopTimer,
                    _ => Self::StopAd,
                }
            }
            0x03 | 0x04 | 0x07 | 0x08 | 0x0C => {
                need(3)?;
                match c {
                    0x03 => Self::WriteConfig([b[1], b[2]]),
                    0x04 => Self::WritePwm {
                        n: b[1] & 1,
                        value: ((b[2] as u16) << 2) | (b[1] >> 6) as u16,
                    },
                    0x07 => Self::StartTimer {
                        cycle: ((b[1] as u16) << 8) | (b[2] & 0xFC) as u16,
                        prescale: b[2] & 3,
                    },
                    0x08 => Self::StartAd {
                        rate: b[1] & 0x0F,
                        mask: b[2],
                    },
                    _ => Self::Spi {
                        cmd: b[1],
                        data: b[2],
                    },
                }
            }
            0x02 | 0x09 | 0x0A | 0x0B | 0x0D | 0x0E | 0x0F => {
                need(2)?;
                let d = b[1];
                match c {
                    0x02 => Self::WriteVref(d & 0x1F),
                    0x09 => Self::IoAddress(d),
                    0x0A => Self::EepromAddress(d),
                    0x0B => Self::SciWrite(d),
                    0x0D => Self::PortDWrite(d),
                    0x0E => Self::EepromWrite(d),
                    _ => Self::User(d),
                }
            }
            other => return Err(format!("{other:02X}h is not a PIC command")),
        };
        Ok(cmd)
    }
}

/// An event the PIC reports on `rd_pic_event`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PicEvent {
    None,
    Error(u8),
    SciReceived(u8),
    SpiReceived(u8),
    Ad { channel: u8, value: u16 },
    SciTxDone,
    Comparator(u8),
    User { code: u8, data: u8 },
}

impl PicEvent {
    pub fn encode(self) -> [u8; 2] {
        match self {
            Self::None => [0x00, 0x00],
            Self::Error(e) => [0x20 | (e & 0x1F), 0],
            Self::SciReceived(d) => [0x40, d],
            Self::SpiReceived(d) => [0x60, d],
            Self::Ad { channel, value } => [
                0x80 | (((value & 3) as u8) << 3) | (channel & 7),
                (value >> 2) as u8,
            ],
            Self::SciTxDone => [0xA0, 0],
            Self::Comparator(c) => [0xC0 | (c & 3), 0],
            Self::User { code, data } => [0xE0 | (code & 0x1F), data],
        }
    }

    /// Decodes by the three high bits of the event byte.
    pub fn parse(b: [u8; 2]) -> Self {
        let [e, d] = b;
        match e >> 5 {
            0 => Self::None,
            1 => Self::Error(e & 0x1F),
            2 => Self::SciReceived(d),
            3 => Self::SpiReceived(d),
            4 => Self::Ad {
                channel: e & 7,
                value: ((d as u16) << 2) | ((e >> 3) & 3) as u16,
            },
            5 => Self::SciTxDone,
            6 => Self::Comparator(e & 3),
            _ => Self::User {
                code: e & 0x1F,
                data: d,
            },
        }
    }
}

/// Who answers on the PIC's SCI and SPI/I2C ports.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum Peer {
    /// What is sent comes back (a wire from TX to RX, MOSI to MISO).
    #[default]
    Loopback,
    /// Nothing answers.
    Silent,
    /// A scripted device: a byte sent gets these bytes back (SCI: each arrives; SPI: the
    /// first is clocked in). Unlisted bytes get nothing (SCI) or FFh (SPI).
    Script(std::collections::BTreeMap<u8, Vec<u8>>),
}

impl Peer {
    fn answer(&self, sent: u8) -> Vec<u8> {
        match self {
            Self::Loopback => vec![sent],
            Self::Silent => Vec::new(),
            Self::Script(table) => table.get(&sent).cloned().unwrap_or_default(),
        }
    }
}

impl core::str::FromStr for Peer {
    type Err = String;

    /// `loopback`, `silent`, or `script:SENT=REPLY,...` in hex, e.g. `script:41=4F4B,01=02`.
    fn from_str(s: &str) -> Result<Self, String> {
        let err = || {
            format!(
                "peer `{s}` is not loopback, silent or script:SENT=REPLY,... (hex bytes, e.g. script:41=4F4B)"
            )
        };
        match s {
            "loopback" => return Ok(Self::Loopback),
            "silent" => return Ok(Self::Silent),
            _ => {}
        }
        let body = s.strip_prefix("script:").ok_or_else(err)?;
        let mut table = std::collections::BTreeMap::new();
        for pair in body.split(',') {
            let (k, v) = pair.split_once('=').ok_or_else(err)?;
            let k = k.trim();
            let v = v.trim();
            // Hex digits only: `from_str_radix` would take a sign (`+f`).
            let hex = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_hexdigit());
            if !hex(k) || !hex(v) || v.len() % 2 != 0 {
                return Err(err());
            }
            let key = u8::from_str_radix(k, 16).map_err(|_| err())?;
            let reply = (0..v.len() / 2)
                .map(|i| u8::from_str_radix(&v[2 * i..2 * i + 2], 16))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|_| err())?;
            table.insert(key, reply);
        }
        Ok(Self::Script(table))
    }
}

/// PIC A/D converter clock: Fosc = 20 MHz.
const FOSC_HZ: u64 = 20_000_000;

/// State of the PIC slave.
#[derive(Clone, Debug)]
pub struct Pic {
    pub eeprom: [u8; 256],
    pub program: Vec<u8>,
    eeprom_addr: u8,
    pub vref: u8,
    pub config: [u8; 2],
    pub pwm: [u16; 2],
    pub port_d: u8,
    /// 1 = input.
    pub io_mask: u8,
    /// Level on port D inputs (defaults to the latch: a loopback plug).
    pub port_d_inputs: Option<u8>,
    pub timer: Option<(u16, u8)>,
    ad: Option<(u8, Nanos)>,
    next_ad: Nanos,
    ad_channel: u8,
    pub peer: Peer,
    events: VecDeque<PicEvent>,
    pub user_data: Vec<u8>,
}

impl Default for Pic {
    fn default() -> Self {
        Self {
            eeprom: [0xFF; 256],
            program: vec![0xFF; 3 * 4096],
            eeprom_addr: 0,
            vref: 0,
            config: [0xFF, 0xFF],
            pwm: [0; 2],
            port_d: 0,
            io_mask: 0xFF,
            port_d_inputs: None,
            timer: None,
            ad: None,
            next_ad: Nanos::ZERO,
            ad_channel: 0,
            peer: Peer::Loopback,
            events: VecDeque::new(),
            user_data: Vec::new(),
        }
    }
}

impl Pic {
    /// A PIC with this EEPROM and program memory.
    pub fn with_memory(eeprom: [u8; 256], program: Vec<u8>) -> Self {
        Self {
            eeprom,
            program,
            ..Self::default()
        }
    }

    /// Period between two conversions of one channel, for `(0000 pfff)`: the rate is Fosc/2048
    /// (p = 1) or Fosc/(4096·2^f) for all channels, so one channel gets 1/8 of it.
    pub fn ad_period_ns(rate: u8) -> Nanos {
        let div = if rate & 0x08 != 0 {
            2048
        } else {
            4096u64 << (rate & 7)
        };
        Nanos::new(8 * div * 1_000_000_000 / FOSC_HZ)
    }

    fn read_port_d(&self) -> u8 {
        let input = self.port_d_inputs.unwrap_or(self.port_d);
        (self.port_d & !self.io_mask) | (input & self.io_mask)
    }

    /// Executes a command at `now`; reads return their bytes.
    pub fn execute(&mut self, now: Nanos, cmd: PicCommand) -> Vec<u8> {
        match cmd {
            PicCommand::ReadEvent => {
                return self
                    .events
                    .pop_front()
                    .unwrap_or(PicEvent::None)
                    .encode()
                    .to_vec();
            }
            PicCommand::ReadPortD => return vec![self.read_port_d()],
            PicCommand::ReadEeprom => {
                let d = self.eeprom[self.eeprom_addr as usize];
                self.eeprom_addr = self.eeprom_addr.wrapping_add(1);
                return vec![d];
            }
            PicCommand::WriteVref(v) => self.vref = v & 0x1F,
            PicCommand::WriteConfig(c) => self.config = c,
            PicCommand::WritePwm { n, value } => self.pwm[n as usize & 1] = value & 0x3FF,
            PicCommand::StopTimer => self.timer = None,
            PicCommand::StopAd => self.ad = None,
            PicCommand::StartTimer { cycle, prescale } => self.timer = Some((cycle, prescale)),
            PicCommand::StartAd { rate, mask } => {
                let period = Self::ad_period_ns(rate) / 8;
                self.ad = Some((mask, period));
                self.next_ad = now + period;
            }
            PicCommand::IoAddress(a) => self.io_mask = a,
            PicCommand::EepromAddress(a) => self.eeprom_addr = a,
            PicCommand::SciWrite(d) => {
                self.events.push_back(PicEvent::SciTxDone);
                for b in self.peer.answer(d) {
                    self.events.push_back(PicEvent::SciReceived(b));
                }
            }
            PicCommand::Spi { data, .. } => {
                // SPI is full duplex: the peer's byte comes back as the clocked-out one goes.
                let back = self.peer.answer(data).first().copied().unwrap_or(0xFF);
                self.events.push_back(PicEvent::SpiReceived(back));
            }
            PicCommand::PortDWrite(d) => self.port_d = d,
            PicCommand::EepromWrite(d) => {
                self.eeprom[self.eeprom_addr as usize] = d;
                self.eeprom_addr = self.eeprom_addr.wrapping_add(1);
            }
            PicCommand::User(d) => self.user_data.push(d),
        }
        Vec::new()
    }

    /// Whether the A/D runs, and its mask.
    pub fn ad_mask(&self) -> Option<u8> {
        self.ad.map(|(m, _)| m)
    }

    /// When the next conversion is due.
    pub fn next_deadline(&self) -> Option<Nanos> {
        self.ad.map(|_| self.next_ad)
    }

    /// Runs the converter up to `now`; `sample(channel, t)` gives the 10-bit input. Conversions
    /// go round the 8 channels; masked ones raise an event.
    pub fn advance(&mut self, now: Nanos, sample: &mut dyn FnMut(u8, Nanos) -> u16) {
        let Some((mask, period)) = self.ad else {
            return;
        };
        while self.next_ad <= now {
            let ch = self.ad_channel;
            if mask & (1 << ch) != 0 {
                let value = sample(ch, self.next_ad);
                self.events.push_back(PicEvent::Ad { channel: ch, value });
            }
            self.ad_channel = (ch + 1) % 8;
            self.next_ad += period.max(Nanos::new(1));
        }
    }

    /// Drains pending events (what the kernel's `pic_event196` loop does).
    pub fn take_events(&mut self) -> Vec<PicEvent> {
        self.events.drain(..).collect()
    }

    /// Clears run-time state (a PIC reset), keeping program and EEPROM.
    pub fn reset(&mut self) {
        *self = Self {
            eeprom: self.eeprom,
            program: core::mem::take(&mut self.program),
            peer: core::mem::take(&mut self.peer),
            ..Self::default()
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_round_trip() {
        let cmds = [
            PicCommand::ReadEvent,
            PicCommand::ReadPortD,
            PicCommand::ReadEeprom,
            PicCommand::WriteVref(17),
            PicCommand::WriteConfig([0x12, 0x34]),
            PicCommand::WritePwm { n: 1, value: 0x2A7 },
            PicCommand::StopTimer,
            PicCommand::StopAd,
            PicCommand::StartTimer {
                cycle: 0x1234,
                prescale: 2,
            },
            PicCommand::StartAd {
                rate: 9,
                mask: 0x81,
            },
            PicCommand::IoAddress(0xF0),
            PicCommand::EepromAddress(7),
            PicCommand::SciWrite(0x41),
            PicCommand::Spi { cmd: 1, data: 2 },
            PicCommand::PortDWrite(0x55),
            PicCommand::EepromWrite(9),
            PicCommand::User(3),
        ];
        for c in cmds {
            assert_eq!(PicCommand::parse(&c.encode()), Ok(c), "{c:?}");
        }
        assert!(PicCommand::parse(&[0x01]).is_err());
        assert!(PicCommand::parse(&[0x0B]).is_err());
        assert!(PicCommand::parse(&[]).is_err());
    }

    #[test]
    fn events_round_trip() {
        for e in [
            PicEvent::None,
            PicEvent::Error(5),
            PicEvent::SciReceived(1),
            PicEvent::SpiReceived(2),
            PicEvent::Ad {
                channel: 5,
                value: 1021,
            },
            PicEvent::SciTxDone,
            PicEvent::Comparator(2),
            PicEvent::User { code: 3, data: 4 },
        ] {
            assert_eq!(PicEvent::parse(e.encode()), e);
        }
    }

    #[test]
    fn eeprom_auto_increments_and_bridges_loop_back() {
        let mut p = Pic::default();
        p.execute(Nanos::ZERO, PicCommand::EepromAddress(10));
        p.execute(Nanos::ZERO, PicCommand::EepromWrite(1));
        p.execute(Nanos::ZERO, PicCommand::EepromWrite(2));
        p.execute(Nanos::ZERO, PicCommand::EepromAddress(10));
        assert_eq!(p.execute(Nanos::ZERO, PicCommand::ReadEeprom), vec![1]);
        assert_eq!(p.execute(Nanos::ZERO, PicCommand::ReadEeprom), vec![2]);
        p.execute(Nanos::ZERO, PicCommand::SciWrite(0x33));
        assert_eq!(p.execute(Nanos::ZERO, PicCommand::ReadEvent), vec![0xA0, 0]);
        assert_eq!(
            p.execute(Nanos::ZERO, PicCommand::ReadEvent),
            vec![0x40, 0x33]
        );
        assert_eq!(p.execute(Nanos::ZERO, PicCommand::ReadEvent), vec![0, 0]);
        p.execute(Nanos::ZERO, PicCommand::IoAddress(0x0F));
        p.execute(Nanos::ZERO, PicCommand::PortDWrite(0xA5));
        p.port_d_inputs = Some(0x03);
        assert_eq!(p.execute(Nanos::ZERO, PicCommand::ReadPortD), vec![0xA3]);
    }

    #[test]
    fn scripted_peers_answer_from_their_table() {
        let mut p = Pic {
            peer: "script:41=4F4B,01=02".parse().unwrap(),
            ..Pic::default()
        };
        p.execute(Nanos::ZERO, PicCommand::SciWrite(0x41));
        assert_eq!(
            p.take_events(),
            vec![
                PicEvent::SciTxDone,
                PicEvent::SciReceived(0x4F),
                PicEvent::SciReceived(0x4B)
            ]
        );
        p.execute(Nanos::ZERO, PicCommand::Spi { cmd: 1, data: 0x01 });
        p.execute(Nanos::ZERO, PicCommand::Spi { cmd: 1, data: 0x07 });
        assert_eq!(
            p.take_events(),
            vec![PicEvent::SpiReceived(0x02), PicEvent::SpiReceived(0xFF)]
        );
        for bad in [
            "",
            "script:",
            "script:4=",
            "script:41=4",
            "script:zz=00",
            "loop",
        ] {
            assert!(bad.parse::<Peer>().is_err(), "{bad}");
        }
        assert_eq!("silent".parse::<Peer>(), Ok(Peer::Silent));
    }

    #[test]
    fn ad_rate_follows_the_seed() {
        // Fosc/2048 over all channels: 9765.6 conversions/s, one channel 1/8 of that.
        assert_eq!(Pic::ad_period_ns(0x08), Nanos::new(819_200));
        assert_eq!(Pic::ad_period_ns(0x01), Nanos::new(3_276_800));
        let mut p = Pic::default();
        p.execute(
            Nanos::ZERO,
            PicCommand::StartAd {
                rate: 0x08,
                mask: 0x01,
            },
        );
        p.advance(Nanos::new(819_200), &mut |ch, _| 100 + ch as u16);
        assert_eq!(
            p.take_events(),
            vec![PicEvent::Ad {
                channel: 0,
                value: 100
            }]
        );
    }
}
