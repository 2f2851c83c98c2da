//! An SLCAN adapter (Lawicel CANUSB style) as a sans-IO model: bytes from the host go in, the
//! answers and received frames come out as bytes, and what the host asked of the bus comes out
//! as [`AdapterEvent`]s. Time is the caller's (milliseconds, for `Z1` timestamps).
//!
//! Answers follow the Lawicel manual and what python-can and Linux's slcan/slcand expect:
//! CR for OK, BEL for an unknown or malformed command or one in the wrong state (`S` while
//! open, a frame while closed), `z`/`Z` CR for a queued frame. Output waiting for the host is
//! bounded ([`MAX_OUTPUT`]): a host that does not read loses frames, and `F` reports the
//! overrun, as a real adapter's receive FIFO overflows.
//!
//! CAN FD: an adapter made [`Adapter::with_fd`] (a CANable 2.0's kind, on a bus that carries
//! FD) takes `d`/`D`/`b`/`B` frames and `Yn` data bit rates before opening, and gives the
//! host the FD frames it receives; a classic one (a CANUSB's kind, or any adapter on buslab's
//! bit-level bus) answers them BEL, and an FD frame refused so is told
//! ([`AdapterEvent::RefusedFd`]).

use std::collections::VecDeque;

use buslab_bus::{CanError, ControllerProblems, ErrorFrame, Record};
use buslab_can::{FdFrame, Frame, Nanos};

use crate::codec::{
    CodecError, Command, Line, LineSplitter, MAX_LINE, Reply, STANDARD_BITRATES, StatusFlags,
    TIMESTAMP_WRAP_MS, data_bitrate, format_reply, parse_command,
};

/// Bytes waiting for the host at most (a USB adapter's buffers are smaller; a PTY holds 4 KiB
/// more).
pub const MAX_OUTPUT: usize = 64 * 1024;

/// The longest reply: an extended FD frame with 64 bytes and a timestamp, with its CR.
const MAX_REPLY: usize = MAX_LINE + 1;

/// What the adapter says about itself (`V`, `v`, `N`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Identity {
    /// `Vhhss`: hardware and software version, decimal digits (python-can reads them as
    /// numbers).
    pub version: [u8; 4],
    /// `vmami`.
    pub detailed_version: [u8; 4],
    /// `Nxxxx`: 4 letters or digits.
    pub serial: [u8; 4],
}

impl Default for Identity {
    fn default() -> Self {
        Self {
            version: *b"1013",
            detailed_version: *b"1014",
            serial: *b"BL01",
        }
    }
}

/// The channel's state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Reset mode: not on the bus (power-up).
    Closed,
    /// `O`: on the bus, transmitting and acknowledging.
    Open,
    /// `L`: receiving only.
    ListenOnly,
}

/// The bit timing the host set before opening.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Timing {
    /// `S0`..`S8`: a standard bit rate in bit/s.
    Bitrate(u32),
    /// `sxxyy`: SJA1000 BTR0/BTR1.
    Btr { btr0: u8, btr1: u8 },
    /// `sxxyyzz`: MCP2515 CNF1..3.
    Cnf([u8; 3]),
}

/// What the host asked for, for the adapter's bus side.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AdapterEvent {
    /// `O` or `L`: the channel opened, with the timing set before (if any) and the CAN FD
    /// data bit rate in bit/s (`Yn`, on an FD adapter).
    Opened {
        listen_only: bool,
        timing: Option<Timing>,
        data_bitrate: Option<u32>,
    },
    /// `C`: the channel closed.
    Closed,
    /// A frame to put on the bus.
    Transmit(Frame),
    /// A CAN FD frame to put on the bus (an FD adapter's).
    TransmitFd(FdFrame),
    /// An FD frame the host sent a classic adapter: refused with BEL.
    RefusedFd(FdFrame),
    /// The channel opened with an acceptance filter that is not "accept all": the model
    /// delivers every frame anyway.
    FilterNotModelled { code: u32, mask: u32 },
    /// A line that is not a command; it was answered with BEL.
    Garbage(CodecError),
    /// Output for the host filled up: frames are being dropped (said once per episode).
    Overrun,
    /// A frame (classic or FD) refused with BEL: the adapter's controller is bus-off (until
    /// the host closes and opens the channel). Said for the first refused frame of each
    /// bus-off.
    RefusedBusOff(Record),
}

/// The error level of the adapter's controller, as its error frames tell it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ErrorLevel {
    /// Both counters below 96.
    #[default]
    Active,
    /// A counter at 96 or more (SJA1000 SR.ES).
    Warning,
    /// A counter at 128 or more: its error flags are recessive.
    Passive,
    /// TXERR passed 255: off the bus until the host closes and opens the channel.
    BusOff,
}

impl ErrorLevel {
    /// The `F` flags this level keeps set while it lasts. Lawicel's `F` has no bus-off bit:
    /// bus-off shows as error warning, error passive and bus error together (docs/decisions.md,
    /// "An SLCAN host at the wrong bit rate").
    pub const fn flags(self) -> u8 {
        match self {
            ErrorLevel::Active => 0,
            ErrorLevel::Warning => StatusFlags::ERROR_WARNING,
            ErrorLevel::Passive => StatusFlags::ERROR_WARNING | StatusFlags::ERROR_PASSIVE,
            ErrorLevel::BusOff => {
                StatusFlags::ERROR_WARNING | StatusFlags::ERROR_PASSIVE | StatusFlags::BUS_ERROR
            }
        }
    }
}

/// The adapter model.
#[derive(Clone, Debug)]
pub struct Adapter {
    identity: Identity,
    splitter: LineSplitter,
    mode: Mode,
    timing: Option<Timing>,
    timestamps: bool,
    acceptance_code: u32,
    acceptance_mask: u32,
    output: Vec<u8>,
    events: VecDeque<AdapterEvent>,
    /// Flags `F` reports once and clears (overruns, bus errors, lost arbitrations).
    sticky: u8,
    dropped: u64,
    /// The controller's error level since the channel opened.
    level: ErrorLevel,
    /// A frame was refused in this bus-off already.
    refused: bool,
    /// The adapter speaks CAN FD.
    fd: bool,
    /// `Yn`: the FD data bit rate set before opening.
    data_bitrate: Option<u32>,
}

impl Default for Adapter {
    fn default() -> Self {
        Self::new(Identity::default())
    }
}

impl Adapter {
    /// A closed adapter, timestamps off, acceptance filter open (power-up defaults).
    pub fn new(identity: Identity) -> Self {
        Self {
            identity,
            splitter: LineSplitter::new(),
            mode: Mode::Closed,
            timing: None,
            timestamps: false,
            acceptance_code: 0,
            acceptance_mask: 0xFFFF_FFFF,
            output: Vec::new(),
            events: VecDeque::new(),
            sticky: 0,
            dropped: 0,
            level: ErrorLevel::Active,
            refused: false,
            fd: false,
            data_bitrate: None,
        }
    }

    /// The same adapter speaking CAN FD (`fd`) or classic CAN only (the default).
    pub fn with_fd(mut self, fd: bool) -> Self {
        self.fd = fd;
        self
    }

    /// Whether the adapter speaks CAN FD.
    pub fn carries_fd(&self) -> bool {
        self.fd
    }

    /// The controller's error level, as its error frames told it.
    pub fn level(&self) -> ErrorLevel {
        self.level
    }

    /// An error frame of the adapter's controller (its node on the bus): `F` reports it, as
    /// the SJA1000's interrupt flags a Lawicel adapter shows (bus error, arbitration lost,
    /// data overrun until read; warning, passive and bus-off while they last), and a bus-off
    /// controller refuses frames with BEL.
    pub fn controller_error(&mut self, error: &ErrorFrame) {
        if self.mode == Mode::Closed {
            return;
        }
        for e in &error.errors {
            match *e {
                CanError::Protocol { .. } | CanError::BusError | CanError::NoAck => {
                    self.sticky |= StatusFlags::BUS_ERROR;
                }
                CanError::LostArbitration { .. } => self.sticky |= StatusFlags::ARBITRATION_LOST,
                CanError::BusOff => self.level = ErrorLevel::BusOff,
                CanError::Restarted => self.level = ErrorLevel::Active,
                CanError::Controller(p) => {
                    const WARNING: u8 =
                        ControllerProblems::TX_WARNING | ControllerProblems::RX_WARNING;
                    const PASSIVE: u8 =
                        ControllerProblems::TX_PASSIVE | ControllerProblems::RX_PASSIVE;
                    if p.0 & ControllerProblems::RX_OVERFLOW != 0 {
                        self.sticky |= StatusFlags::DATA_OVERRUN;
                    }
                    if p.0 & PASSIVE != 0 {
                        self.level = ErrorLevel::Passive;
                    } else if p.0 & WARNING != 0 {
                        self.level = ErrorLevel::Warning;
                    } else if p.0 & ControllerProblems::ACTIVE != 0 {
                        self.level = ErrorLevel::Active;
                    }
                }
                CanError::TxTimeout | CanError::Transceiver(_) | CanError::Unknown(_) => {}
            }
        }
        if self.level != ErrorLevel::BusOff {
            self.refused = false;
        }
    }

    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Frames dropped so far because the host did not read.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Bytes from the host.
    pub fn receive(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            let reply = match self.splitter.push(byte) {
                None => continue,
                Some(Line::TooLong) => Err(CodecError::TooLong),
                Some(Line::Text(text) | Line::Bell(text)) => parse_command(text),
            };
            let reply = match reply {
                Ok(command) => self.command(command),
                Err(error) => {
                    self.events.push_back(AdapterEvent::Garbage(error));
                    Some(Reply::Error)
                }
            };
            if let Some(reply) = reply {
                self.reply(&reply);
            }
        }
    }

    /// A frame the adapter received from the bus at `now` (since any epoch): sent to the host
    /// if the channel is open.
    pub fn deliver(&mut self, frame: &Frame, now: Nanos) {
        if self.mode == Mode::Closed || !self.room_for_frame() {
            return;
        }
        let timestamp_ms = self.timestamp(now);
        self.reply(&Reply::Frame {
            frame: *frame,
            timestamp_ms,
        });
    }

    /// A CAN FD frame the adapter received from the bus at `now`: sent to the host if the
    /// channel is open. A classic adapter has none to give (its controller knows no FD): the
    /// frame is dropped and counted with [`dropped`](Self::dropped).
    pub fn deliver_fd(&mut self, frame: &FdFrame, now: Nanos) {
        if self.mode == Mode::Closed {
            return;
        }
        if !self.fd {
            self.dropped += 1;
            return;
        }
        if !self.room_for_frame() {
            return;
        }
        let timestamp_ms = self.timestamp(now);
        self.reply(&Reply::FdFrame {
            frame: *frame,
            timestamp_ms,
        });
    }

    /// Whether a received frame fits in the output; if not, it is dropped and the overrun
    /// told.
    fn room_for_frame(&mut self) -> bool {
        if self.output.len() + MAX_REPLY <= MAX_OUTPUT {
            return true;
        }
        self.dropped += 1;
        if self.sticky & StatusFlags::DATA_OVERRUN == 0 {
            self.events.push_back(AdapterEvent::Overrun);
        }
        self.sticky |= StatusFlags::DATA_OVERRUN | StatusFlags::RX_FIFO_FULL;
        false
    }

    fn timestamp(&self, now: Nanos) -> Option<u16> {
        self.timestamps
            .then(|| (now / Nanos::from_millis(1) % u64::from(TIMESTAMP_WRAP_MS)) as u16)
    }

    /// The bytes waiting for the host.
    pub fn output(&self) -> &[u8] {
        &self.output
    }

    /// Drops the first `n` bytes of [`output`](Self::output) (the host took them).
    pub fn consume(&mut self, n: usize) {
        self.output.drain(..n.min(self.output.len()));
    }

    /// Everything waiting for the host, taken.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.output)
    }

    pub fn poll_event(&mut self) -> Option<AdapterEvent> {
        self.events.pop_front()
    }

    fn reply(&mut self, reply: &Reply) {
        if self.output.len() + MAX_REPLY > MAX_OUTPUT {
            // A host that writes without reading: its answers are lost too.
            self.sticky |= StatusFlags::DATA_OVERRUN;
            return;
        }
        format_reply(reply, &mut self.output);
    }

    /// A frame refused because the controller is bus-off; the first of each bus-off is told.
    fn refuse_bus_off(&mut self, frame: Record) -> Option<Reply> {
        if !std::mem::replace(&mut self.refused, true) {
            self.events.push_back(AdapterEvent::RefusedBusOff(frame));
        }
        Some(Reply::Error)
    }

    /// Carries out one command; the answer, if any.
    fn command(&mut self, command: Command) -> Option<Reply> {
        let closed = self.mode == Mode::Closed;
        let ok_if = |condition: bool| Some(if condition { Reply::Ok } else { Reply::Error });
        match command {
            // slcanpty skips empty lines; python-can sends one and ignores any answer.
            Command::Empty => None,
            Command::Bitrate(code) if closed => {
                self.timing = Some(Timing::Bitrate(STANDARD_BITRATES[usize::from(code)]));
                Some(Reply::Ok)
            }
            Command::Btr { btr0, btr1 } if closed => {
                self.timing = Some(Timing::Btr { btr0, btr1 });
                Some(Reply::Ok)
            }
            Command::Cnf(regs) if closed => {
                self.timing = Some(Timing::Cnf(regs));
                Some(Reply::Ok)
            }
            Command::DataBitrate(code) if closed && self.fd => {
                self.data_bitrate = data_bitrate(code);
                Some(Reply::Ok)
            }
            // While open, as `S`; on a classic adapter, as an unknown command.
            Command::Bitrate(_)
            | Command::Btr { .. }
            | Command::Cnf(_)
            | Command::DataBitrate(_) => Some(Reply::Error),
            Command::Open | Command::ListenOnly if closed => {
                let listen_only = command == Command::ListenOnly;
                self.mode = if listen_only {
                    Mode::ListenOnly
                } else {
                    Mode::Open
                };
                // Opening initialises the controller: counters at zero, bus-off ended.
                self.level = ErrorLevel::Active;
                self.refused = false;
                self.events.push_back(AdapterEvent::Opened {
                    listen_only,
                    timing: self.timing,
                    data_bitrate: self.data_bitrate.filter(|_| self.fd),
                });
                if self.acceptance_mask != 0xFFFF_FFFF {
                    self.events.push_back(AdapterEvent::FilterNotModelled {
                        code: self.acceptance_code,
                        mask: self.acceptance_mask,
                    });
                }
                Some(Reply::Ok)
            }
            Command::Open | Command::ListenOnly => Some(Reply::Error),
            // Closing a closed channel is harmless: python-can and slcand start with `C`.
            Command::Close => {
                if !closed {
                    self.mode = Mode::Closed;
                    self.events.push_back(AdapterEvent::Closed);
                }
                Some(Reply::Ok)
            }
            Command::Transmit(frame)
                if self.mode == Mode::Open && self.level == ErrorLevel::BusOff =>
            {
                self.refuse_bus_off(Record::Frame(frame))
            }
            Command::Transmit(frame) if self.mode == Mode::Open => {
                self.events.push_back(AdapterEvent::Transmit(frame));
                Some(Reply::Queued {
                    extended: frame.is_extended(),
                })
            }
            Command::Transmit(_) => Some(Reply::Error),
            Command::TransmitFd(frame) if !self.fd => {
                self.events.push_back(AdapterEvent::RefusedFd(frame));
                Some(Reply::Error)
            }
            Command::TransmitFd(frame)
                if self.mode == Mode::Open && self.level == ErrorLevel::BusOff =>
            {
                self.refuse_bus_off(Record::Fd(frame))
            }
            Command::TransmitFd(frame) if self.mode == Mode::Open => {
                self.events.push_back(AdapterEvent::TransmitFd(frame));
                Some(Reply::Queued {
                    extended: frame.is_extended(),
                })
            }
            Command::TransmitFd(_) => Some(Reply::Error),
            Command::Status => {
                let flags = StatusFlags(std::mem::take(&mut self.sticky) | self.level.flags());
                Some(Reply::Status(flags))
            }
            Command::Version => Some(Reply::Version(self.identity.version)),
            Command::DetailedVersion => {
                Some(Reply::DetailedVersion(self.identity.detailed_version))
            }
            Command::SerialNumber => Some(Reply::SerialNumber(self.identity.serial)),
            Command::Timestamps(on) => {
                self.timestamps = on;
                Some(Reply::Ok)
            }
            Command::AcceptanceCode(code) => {
                if closed {
                    self.acceptance_code = code;
                }
                ok_if(closed)
            }
            Command::AcceptanceMask(mask) => {
                if closed {
                    self.acceptance_mask = mask;
                }
                ok_if(closed)
            }
            // As slcanpty: auto-poll is always on (X1 fine, X0 and polling refused); UART rate,
            // filter mode and auto-start are accepted and have no effect.
            Command::Other { letter, argument } => match (letter, argument.as_str()) {
                (b'X', "1") | (b'U' | b'W' | b'Q', _) => Some(Reply::Ok),
                _ => Some(Reply::Error),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(text: &str) -> Frame {
        text.parse().unwrap()
    }

    fn exchange(adapter: &mut Adapter, input: &str) -> String {
        adapter.receive(input.as_bytes());
        String::from_utf8(adapter.take_output()).unwrap()
    }

    fn events(adapter: &mut Adapter) -> Vec<AdapterEvent> {
        std::iter::from_fn(|| adapter.poll_event()).collect()
    }

    #[test]
    fn python_can_session() {
        let mut a = Adapter::default();
        // python-can 4.6.1 opening with bitrate=500000: C, S6, an empty line, O twice, V, N.
        assert_eq!(
            exchange(&mut a, "C\rS6\r\rO\rO\rV\rN\r"),
            "\r\r\r\x07V1013\rNBL01\r"
        );
        assert_eq!(
            events(&mut a),
            [AdapterEvent::Opened {
                listen_only: false,
                timing: Some(Timing::Bitrate(500_000)),
                data_bitrate: None,
            }]
        );
        assert_eq!(
            exchange(&mut a, "t1233010203\rT1ABCDEF02DEAD\rr7FF2\r"),
            "z\rZ\rz\r"
        );
        assert_eq!(
            events(&mut a),
            [
                AdapterEvent::Transmit(frame("123#010203")),
                AdapterEvent::Transmit(frame("1ABCDEF0#DEAD")),
                AdapterEvent::Transmit(frame("7FF#R2")),
            ]
        );
        a.deliver(&frame("321#AABB"), Nanos::from_millis(5));
        a.deliver(&frame("12345678#R3"), Nanos::from_millis(6));
        assert_eq!(
            String::from_utf8(a.take_output()).unwrap(),
            "t3212AABB\rR123456783\r"
        );
        assert_eq!(exchange(&mut a, "C\r"), "\r");
        assert_eq!(events(&mut a), [AdapterEvent::Closed]);
        a.deliver(&frame("321#AABB"), Nanos::from_millis(7));
        assert!(a.output().is_empty(), "a closed channel receives nothing");
    }

    #[test]
    fn slcand_session_with_timestamps_and_listen_only() {
        let mut a = Adapter::default();
        // slcand -s5 -l: C, S5, then L; a host that wants timestamps sends Z1 first.
        assert_eq!(exchange(&mut a, "C\rZ1\rS5\rL\r"), "\r\r\r\r");
        assert_eq!(
            events(&mut a),
            [AdapterEvent::Opened {
                listen_only: true,
                timing: Some(Timing::Bitrate(250_000)),
                data_bitrate: None,
            }]
        );
        assert_eq!(
            exchange(&mut a, "t1230\r"),
            "\x07",
            "listen-only sends nothing"
        );
        assert!(events(&mut a).is_empty());
        a.deliver(&frame("123#01"), Nanos::from_millis(60_000 + 59_999));
        assert_eq!(String::from_utf8(a.take_output()).unwrap(), "t123101EA5F\r");
    }

    #[test]
    fn wrong_state_and_garbage_get_bel_and_nothing_else() {
        let mut a = Adapter::default();
        assert_eq!(exchange(&mut a, "t1230\r"), "\x07", "frame while closed");
        assert_eq!(
            exchange(&mut a, "s031C\rO\rS6\r"),
            "\r\r\x07",
            "S while open"
        );
        assert_eq!(exchange(&mut a, "M00000000\r"), "\x07", "filter while open");
        assert_eq!(exchange(&mut a, "hello\r"), "\x07");
        assert_eq!(exchange(&mut a, "t12\r"), "\x07");
        assert_eq!(exchange(&mut a, &"x".repeat(5000)), "");
        assert_eq!(
            exchange(&mut a, "\r"),
            "\x07",
            "an overlong line is one error"
        );
        assert_eq!(exchange(&mut a, "F\rX0\rX1\rP\rU1\r"), "F00\r\x07\r\x07\r");
        let garbage = events(&mut a)
            .into_iter()
            .filter(|e| matches!(e, AdapterEvent::Garbage(_)))
            .count();
        assert_eq!(garbage, 3);
    }

    #[test]
    fn a_host_that_does_not_read_loses_frames_and_f_says_so() {
        let mut a = Adapter::default();
        exchange(&mut a, "O\r");
        events(&mut a);
        let f = frame("7FF#1122334455667788");
        for t in 0..10_000 {
            a.deliver(&f, Nanos::from_millis(t));
        }
        assert!(a.output().len() <= MAX_OUTPUT);
        assert!(a.dropped() > 0);
        assert_eq!(events(&mut a), [AdapterEvent::Overrun]);
        a.take_output();
        assert_eq!(exchange(&mut a, "F\r"), "F09\r");
        assert_eq!(exchange(&mut a, "F\r"), "F00\r", "F clears the overrun");
    }

    #[test]
    fn an_acceptance_filter_is_reported_as_not_modelled() {
        let mut a = Adapter::default();
        assert_eq!(exchange(&mut a, "M00000123\rm00000000\rO\r"), "\r\r\r");
        assert_eq!(
            events(&mut a)[1],
            AdapterEvent::FilterNotModelled {
                code: 0x123,
                mask: 0
            }
        );
    }

    /// A bit-rate mismatch told to the host: python-can at 500 kbit/s on a 125 kbit/s bus.
    #[test]
    fn a_mismatched_host_sees_the_controller_state_in_f_and_bel_when_bus_off() {
        use buslab_bus::{ControllerState, Ecc, ErrorCounters};
        let mut a = Adapter::default();
        exchange(&mut a, "S6\rO\r");
        events(&mut a);
        let counters = |tx, rx| ErrorCounters { tx, rx };
        a.controller_error(&ErrorFrame::sja1000_bus_error(
            Ecc(0x3C),
            Some(counters(8, 1)),
        ));
        assert_eq!(exchange(&mut a, "F\r"), "F80\r", "a bus error, once");
        assert_eq!(exchange(&mut a, "F\r"), "F00\r");
        a.controller_error(&ErrorFrame::state_change(
            ControllerState::Warning,
            counters(96, 1),
        ));
        assert_eq!(exchange(&mut a, "F\r"), "F04\r", "the warning lasts");
        a.controller_error(&ErrorFrame::state_change(
            ControllerState::Passive,
            counters(128, 1),
        ));
        assert_eq!(exchange(&mut a, "F\rF\r"), "F24\rF24\r");
        assert_eq!(
            exchange(&mut a, "t1230\r"),
            "z\r",
            "a passive node still sends"
        );
        a.controller_error(&ErrorFrame::state_change(
            ControllerState::BusOff,
            counters(255, 1),
        ));
        assert_eq!(a.level(), ErrorLevel::BusOff);
        assert_eq!(exchange(&mut a, "F\r"), "FA4\r");
        assert_eq!(
            exchange(&mut a, "t1230\rt1230\r"),
            "\x07\x07",
            "bus-off refuses frames"
        );
        assert_eq!(
            events(&mut a),
            [
                AdapterEvent::Transmit(frame("123#")),
                AdapterEvent::RefusedBusOff(Record::Frame(frame("123#")))
            ],
            "the first refused frame is told"
        );
        // Closing and opening again initialises the controller, as a CANUSB's C and O.
        assert_eq!(exchange(&mut a, "C\rS4\rO\rF\rt1230\r"), "\r\r\rF00\rz\r");
    }

    fn fd(text: &str) -> FdFrame {
        text.parse().unwrap()
    }

    /// python-can 4.6.1 with `timing=BitTimingFd(500 kbit/s, 2 Mbit/s)`: C, S6, Y2, O, then
    /// FD frames as its `send` spells them, on an FD adapter.
    #[test]
    fn an_fd_adapter_takes_python_cans_fd_session_both_ways() {
        let mut a = Adapter::default().with_fd(true);
        assert!(a.carries_fd());
        assert_eq!(exchange(&mut a, "C\rS6\rY2\rO\r"), "\r\r\r\r");
        assert_eq!(
            events(&mut a),
            [AdapterEvent::Opened {
                listen_only: false,
                timing: Some(Timing::Bitrate(500_000)),
                data_bitrate: Some(2_000_000),
            }]
        );
        assert_eq!(exchange(&mut a, "Y5\r"), "\x07", "Y while open, as S");
        let long = format!("B1ABCDEF0F{}", "A5".repeat(64));
        assert_eq!(
            exchange(
                &mut a,
                &format!("d1233112233\rb123900112233445566778899AABB\r{long}\r")
            ),
            "z\rz\rZ\r"
        );
        assert_eq!(
            events(&mut a),
            [
                AdapterEvent::TransmitFd(fd("123##0112233")),
                AdapterEvent::TransmitFd(fd("123##100112233445566778899AABB")),
                AdapterEvent::TransmitFd(fd(&format!("1ABCDEF0##1{}", "A5".repeat(64)))),
            ]
        );
        a.deliver_fd(&fd("321##1AABBCCDDEEFF001122334455"), Nanos::from_millis(5));
        a.deliver(&frame("321#AABB"), Nanos::from_millis(6));
        a.deliver_fd(&fd("12345678##0"), Nanos::from_millis(7));
        assert_eq!(
            String::from_utf8(a.take_output()).unwrap(),
            "b3219AABBCCDDEEFF001122334455\rt3212AABB\rD123456780\r"
        );
    }

    #[test]
    fn fd_frames_on_a_classic_adapter_get_bel_and_are_told() {
        let mut a = Adapter::default();
        assert!(!a.carries_fd());
        assert_eq!(exchange(&mut a, "S6\rY2\rO\r"), "\r\x07\r", "Y unknown");
        assert_eq!(
            events(&mut a),
            [AdapterEvent::Opened {
                listen_only: false,
                timing: Some(Timing::Bitrate(500_000)),
                data_bitrate: None,
            }]
        );
        assert_eq!(exchange(&mut a, "d1233112233\rt1230\r"), "\x07z\r");
        assert_eq!(
            events(&mut a),
            [
                AdapterEvent::RefusedFd(fd("123##0112233")),
                AdapterEvent::Transmit(frame("123#")),
            ]
        );
        // An FD frame from the bus has nowhere to go: dropped and counted.
        a.deliver_fd(&fd("321##0AA"), Nanos::ZERO);
        assert!(a.output().is_empty());
        assert_eq!(a.dropped(), 1);
    }

    #[test]
    fn fd_frames_follow_the_channels_state() {
        let mut a = Adapter::default().with_fd(true);
        assert_eq!(exchange(&mut a, "d1230\r"), "\x07", "closed");
        a.deliver_fd(&fd("321##0AA"), Nanos::ZERO);
        assert!(a.output().is_empty(), "a closed channel receives nothing");
        assert_eq!(
            exchange(&mut a, "Z1\rL\rd1230\r"),
            "\r\r\x07",
            "listen-only"
        );
        a.deliver_fd(&fd("321##0AA"), Nanos::from_millis(60_001));
        assert_eq!(a.take_output(), b"d3211AA0001\r", "with its timestamp");
        exchange(&mut a, "C\rO\r");
        events(&mut a);
        a.controller_error(&ErrorFrame::new(vec![CanError::BusOff], None));
        assert_eq!(exchange(&mut a, "b1230\rd1230\r"), "\x07\x07", "bus-off");
        assert_eq!(
            events(&mut a),
            [AdapterEvent::RefusedBusOff(Record::Fd(fd("123##1")))]
        );
    }

    #[test]
    fn a_host_that_does_not_read_loses_fd_frames_within_the_bound() {
        let mut a = Adapter::default().with_fd(true);
        exchange(&mut a, "O\r");
        events(&mut a);
        let f = fd(&format!("1FFFFFFF##1{}", "00".repeat(64)));
        for t in 0..10_000 {
            a.deliver_fd(&f, Nanos::from_millis(t));
        }
        assert!(a.output().len() <= MAX_OUTPUT);
        assert!(a.dropped() > 0);
        assert_eq!(events(&mut a), [AdapterEvent::Overrun]);
    }
}
