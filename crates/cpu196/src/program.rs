//! User hooks (SPEC C2): the kernel calls a configuration set's program on events of the lower
//! loop. Programs are Rust trait objects: a few useful ones ship with the model, and a
//! [`ModuleRuntime`] (`buslab-cpu196-wasm`) makes them from modules a user stored in flash.

use std::collections::BTreeMap;

use buslab_device::Nanos;

use crate::codes::Alert;
use crate::flash::Flash;
use crate::message::{AdSample, DisplayFormat, FileMode, Message, Start, Thread};
use crate::pic::{PicCommand, PicEvent};

/// What a hook returns: continue or stop the lower loop (`_ContExec_` / `_StopExec_`), and
/// optionally a START to perform (the 16-bit value; `0x8000` = none).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Flow {
    pub stop: bool,
    pub start: Option<Start>,
}

impl Flow {
    pub const CONTINUE: Self = Self {
        stop: false,
        start: None,
    };
    pub const STOP: Self = Self {
        stop: true,
        start: None,
    };

    /// From the seed's two return values.
    pub fn from_raw(stop: bool, start_word: u16) -> Self {
        let start = (start_word != Start::NO_START).then(|| Start::from_word(start_word));
        Self { stop, start }
    }
}

/// The kernel services a hook may call (display, files, virtual channels, PWM, alerts).
pub struct Api<'a> {
    pub now_ns: Nanos,
    /// Arguments of this configuration set (words 1..7 of `ptrprg.user[n]`).
    pub args: [u16; 7],
    /// Latest 80C196 channel values on the 16-bit scale (`ad_voie[n].donnee`).
    pub ad: [u16; 8],
    /// Latest PIC channel values, 10-bit (`ad_pic.donnee`).
    pub pic_ad: [u16; 8],
    /// The three 80C196 PWM outputs (8-bit).
    pub pwm: &'a mut [u8; 3],
    pub(crate) out: &'a mut Vec<Message>,
    pub(crate) next_file: &'a mut u8,
    pub(crate) pic: &'a mut Vec<PicCommand>,
    pub(crate) stop: bool,
}

impl Api<'_> {
    fn send(&mut self, m: Message) {
        self.out.push(m);
    }

    /// `affiche(n, text)`.
    pub fn display_text(&mut self, text: &str, newline: bool) {
        for chunk in text.as_bytes().chunks(255) {
            self.send(Message::Thread(Thread::Display {
                format: DisplayFormat::Text,
                newline,
                data: chunk.to_vec(),
            }));
        }
    }

    /// `affiche` of 16-bit words in a display format.
    pub fn display_words(&mut self, format: DisplayFormat, words: &[u16], newline: bool) {
        for chunk in words.chunks(255) {
            let data = chunk.iter().flat_map(|w| w.to_le_bytes()).collect();
            self.send(Message::Thread(Thread::Display {
                format,
                newline,
                data,
            }));
        }
    }

    /// `affiche` in any format: `data` holds the items as the board keeps them (2 bytes per
    /// 16-bit word, little-endian); cut into displays of at most 255 items.
    pub fn display(&mut self, format: DisplayFormat, data: &[u8], newline: bool) {
        let item = if format.is_word() { 2 } else { 1 };
        for chunk in data.chunks(255 * item) {
            self.send(Message::Thread(Thread::Display {
                format,
                newline,
                data: chunk.to_vec(),
            }));
        }
    }

    /// `emission_canal_virtuel_12bits(n, d)`.
    pub fn virtual_channel(&mut self, channel: u8, value12: u16) {
        self.send(Message::AdSample(AdSample::Virtual {
            channel: channel & 7,
            value: value12.min(0xFFF),
        }));
    }

    pub fn alert(&mut self, alert: Alert) {
        self.send(Message::Alert(alert));
    }

    /// `fopen`: asks the PC to open `name`; returns the handle.
    pub fn fopen(&mut self, name: &str, mode: FileMode) -> u8 {
        let file = *self.next_file;
        *self.next_file = self.next_file.wrapping_add(1);
        self.send(Message::Thread(Thread::Open {
            mode,
            name: name.as_bytes()[..name.len().min(255)].to_vec(),
            file,
        }));
        file
    }

    pub fn fwrite(&mut self, file: u8, data: &[u8]) {
        for chunk in data.chunks(255) {
            self.send(Message::Thread(Thread::Write {
                data: chunk.to_vec(),
                file,
            }));
        }
    }

    /// `fread(f, n)`: the bytes arrive later in [`UserProgram::fread`].
    pub fn fread(&mut self, file: u8, len: u8) {
        self.send(Message::Thread(Thread::ReadRequest { len, file }));
    }

    pub fn fclose(&mut self, file: u8) {
        self.send(Message::Thread(Thread::Close { file }));
    }

    /// The handle the next [`fopen`](Self::fopen) returns.
    pub fn next_file(&self) -> u8 {
        *self.next_file
    }

    /// The kernel ends the lower loop as this hook returns, whatever it returns (a program
    /// the kernel stopped, from a hook without a return value).
    pub fn stop_lower_loop(&mut self) {
        self.stop = true;
    }

    /// A command to the PIC (`pic_wrc`); the kernel sends it as the hook returns.
    pub fn pic_command(&mut self, command: PicCommand) {
        self.pic.push(command);
    }
}

/// The hooks of one configuration set. Every method has a do-nothing default; software timers
/// run only for programs that say they have the timer hook ([`timers`](Self::timers)).
pub trait UserProgram: Send {
    /// Short name for logs.
    fn name(&self) -> &'static str;
    /// `init_prog`: entering the lower loop.
    fn init(&mut self, _k: &mut Api) -> Flow {
        Flow::CONTINUE
    }
    /// `user_prog`: the external interrupt (HSI.0), via the sequencer.
    fn user(&mut self, _k: &mut Api) -> Flow {
        Flow::CONTINUE
    }
    /// Parameter counts of the user commands this program understands (`(cmd, len)`); the
    /// kernel's decoder delimits them while the program runs. Others carry no parameters.
    fn user_commands(&self) -> &[(u8, u8)] {
        &[]
    }
    /// `RS_prog`: a user command (00h..EFh) from the PC. No return value (as in the seed).
    fn rs(&mut self, _k: &mut Api, _cmd: u8, _params: &[u8]) {}
    /// `pic_prog`: a PIC event.
    fn pic(&mut self, _k: &mut Api, _event: PicEvent) -> Flow {
        Flow::CONTINUE
    }
    /// Which software timer hooks exist (`pas_prog1`, `pas_prog2`).
    fn timers(&self) -> [bool; 2] {
        [false, false]
    }
    /// `pas_prog1` / `pas_prog2` (`timer` = 1 or 2).
    fn timer(&mut self, _k: &mut Api, _timer: u8) -> Flow {
        Flow::CONTINUE
    }
    /// `AD_prog`: an A/D interrupt's data is ready (`k.ad`).
    fn ad(&mut self, _k: &mut Api) -> Flow {
        Flow::CONTINUE
    }
    /// `Main_Fread`: bytes the PC read for `file` (empty at end of file).
    fn fread(&mut self, _k: &mut Api, _file: u8, _data: &[u8]) {}
    /// `fin_prog`: leaving the lower loop.
    fn fin(&mut self, _k: &mut Api) {}
}

/// Makes a program from its 7 arguments.
pub type ProgramFactory = Box<dyn Fn([u16; 7]) -> Box<dyn UserProgram> + Send>;

/// What word 0 of `ptrprg.user[n]` names: nothing (0 or FFFFh), a built-in program
/// (1..7FFFh), or a module stored in flash (`1000 0bbb kkkk kkkk`: bank b, first block k).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProgramRef {
    None,
    BuiltIn(u16),
    Module { bank: u8, block: u8 },
}

/// Word 0 of `ptrprg.user[n]` with bit 15 set and any of bits 11..14 too.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "program word {0:04X}h names no program: a module is 8000h | bank << 8 | block (bank 0..7, bits 11..14 zero)"
)]
pub struct InvalidProgramWord(pub u16);

impl ProgramRef {
    const MODULE: u16 = 0x8000;

    pub fn from_word(word: u16) -> Result<Self, InvalidProgramWord> {
        Ok(match word {
            0 | 0xFFFF => Self::None,
            w if w & Self::MODULE == 0 => Self::BuiltIn(w),
            w if w & 0x7800 != 0 => return Err(InvalidProgramWord(w)),
            w => Self::Module {
                bank: (w >> 8) as u8 & 7,
                block: w as u8,
            },
        })
    }

    /// The word; `None` for a built-in id outside 1..7FFFh.
    pub fn word(self) -> Option<u16> {
        match self {
            Self::None => Some(0),
            Self::BuiltIn(id) => (1..Self::MODULE).contains(&id).then_some(id),
            Self::Module { bank, block } => {
                (bank < 8).then(|| Self::MODULE | u16::from(bank) << 8 | u16::from(block))
            }
        }
    }
}

/// Why a program stored in flash could not be made.
pub type LoadError = Box<dyn std::error::Error + Send + Sync>;

/// Makes programs from modules stored in flash (`buslab-cpu196-wasm` runs WebAssembly ones):
/// the kernel knows only where a module starts, the runtime its layout and how to run it.
pub trait ModuleRuntime: Send {
    fn load(
        &self,
        flash: &Flash,
        bank: u8,
        block: u8,
        args: [u16; 7],
    ) -> Result<Box<dyn UserProgram>, LoadError>;
}

/// Programs by id (word 0 of `ptrprg.user[n]`), and the runtime of the modules in flash.
pub struct Registry {
    programs: BTreeMap<u16, (&'static str, ProgramFactory)>,
    runtime: Option<Box<dyn ModuleRuntime>>,
}

impl Default for Registry {
    /// The shipped programs: 1 `logger`, 2 `threshold-alarm`, 3 `virtual-channels`,
    /// 4 `pulse-train`, 5 `pwm-playback`.
    fn default() -> Self {
        let mut r = Self {
            programs: BTreeMap::new(),
            runtime: None,
        };
        r.register(LOGGER, "logger", Box::new(|a| Box::new(Logger::new(a))));
        r.register(
            THRESHOLD_ALARM,
            "threshold-alarm",
            Box::new(|a| Box::new(ThresholdAlarm::new(a))),
        );
        r.register(
            VIRTUAL_CHANNELS,
            "virtual-channels",
            Box::new(|_| Box::new(VirtualChannels)),
        );
        r.register(
            PULSE_TRAIN,
            "pulse-train",
            Box::new(|a| Box::new(PulseTrain::new(a))),
        );
        r.register(
            PWM_PLAYBACK,
            "pwm-playback",
            Box::new(|_| Box::new(PwmPlayback::default())),
        );
        r
    }
}

impl Registry {
    pub fn register(&mut self, id: u16, name: &'static str, factory: ProgramFactory) {
        self.programs.insert(id, (name, factory));
    }

    pub fn make(&self, id: u16, args: [u16; 7]) -> Option<Box<dyn UserProgram>> {
        self.programs.get(&id).map(|(_, f)| f(args))
    }

    pub fn list(&self) -> impl Iterator<Item = (u16, &'static str)> + '_ {
        self.programs.iter().map(|(id, (name, _))| (*id, *name))
    }

    /// Installs the runtime that runs modules stored in flash.
    pub fn set_module_runtime(&mut self, runtime: Box<dyn ModuleRuntime>) {
        self.runtime = Some(runtime);
    }

    /// The program a configuration set names, made with its arguments.
    pub fn make_ref(
        &self,
        program: ProgramRef,
        flash: &Flash,
        args: [u16; 7],
    ) -> Result<Option<Box<dyn UserProgram>>, LoadError> {
        match program {
            ProgramRef::None => Ok(None),
            ProgramRef::BuiltIn(id) => match self.make(id, args) {
                Some(p) => Ok(Some(p)),
                None => Err(format!("program {id} is not installed").into()),
            },
            ProgramRef::Module { bank, block } => match &self.runtime {
                Some(rt) => rt.load(flash, bank, block, args).map(Some).map_err(|e| {
                    format!("the module at bank {bank} block {block:02X}h: {e}").into()
                }),
                None => Err(format!(
                    "the module at bank {bank} block {block:02X}h cannot run: this board has no module runtime"
                )
                .into()),
            },
        }
    }
}

pub const LOGGER: u16 = 1;
pub const THRESHOLD_ALARM: u16 = 2;
pub const VIRTUAL_CHANNELS: u16 = 3;
pub const PULSE_TRAIN: u16 = 4;
pub const PWM_PLAYBACK: u16 = 5;

/// The threshold alarm's user command: `10h hi lo` sets the threshold (10-bit).
pub const SET_THRESHOLD: u8 = 0x10;

/// Greets on the THREAD display and writes channels 0 and 1 (10-bit) to `ad.csv` on the PC,
/// one line every `args[0]` interrupts (default 100).
pub struct Logger {
    every: u16,
    count: u16,
    lines: u16,
    file: Option<u8>,
}

impl Logger {
    pub fn new(args: [u16; 7]) -> Self {
        Self {
            every: if args[0] == 0 || args[0] == 0xFFFF {
                100
            } else {
                args[0]
            },
            count: 0,
            lines: 0,
            file: None,
        }
    }
}

impl UserProgram for Logger {
    fn name(&self) -> &'static str {
        "logger"
    }
    fn init(&mut self, k: &mut Api) -> Flow {
        k.display_text("logger: writing ad.csv", true);
        let f = k.fopen("ad.csv", FileMode::Write);
        k.fwrite(f, b"ms,ch0,ch1\n");
        self.file = Some(f);
        Flow::CONTINUE
    }
    fn ad(&mut self, k: &mut Api) -> Flow {
        self.count += 1;
        if self.count >= self.every {
            self.count = 0;
            if let Some(f) = self.file {
                let line = format!(
                    "{},{},{}\n",
                    k.now_ns / 1_000_000,
                    (k.ad[0] + 32) >> 6,
                    (k.ad[1] + 32) >> 6
                );
                k.fwrite(f, line.as_bytes());
                self.lines += 1;
            }
        }
        Flow::CONTINUE
    }
    fn fin(&mut self, k: &mut Api) {
        if let Some(f) = self.file.take() {
            k.fclose(f);
        }
        // The numbers as the seed's monitor shows them: unsigned 16-bit, then hex.
        k.display_text("logger: done, lines written: ", false);
        k.display_words(DisplayFormat::Unsigned16, &[self.lines], true);
        k.display_words(DisplayFormat::Hex16, &[self.lines], true);
    }
}

/// Raises `alert_user_alarm` and prints a line when channel `args[0]` (10-bit) rises above
/// `args[1]`; stops the lower loop if `args[2]` is 1. Re-arms below the threshold, or on the
/// external interrupt (an acknowledge button). User command `10h hi lo` sets the threshold.
pub struct ThresholdAlarm {
    channel: usize,
    threshold: u16,
    stop: bool,
    armed: bool,
}

impl ThresholdAlarm {
    pub fn new(a: [u16; 7]) -> Self {
        Self {
            channel: (a[0] & 7) as usize,
            threshold: a[1].min(1023),
            stop: a[2] == 1,
            armed: true,
        }
    }
}

impl UserProgram for ThresholdAlarm {
    fn name(&self) -> &'static str {
        "threshold-alarm"
    }
    fn user_commands(&self) -> &'static [(u8, u8)] {
        &[(SET_THRESHOLD, 2)]
    }
    fn rs(&mut self, k: &mut Api, cmd: u8, params: &[u8]) {
        if cmd == SET_THRESHOLD && params.len() == 2 {
            self.threshold = u16::from_be_bytes([params[0], params[1]]).min(1023);
            k.display_text(&format!("threshold = {}", self.threshold), true);
        }
    }
    fn user(&mut self, k: &mut Api) -> Flow {
        self.armed = true;
        k.display_text("alarm acknowledged", true);
        Flow::CONTINUE
    }
    fn ad(&mut self, k: &mut Api) -> Flow {
        let v = (k.ad[self.channel] + 32) >> 6;
        if self.armed && v > self.threshold {
            self.armed = false;
            k.alert(Alert::USER_ALARM);
            k.display_text(
                &format!(
                    "alarm: channel {} at {v} > {}",
                    self.channel, self.threshold
                ),
                true,
            );
            if self.stop {
                return Flow::STOP;
            }
        } else if v <= self.threshold {
            self.armed = true;
        }
        Flow::CONTINUE
    }
}

/// Streams two virtual channels computed from the inputs: 0 = mean of channels 0 and 1,
/// 1 = (channel 0 − channel 1) + 2048, both 12-bit.
pub struct VirtualChannels;

impl UserProgram for VirtualChannels {
    fn name(&self) -> &'static str {
        "virtual-channels"
    }
    fn ad(&mut self, k: &mut Api) -> Flow {
        let a = (k.ad[0] >> 4) as i32;
        let b = (k.ad[1] >> 4) as i32;
        k.virtual_channel(0, ((a + b) / 2) as u16);
        k.virtual_channel(1, (a - b + 2048).clamp(0, 4095) as u16);
        Flow::CONTINUE
    }
}

/// A stimulation pulse train on PWM 0: each software-timer-1 tick toggles between 0 and
/// `args[0]` (default 128); after `args[1]` pulses (default 10) it stops the lower loop.
pub struct PulseTrain {
    amplitude: u8,
    pulses: u16,
    done: u16,
    high: bool,
}

impl PulseTrain {
    pub fn new(a: [u16; 7]) -> Self {
        let pick = |v: u16, d: u16| if v == 0 || v == 0xFFFF { d } else { v };
        Self {
            amplitude: pick(a[0], 128).min(255) as u8,
            pulses: pick(a[1], 10),
            done: 0,
            high: false,
        }
    }
}

impl UserProgram for PulseTrain {
    fn name(&self) -> &'static str {
        "pulse-train"
    }
    fn timers(&self) -> [bool; 2] {
        [true, false]
    }
    fn timer(&mut self, k: &mut Api, _timer: u8) -> Flow {
        self.high = !self.high;
        k.pwm[0] = if self.high { self.amplitude } else { 0 };
        if !self.high {
            self.done += 1;
            if self.done >= self.pulses {
                k.display_text(&format!("pulse-train: {} pulses", self.done), true);
                return Flow::STOP;
            }
        }
        Flow::CONTINUE
    }
    fn fin(&mut self, k: &mut Api) {
        k.pwm[0] = 0;
    }
}

/// Plays a stimulation pattern kept on the PC: reads `pattern.bin` through the file service
/// (`fread`, 64 bytes at a time, always one request ahead) and puts one byte on PWM 0 per
/// software-timer-1 tick; at the end of the file it reports the count and stops.
#[derive(Default)]
pub struct PwmPlayback {
    file: Option<u8>,
    buffer: std::collections::VecDeque<u8>,
    asked: bool,
    at_end: bool,
    played: u16,
}

impl PwmPlayback {
    const CHUNK: u8 = 64;

    fn refill(&mut self, k: &mut Api) {
        if let Some(f) = self.file
            && !self.asked
            && !self.at_end
            && self.buffer.len() < Self::CHUNK as usize
        {
            k.fread(f, Self::CHUNK);
            self.asked = true;
        }
    }
}

impl UserProgram for PwmPlayback {
    fn name(&self) -> &'static str {
        "pwm-playback"
    }
    fn timers(&self) -> [bool; 2] {
        [true, false]
    }
    fn init(&mut self, k: &mut Api) -> Flow {
        self.file = Some(k.fopen("pattern.bin", FileMode::Read));
        self.refill(k);
        Flow::CONTINUE
    }
    fn fread(&mut self, k: &mut Api, _file: u8, data: &[u8]) {
        self.asked = false;
        self.at_end = data.is_empty();
        self.buffer.extend(data);
        self.refill(k);
    }
    fn timer(&mut self, k: &mut Api, _timer: u8) -> Flow {
        match self.buffer.pop_front() {
            Some(v) => {
                k.pwm[0] = v;
                self.played += 1;
                self.refill(k);
                Flow::CONTINUE
            }
            None if self.at_end => {
                k.display_text(
                    &format!("pwm-playback: {} samples played", self.played),
                    true,
                );
                Flow::STOP
            }
            // Starved: the PC has not answered yet; hold the output.
            None => Flow::CONTINUE,
        }
    }
    fn fin(&mut self, k: &mut Api) {
        if let Some(f) = self.file.take() {
            k.fclose(f);
        }
        k.pwm[0] = 0;
    }
}
