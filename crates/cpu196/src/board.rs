//! The CPU196 kernel (SPEC C2, C3) as a sans-IO state machine in virtual time: bytes from the
//! PC go in with their arrival time, bytes to the PC come out when their transmission at the
//! configured line rate has completed.

use std::collections::VecDeque;

use buslab_device::{ByteDevice, ChangeLog, Changes, LineSettings, Nanos, Persistent, ReplayError};

use crate::acquisition::Acquisition;
use crate::adconfig::AdConfig;
use crate::codes::{Alert, MsgCode};
use crate::decoder::{Decoder, Event, FrameError, PIC_CHUNK};
use crate::flash::FlashError;
use crate::image::{BootConfig, Image, Protocol, encrypt_serial};
use crate::message::*;
use crate::pic::{Pic, PicCommand, PicEvent};
use crate::prginf::{self, ConfigSet};
use crate::program::{Api, Flow, Registry, UserProgram};
use crate::source::Inputs;
use crate::wire::{self, PIC_BLOCK};

/// The board's own watchdog: an `FF` after this long without sending anything.
pub const WATCHDOG_PERIOD_NS: Nanos = Nanos::from_secs(1);
/// With the watchdog on, the lower loop stops if the PC is silent this long.
pub const LINK_LOST_NS: Nanos = Nanos::from_secs(3);
/// Battery check period.
pub const BATTERY_PERIOD_NS: Nanos = Nanos::from_millis(100);
/// Transmit FIFO size: A/D frames that would not fit are dropped (and `alert_ad_overrun`).
pub const TX_FIFO: usize = 4096;
/// Replies waiting beyond this mean the kernel is still inside its send routine when the next
/// byte arrives: that byte is lost. A PC flooding small requests for large replies (4-byte
/// PIC block reads get 4100 bytes) must not grow the queue without end.
pub const TX_BACKLOG: usize = 64 * 1024;
/// A START asked for by a hook while a START is being performed (an `init_prog` that starts
/// a set) is done this much later, on a later pass of the kernel, not recursively.
pub const NESTED_START_DELAY_NS: Nanos = Nanos::from_millis(1);
/// CPUFORMAT's emergency erase is accepted this long after a reset.
pub const EMERGENCY_WINDOW_NS: Nanos = Nanos::from_millis(100);
pub use crate::adconfig::MAX_LINE_SHARE;

/// Kernel commands refused in the lower loop (`_commande_invalide_[9]`).
pub const INVALID_IN_LOWER_LOOP: [u8; 9] = [
    wire::CPUINF,
    wire::START,
    wire::POWERDOWN,
    wire::PRGFLASH,
    wire::PRGPIC,
    wire::CPUFORMAT,
    wire::ADCONT,
    wire::ADSAMPLE,
    wire::CFGAD,
];

/// Counters for benchmarks and monitors.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// `FA` frames queued for the PC.
    pub fa_sent: u64,
    /// `FA` frames dropped because the transmit FIFO was full.
    pub fa_dropped: u64,
    /// Frame errors on the PC's stream.
    pub rx_errors: u64,
    /// Bytes from the PC lost because more than [`TX_BACKLOG`] bytes of replies waited.
    pub rx_lost: u64,
}

/// Which loop the kernel is in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Sleeping between events.
    Upper,
    /// After START: A/D and timers running, hooks called.
    Lower { bank: u8, config: u8 },
    /// Supply cut; only the power button wakes it.
    PoweredDown,
}

/// The transmitter: bytes leave one character time apart.
#[derive(Debug)]
struct Tx {
    queue: VecDeque<u8>,
    byte_ns: Nanos,
    /// Completion time of the front byte.
    front_done: Nanos,
    /// When the line became (or becomes) free after the last byte.
    free_at: Nanos,
    last_send: Nanos,
}

impl Tx {
    fn push(&mut self, at: Nanos, bytes: &[u8]) {
        if self.queue.is_empty() {
            self.front_done = at.max(self.free_at) + self.byte_ns;
        }
        self.queue.extend(bytes);
        self.last_send = at;
    }

    fn poll(&mut self, now: Nanos, out: &mut Vec<u8>) {
        while !self.queue.is_empty() && self.front_done <= now {
            out.push(self.queue.pop_front().expect("not empty"));
            self.free_at = self.front_done;
            self.front_done += self.byte_ns;
        }
    }

    fn deadline(&self) -> Option<Nanos> {
        (!self.queue.is_empty()).then_some(self.front_done)
    }
}

struct Run {
    set: ConfigSet,
    acq: Option<Acquisition>,
    program: Option<Box<dyn UserProgram>>,
    timers: [Option<(Nanos, Nanos)>; 2],
    overrun: bool,
}

/// The board.
pub struct Board {
    image: Image,
    /// Analog inputs (change them any time).
    pub inputs: Inputs,
    registry: Registry,
    line: LineSettings,
    decoder: Decoder,
    tx: Tx,
    mode: Mode,
    run: Option<Run>,
    pic: Pic,
    pwm196: [u8; 3],
    pic_ad: [u16; 8],
    adrs: u8,
    page: u8,
    last_rx: Nanos,
    battery: Option<u8>,
    next_battery: Nanos,
    next_file: u8,
    /// Counts changes of the image; `clean` is the count [`Board::take_dirty`] last saw.
    generation: u64,
    clean: u64,
    /// A START a hook asked for while a START was already being performed (an `init_prog`
    /// that starts a set), and when it is done.
    pending_start: Option<(Nanos, Start)>,
    /// Whether a hook-requested START is being performed.
    starting: bool,
    /// Changes of the image not yet taken by the host (for its journal).
    changes: ChangeLog,
    /// The PIC block write being received was refused at its first chunk.
    pic_write_refused: bool,
    log: Vec<String>,
    stats: Stats,
    reset_at: Nanos,
}

impl Board {
    /// Powers a board on at `now` with `image`; its line runs at the image's baud rate, 8N1.
    pub fn new(image: Image, inputs: Inputs, now: Nanos) -> Self {
        Self::with_registry(image, inputs, Registry::default(), now)
    }

    /// [`new`](Self::new) with these programs (and module runtime) already there for the
    /// boot START.
    pub fn with_registry(image: Image, inputs: Inputs, registry: Registry, now: Nanos) -> Self {
        let line = LineSettings::n81(if image.boot.protocol == Protocol::Midi {
            31250
        } else {
            image.boot.baud
        });
        let mut b = Self {
            pic: Pic::with_memory(image.pic_eeprom, image.pic_program.clone()),
            image,
            inputs,
            registry,
            line,
            decoder: Decoder::new(),
            tx: Tx {
                queue: VecDeque::new(),
                byte_ns: line.byte_time(),
                front_done: Nanos::ZERO,
                free_at: Nanos::ZERO,
                last_send: now,
            },
            mode: Mode::Upper,
            run: None,
            pwm196: [0; 3],
            pic_ad: [0; 8],
            adrs: 0,
            page: 0,
            last_rx: now,
            battery: None,
            next_battery: now,
            next_file: 0,
            generation: 0,
            clean: 0,
            pending_start: None,
            starting: false,
            changes: ChangeLog::default(),
            pic_write_refused: false,
            log: Vec::new(),
            stats: Stats::default(),
            reset_at: now,
        };
        b.boot(now);
        b
    }

    /// The line this board expects.
    pub fn line(&self) -> LineSettings {
        self.line
    }

    /// Overrides the line rate (and records it in the boot configuration).
    pub fn set_baud(&mut self, baud: u32) {
        self.image.boot.baud = baud;
        self.line = LineSettings::n81(baud);
        self.tx.byte_ns = self.line.byte_time();
        self.changed(None);
    }

    pub fn image(&self) -> &Image {
        &self.image
    }

    /// Whether the image changed since the last call (the adapter then saves it).
    pub fn take_dirty(&mut self) -> bool {
        let dirty = self.clean != self.generation;
        self.clean = self.generation;
        dirty
    }

    pub fn mode(&self) -> Mode {
        self.mode
    }

    pub fn stats(&self) -> Stats {
        self.stats
    }

    pub fn pwm(&self) -> [u8; 3] {
        self.pwm196
    }

    pub fn pic(&self) -> &Pic {
        &self.pic
    }

    /// Who answers on the PIC's SCI and SPI/I2C bridges.
    pub fn set_peer(&mut self, peer: crate::pic::Peer) {
        self.pic.peer = peer;
    }

    /// Registers a user program under `id` (word 0 of `ptrprg.user[n]`).
    pub fn registry_mut(&mut self) -> &mut Registry {
        &mut self.registry
    }

    fn note(&mut self, line: String) {
        // Bounded: a board nobody reads the log of must not grow.
        if self.log.len() >= 1000 {
            self.log.remove(0);
        }
        self.log.push(line);
    }

    /// Kernel log lines (what it did and refused), drained.
    pub fn take_log(&mut self) -> Vec<String> {
        core::mem::take(&mut self.log)
    }

    /// A rising edge on HSI.0 (the external user interrupt): in the lower loop, `user_prog`
    /// runs.
    pub fn external_interrupt(&mut self, now: Nanos) {
        self.advance(now);
        self.call_hook(now, |p, k| p.user(k));
    }

    /// Presses the power button (BPON): a powered-down board boots.
    pub fn power_button(&mut self, now: Nanos) {
        if self.mode == Mode::PoweredDown {
            self.boot(now);
        }
    }

    /// Reset: every variable reinitialised, report `F4 03`, then the boot START if any.
    fn boot(&mut self, now: Nanos) {
        self.reset_at = now;
        self.pending_start = None;
        self.mode = Mode::Upper;
        self.run = None;
        self.decoder = Decoder::new();
        self.pic.reset();
        self.pwm196 = self.image.boot.pwm196;
        self.pic.pwm[0] = self.image.boot.pic_pwm;
        self.pic.vref = self.image.boot.pic_vref;
        self.pic_ad = [0; 8];
        self.adrs = 0;
        self.battery = None;
        self.next_battery = now;
        self.last_rx = now;
        self.send(now, &Message::Power(Power::WasReset));
        // `sefm thhh pabb bnnn`: e and f (PIC A/D and timer kept) are not START bits.
        let boot = Start::from_word(self.image.boot.boot_start & !0x6000);
        if self.image.boot.boot_start & 0x8000 == 0 {
            self.start(now, boot, false);
        }
    }

    fn protocol_on(&self) -> bool {
        self.image.boot.protocol == Protocol::Cpu196
    }

    fn send(&mut self, at: Nanos, m: &Message) {
        if !self.protocol_on() {
            return;
        }
        let mut bytes = Vec::new();
        if let Err(e) = m.encode(&mut bytes) {
            self.note(format!("not sent: {e}"));
            return;
        }
        self.tx.push(at, &bytes);
    }

    fn msg(&mut self, at: Nanos, code: MsgCode) {
        self.send(at, &Message::Msg(code));
    }

    // ----- events -------------------------------------------------------------------------

    fn on_frame_error(&mut self, now: Nanos, e: FrameError) {
        self.stats.rx_errors += 1;
        self.note(format!("frame error: {e}"));
        let code = match e {
            FrameError::WrongComplement { .. } => MsgCode::RECEPTION_ERROR,
            FrameError::TimeOut { .. } => MsgCode::TIME_OUT,
            FrameError::Params(_) | FrameError::Parse(_) => MsgCode::INVALID_PARAMETER_VALUE,
        };
        self.msg(now, code);
    }

    fn on_message(&mut self, now: Nanos, m: Message) {
        // The first 15 chunks of a PIC block write were written and acknowledged as they came
        // (or the write was refused at the first one): the last chunk completes it.
        if let Message::PicWrite { block, data } = &m {
            let last = (PIC_BLOCK / PIC_CHUNK - 1) as u8;
            return self.pic_chunk(now, *block, last, &data[PIC_BLOCK - PIC_CHUNK..]);
        }
        let cmd = m.command();
        if matches!(self.mode, Mode::Lower { .. }) && INVALID_IN_LOWER_LOOP.contains(&cmd) {
            self.note(format!(
                "{} refused in the lower loop",
                wire::command_name(cmd)
            ));
            return self.msg(now, MsgCode::INVALID_COMMAND);
        }
        match m {
            Message::Watchdog => self.send(now, &Message::Watchdog),
            Message::CpuInfoRequest => {
                let info = self.cpu_info(now);
                self.send(now, &Message::CpuInfo(info));
            }
            Message::Start(s) => self.start(now, s, true),
            Message::Stop => {
                self.end_run(now);
                self.msg(now, MsgCode::COMPLETED);
            }
            Message::Power(Power::PowerDown) => {
                self.end_run(now);
                self.send(now, &Message::Power(Power::PoweredDown));
                self.mode = Mode::PoweredDown;
            }
            Message::Power(Power::Reset) => {
                self.end_run(now);
                self.boot(now);
            }
            Message::FlashReadRequest { bank, block } => match self.image.flash.read(bank, block) {
                Ok(d) => {
                    let data = Box::new(<[u8; 256]>::try_from(d).expect("block"));
                    self.send(now, &Message::FlashData(data));
                }
                Err(e) => self.flash_error(now, e),
            },
            Message::FlashWrite { bank, block, data } => {
                match self.image.flash.write(bank, block, &data) {
                    Ok(()) => {
                        self.changed(Some(ImageChange::flash_block(bank, block, &data)));
                        self.msg(now, MsgCode::COMPLETED);
                    }
                    Err(e) => self.flash_error(now, e),
                }
            }
            Message::FlashErase { bank } => match self.image.flash.erase(bank) {
                Ok(()) => {
                    self.changed(Some(ImageChange::erase_bank(bank)));
                    self.msg(now, MsgCode::COMPLETED);
                }
                Err(e) => self.flash_error(now, e),
            },
            Message::PicReadRequest { block } => match pic_range(block) {
                Some(r) => {
                    let data =
                        Box::new(<[u8; PIC_BLOCK]>::try_from(&self.pic.program[r]).expect("block"));
                    self.send(now, &Message::PicData(data));
                }
                None => self.bad_param(now, format!("PIC block {block} is out of range 1..3")),
            },
            Message::PicWrite { .. } => unreachable!("handled above"),
            Message::EepromReadRequest => {
                self.send(now, &Message::EepromData(Box::new(self.pic.eeprom)));
            }
            Message::EepromWrite(data) => {
                self.pic.eeprom = *data;
                self.image.pic_eeprom = *data;
                self.changed(Some(ImageChange::eeprom(&data)));
                self.msg(now, MsgCode::COMPLETED);
            }
            Message::Format(f) => self.format(now, f),
            Message::Pwm(Pwm::Set { n, low, value }) => {
                if n < 3 {
                    self.pwm196[n as usize] = value;
                } else {
                    self.pic.execute(
                        now,
                        PicCommand::WritePwm {
                            n: 0,
                            value: ((value as u16) << 2) | low as u16,
                        },
                    );
                }
            }
            Message::Pwm(Pwm::Dac(v)) => {
                if v > 31 {
                    self.bad_param(now, format!("D/A value {v} is out of range 0..31"));
                } else {
                    self.pic.execute(now, PicCommand::WriteVref(v));
                }
            }
            Message::Bridge(b) => self.bridge(now, b),
            Message::CfgAdRequest { bank, config } => match self.config_set(bank, config) {
                Some(set) => {
                    let m = Message::CfgAd {
                        c196: set.ad_init,
                        pic: [set.adon[0], set.adon[1], set.adrs],
                    };
                    self.send(now, &m);
                }
                None => self.bad_param(
                    now,
                    format!("bank {bank} holds no valid configuration table"),
                ),
            },
            Message::Thread(Thread::ReadData { data, file }) => {
                self.call_hook(now, |p, k| {
                    p.fread(k, file, &data);
                    Flow::CONTINUE
                });
            }
            // Replies to the board's file requests; nothing to do.
            Message::Msg(code) => self.note(format!("PC says {code}")),
            Message::User { cmd, params } => {
                if self.run.as_ref().is_some_and(|r| r.program.is_some()) {
                    self.call_hook(now, |p, k| {
                        p.rs(k, cmd, &params);
                        Flow::CONTINUE
                    });
                } else {
                    self.note(format!("user command {cmd:02X}h with no program running"));
                    self.msg(now, MsgCode::INVALID_COMMAND);
                }
            }
            other => {
                self.note(format!(
                    "{} is not a command a PC sends",
                    wire::command_name(other.command())
                ));
                self.msg(now, MsgCode::INVALID_COMMAND);
            }
        }
    }

    /// CPUFORMAT (`F7`).
    fn format(&mut self, now: Nanos, f: Format) {
        let guard = |nsc: &[u8; 8], img: &Image| *nsc == encrypt_serial(&img.serial);
        match f {
            Format::ReadPicKernel { nsc }
            | Format::WritePicKernel { nsc, .. }
            | Format::NewSerial { nsc, .. }
                if !guard(&nsc, &self.image) =>
            {
                self.bad_param(
                    now,
                    "CPUFORMAT: the encrypted serial number does not match this board".into(),
                )
            }
            Format::ReadPicKernel { .. } => {
                let data = Box::new(
                    <[u8; PIC_BLOCK]>::try_from(&self.image.pic_kernel[..]).expect("4096"),
                );
                self.send(now, &Message::Format(Format::PicKernel(data)));
            }
            Format::WritePicKernel { data, .. } => {
                self.image.pic_kernel.copy_from_slice(&data[..]);
                self.changed(None);
                for _ in 0..PIC_BLOCK / 256 {
                    self.msg(now, MsgCode::COMPLETED);
                }
            }
            Format::NewSerial { new, .. } => {
                self.image.serial = new;
                for bank in 0..8 {
                    self.image.flash.erase(bank).expect("valid bank");
                }
                self.image.pic_program.fill(0xFF);
                self.image.pic_eeprom = [0xFF; 256];
                self.pic.program.fill(0xFF);
                self.pic.eeprom = [0xFF; 256];
                self.changed(None);
                self.msg(now, MsgCode::COMPLETED);
            }
            Format::ReadBootBlock { block } => match block {
                5 => {
                    let data = if self.image.csboot_blank {
                        [0xFF; 256]
                    } else {
                        self.image.boot.to_csboot(&self.image.boot_user)
                    };
                    self.send(now, &Message::Format(Format::BootBlock(Box::new(data))));
                }
                // 600h..7FFh: the log table.
                6 | 7 => {
                    let words = &self.image.log_table.0[(block as usize - 6) * 128..][..128];
                    let data: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
                    let data = Box::new(<[u8; 256]>::try_from(&data[..]).expect("256"));
                    self.send(now, &Message::Format(Format::BootBlock(data)));
                }
                8..=31 => self.send(
                    now,
                    &Message::Format(Format::BootBlock(Box::new([0xFF; 256]))),
                ),
                _ => self.bad_param(now, format!("boot block {block} is out of range 5..31")),
            },
            Format::WriteBootBlock(data) => {
                if !self.image.csboot_blank {
                    self.note(
                        "boot block 5 is not blank; erase the boot flash first (F7 07)".into(),
                    );
                    return self.msg(now, MsgCode::NOT_BLANK_ERROR);
                }
                match BootConfig::from_csboot(&data) {
                    Some((boot, user)) => {
                        self.image.boot = boot;
                        self.image.boot_user = user;
                        self.image.csboot_blank = false;
                        self.note("new boot configuration: it applies from the next reset".into());
                    }
                    // Not marked valid: the kernel keeps running on its defaults.
                    None => self
                        .note("boot block 5 written without AA55h: defaults stay in force".into()),
                }
                self.changed(None);
                self.msg(now, MsgCode::COMPLETED);
            }
            Format::EraseBoot => {
                self.image.csboot_blank = true;
                self.image.boot = BootConfig {
                    baud: self.image.boot.baud,
                    ..BootConfig::default()
                };
                self.changed(None);
                self.msg(now, MsgCode::COMPLETED);
            }
            Format::CompressionTable { table, comp } => {
                self.image.log_table = crate::acquisition::LogTable::from_bytes(&table);
                self.image.compression = comp;
                self.changed(None);
                self.msg(now, MsgCode::COMPLETED);
            }
            Format::Emergency { xy } => {
                if now.saturating_sub(self.reset_at) > EMERGENCY_WINDOW_NS {
                    self.note("emergency erase is only accepted within 100 ms of a reset".into());
                    return self.msg(now, MsgCode::INVALID_COMMAND);
                }
                let (x, y) = (xy >> 4, xy & 0x0F);
                let (flash, boot, pic) = (
                    y == 3 || x == 0xF,
                    y == 0xC || x == 0xF,
                    x == 0xC || x == 0xA,
                );
                if !(flash || boot || pic) {
                    return self.bad_param(
                        now,
                        format!("emergency erase code {xy:02X}h erases nothing"),
                    );
                }
                if flash {
                    for bank in 0..8 {
                        self.image.flash.erase(bank).expect("valid bank");
                    }
                }
                if boot {
                    self.image.csboot_blank = true;
                    self.image.boot = BootConfig {
                        baud: self.image.boot.baud,
                        ..BootConfig::default()
                    };
                }
                if pic {
                    self.image.pic_program.fill(0xFF);
                    self.image.pic_eeprom = [0xFF; 256];
                    self.pic.program.fill(0xFF);
                    self.pic.eeprom = [0xFF; 256];
                }
                self.changed(None);
                self.msg(now, MsgCode::COMPLETED);
                if x == 0xA {
                    // PIC high-voltage programming, then standby.
                    self.send(now, &Message::Power(Power::PoweredDown));
                    self.mode = Mode::PoweredDown;
                }
            }
            Format::PicKernel(_) | Format::BootBlock(_) => {
                self.note("CPUFORMAT 01/05 are board-to-PC replies".into());
                self.msg(now, MsgCode::INVALID_COMMAND);
            }
        }
    }

    /// 256 bytes of a PIC block write: written and acknowledged at once (flow control: the host
    /// sends the next 256 when it has the acknowledgement). A write to a block out of range is
    /// refused at its first chunk; the rest of its frame is swallowed without more replies.
    fn pic_chunk(&mut self, now: Nanos, block: u8, index: u8, data: &[u8]) {
        let last = usize::from(index) + 1 == PIC_BLOCK / PIC_CHUNK;
        if index == 0 {
            self.pic_write_refused = false;
        }
        if self.pic_write_refused {
            self.pic_write_refused = !last;
            return;
        }
        if matches!(self.mode, Mode::Lower { .. }) {
            self.pic_write_refused = !last;
            self.note("PRGPIC refused in the lower loop".into());
            return self.msg(now, MsgCode::INVALID_COMMAND);
        }
        let Some(range) = pic_range(block) else {
            self.pic_write_refused = !last;
            return self.bad_param(now, format!("PIC block {block} is out of range 1..3"));
        };
        let at = range.start + usize::from(index) * PIC_CHUNK;
        self.pic.program[at..at + PIC_CHUNK].copy_from_slice(data);
        self.image.pic_program[at..at + PIC_CHUNK].copy_from_slice(data);
        self.changed(Some(ImageChange::pic_program(at, data)));
        self.msg(now, MsgCode::COMPLETED);
    }

    /// The image changed: `change` tells how as a journal record (`None`: a change no record
    /// describes; the host saves the whole image).
    fn changed(&mut self, change: Option<Vec<u8>>) {
        self.generation += 1;
        match change {
            Some(record) => self.changes.record(record),
            None => self.changes.need_snapshot(),
        }
    }

    fn bad_param(&mut self, now: Nanos, why: String) {
        self.note(why);
        self.msg(now, MsgCode::INVALID_PARAMETER_VALUE);
    }

    fn flash_error(&mut self, now: Nanos, e: FlashError) {
        self.note(e.to_string());
        let code = match e {
            FlashError::Forbidden { .. } => MsgCode::INVALID_PARAMETER_VALUE,
            FlashError::NotBlank { .. } => MsgCode::NOT_BLANK_ERROR,
        };
        self.msg(now, code);
    }

    fn cpu_info(&self, now: Nanos) -> CpuInfo {
        let supply = (self.inputs.pic[0].volts(now) * 20.0)
            .round()
            .clamp(0.0, 255.0) as u8;
        CpuInfo {
            quartz: 20,
            version_196: 3,
            version_pic: 2,
            pic_revision: 0,
            serial: self.image.serial,
            address: self.image.boot.address,
            supply,
            compression: self.image.compression,
        }
    }

    fn bridge(&mut self, now: Nanos, b: Bridge) {
        match b {
            Bridge::SpiSend(d) => {
                self.pic.execute(now, PicCommand::Spi { cmd: 1, data: d });
            }
            Bridge::SciSend(d) => {
                self.pic.execute(now, PicCommand::SciWrite(d));
            }
            Bridge::ParallelWrite(d) => {
                self.pic.execute(now, PicCommand::PortDWrite(d));
            }
            Bridge::ParallelAddress(a) => {
                self.pic.execute(now, PicCommand::IoAddress(a));
            }
            Bridge::ParallelReadRequest => {
                let d = self.pic.execute(now, PicCommand::ReadPortD)[0];
                self.send(now, &Message::Bridge(Bridge::ParallelRead(d)));
            }
            other => {
                self.note(format!("{other:?} is a board-to-PC report"));
                self.msg(now, MsgCode::INVALID_COMMAND);
            }
        }
        self.pic_events(now);
    }

    fn config_set(&self, bank: u8, config: u8) -> Option<ConfigSet> {
        let a = self.image.flash.read(bank, prginf::PRGINF_BLOCK).ok()?;
        let p = self.image.flash.read(bank, prginf::PTRPRG_BLOCK).ok()?;
        prginf::read_config(a, p, config)
    }

    // ----- lower loop ---------------------------------------------------------------------

    fn start(&mut self, now: Nanos, s: Start, from_pc: bool) {
        if !s.is_valid() {
            return self.bad_param(
                now,
                format!(
                    "START {:04X}h: bits 6 and 5 of the second byte must be 0",
                    s.word()
                ),
            );
        }
        if s.no_start() || s.page_change() {
            self.page = s.bank();
            return self.msg(now, MsgCode::COMPLETED);
        }
        let Some(set) = self.config_set(s.bank(), s.config()) else {
            return self.bad_param(
                now,
                format!("bank {} holds no valid configuration table", s.bank()),
            );
        };
        let acq = if s.ad196() {
            let cfg = match AdConfig::check_start(&set.ad_init, self.line) {
                Ok(c) => c,
                Err(e) => {
                    self.note(format!("A/D configuration {}: {e}", s.config()));
                    return self.msg(now, MsgCode::AD_CONFIG_ERROR);
                }
            };
            Some(Acquisition::new(cfg, now))
        } else {
            None
        };
        let made = set
            .program_ref()
            .map_err(Into::into)
            .and_then(|program| self.registry.make_ref(program, &self.image.flash, set.args));
        let program = match made {
            Ok(p) => p,
            Err(e) => {
                let why = format!("configuration {}: {e}", s.config());
                // Said on the THREAD display too: the monitor shows it, where an FE 04 alone
                // would leave the user guessing.
                self.send(
                    now,
                    &Message::Thread(Thread::Display {
                        format: DisplayFormat::Text,
                        newline: true,
                        data: why.as_bytes()[..why.len().min(255)].to_vec(),
                    }),
                );
                return self.bad_param(now, why);
            }
        };
        if self.run.is_some() {
            self.end_run(now);
        }
        let timer = |has: bool, cycle: u16| {
            (has && cycle != 0).then(|| {
                let period = Nanos::new(800) * u64::from(cycle);
                (period, now + period)
            })
        };
        let has = program.as_ref().map_or([false, false], |p| p.timers());
        let timers = [timer(has[0], set.cycle1), timer(has[1], set.cycle2)];
        if from_pc {
            self.msg(now, MsgCode::COMPLETED);
        }
        if acq.is_some() {
            let m = Message::CfgAd {
                c196: set.ad_init,
                pic: [set.adon[0], set.adon[1], set.adrs],
            };
            self.send(now, &m);
        }
        if s.adpic() {
            self.pic.execute(
                now,
                PicCommand::StartAd {
                    rate: set.adon[1],
                    mask: set.adon[0],
                },
            );
            self.adrs = set.adrs;
        }
        if s.pic_timer() {
            let c = u16::from_be_bytes(set.cycle);
            self.pic.execute(
                now,
                PicCommand::StartTimer {
                    cycle: c & 0xFFFC,
                    prescale: (c & 3) as u8,
                },
            );
        }
        self.page = s.bank();
        self.mode = Mode::Lower {
            bank: s.bank(),
            config: s.config(),
        };
        self.run = Some(Run {
            set,
            acq,
            program,
            timers,
            overrun: false,
        });
        self.last_rx = self.last_rx.max(now);
        self.call_hook(now, |p, k| p.init(k));
        // After init_prog: a module declares its user commands there.
        if let Some(p) = self.run.as_ref().and_then(|r| r.program.as_ref()) {
            for &(cmd, len) in p.user_commands() {
                self.decoder.set_user_len(cmd, len);
            }
        }
    }

    fn end_run(&mut self, now: Nanos) {
        // A STOP (or a stop from a hook, a lost link) also cancels a START still to come.
        self.pending_start = None;
        if self.run.is_none() {
            return;
        }
        self.call_hook(now, |p, k| {
            p.fin(k);
            Flow::CONTINUE
        });
        if let Some(p) = self.run.take().and_then(|r| r.program) {
            for &(cmd, _) in p.user_commands() {
                self.decoder.set_user_len(cmd, 0);
            }
        }
        self.pic.execute(now, PicCommand::StopAd);
        self.pic.execute(now, PicCommand::StopTimer);
        self.adrs = 0;
        self.mode = Mode::Upper;
    }

    /// Calls a hook of the running program and applies what it returns.
    fn call_hook(&mut self, now: Nanos, f: impl FnOnce(&mut dyn UserProgram, &mut Api) -> Flow) {
        let Some(run) = self.run.as_mut() else { return };
        let Some(mut program) = run.program.take() else {
            return;
        };
        let ad = run.acq.as_ref().map_or([0; 8], |a| a.values);
        let args = run.set.args;
        let mut out = Vec::new();
        let mut pic = Vec::new();
        let flow = {
            let mut api = Api {
                now_ns: now,
                args,
                ad,
                pic_ad: self.pic_ad,
                pwm: &mut self.pwm196,
                out: &mut out,
                next_file: &mut self.next_file,
                pic: &mut pic,
                stop: false,
            };
            let flow = f(program.as_mut(), &mut api);
            Flow {
                stop: flow.stop || api.stop,
                ..flow
            }
        };
        if let Some(run) = self.run.as_mut() {
            run.program = Some(program);
        }
        for m in &out {
            self.send(now, m);
        }
        for command in pic {
            self.pic.execute(now, command);
        }
        if flow.stop {
            self.end_run(now);
        }
        if let Some(s) = flow.start {
            if self.starting {
                // Not recursively: a set whose init starts itself would never return.
                self.pending_start = Some((now + NESTED_START_DELAY_NS, s));
            } else {
                self.starting = true;
                self.start(now, s, false);
                self.starting = false;
            }
        }
    }

    fn pic_events(&mut self, now: Nanos) {
        for ev in self.pic.take_events() {
            match ev {
                PicEvent::Ad { channel, value } => {
                    self.pic_ad[channel as usize] = value;
                    if self.adrs & (1 << channel) != 0 {
                        self.send(now, &Message::AdSample(AdSample::Pic { channel, value }));
                    }
                }
                PicEvent::SciReceived(d) => {
                    self.send(now, &Message::Bridge(Bridge::SciReceived(d)))
                }
                PicEvent::SpiReceived(d) => {
                    self.send(now, &Message::Bridge(Bridge::SpiReceived(d)))
                }
                PicEvent::Error(_) => self.send(now, &Message::Alert(Alert::PIC_ERROR)),
                _ => {}
            }
            self.call_hook(now, |p, k| p.pic(k, ev));
        }
    }

    /// The next lower-loop event: (time, 0 = A/D interrupt, 1/2 = software timer).
    fn next_run_event(&self) -> Option<(Nanos, u8)> {
        let run = self.run.as_ref()?;
        // Asked at every step of the board: a plain scan, the A/D first on a tie.
        let mut first = run.acq.as_ref().map(|a| (a.next_interrupt_at(), 0));
        for (which, timer) in (1..).zip(run.timers) {
            if let Some((_, at)) = timer
                && first.is_none_or(|(t, _)| at < t)
            {
                first = Some((at, which));
            }
        }
        first
    }

    fn run_event(&mut self, at: Nanos, which: u8) {
        let Some(run) = self.run.as_mut() else { return };
        if which == 0 {
            let Some(acq) = run.acq.as_mut() else { return };
            let data = acq.run_interrupt(&self.inputs.c196, &self.image.log_table);
            if !data.is_empty() {
                if self.tx.queue.len() + data.len() + 3 > TX_FIFO {
                    self.stats.fa_dropped += 1;
                    if !run.overrun {
                        run.overrun = true;
                        self.send(at, &Message::Alert(Alert::AD_OVERRUN));
                    }
                } else {
                    self.stats.fa_sent += 1;
                    self.send(at, &Message::AdCont(data));
                }
            }
            self.call_hook(at, |p, k| p.ad(k));
        } else {
            let slot = &mut run.timers[which as usize - 1];
            if let Some((period, next)) = slot.as_mut() {
                *next += *period;
            }
            self.call_hook(at, |p, k| p.timer(k, which));
        }
    }

    fn watchdog_deadline(&self) -> Option<Nanos> {
        (self.image.boot.watchdog && self.mode != Mode::PoweredDown && self.protocol_on())
            .then(|| self.tx.last_send.max(self.tx.free_at) + WATCHDOG_PERIOD_NS)
    }

    fn link_lost_deadline(&self) -> Option<Nanos> {
        (self.image.boot.watchdog && matches!(self.mode, Mode::Lower { .. }))
            .then(|| self.last_rx + LINK_LOST_NS)
    }

    fn battery_check(&mut self, now: Nanos) {
        let th = self.image.boot.battery_thresholds;
        self.next_battery = now + BATTERY_PERIOD_NS;
        if th == [0xFF; 3] {
            return;
        }
        let level = (crate::source::reading10(&self.inputs.pic[0], now) >> 2) as u8;
        let state = th.iter().filter(|&&t| t != 0xFF && level >= t).count() as u8;
        let report = match self.battery {
            None => state < 2,
            Some(old) => old != state,
        };
        self.battery = Some(state);
        if report {
            self.send(now, &Message::Alert(Alert::battery(state)));
        }
    }

    /// Runs everything due up to `now`.
    fn advance(&mut self, now: Nanos) {
        if self.mode == Mode::PoweredDown {
            return;
        }
        if let Some((at, s)) = self.pending_start.filter(|&(at, _)| at <= now) {
            self.pending_start = None;
            self.starting = true;
            self.start(at, s, false);
            self.starting = false;
        }
        if let Some(Event::Error(e)) = self.decoder.poll(now) {
            self.on_frame_error(now, e);
        }
        while let Some((at, which)) = self.next_run_event().filter(|(at, _)| *at <= now) {
            self.run_event(at, which);
        }
        if let Some(at) = self.link_lost_deadline().filter(|&at| at <= now) {
            self.send(at, &Message::Alert(Alert::LINK_LOST));
            self.end_run(at);
        }
        self.pic.advance(now, &mut |ch, t| {
            crate::source::reading10(&self.inputs.pic[ch as usize], t)
        });
        self.pic_events(now);
        if self.next_battery <= now {
            self.battery_check(now);
        }
        if let Some(at) = self.watchdog_deadline().filter(|&at| at <= now) {
            self.send(at, &Message::Watchdog);
        }
    }
}

fn pic_range(block: u8) -> Option<core::ops::Range<usize>> {
    (1..=3)
        .contains(&block)
        .then(|| (block as usize - 1) * PIC_BLOCK..block as usize * PIC_BLOCK)
}

impl Persistent for Board {
    type Snapshot = Image;

    fn state_generation(&self) -> u64 {
        self.generation
    }

    fn snapshot(&self) -> Image {
        self.image.clone()
    }

    /// The image file (TOML).
    fn file_bytes(image: &Image) -> Vec<u8> {
        image.to_toml().into_bytes()
    }

    /// Flash block writes and bank erases, PIC program and EEPROM writes (see [`ImageChange`]);
    /// other changes ask for a whole image.
    fn take_changes(&mut self) -> Changes {
        self.changes.take()
    }

    fn replay(image: &mut Image, record: &[u8]) -> Result<(), ReplayError> {
        ImageChange::apply(image, record)
    }
}

/// The image changes a journal records, each setting part of the image:
/// - `F bank block data[256]`: a flash block written;
/// - `E bank`: a flash bank erased;
/// - `P offset[2] data`: PIC program memory from `offset` (0..12287);
/// - `R data[256]`: the PIC EEPROM.
pub struct ImageChange;

impl ImageChange {
    const FLASH: u8 = b'F';
    const ERASE: u8 = b'E';
    const PIC: u8 = b'P';
    const EEPROM: u8 = b'R';

    pub fn flash_block(bank: u8, block: u8, data: &[u8; 256]) -> Vec<u8> {
        let mut r = vec![Self::FLASH, bank, block];
        r.extend_from_slice(data);
        r
    }

    pub fn erase_bank(bank: u8) -> Vec<u8> {
        vec![Self::ERASE, bank]
    }

    pub fn pic_program(offset: usize, data: &[u8]) -> Vec<u8> {
        let mut r = vec![Self::PIC];
        r.extend_from_slice(&(offset as u16).to_be_bytes());
        r.extend_from_slice(data);
        r
    }

    pub fn eeprom(data: &[u8; 256]) -> Vec<u8> {
        let mut r = vec![Self::EEPROM];
        r.extend_from_slice(data);
        r
    }

    /// Applies a record to an image.
    pub fn apply(image: &mut Image, record: &[u8]) -> Result<(), ReplayError> {
        let bad = |why| Err(ReplayError::new(record, why));
        match record {
            [Self::FLASH, bank, block, data @ ..] => {
                let Ok(data) = <&[u8; 256]>::try_from(data) else {
                    return bad("a flash block is 256 bytes");
                };
                if !image.flash.restore_block(*bank, *block, data) {
                    return bad("no such flash bank");
                }
            }
            [Self::ERASE, bank] => {
                if image.flash.erase(*bank).is_err() {
                    return bad("no such flash bank");
                }
            }
            [Self::PIC, high, low, data @ ..] => {
                let at = usize::from(u16::from_be_bytes([*high, *low]));
                match image.pic_program.get_mut(at..at + data.len()) {
                    Some(slot) if !data.is_empty() => slot.copy_from_slice(data),
                    _ => return bad("outside PIC program memory"),
                }
            }
            [Self::EEPROM, data @ ..] => match <[u8; 256]>::try_from(data) {
                Ok(data) => image.pic_eeprom = data,
                Err(_) => return bad("the EEPROM is 256 bytes"),
            },
            _ => return bad("unknown change"),
        }
        Ok(())
    }
}

impl ByteDevice for Board {
    fn receive(&mut self, now_ns: Nanos, byte: u8) {
        if self.mode == Mode::PoweredDown || !self.protocol_on() {
            return;
        }
        self.advance(now_ns);
        self.last_rx = now_ns;
        if self.tx.queue.len() > TX_BACKLOG {
            self.stats.rx_lost += 1;
            return;
        }
        match self.decoder.push(now_ns, byte) {
            Some(Event::Message(m)) => self.on_message(now_ns, m),
            Some(Event::Error(e)) => self.on_frame_error(now_ns, e),
            Some(Event::PicChunk { block, index, data }) => {
                self.pic_chunk(now_ns, block, index, &data[..]);
            }
            None => {}
        }
    }

    fn poll(&mut self, now_ns: Nanos, out: &mut Vec<u8>) {
        self.advance(now_ns);
        self.tx.poll(now_ns, out);
    }

    fn next_deadline(&self) -> Option<Nanos> {
        if self.mode == Mode::PoweredDown {
            return self.tx.deadline();
        }
        [
            self.tx.deadline(),
            self.decoder.deadline(),
            self.pending_start.map(|(at, _)| at),
            self.next_run_event().map(|(at, _)| at),
            self.link_lost_deadline(),
            self.pic.next_deadline(),
            Some(self.next_battery),
            self.watchdog_deadline(),
        ]
        .into_iter()
        .flatten()
        .min()
    }
}
