//! One client connection of a socketcand server, sans-IO (quinn-proto's shape): bytes from the
//! client go in, bytes for the client and [`Action`]s for the bus come out, and time is given.
//!
//! The session keeps socketcand's state machine (`< hi >`, `< open BUS >`, `< rawmode >`),
//! answers what it can itself (echo, mode changes, protocol errors) and hands the rest to the
//! host as actions: join the bus, send a frame, answer an extension request. The host answers
//! a [`Action::Join`] with [`Session::joined`] and a [`Action::Request`] with
//! [`Session::reply`]; until then the session hands out nothing more, so replies keep the order
//! of the requests (except `buslab_flush`, answered when the frames are done, which lets
//! later commands through). Frames from the bus go in with [`Session::deliver_frame`].
//!
//! When the client leaves, the host says so: [`Session::close_output`] as soon as it knows
//! nothing reaches the client any more, [`Session::finish_input`] once it has read the last
//! byte. The session still hands out everything the client sent before, in order (its frames
//! are the bus's once handed over), tells what the end cut short ([`Action::Unfinished`]),
//! and is [`Session::is_drained`] after that.
//!
//! A client may put at most [`SessionConfig::fault_rate`] faults on the wire; one more is
//! answered `< buslab_refused fault rate … >` by the session itself.

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::time::Duration;

use buslab_bus::admin::FaultLimit;
use buslab_can::{Frame, Nanos};

use crate::command::Command;
use crate::element::Deframer;
use crate::message::{FormattedFrame, ServerMessage, Timestamp};
use crate::reply::refused_reply;

/// SocketCAN's "error counters in data[6..7]" class bit.
const CAN_ERR_CNT: u32 = 0x200;

/// What the host must do for the session.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Action {
    /// Put a node on the bus for this client; answer with [`Session::joined`].
    Join,
    /// Transmit a frame from this client's node.
    Send(Frame),
    /// An extension command for the bus (`buslab_*`); answer with [`Session::reply`].
    Request(Command),
    /// Close the connection once the pending output is written.
    Close,
    /// The client's input ended in the middle of an element (or in a short run of text
    /// outside `< >`): `bytes` bytes, starting with `excerpt`, are discarded. For the log.
    Unfinished { excerpt: String, bytes: usize },
}

/// At most `max` in any `per` (and so a burst of `max` at once).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RateLimit {
    pub max: u32,
    pub per: Duration,
}

impl RateLimit {
    /// The nanoseconds between two once the burst is used up.
    fn interval(&self) -> Nanos {
        self.period() / u64::from(self.max.max(1))
    }

    fn period(&self) -> Nanos {
        Nanos::from(self.per)
    }
}

/// Faults one client may put on the wire: a person at the dashboard or a test script never
/// needs more, and a client that loops on `< buslab_fault … >` cannot flood the bus's log.
pub const FAULT_RATE: RateLimit = RateLimit {
    max: 20,
    per: Duration::from_secs(1),
};

/// Limits and behaviour of a session.
#[derive(Clone, Debug)]
pub struct SessionConfig {
    /// The one bus name clients may open.
    pub channel: String,
    /// Bytes waiting for the client beyond which frames are dropped for it (counted).
    pub max_output: usize,
    /// How long (ns) frames wait after the rawmode `< ok >`: python-can reads that reply with
    /// one `recv()` and compares it whole, so frames must not share its read.
    pub raw_hold_ns: Nanos,
    /// A client that has not opened the bus this long (ns) after connecting is told so and
    /// closed, so idle connections cannot lock others out.
    pub open_timeout_ns: Nanos,
    /// Faults this client may put on the wire.
    pub fault_rate: RateLimit,
}

impl SessionConfig {
    pub fn new(channel: impl Into<String>) -> Self {
        Self {
            channel: channel.into(),
            max_output: 256 * 1024,
            raw_hold_ns: Nanos::from_millis(50),
            open_timeout_ns: Nanos::from_secs(30),
            fault_rate: FAULT_RATE,
        }
    }
}

/// Where a client is in socketcand's state machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    NoBus,
    Bcm,
    Raw,
}

/// What the session waits for from the host.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Waiting {
    Nothing,
    Join,
    Reply,
}

/// One client connection.
#[derive(Debug)]
pub struct Session {
    config: SessionConfig,
    deframer: Deframer,
    mode: Mode,
    waiting: Waiting,
    node: Option<u32>,
    /// Remote frames as `R<dlc>` (buslab's extension).
    remote_as_r: bool,
    out: VecDeque<u8>,
    /// Frames formatted while the rawmode reply must go out alone, and until when.
    held: String,
    hold_until: Option<Nanos>,
    open_deadline: Option<Nanos>,
    closing: bool,
    /// The client will send nothing more (the host read its last byte).
    input_finished: bool,
    /// Nothing reaches the client any more: replies and frames are not queued.
    output_closed: bool,
    /// When the next fault is due by the client's rate, spread evenly (the generic cell rate
    /// algorithm: a request more than the rate's period ahead of this is refused).
    fault_due: Nanos,
    dropped: u64,
    errors_dropped: u64,
}

impl Session {
    /// A new connection at `now` (ns): the greeting is queued.
    pub fn new(config: SessionConfig, now: Nanos) -> Self {
        let open_deadline = Some(now.saturating_add(config.open_timeout_ns));
        let mut s = Self {
            config,
            deframer: Deframer::new(),
            mode: Mode::NoBus,
            waiting: Waiting::Nothing,
            node: None,
            remote_as_r: false,
            out: VecDeque::new(),
            held: String::new(),
            hold_until: None,
            open_deadline,
            closing: false,
            input_finished: false,
            output_closed: false,
            fault_due: Nanos::ZERO,
            dropped: 0,
            errors_dropped: 0,
        };
        s.send(&ServerMessage::Hi);
        s
    }

    /// The node this client joined as, once it has.
    pub fn node(&self) -> Option<u32> {
        self.node
    }

    /// Frames dropped for this client because it did not read them in time.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Whether the session wants more bytes from the client now. While it waits for the host,
    /// is closing, or has [`SessionConfig::max_output`] bytes of replies the client has not
    /// read, the host should leave them in the socket (TCP pushes back), so a client that
    /// sends without reading cannot make the server hold its replies without end.
    pub fn wants_input(&self) -> bool {
        !self.closing
            && !self.input_finished
            && self.waiting == Waiting::Nothing
            && self.deframer_len() < 64 * 1024
            && self.out.len() < self.config.max_output
    }

    /// The client will send nothing more: the host has read its last byte (end of stream,
    /// or the connection failed after it). What it sent is still handed out by
    /// [`Self::poll_action`], then what the end cut short ([`Action::Unfinished`]).
    pub fn finish_input(&mut self) {
        self.input_finished = true;
    }

    /// Nothing reaches the client any more (it closed or reset the connection): what waits
    /// for it is dropped, and replies and frames are no longer queued. Its input is still
    /// taken (what it sent before it left).
    pub fn close_output(&mut self) {
        self.output_closed = true;
        self.out.clear();
        self.held.clear();
        self.hold_until = None;
        self.open_deadline = None;
    }

    /// Whether the client's output is closed ([`Self::close_output`]).
    pub fn is_output_closed(&self) -> bool {
        self.output_closed
    }

    /// Whether everything the client sent has been handed out: its input finished and
    /// nothing of it is left (or the session closed itself).
    pub fn is_drained(&self) -> bool {
        self.closing
            || (self.input_finished && self.waiting == Waiting::Nothing && self.deframer.is_empty())
    }

    /// Error replies dropped because the client did not read the earlier ones.
    pub fn errors_dropped(&self) -> u64 {
        self.errors_dropped
    }

    fn deframer_len(&self) -> usize {
        self.deframer.len()
    }

    /// Bytes received from the client.
    pub fn receive(&mut self, bytes: &[u8]) {
        if !self.closing && !self.input_finished {
            self.deframer.push(bytes);
        }
    }

    /// The next thing the host must do at `now` (ns), after handling every element that needs
    /// nothing from it. `None`: nothing until more bytes arrive (or the host answers).
    pub fn poll_action(&mut self, now: Nanos) -> Option<Action> {
        if self.closing {
            return None;
        }
        while self.waiting == Waiting::Nothing {
            // Parsed where it lies in the input buffer (not copied into a String first: every
            // frame a client sends is an element).
            let Some(inside) = self.deframer.next_inside() else {
                if !self.input_finished {
                    return None;
                }
                let (excerpt, bytes) = self.deframer.take_unfinished()?;
                return Some(Action::Unfinished { excerpt, bytes });
            };
            let parsed = match inside.and_then(crate::element::element_text) {
                Ok(text) => Command::parse(text).map_err(|e| e.to_string()),
                Err(e) => Err(e.to_string()),
            };
            let command = match parsed {
                Ok(c) => c,
                Err(e) => {
                    self.protocol_error(e);
                    continue;
                }
            };
            if let Some(action) = self.handle(command, now) {
                return Some(action);
            }
        }
        None
    }

    /// Whether the client may put one more fault on the wire at `now`; if so it is counted.
    fn fault_allowed(&mut self, now: Nanos) -> Result<(), FaultLimit> {
        let rate = self.config.fault_rate;
        let due = self.fault_due.max(now);
        // The burst: up to `max` ahead of the even spread.
        let tolerance = rate.period().saturating_sub(rate.interval());
        let ahead = due - now;
        if ahead > tolerance {
            return Err(FaultLimit::Rate {
                max: rate.max,
                per: rate.per,
                retry_after: (ahead - tolerance).as_duration(),
            });
        }
        self.fault_due = due.saturating_add(rate.interval());
        Ok(())
    }

    fn handle(&mut self, command: Command, now: Nanos) -> Option<Action> {
        match (self.mode, command) {
            (_, Command::Echo) => self.send(&ServerMessage::Echo),
            (Mode::NoBus, Command::Open(bus)) => {
                if bus != self.config.channel {
                    // As socketcand: refuse and close.
                    self.send(&ServerMessage::Error("could not open bus".into()));
                    return Some(self.close());
                }
                self.waiting = Waiting::Join;
                return Some(Action::Join);
            }
            (Mode::NoBus, _) => self.send(&ServerMessage::Error(
                "open a bus first: < open BUS >".into(),
            )),
            (Mode::Bcm, Command::RawMode) => {
                self.mode = Mode::Raw;
                self.send(&ServerMessage::Ok);
                self.hold_until = Some(Nanos::ZERO);
            }
            (Mode::Raw, Command::RawMode) => {
                self.send(&ServerMessage::Error("already in raw mode".into()))
            }
            (_, Command::Open(_)) => self.send(&ServerMessage::Error(
                "a bus is already open on this connection".into(),
            )),
            (_, Command::BcmMode | Command::ControlMode | Command::IsotpMode) => self.send(
                &ServerMessage::Error("buslab serves raw mode only (send rawmode)".into()),
            ),
            (_, Command::Unsupported { name, .. }) => self.send(&ServerMessage::Error(format!(
                "{name} is not supported by buslab (raw mode only)"
            ))),
            (_, Command::Send(frame)) => return Some(Action::Send(frame)),
            (_, Command::Extensions) => {
                self.remote_as_r = true;
                self.send(&ServerMessage::Ok);
            }
            // Answered whenever the node's frames are done, which may be never (no ACK): the
            // client must still be able to ask for its status meanwhile.
            (_, Command::Flush) => return Some(Action::Request(Command::Flush)),
            (_, command @ Command::Fault { .. }) => match self.fault_allowed(now) {
                Ok(()) => {
                    self.waiting = Waiting::Reply;
                    return Some(Action::Request(command));
                }
                Err(limit) => self.send(&refused_reply(&limit)),
            },
            (_, command) => {
                self.waiting = Waiting::Reply;
                return Some(Action::Request(command));
            }
        }
        None
    }

    /// The host's answer to [`Action::Join`]: the node's number, or why it could not join
    /// (the client is told and the connection closes).
    pub fn joined(&mut self, result: Result<u32, String>) -> Option<Action> {
        self.waiting = Waiting::Nothing;
        match result {
            Ok(number) => {
                self.node = Some(number);
                self.mode = Mode::Bcm;
                self.open_deadline = None;
                self.send(&ServerMessage::Ok);
                None
            }
            Err(reason) => {
                self.send(&ServerMessage::Error(reason));
                Some(self.close())
            }
        }
    }

    /// The host's answer to an [`Action::Request`] (for `buslab_flush`, which does not hold
    /// up what follows it, whenever it comes).
    pub fn reply(&mut self, message: &ServerMessage) {
        self.waiting = Waiting::Nothing;
        self.send(message);
    }

    /// A frame from the bus at `timestamp`; `false` if it was dropped because the client does
    /// not read fast enough. Frames are delivered only in raw mode.
    pub fn deliver_frame(&mut self, frame: &Frame, timestamp: Timestamp, now: Nanos) -> bool {
        if self.mode != Mode::Raw || self.closing || self.output_closed {
            return true;
        }
        self.deliver_formatted(&FormattedFrame::new(frame, timestamp), now)
    }

    /// [`Self::deliver_frame`] with the frame formatted already (once for every session).
    pub fn deliver_formatted(&mut self, frame: &FormattedFrame, now: Nanos) -> bool {
        if self.mode != Mode::Raw || self.closing || self.output_closed {
            return true;
        }
        self.release_held(now);
        if self.out.len() + self.held.len() >= self.config.max_output {
            self.dropped += 1;
            return false;
        }
        let text = frame.text(self.remote_as_r);
        if self.hold_until.is_some() {
            self.held.push_str(text);
        } else {
            self.out.extend(text.as_bytes());
        }
        true
    }

    /// Frames formatted already, their lines one after another (no remote frame among them:
    /// whether the client takes those as `R<dlc>` changes nothing), as one
    /// [`Self::deliver_formatted`] per line when the output has room for all of them: then
    /// `true`. `false` when it may not, and nothing is delivered: the caller hands them over
    /// one by one, so that those that do not fit are dropped and counted as ever. (A receiver
    /// gets the same run of frames as every other: one copy instead of one call per frame.)
    pub fn deliver_formatted_lines(&mut self, lines: &str, now: Nanos) -> bool {
        if self.mode != Mode::Raw || self.closing || self.output_closed {
            return true;
        }
        self.release_held(now);
        // Each line is checked against the limit before it goes in: if all of them fit,
        // each did.
        if self.out.len() + self.held.len() + lines.len() > self.config.max_output {
            return false;
        }
        if self.hold_until.is_some() {
            self.held.push_str(lines);
        } else {
            self.out.extend(lines.as_bytes());
        }
        true
    }

    /// An error frame from the bus (SocketCAN's CAN ID with the class bits, and its 8 data
    /// bytes): in raw mode's layout, the class alone as socketcand -e sends it, or with the
    /// data bytes too for a client that asked for buslab's extensions.
    pub fn deliver_error_frame(
        &mut self,
        class: u32,
        data: &[u8; 8],
        timestamp: Timestamp,
        now: Nanos,
    ) -> bool {
        if self.mode != Mode::Raw || self.closing || self.output_closed {
            return true;
        }
        let with_data = self.remote_as_r;
        // Without the data bytes the counters bit (CAN_ERR_CNT) would promise what is not sent.
        let class = if with_data {
            class
        } else {
            class & !CAN_ERR_CNT
        };
        self.deliver(now, |text| {
            let _ = write!(text, "< error {class:03X} {timestamp}");
            if with_data {
                for b in data {
                    let _ = write!(text, " {b:02X}");
                }
            }
            text.push_str(" >");
        })
    }

    fn deliver(&mut self, now: Nanos, write: impl FnOnce(&mut String)) -> bool {
        self.release_held(now);
        if self.out.len() + self.held.len() >= self.config.max_output {
            self.dropped += 1;
            return false;
        }
        if self.hold_until.is_some() {
            write(&mut self.held);
        } else {
            let mut text = String::with_capacity(48);
            write(&mut text);
            self.out.extend(text.as_bytes());
        }
        true
    }

    /// Releases frames held after the rawmode reply once their time has come.
    fn release_held(&mut self, now: Nanos) {
        if let Some(until) = self.hold_until
            && until != Nanos::ZERO
            && now >= until
        {
            self.hold_until = None;
            self.out.extend(self.held.as_bytes());
            self.held.clear();
        }
    }

    /// Time passes: held frames are released, a client that never opened the bus is closed.
    pub fn handle_timeout(&mut self, now: Nanos) -> Option<Action> {
        self.release_held(now);
        if self.open_deadline.is_some_and(|d| now >= d) && !self.closing {
            self.open_deadline = None;
            self.send(&ServerMessage::Error(
                "the bus was not opened in time (send < open BUS > first); closing".into(),
            ));
            return Some(self.close());
        }
        None
    }

    /// When [`Self::handle_timeout`] must be called even if nothing else happens.
    pub fn next_deadline(&self) -> Option<Nanos> {
        let hold = self.hold_until.filter(|&t| t != Nanos::ZERO);
        [hold, self.open_deadline].into_iter().flatten().min()
    }

    /// The bytes waiting for the client, as two slices.
    pub fn output(&self) -> (&[u8], &[u8]) {
        self.out.as_slices()
    }

    /// How many more frame lines of at most `line` bytes this session takes before it drops
    /// frames ([`Self::deliver_formatted`] takes one while fewer than
    /// [`SessionConfig::max_output`] bytes wait); `None` when it is not handed frames (not in
    /// raw mode, or closing).
    pub fn frame_room(&self, line: usize) -> Option<usize> {
        if self.mode != Mode::Raw || self.closing || self.output_closed {
            return None;
        }
        let waiting = self.out.len() + self.held.len();
        Some(
            self.config
                .max_output
                .saturating_sub(waiting)
                .div_ceil(line.max(1)),
        )
    }

    /// Whether bytes wait for the client.
    pub fn has_output(&self) -> bool {
        !self.out.is_empty()
    }

    /// `n` bytes of [`Self::output`] were written to the client. When the rawmode reply has
    /// left alone, the hold on frames starts at `now`.
    pub fn consumed(&mut self, n: usize, now: Nanos) {
        self.out.drain(..n.min(self.out.len()));
        if self.out.is_empty() && self.hold_until == Some(Nanos::ZERO) {
            self.hold_until = Some(now.saturating_add(self.config.raw_hold_ns));
        }
    }

    /// Whether the session is over (its last words may still be in [`Self::output`]).
    pub fn is_closing(&self) -> bool {
        self.closing
    }

    fn close(&mut self) -> Action {
        self.closing = true;
        self.waiting = Waiting::Nothing;
        Action::Close
    }

    fn send(&mut self, message: &ServerMessage) {
        if !self.output_closed {
            self.out.extend(message.to_string().as_bytes());
        }
    }

    /// One error per malformed element, while the client reads them: beyond
    /// [`SessionConfig::max_output`] bytes waiting they are counted, not queued.
    fn protocol_error(&mut self, text: String) {
        if self.out.len() >= self.config.max_output {
            self.errors_dropped += 1;
        } else {
            self.send(&ServerMessage::Error(text));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn output(s: &mut Session, now: Nanos) -> String {
        let (a, b) = s.output();
        let text = String::from_utf8([a, b].concat()).unwrap();
        s.consumed(text.len(), now);
        text
    }

    fn frame(text: &str) -> Frame {
        text.parse().unwrap()
    }

    fn ts(secs: u64) -> Timestamp {
        Timestamp::from_secs(secs)
    }

    /// A session through `< open vcan0 >` and `< rawmode >`, joined as node 7.
    fn raw_session() -> Session {
        let mut s = Session::new(SessionConfig::new("vcan0"), Nanos::ZERO);
        assert_eq!(output(&mut s, Nanos::ZERO), "< hi >");
        s.receive(b"< open vcan0 >");
        assert_eq!(s.poll_action(Nanos::ZERO), Some(Action::Join));
        assert_eq!(s.joined(Ok(7)), None);
        assert_eq!(output(&mut s, Nanos::ZERO), "< ok >");
        s.receive(b"< rawmode >");
        assert_eq!(s.poll_action(Nanos::ZERO), None);
        assert_eq!(output(&mut s, Nanos::ZERO), "< ok >");
        s
    }

    #[test]
    fn handshake_then_frames_both_ways() {
        let mut s = raw_session();
        s.receive(b"< send 123 2 11 22 >< send 7ff 0 >");
        assert_eq!(
            s.poll_action(Nanos::ZERO),
            Some(Action::Send(frame("123#1122")))
        );
        assert_eq!(
            s.poll_action(Nanos::ZERO),
            Some(Action::Send(frame("7FF#")))
        );
        assert_eq!(s.poll_action(Nanos::ZERO), None);
        // Frames wait 50 ms after the rawmode reply left, then go out.
        assert!(s.deliver_frame(&frame("321#AA"), ts(1), Nanos::new(1_000)));
        assert!(!s.has_output());
        assert_eq!(s.next_deadline(), Some(Nanos::new(50_000_000)));
        assert_eq!(s.handle_timeout(Nanos::new(50_000_000)), None);
        assert_eq!(
            output(&mut s, Nanos::new(50_000_000)),
            "< frame 321 1.000000 AA >"
        );
        assert!(s.deliver_frame(&frame("1ABCDEF0#R2"), ts(2), Nanos::new(60_000_000)));
        assert_eq!(
            output(&mut s, Nanos::new(60_000_000)),
            "< frame 1ABCDEF0 2.000000  >"
        );
    }

    /// A run of lines goes in as the same frames one by one would, held after `rawmode` as
    /// they are; a run that might not fit is refused whole, and one by one the frames that
    /// fit go in and the rest are dropped and counted.
    #[test]
    fn a_run_of_formatted_lines_is_what_its_frames_one_by_one_give() {
        let frames = [frame("123#0102"), frame("7FF#"), frame("1ABCDEF0#AA")];
        let formatted: Vec<_> = frames
            .iter()
            .enumerate()
            .map(|(k, f)| FormattedFrame::new(f, ts(k as u64)))
            .collect();
        let lines: String = formatted.iter().map(|f| f.text(false)).collect();
        let (mut one_by_one, mut run) = (raw_session(), raw_session());
        let now = Nanos::new(1_000);
        for f in &formatted {
            assert!(one_by_one.deliver_formatted(f, now));
        }
        assert!(run.deliver_formatted_lines(&lines, now));
        // Both held until 50 ms after the rawmode reply.
        assert!(!run.has_output());
        let later = Nanos::new(50_000_000);
        assert_eq!(run.handle_timeout(later), None);
        assert_eq!(one_by_one.handle_timeout(later), None);
        assert_eq!(output(&mut run, later), output(&mut one_by_one, later));
        // A raw session (no hold) whose output takes `max` bytes.
        let limited = |max| {
            let mut config = SessionConfig::new("vcan0");
            config.max_output = max;
            let mut s = Session::new(config, Nanos::ZERO);
            assert_eq!(output(&mut s, Nanos::ZERO), "< hi >");
            s.mode = Mode::Raw;
            s
        };
        // An output limit inside the run: refused whole, nothing delivered or counted.
        let mut small = limited(lines.len() - 1);
        assert!(!small.deliver_formatted_lines(&lines, later));
        assert!(!small.has_output());
        assert_eq!(small.dropped, 0);
        let delivered: Vec<bool> = formatted
            .iter()
            .map(|f| small.deliver_formatted(f, later))
            .collect();
        assert_eq!(delivered, [true, true, true]);
        let mut tiny = limited(formatted[0].text(false).len());
        assert!(!tiny.deliver_formatted_lines(&lines, later));
        let delivered: Vec<bool> = formatted
            .iter()
            .map(|f| tiny.deliver_formatted(f, later))
            .collect();
        assert_eq!(delivered, [true, false, false]);
        assert_eq!(tiny.dropped, 2);
    }

    #[test]
    fn a_frame_formatted_once_reads_as_each_session_formats_it() {
        let mut plain = raw_session();
        let mut ext = raw_session();
        ext.receive(b"< buslab_ext >");
        assert_eq!(ext.poll_action(Nanos::ZERO), None);
        assert_eq!(output(&mut ext, Nanos::ZERO), "< ok >");
        for text in ["123#0102030405060708", "1ABCDEF0#R2", "7FF#"] {
            let f = frame(text);
            for s in [&mut plain, &mut ext] {
                assert!(s.deliver_frame(&f, ts(1), Nanos::new(60_000_000)));
                let direct = output(s, Nanos::new(60_000_000));
                let once = FormattedFrame::new(&f, ts(1));
                assert!(s.deliver_formatted(&once, Nanos::new(60_000_000)));
                assert_eq!(output(s, Nanos::new(60_000_000)), direct, "{text}");
            }
        }
        ext.deliver_formatted(
            &FormattedFrame::new(&frame("1ABCDEF0#R2"), ts(2)),
            Nanos::new(60_000_000),
        );
        assert_eq!(
            output(&mut ext, Nanos::new(60_000_000)),
            "< frame 1ABCDEF0 2.000000 R2 >"
        );
    }

    #[test]
    fn requests_are_answered_in_order_and_block_what_follows() {
        let mut s = raw_session();
        s.receive(b"< buslab_status >< send 123 0 >");
        assert_eq!(
            s.poll_action(Nanos::ZERO),
            Some(Action::Request(Command::Status(None)))
        );
        assert!(!s.wants_input());
        assert_eq!(s.poll_action(Nanos::ZERO), None, "waits for the reply");
        s.reply(&ServerMessage::Other {
            name: "buslab_status".into(),
            args: vec!["7".into()],
        });
        assert_eq!(
            s.poll_action(Nanos::ZERO),
            Some(Action::Send(frame("123#")))
        );
        assert_eq!(output(&mut s, Nanos::ZERO), "< buslab_status 7 >");
    }

    #[test]
    fn a_flush_does_not_hold_up_the_commands_after_it() {
        let mut s = raw_session();
        s.receive(b"< buslab_flush >< buslab_status >");
        assert_eq!(
            s.poll_action(Nanos::ZERO),
            Some(Action::Request(Command::Flush))
        );
        assert_eq!(
            s.poll_action(Nanos::ZERO),
            Some(Action::Request(Command::Status(None)))
        );
    }

    #[test]
    fn garbage_gets_one_error_per_element_and_the_session_goes_on() {
        let mut s = raw_session();
        s.receive(b"junk< nonsense >< send 123 9 >< echo >");
        assert_eq!(s.poll_action(Nanos::ZERO), None);
        let text = output(&mut s, Nanos::ZERO);
        assert_eq!(text.matches("< error").count(), 3, "{text}");
        assert!(text.ends_with("< echo >"), "{text}");
    }

    #[test]
    fn the_wrong_bus_and_a_failed_join_close_the_connection() {
        let mut s = Session::new(SessionConfig::new("vcan0"), Nanos::ZERO);
        s.receive(b"< open can9 >");
        assert_eq!(s.poll_action(Nanos::ZERO), Some(Action::Close));
        assert!(output(&mut s, Nanos::ZERO).ends_with("< error could not open bus >"));
        assert!(s.is_closing());
        let mut s = Session::new(SessionConfig::new("vcan0"), Nanos::ZERO);
        s.receive(b"< open vcan0 >");
        assert_eq!(s.poll_action(Nanos::ZERO), Some(Action::Join));
        assert_eq!(s.joined(Err("the bus is full".into())), Some(Action::Close));
        assert!(output(&mut s, Nanos::ZERO).ends_with("< error the bus is full >"));
    }

    #[test]
    fn a_client_that_never_opens_is_closed_after_the_timeout() {
        let mut config = SessionConfig::new("vcan0");
        config.open_timeout_ns = Nanos::new(1_000);
        let mut s = Session::new(config, Nanos::new(10));
        assert_eq!(s.next_deadline(), Some(Nanos::new(1_010)));
        assert_eq!(s.handle_timeout(Nanos::new(1_009)), None);
        assert_eq!(s.handle_timeout(Nanos::new(1_010)), Some(Action::Close));
        assert!(output(&mut s, Nanos::ZERO).contains("the bus was not opened in time"));
    }

    #[test]
    fn a_client_that_does_not_read_loses_frames_beyond_its_output_limit() {
        let mut s = raw_session();
        s.handle_timeout(Nanos::MAX / 2);
        let mut config = SessionConfig::new("vcan0");
        config.max_output = 100;
        s.config = config;
        let mut delivered = 0;
        for _ in 0..10 {
            delivered += s.deliver_frame(&frame("123#11"), ts(1), Nanos::MAX / 2) as u32;
        }
        assert!(delivered > 0 && delivered < 10);
        assert_eq!(s.dropped(), 10 - delivered as u64);
    }

    #[test]
    fn garbage_from_a_client_that_does_not_read_is_answered_within_the_output_limit() {
        let mut config = SessionConfig::new("vcan0");
        config.max_output = 4096;
        let mut s = Session::new(config, Nanos::ZERO);
        // A megabyte of malformed elements, read as fast as the host can: one error each
        // until 4 KiB of replies wait, then none; input stops being wanted.
        let garbage = b"<x>".repeat(350_000);
        let mut fed = 0;
        while s.wants_input() && fed < garbage.len() {
            let end = (fed + 16 * 1024).min(garbage.len());
            s.receive(&garbage[fed..end]);
            fed = end;
            assert_eq!(s.poll_action(Nanos::ZERO), None);
        }
        assert!(s.out.len() < 4096 + 100, "{} bytes of replies", s.out.len());
        assert!(!s.wants_input());
        assert!(s.errors_dropped() > 0);
        // Once the client reads, it is served again.
        output(&mut s, Nanos::ZERO);
        assert!(s.wants_input());
        // A run of junk is one error, however long: a megabyte of `>`.
        let mut s = raw_session();
        s.receive(&vec![b'>'; 1 << 20]);
        s.receive(b"< echo >");
        assert_eq!(s.poll_action(Nanos::ZERO), None);
        let text = output(&mut s, Nanos::ZERO);
        assert_eq!(text.matches("< error").count(), 1, "{text}");
        assert!(text.ends_with("< echo >"), "{text}");
    }

    #[test]
    fn what_a_client_sent_before_it_left_is_all_handed_out_then_what_the_end_cut_short() {
        // python-can's `with can.Bus(…) as bus: bus.send(…)`: the frame and the close come
        // together. The host learns of the close first (no more output), reads the rest.
        let mut s = raw_session();
        s.deliver_frame(&frame("321#AA"), ts(1), Nanos::ZERO);
        s.close_output();
        assert!(!s.has_output(), "nothing waits for a client that left");
        assert!(s.deliver_frame(&frame("321#BB"), ts(1), Nanos::ZERO));
        assert!(!s.has_output());
        assert!(s.wants_input(), "what it sent before it left is still read");
        s.receive(b"< send 123 1 01 >< buslab_status >< send 124 0 >< send 125 2 0");
        s.finish_input();
        assert!(!s.wants_input());
        assert!(!s.is_drained());
        assert_eq!(
            s.poll_action(Nanos::ZERO),
            Some(Action::Send(frame("123#01")))
        );
        assert_eq!(
            s.poll_action(Nanos::ZERO),
            Some(Action::Request(Command::Status(None)))
        );
        s.reply(&ServerMessage::Ok);
        assert!(
            !s.has_output(),
            "replies to a client that left are not queued"
        );
        assert_eq!(
            s.poll_action(Nanos::ZERO),
            Some(Action::Send(frame("124#")))
        );
        assert_eq!(
            s.poll_action(Nanos::ZERO),
            Some(Action::Unfinished {
                excerpt: "< send 125 2 0".into(),
                bytes: 14
            })
        );
        assert!(s.is_drained());
        assert_eq!(s.poll_action(Nanos::ZERO), None);
        // Bytes after the end are not taken.
        s.receive(b"< send 126 0 >");
        assert_eq!(s.poll_action(Nanos::ZERO), None);
    }

    #[test]
    fn a_client_that_closes_after_whole_elements_leaves_nothing_unfinished() {
        let mut s = raw_session();
        s.receive(b"< send 123 0 >\n");
        s.finish_input();
        assert_eq!(
            s.poll_action(Nanos::ZERO),
            Some(Action::Send(frame("123#")))
        );
        assert_eq!(s.poll_action(Nanos::ZERO), None);
        assert!(s.is_drained());
    }

    #[test]
    fn faults_beyond_the_clients_rate_are_refused_with_the_limit_and_the_wait() {
        let mut s = raw_session();
        let fault = b"< buslab_fault 10 stuck >";
        let mut refused = Vec::new();
        // The whole burst at once, then one more every 50 ms (20 per second).
        for k in 0..FAULT_RATE.max + 1 {
            s.receive(fault);
            match s.poll_action(Nanos::new(1_000)) {
                Some(Action::Request(Command::Fault { .. })) => s.reply(&ServerMessage::Ok),
                None => refused.push(k),
                other => panic!("{other:?}"),
            }
        }
        assert_eq!(refused, [FAULT_RATE.max]);
        let text = output(&mut s, Nanos::new(1_000));
        assert!(
            text.ends_with("< buslab_refused fault rate max=20 per_ms=1000 retry_ms=50 >"),
            "{text}"
        );
        s.receive(fault);
        assert_eq!(
            s.poll_action(Nanos::new(1_000) + Nanos::new(49_999_999)),
            None,
            "not yet"
        );
        assert!(output(&mut s, Nanos::ZERO).contains("retry_ms=1 "));
        s.receive(fault);
        assert!(matches!(
            s.poll_action(Nanos::new(1_000) + Nanos::new(50_000_000)),
            Some(Action::Request(Command::Fault { .. }))
        ));
        s.reply(&ServerMessage::Ok);
        // After a quiet second the whole burst is there again.
        for _ in 0..FAULT_RATE.max {
            s.receive(fault);
            assert!(matches!(
                s.poll_action(Nanos::new(2_100_000_000)),
                Some(Action::Request(Command::Fault { .. }))
            ));
            s.reply(&ServerMessage::Ok);
        }
        s.receive(fault);
        assert_eq!(s.poll_action(Nanos::new(2_100_000_000)), None);
    }

    #[test]
    fn frames_before_rawmode_are_not_delivered() {
        let mut s = Session::new(SessionConfig::new("vcan0"), Nanos::ZERO);
        output(&mut s, Nanos::ZERO);
        assert!(s.deliver_frame(&frame("123#"), ts(0), Nanos::ZERO));
        assert!(!s.has_output());
    }
}
