//! MoniCAN itself: keys and frames in, frames and VT100 bytes out, time explicit (ns).

use std::collections::{BTreeMap, VecDeque};

use buslab_can::{Frame, Id, Nanos, StandardId};
use buslab_slio::board::{OutputLevels, set_bit};
use buslab_slio::{
    CALIBRATION_ID, Direction as SlioDirection, Master, MasterEvent, Register, Reply, RequestId,
    SlioId, Transmit,
};

use crate::command::{Action, Adc, Command, CommandLine, Dpm, KeyOutcome};
use crate::layout::*;
use crate::mail::MailReader;
use crate::screen::Screen;

/// The mail identifier unless configured otherwise (docs/decisions.md: 0x7F0..0x7FF are
/// forbidden by CAN 2.0A, whose 7 most significant identifier bits must not all be
/// recessive).
pub const DEFAULT_MAIL_ID: u16 = 0x700;
/// Bytes of a supervisor's message kept unless configured otherwise: a little more than the
/// page of 20 × 80 characters that shows it.
pub const DEFAULT_MAIL_LIMIT: usize = 2048;
/// The largest mail size limit accepted.
pub const MAX_MAIL_LIMIT: usize = 64 * 1024;

/// What MoniCAN writes into a SLIO that signs on (the demo board, seed §3.2.2.2).
pub const OUTPUT_ENABLE: u16 = buslab_slio::board::OUTPUT_ENABLE;
/// DATA_OUTPUT after sign-on: P13 high, so P0..P3 show the input switches, every LED off.
pub const INITIAL_OUTPUTS: u16 = 1 << buslab_slio::board::SELECT_PIN;
/// What a request for the pin levels is named on the notice line when it gets no answer.
const LEVELS: &str = "pin levels for an LED command";

pub const MAIL_NOTICE: &str = "you've got mail ! (press Ctrl R to read it)";
/// What MoniCAN says when it is asked for the loader but has none to hand over to (in the
/// user's terminal, `buslab monican`); on the PowerPC node the loader takes over at once.
pub const LOADER_NOTICE: &str = "loader requested by the supervisor (no loader on this host)";
/// The hint at the bottom of a page shown over the SLIO screen.
pub const PAGE_HINT: &str = "press any key to return to the SLIO screen";

/// Keys MoniCAN reacts to besides the command fields.
pub const CTRL_L: u8 = 0x0C;
pub const CTRL_R: u8 = 0x12;
pub const ESC: u8 = 0x1B;

/// Events queued for the owner at most; older ones are dropped first.
const MAX_EVENTS: usize = 64;
/// Bytes of an escape sequence swallowed at most (a terminal's function keys are shorter).
const MAX_SEQUENCE: u8 = 16;

/// How MoniCAN is set up.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Config {
    /// The bus's bit rate (the period of the calibration frames is counted in bit-times).
    pub bitrate: u32,
    /// The 11-bit identifier a supervisor announces and sends its messages on.
    pub mail_id: u16,
    /// Bytes of a message kept; what comes beyond is counted and said, not shown.
    pub mail_limit: usize,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            bitrate: 125_000,
            mail_id: DEFAULT_MAIL_ID,
            mail_limit: DEFAULT_MAIL_LIMIT,
        }
    }
}

/// A configuration MoniCAN cannot run with.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    #[error("bit rate {0} bit/s: MoniCAN needs the bus's bit rate, a positive number")]
    Bitrate(u32),
    #[error("mail identifier 0x{0:X} is not an 11-bit identifier (0x001..=0x7FF)")]
    MailIdRange(u16),
    #[error("mail identifier 0x{id:03X} is {what}; choose another 11-bit identifier")]
    MailIdTaken { id: u16, what: &'static str },
    #[error("mail size limit {0} bytes is out of range 1..={MAX_MAIL_LIMIT}")]
    MailLimit(usize),
}

impl Config {
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.bitrate == 0 {
            return Err(ConfigError::Bitrate(self.bitrate));
        }
        let id = self.mail_id;
        if id > 0x7FF {
            return Err(ConfigError::MailIdRange(id));
        }
        let taken = |what| Err(ConfigError::MailIdTaken { id, what });
        if id == 0 {
            return taken("the loader's (a remote frame with ID 0 asks for it)");
        }
        if id == CALIBRATION_ID {
            return taken("the SLIO calibration identifier");
        }
        if SlioId::from_id(standard(id)).is_some() {
            return taken("a SLIO identifier");
        }
        if !(1..=MAX_MAIL_LIMIT).contains(&self.mail_limit) {
            return Err(ConfigError::MailLimit(self.mail_limit));
        }
        Ok(())
    }
}

fn standard(raw: u16) -> Id {
    Id::Standard(StandardId::new(raw & 0x7FF).expect("11 bits"))
}

/// Something the owner of MoniCAN may act on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Event {
    /// A SLIO signed on; MoniCAN initialises its outputs.
    SignedOn(SlioId),
    /// A command was typed and its frame queued.
    CommandSent(Command),
    /// A SLIO did not answer a request in time.
    NoAnswer(SlioId),
    /// The supervisor sent a remote frame with ID 0 and DLC 0: it wants the loader (the
    /// PowerPC node hands over to it, `buslab-loader`).
    LoaderRequested,
    /// The user asked for the supervisor's message; MoniCAN answered the notifier.
    MailRequested,
}

/// What MoniCAN shows of one SLIO: only values the SLIO sent.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SlioView {
    /// It signed on (or answered).
    pub present: bool,
    /// DATA_OUTPUT.
    pub outputs: Option<u16>,
    /// DATA_INPUT.
    pub inputs: Option<u16>,
    /// The last conversion of ADC1 and ADC2 (10 bits).
    pub adc: [Option<u16>; 2],
    /// DPM1 and DPM2 (10 bits).
    pub dpm: [Option<u16>; 2],
}

/// What a request MoniCAN sent was for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Purpose {
    /// A DATA_OUTPUT write (counted until confirmed, see `intended`).
    Outputs,
    /// A read of DATA_INPUT for the output levels an LED command waits for (`deferred`).
    Levels,
    Convert(Adc),
    Other,
}

/// LED commands typed before MoniCAN knew the SLIO's outputs: the pins to drive high and low
/// once it does.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct LedChanges {
    high: u16,
    low: u16,
}

impl LedChanges {
    fn add(&mut self, pin: u8, on: bool) {
        let bit = 1 << pin;
        if on {
            self.high |= bit;
            self.low &= !bit;
        } else {
            self.low |= bit;
            self.high &= !bit;
        }
    }

    fn apply(self, base: u16) -> u16 {
        (base | self.high) & !self.low
    }
}

#[derive(Clone, Copy, Debug)]
struct Sent {
    slio: SlioId,
    purpose: Purpose,
    what: &'static str,
}

/// Where the key decoder is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Keys {
    Normal,
    /// After ESC.
    Escape,
    /// Inside `ESC [ ...` (count of bytes so far).
    Csi(u8),
    /// After `ESC O`: one more byte.
    Ss3,
}

#[derive(Debug)]
enum Page {
    Slios,
    Mail(MailReader),
    /// A page of text from the program's host (the loader's report), until a key.
    Text {
        title: String,
        lines: Vec<String>,
    },
}

/// The MoniCAN application.
#[derive(Debug)]
pub struct MoniCan {
    config: Config,
    master: Master,
    screen: Screen,
    dirty: bool,
    line: CommandLine,
    keys: Keys,
    page: Page,
    slios: [SlioView; 16],
    last_frame: Option<Frame>,
    notice: Option<String>,
    mail_waiting: bool,
    input_log: Option<String>,
    output_log: Option<String>,
    /// MoniCAN's own frames (the answer to the mail notifier), before the master's.
    outbox: VecDeque<Transmit>,
    /// Requests waiting for their answer, oldest first.
    sent: BTreeMap<u64, Sent>,
    /// DATA_OUTPUT as the commands sent so far make it, while writes are unconfirmed: a second
    /// LED command builds on the first even before the SLIO confirmed it.
    intended: [Option<u16>; 16],
    /// The outputs as the SLIO last told them (its DATA_OUTPUT answers, the levels DATA_INPUT
    /// reads back), whoever asked: what an LED command keeps of the other pins.
    levels: [OutputLevels; 16],
    /// LED commands waiting for the levels (a SLIO calibrated by another master, whose
    /// outputs MoniCAN never saw): they are written once DATA_INPUT tells.
    deferred: [Option<LedChanges>; 16],
    /// The ADC input last asked of each SLIO, for a conversion result nobody waits for.
    last_adc: [Option<Adc>; 16],
    events: VecDeque<Event>,
}

impl MoniCan {
    /// MoniCAN at start-up (§4.3.2.1): the screen is initialised (the first
    /// [`take_screen`](Self::take_screen) clears the terminal and draws it), the 48
    /// calibration frames are queued, then it waits for sign-ons.
    pub fn new(config: Config, now: Nanos) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            master: Master::new(config.bitrate, now),
            config,
            screen: Screen::new(),
            dirty: true,
            line: CommandLine::new(),
            keys: Keys::Normal,
            page: Page::Slios,
            slios: [SlioView::default(); 16],
            last_frame: None,
            notice: None,
            mail_waiting: false,
            input_log: None,
            output_log: None,
            outbox: VecDeque::new(),
            sent: BTreeMap::new(),
            intended: [None; 16],
            levels: [OutputLevels::default(); 16],
            deferred: [None; 16],
            last_adc: [None; 16],
            events: VecDeque::new(),
        })
    }

    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The SLIO host side MoniCAN drives (inventory, what each SLIO confirmed).
    pub fn master(&self) -> &Master {
        &self.master
    }

    /// What the screen shows of a SLIO.
    pub fn slio(&self, slio: SlioId) -> &SlioView {
        &self.slios[slio.number() as usize]
    }

    /// The SLIOs marked on the screen.
    pub fn present(&self) -> impl Iterator<Item = SlioId> + '_ {
        SlioId::all().filter(|s| self.slio(*s).present)
    }

    /// Whether a message waits to be read (Ctrl R).
    pub fn mail_waiting(&self) -> bool {
        self.mail_waiting
    }

    /// Whether the message page is shown.
    pub fn reading_mail(&self) -> bool {
        matches!(self.page, Page::Mail(_))
    }

    /// Shows a page of text over the SLIO screen (rows 3..22, 80 columns each, the rest cut)
    /// until a key is pressed; MoniCAN goes on meanwhile.
    pub fn show_page(&mut self, title: impl Into<String>, lines: Vec<String>) {
        self.page = Page::Text {
            title: title.into(),
            lines,
        };
        self.screen.redraw();
        self.dirty = true;
    }

    /// Whether a page of text is shown.
    pub fn showing_page(&self) -> bool {
        matches!(self.page, Page::Text { .. })
    }

    /// The notice line (row 20), if any.
    pub fn notice(&self) -> Option<&str> {
        if self.mail_waiting {
            return Some(MAIL_NOTICE);
        }
        self.notice.as_deref()
    }

    /// Puts a line of the adapter's on the notice row (e.g. a bus that does not take frames).
    pub fn set_notice(&mut self, text: impl Into<String>) {
        self.notice = Some(text.into());
        self.dirty = true;
    }

    /// Empties the notice row (a mail notice stays until the mail is read).
    pub fn clear_notice(&mut self) {
        self.notice = None;
        self.dirty = true;
    }

    /// The next event.
    pub fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    fn event(&mut self, event: Event) {
        if self.events.len() == MAX_EVENTS {
            self.events.pop_front();
        }
        self.events.push_back(event);
    }

    // ------------------------------------------------------------------ input

    /// A byte the terminal sent at `now` (the time is not needed: a command's request is timed
    /// from when its frame is handed over, [`Self::poll_transmit`]).
    pub fn handle_key(&mut self, _now: Nanos, byte: u8) {
        self.dirty = true;
        match self.keys {
            Keys::Escape => {
                self.keys = match byte {
                    b'[' => Keys::Csi(1),
                    b'O' => Keys::Ss3,
                    _ => Keys::Normal,
                };
                if self.keys != Keys::Normal {
                    return;
                }
            }
            Keys::Csi(n) => {
                // Parameters and intermediates until the final byte.
                let last = (0x40..=0x7E).contains(&byte) || n >= MAX_SEQUENCE;
                self.keys = if last { Keys::Normal } else { Keys::Csi(n + 1) };
                return;
            }
            Keys::Ss3 => {
                self.keys = Keys::Normal;
                return;
            }
            Keys::Normal => {}
        }
        if byte == ESC {
            // Escape clears the command at once; a function key's sequence that follows is
            // swallowed.
            self.keys = Keys::Escape;
        }
        if matches!(self.page, Page::Mail(_) | Page::Text { .. }) {
            // Ctrl L redraws the page (a terminal that connected after the loader's report
            // was drawn); any other key goes back to the SLIO screen, redrawn from what is
            // known.
            if byte != CTRL_L {
                self.page = Page::Slios;
            }
            self.screen.redraw();
            return;
        }
        match byte {
            ESC => self.line.clear(),
            CTRL_L => self.screen.redraw(),
            CTRL_R if self.mail_waiting => self.open_mail(),
            _ => {
                let key = byte.to_ascii_uppercase();
                match self.line.key(key) {
                    KeyOutcome::Edited => {}
                    KeyOutcome::Refused => self.screen.bell(),
                    KeyOutcome::Complete(command) => self.execute(command),
                }
            }
        }
    }

    /// A frame received from the bus at `now` (not one MoniCAN sent).
    pub fn handle_frame(&mut self, now: Nanos, frame: &Frame) {
        self.dirty = true;
        self.last_frame = Some(*frame);
        let id = frame.id();
        if frame.is_remote() && id == standard(0) && frame.dlc() == 0 {
            self.notice = Some(LOADER_NOTICE.to_string());
            self.event(Event::LoaderRequested);
            return;
        }
        if id == standard(self.config.mail_id) {
            if frame.is_remote() {
                // The notifier announces a mail (seed §5.4.5: a remote frame on `idmail`).
                self.mail_waiting = true;
            } else {
                self.mail_frame(frame.payload());
            }
            return;
        }
        if let Some((slio, SlioDirection::FromSlio)) = SlioId::from_id(id)
            && !frame.is_remote()
            && let Ok(reply) = Reply::parse(frame.payload())
            && reply.status.reset_detected
            && reply.register == Register::DataInput
        {
            // Reset: LED commands that waited for its old outputs are void (they are
            // initialised again).
            self.deferred[slio.number() as usize] = None;
            self.master.handle_frame(now, frame);
            self.drain_master();
            self.sign_on(slio);
            return;
        }
        if self.master.handle_frame(now, frame) {
            self.drain_master();
        }
    }

    /// Time passes: the periodic calibration, requests that got no answer.
    pub fn handle_timeout(&mut self, now: Nanos) {
        self.master.handle_timeout(now);
        self.drain_master();
    }

    /// When [`handle_timeout`](Self::handle_timeout) must be called (ns).
    pub fn next_deadline(&self) -> Option<Nanos> {
        self.master.next_deadline()
    }

    /// The next frame to send, handed to the adapter at `now` (a request's answer is awaited
    /// from then on); `single_shot` frames are tried once (the calibration frames, which
    /// nobody acknowledges before the SLIOs are calibrated).
    pub fn poll_transmit(&mut self, now: Nanos) -> Option<Transmit> {
        self.outbox
            .pop_front()
            .or_else(|| self.master.poll_transmit(now))
    }

    /// The last start-up calibration frame went out at `now`: the periodic calibration
    /// follows one period after it ([`Master::start_up_sent`]).
    pub fn start_up_sent(&mut self, now: Nanos) {
        self.master.start_up_sent(now);
    }

    /// Frames waiting to be sent.
    pub fn queued(&self) -> usize {
        self.outbox.len() + self.master.queued()
    }

    // ----------------------------------------------------------------- output

    /// The VT100 bytes that bring the terminal up to date (only the cells that changed; all
    /// of it after start-up, Ctrl L or a page change). Empty when nothing changed.
    pub fn take_screen(&mut self) -> Vec<u8> {
        self.compose();
        let mut out = Vec::new();
        self.screen.render(&mut out);
        out
    }

    /// The next [`take_screen`](Self::take_screen) clears the terminal and draws everything
    /// (a terminal that connected late, lost bytes).
    pub fn redraw(&mut self) {
        self.screen.redraw();
    }

    /// The screen's text as it should be shown (24 lines, trailing blanks removed).
    pub fn text(&mut self) -> String {
        self.compose();
        self.screen.text()
    }

    // -------------------------------------------------------------- behaviour

    fn execute(&mut self, command: Command) {
        let slio = command.slio;
        let i = slio.number() as usize;
        match command.action {
            Action::ReadInputs { .. } => {
                self.read_inputs(slio, Purpose::Other, "inputs");
            }
            Action::Convert(adc) => {
                let value = match adc {
                    Adc::Adc1 => buslab_slio::board::CONVERT_ADC1,
                    Adc::Adc2 => buslab_slio::board::CONVERT_ADC2,
                };
                self.last_adc[i] = Some(adc);
                self.write(
                    slio,
                    Register::AnalogConfig,
                    value,
                    Purpose::Convert(adc),
                    "conversion",
                );
            }
            Action::Led { pin, on } => {
                // The other outputs keep their levels: the ones MoniCAN asked for, else the
                // ones the SLIO told. Unknown (a SLIO another master initialised), they are
                // read first (DATA_INPUT: outputs read back their levels), and the command
                // waits for the answer.
                let base = self.intended[i].or(self.levels[i].get());
                if let (Some(base), None) = (base, self.deferred[i]) {
                    self.write_outputs(slio, set_bit(base, pin, on));
                } else {
                    let waiting = self.deferred[i].is_some();
                    self.deferred[i].get_or_insert_default().add(pin, on);
                    if !waiting {
                        self.read_inputs(slio, Purpose::Levels, LEVELS);
                    }
                }
            }
            Action::Dpm { output, value } => {
                let register = match output {
                    Dpm::Dpm1 => Register::Dpm1,
                    Dpm::Dpm2 => Register::Dpm2,
                };
                self.write(slio, register, dpm_register(value), Purpose::Other, "DPM");
            }
        }
        self.event(Event::CommandSent(command));
    }

    /// A sign-on (§4.3.2.1 step 5): mark the SLIO, initialise its outputs and DPMs, then
    /// read its inputs (now the input switches, P13 being high).
    fn sign_on(&mut self, slio: SlioId) {
        let i = slio.number() as usize;
        self.slios[i].present = true;
        self.intended[i] = None;
        self.write(
            slio,
            Register::OutputEnable,
            OUTPUT_ENABLE,
            Purpose::Other,
            "initialisation",
        );
        self.write(slio, Register::Dpm1, 0, Purpose::Other, "initialisation");
        self.write(slio, Register::Dpm2, 0, Purpose::Other, "initialisation");
        self.write_outputs(slio, INITIAL_OUTPUTS);
        self.read_inputs(slio, Purpose::Other, "initialisation");
        self.event(Event::SignedOn(slio));
    }

    fn write_outputs(&mut self, slio: SlioId, value: u16) {
        self.intended[slio.number() as usize] = Some(value);
        self.write(
            slio,
            Register::DataOutput,
            value,
            Purpose::Outputs,
            "outputs",
        );
    }

    fn write(
        &mut self,
        slio: SlioId,
        register: Register,
        value: u16,
        purpose: Purpose,
        what: &'static str,
    ) {
        let request = self.master.write(slio, register, value);
        self.sent.insert(
            request.0,
            Sent {
                slio,
                purpose,
                what,
            },
        );
    }

    /// A read of DATA_INPUT (the 3-byte frame `29C#000000` for SLIO 3: seed §2.1.2.1).
    fn read_inputs(&mut self, slio: SlioId, purpose: Purpose, what: &'static str) {
        match self.master.read(slio, Register::DataInput) {
            Ok(request) => {
                self.sent.insert(
                    request.0,
                    Sent {
                        slio,
                        purpose,
                        what,
                    },
                );
            }
            // DATA_INPUT is read-only: it always has a read.
            Err(e) => self.notice = Some(e.to_string()),
        }
    }

    fn drain_master(&mut self) {
        while let Some(event) = self.master.poll_event() {
            self.dirty = true;
            match event {
                MasterEvent::Present { slio, .. } => {
                    self.slios[slio.number() as usize].present = true;
                }
                MasterEvent::Register {
                    slio,
                    register,
                    value,
                } => self.show_register(slio, register, value),
                MasterEvent::Confirmed { request, .. } => {
                    self.done(request);
                }
                MasterEvent::NoAnswer { request, slio } => {
                    let sent = self.done(request);
                    if sent.is_some_and(|s| s.purpose == Purpose::Levels) {
                        // The LED commands that waited are not sent: the outputs stay unknown.
                        self.deferred[slio.number() as usize] = None;
                    }
                    let what = sent.map_or("request", |s| s.what);
                    self.notice = Some(format!("SLIO {slio} did not answer ({what})"));
                    self.event(Event::NoAnswer(slio));
                }
                // The master calibrates again and repeats what was unanswered.
                MasterEvent::CalibrationLost { .. } => {}
            }
        }
    }

    /// A request is over (answered or not).
    fn done(&mut self, request: RequestId) -> Option<Sent> {
        let sent = self.sent.remove(&request.0)?;
        if sent.purpose == Purpose::Outputs {
            let i = sent.slio.number() as usize;
            let more = self
                .sent
                .values()
                .any(|s| s.slio == sent.slio && s.purpose == Purpose::Outputs);
            if !more {
                // Nothing unconfirmed any more: the SLIO's word is the truth.
                self.intended[i] = None;
            }
        }
        Some(sent)
    }

    /// A register's content the SLIO sent: the only way a value reaches the screen.
    fn show_register(&mut self, slio: SlioId, register: Register, value: u16) {
        let i = slio.number() as usize;
        self.levels[i].learn(register, value);
        if let Some(base) = self.levels[i].get()
            && let Some(changes) = self.deferred[i].take()
        {
            let base = self.intended[i].unwrap_or(base);
            self.write_outputs(slio, changes.apply(base));
        }
        let view = &mut self.slios[i];
        let label = match register {
            Register::DataInput => {
                view.inputs = Some(value);
                "Data input"
            }
            Register::DataOutput => {
                view.outputs = Some(value);
                "Data_output"
            }
            Register::Dpm1 => {
                view.dpm[0] = Some(value);
                "DPM1"
            }
            Register::Dpm2 => {
                view.dpm[1] = Some(value);
                "DPM2"
            }
            Register::Adc => {
                // The oldest conversion waiting for this SLIO is the one answered (the master
                // matches answers in the same order).
                let channel = self
                    .sent
                    .values()
                    .find_map(|s| match s.purpose {
                        Purpose::Convert(adc) if s.slio == slio => Some(adc),
                        _ => None,
                    })
                    .or(self.last_adc[i]);
                match channel {
                    Some(Adc::Adc1) => {
                        self.slios[i].adc[0] = Some(value);
                        "ADC1"
                    }
                    Some(Adc::Adc2) => {
                        self.slios[i].adc[1] = Some(value);
                        "ADC2"
                    }
                    None => "ADC",
                }
            }
            Register::OutputEnable => "Output_enable",
            Register::AnalogConfig => "Analog_config",
            Register::PositiveEdge => "Positive_edge",
            Register::NegativeEdge => "Negative_edge",
        };
        let line = format!("ID_slio:{slio} {label}:{value:04X}");
        if matches!(register, Register::DataInput | Register::Adc) {
            self.input_log = Some(line);
        } else {
            self.output_log = Some(line);
        }
    }

    fn mail_frame(&mut self, data: &[u8]) {
        match &mut self.page {
            Page::Mail(reader) if !reader.is_complete() => {
                reader.push(data);
            }
            _ => self.mail_waiting = true,
        }
    }

    /// Ctrl R: the SLIO screen is cleared and the notifier is told MoniCAN is ready (a remote
    /// frame with the mail identifier).
    fn open_mail(&mut self) {
        self.mail_waiting = false;
        self.page = Page::Mail(MailReader::new(self.config.mail_limit));
        self.screen.redraw();
        let frame = Frame::remote(standard(self.config.mail_id), 0).expect("DLC 0");
        self.outbox.push_back(Transmit {
            frame,
            single_shot: false,
        });
        self.event(Event::MailRequested);
    }

    // ---------------------------------------------------------------- drawing

    /// Brings the wanted screen text up to the state (done lazily, when the screen is asked
    /// for: a busy bus changes the state far more often than a terminal can show).
    fn compose(&mut self) {
        if !self.dirty {
            return;
        }
        self.dirty = false;
        let screen = &mut self.screen;
        match &self.page {
            Page::Mail(reader) => {
                reader.draw(screen);
                return;
            }
            Page::Text { title, lines } => {
                draw_text_page(screen, title, lines);
                return;
            }
            Page::Slios => {}
        }
        screen.blank();
        screen.put_line(TITLE_ROW, TITLE);
        screen.put_line(HEADER_ROW, HEADER);
        for slio in SlioId::all() {
            let row = slio_row(slio);
            let view = &self.slios[slio.number() as usize];
            screen.put_line(row, &blank_row(slio));
            if view.present {
                screen.put(row, MARK_COL, "*");
            }
            let hex4 = |v: Option<u16>| v.map_or("XXXX".to_string(), |v| format!("{v:04X}"));
            // ADC and DPM registers hold 10 bits; the screen shows their top 8 (00..FF).
            let hex2 =
                |v: Option<u16>| v.map_or("XX".to_string(), |v| format!("{:02X}", v >> 2 & 0xFF));
            screen.put(row, OUTPUTS_COL, &hex4(view.outputs));
            screen.put(row, INPUTS_COL, &hex4(view.inputs));
            screen.put(row, ADC1_COL, &hex2(view.adc[0]));
            screen.put(row, ADC2_COL, &hex2(view.adc[1]));
            screen.put(row, DPM1_COL, &hex2(view.dpm[0]));
            screen.put(row, DPM2_COL, &hex2(view.dpm[1]));
        }
        screen.put_line(LAST_FRAME_ROW, &last_frame_line(self.last_frame.as_ref()));
        let notice = if self.mail_waiting {
            Some(MAIL_NOTICE)
        } else {
            self.notice.as_deref()
        };
        screen.put_line(NOTICE_ROW, notice.unwrap_or(""));
        screen.put_line(RULE_ROW, &rule());
        screen.put_line(INPUT_LOG_ROW, self.input_log.as_deref().unwrap_or(""));
        screen.put_line(OUTPUT_LOG_ROW, self.output_log.as_deref().unwrap_or(""));
        screen.put_line(COMMAND_ROW, &blank_command_line());
        let [slio, io, pin, value] = self.line.fields();
        screen.put(COMMAND_ROW, SLIO_FIELD.1, &slio);
        screen.put(COMMAND_ROW, IO_FIELD.1, &io);
        screen.put(COMMAND_ROW, PIN_FIELD.1, &pin);
        screen.put(COMMAND_ROW, VALUE_FIELD.1, &value);
        screen.set_cursor(COMMAND_ROW, self.line.cursor_col());
    }
}

/// A page of text: the title on row 1, the lines from row 3 to row 22, the hint on row 24.
fn draw_text_page(screen: &mut Screen, title: &str, lines: &[String]) {
    screen.blank();
    screen.put_line(1, title);
    for (row, line) in (3u8..=22).zip(lines) {
        screen.put_line(row, line);
    }
    screen.put_line(24, PAGE_HINT);
    screen.set_cursor(24, PAGE_HINT.len() as u8 + 1);
}

/// A DPM value typed as 00..FF, as the 10-bit register holds it (its top 8 bits).
pub fn dpm_register(value: u8) -> u16 {
    u16::from(value) << 2
}

/// `Last frame received : ID1:53 ID2:A0 DATA1:23 DATA2:20 DATA3:00`: the identifier as the
/// SJA1000's PeliCAN receive buffer holds it (ID1 = ID.10..3; ID2 = ID.2..0, RTR), then the
/// data bytes; a frame whose bytes do not fit in 80 columns that way shows them as
/// `DATA:11 22 ...`; a remote frame adds its DLC.
pub fn last_frame_line(frame: Option<&Frame>) -> String {
    let mut line = "Last frame received :".to_string();
    let Some(frame) = frame else {
        return line;
    };
    let rtr = u8::from(frame.is_remote());
    match frame.id() {
        Id::Standard(id) => {
            let raw = id.as_raw();
            line += &format!(
                " ID1:{:02X} ID2:{:02X}",
                raw >> 3,
                (raw & 7) << 5 | u16::from(rtr) << 4
            );
        }
        Id::Extended(id) => {
            let raw = id.as_raw();
            line += &format!(
                " ID1:{:02X} ID2:{:02X} ID3:{:02X} ID4:{:02X}",
                raw >> 21 & 0xFF,
                raw >> 13 & 0xFF,
                raw >> 5 & 0xFF,
                (raw & 0x1F) << 3 | u32::from(rtr) << 2
            );
        }
    }
    if frame.is_remote() {
        return line + &format!(" remote DLC:{}", frame.dlc());
    }
    let long: String = frame
        .payload()
        .iter()
        .enumerate()
        .map(|(k, b)| format!(" DATA{}:{b:02X}", k + 1))
        .collect();
    if line.len() + long.len() <= crate::screen::COLS {
        return line + &long;
    }
    let bytes: Vec<String> = frame.payload().iter().map(|b| format!("{b:02X}")).collect();
    format!("{line} DATA:{}", bytes.join(" "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_last_frame_line_reads_like_the_seed() {
        let f = Frame::data(SlioId::new(3).unwrap().reply_id(), &[0x23, 0x20, 0x00]).unwrap();
        assert_eq!(
            last_frame_line(Some(&f)),
            "Last frame received : ID1:53 ID2:A0 DATA1:23 DATA2:20 DATA3:00"
        );
        let long: Frame = "12345678#1122334455667788".parse().unwrap();
        let line = last_frame_line(Some(&long));
        assert_eq!(
            line,
            "Last frame received : ID1:91 ID2:A2 ID3:B3 ID4:C0 DATA:11 22 33 44 55 66 77 88"
        );
        assert!(line.len() <= 80);
        let remote: Frame = "000#R".parse().unwrap();
        assert_eq!(
            last_frame_line(Some(&remote)),
            "Last frame received : ID1:00 ID2:10 remote DLC:0"
        );
        let eight: Frame = "7FF#0102030405060708".parse().unwrap();
        assert!(last_frame_line(Some(&eight)).len() <= 80);
    }

    #[test]
    fn configurations_that_clash_are_refused() {
        let with_id = |mail_id| Config {
            mail_id,
            ..Config::default()
        };
        assert_eq!(Config::default().validate(), Ok(()));
        assert!(matches!(
            with_id(0).validate(),
            Err(ConfigError::MailIdTaken { .. })
        ));
        assert!(matches!(
            with_id(0x0AA).validate(),
            Err(ConfigError::MailIdTaken { .. })
        ));
        assert!(matches!(
            with_id(0x285).validate(),
            Err(ConfigError::MailIdTaken { .. })
        ));
        assert_eq!(
            with_id(0x800).validate(),
            Err(ConfigError::MailIdRange(0x800))
        );
        let zero = Config {
            bitrate: 0,
            ..Config::default()
        };
        assert_eq!(zero.validate(), Err(ConfigError::Bitrate(0)));
        let huge = Config {
            mail_limit: MAX_MAIL_LIMIT + 1,
            ..Config::default()
        };
        assert!(huge.validate().is_err());
        assert_eq!(
            with_id(0x285).validate().unwrap_err().to_string(),
            "mail identifier 0x285 is a SLIO identifier; choose another 11-bit identifier"
        );
    }
}
