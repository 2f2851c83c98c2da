//! A [`CanBus`] over an SLCAN adapter on a serial port (a USB CDC adapter such as CANable or
//! Lawicel CANUSB, or a pseudo-terminal served by `buslab slcan serve`).
//!
//! Opening discards what the port had queued, then runs the [`Handshake`]: `C` (which also
//! ends a line left half-typed), `Z1` (timestamps, optional), `N` (serial number), the bit rate
//! (`S0`..`S8` for the standard rates, `sxxyy` with SJA1000 registers at 8 MHz for others) and
//! `O` (or `L`), each followed by `V`, whose answer closes the exchange: a reply left over from
//! an earlier session cannot be taken for an answer. Adapters that answer nothing but `V`
//! (CANable's firmware) work too. Dropping the bus waits for the answers to the frames sent,
//! then closes the channel. Frames are sent without waiting for the adapter's answer (as
//! python-can does); a refused frame (BEL) is logged. Received frames carry the host time,
//! refined by the adapter's timestamps.
//!
//! CAN FD (CANable 2.0 style, as python-can's `slcan` interface speaks it): an adapter opened
//! with [`SlcanOptions::fd`] takes FD frames ([`CanBus::send_fd`] writes `d`/`D`, or `b`/`B`
//! with BRS), and with [`SlcanOptions::data_bitrate`] the opening also sets the data bit rate
//! (`Yn`, after the nominal one). No SLCAN command asks an adapter whether it speaks FD, so the
//! user says so; without it FD frames are refused by name ([`NoFd::ClassicAdapter`]). FD frames
//! the adapter sends (`d`, `D`, `b`, `B`) are received either way.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use buslab_bus::{
    BitTiming, BusError, CanBus, ErrorState, FdSupport, Filter, Message, NoFd, RecvWaker,
    matches_any_id, wall_clock,
};
use buslab_can::{FdFrame, Frame};
use buslab_device::LineSettings;
use buslab_link::wake::{WakeLine, wait_readable};
use buslab_link::{SerialError, open_tty, tty_fd};
use serialport::{ClearBuffer, SerialPort, TTYPort};

use crate::clock::DeviceClock;
use crate::codec::{
    CodecError, Command, DATA_BITRATES, Line, LineSplitter, MAX_REPLY_LINE, Reply,
    STANDARD_BITRATES, StatusFlags, format_command, parse_reply,
};
use crate::handshake::{
    AcceptanceAnswer, CANABLE_BITRATES, Firmware, Handshake, HandshakeError, Plan, Status,
};

/// The CAN clock `sxxyy` registers are computed for: an SJA1000 at 16 MHz (Lawicel CAN232,
/// CANUSB) divides by 2; python-can requires the same for its `timing`.
pub const BTR_CLOCK_HZ: u32 = 8_000_000;

/// Received frames kept while nobody calls `recv`; beyond, the oldest are dropped.
pub const MAX_INBOX: usize = 262_144;

/// How to open an adapter.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SlcanOptions {
    /// The serial line's baud rate (ignored by USB CDC adapters and PTYs).
    pub baud: u32,
    /// The CAN bit rate; `None` keeps what the adapter has.
    pub bitrate: Option<u32>,
    /// Open with `L`: receive only, never transmit or acknowledge.
    pub listen_only: bool,
    /// How long to wait for each answer while opening.
    pub reply_timeout: Duration,
    /// The adapter speaks CAN FD (a CANable 2.0's firmware): FD frames may be sent.
    pub fd: bool,
    /// The CAN FD data bit rate to set while opening (`Yn`: one of [`DATA_BITRATES`]); it
    /// implies [`Self::fd`]. `None` keeps what the adapter has.
    pub data_bitrate: Option<u32>,
}

/// After the first version line, the line must stay quiet this long (or [`SETTLE_CHARS`]
/// characters at its rate, if longer) before the leftovers count as read: USB adapters send
/// every millisecond, FTDI ones (CANUSB) every 16 ms.
pub const SETTLE: Duration = Duration::from_millis(50);

/// See [`SETTLE`].
pub const SETTLE_CHARS: u32 = 32;

impl Default for SlcanOptions {
    fn default() -> Self {
        Self {
            baud: 115_200,
            bitrate: None,
            listen_only: false,
            reply_timeout: Duration::from_secs(2),
            fd: false,
            data_bitrate: None,
        }
    }
}

/// Why an adapter could not be opened or used.
#[derive(Debug, thiserror::Error)]
pub enum SlcanError {
    #[error(transparent)]
    Open(#[from] SerialError),
    #[error(
        "bit rate {bitrate} bit/s cannot be set: not a standard rate ({}) and no SJA1000 timing at 8 MHz reaches it",
        standard_rates()
    )]
    Bitrate { bitrate: u32 },
    #[error(
        "data bit rate {bitrate} bit/s cannot be set: SLCAN's Y command has {}",
        data_rates()
    )]
    DataBitrate { bitrate: u32 },
    #[error("{device}: the adapter refused {command:?} (answered BEL)")]
    Refused { device: String, command: String },
    #[error("{device}: {source}")]
    Handshake {
        device: String,
        source: HandshakeError,
    },
    #[error(
        "{device}: the adapter does not answer F (CANable's slcan firmware answers only V): no status to read"
    )]
    NoStatus { device: String },
    #[error(
        "{device}: no answer to {command:?} within {timeout:?}: is it an SLCAN adapter? (every exchange ends with V, which they all answer)"
    )]
    NoAnswer {
        device: String,
        command: String,
        timeout: Duration,
    },
    #[error("{device}: {source}")]
    Io { device: String, source: io::Error },
}

fn data_rates() -> String {
    DATA_BITRATES
        .iter()
        .map(|(code, rate)| format!("Y{code} = {rate}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn standard_rates() -> String {
    STANDARD_BITRATES
        .iter()
        .map(u32::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The command that sets `bitrate`: `Sn` for a standard rate, else `sxxyy`.
pub fn bitrate_command(bitrate: u32) -> Result<Command, SlcanError> {
    if let Some(code) = STANDARD_BITRATES.iter().position(|&r| r == bitrate) {
        return Ok(Command::Bitrate(code as u8));
    }
    let timing = BitTiming::for_bitrate(BTR_CLOCK_HZ, bitrate, None)
        .ok()
        .filter(|t| t.bitrate(BTR_CLOCK_HZ) == bitrate)
        .ok_or(SlcanError::Bitrate { bitrate })?;
    let (btr0, btr1) = timing.registers();
    Ok(Command::Btr { btr0, btr1 })
}

/// An open SLCAN adapter.
pub struct SlcanBus {
    port: TTYPort,
    device: String,
    channel: String,
    splitter: LineSplitter,
    /// Received frames and FD frames.
    inbox: VecDeque<Message>,
    /// Answers owed to frames sent (python-can style: not waited for).
    owed: usize,
    /// The adapter answers commands and frames (CANable's firmware does not).
    acknowledges: bool,
    /// CRs on their way that answer nothing of ours (a CANable variant's after `V`).
    stray_acks: usize,
    filters: Vec<Filter>,
    clock: DeviceClock,
    firmware: Option<Firmware>,
    serial: Option<[u8; 4]>,
    refused: u64,
    acceptance: AcceptanceAnswer,
    fd: bool,
    /// Ends a wait for frames from another thread, once [`CanBus::recv_waker`] asked for it
    /// (a wait for an answer to a command is not ended by it).
    wake: Option<WakeLine>,
}

impl SlcanBus {
    /// Opens the adapter at `device` and its channel.
    pub fn open(device: &str, options: &SlcanOptions) -> Result<Self, SlcanError> {
        Self::open_with_acceptance(device, options, None)
    }

    /// [`Self::open`], setting the acceptance code and mask (`M`/`m`: SJA1000 ACR0..3 and
    /// AMR0..3) first on adapters that answer like Lawicel's; see
    /// [`Self::acceptance_answer`].
    pub fn open_with_acceptance(
        device: &str,
        options: &SlcanOptions,
        acceptance: Option<(u32, u32)>,
    ) -> Result<Self, SlcanError> {
        // A bit rate no command reaches is refused before anything is sent; 750 kbit/s only
        // CANable's S7 reaches.
        let bitrate = match options.bitrate {
            None => None,
            Some(rate) => match bitrate_command(rate) {
                Ok(command) => Some((rate, Some(command))),
                Err(_) if CANABLE_BITRATES.contains(&rate) => Some((rate, None)),
                Err(e) => return Err(e),
            },
        };
        let data_bitrate = match options.data_bitrate {
            None => None,
            Some(rate) => Some(
                DATA_BITRATES
                    .iter()
                    .find(|(_, r)| *r == rate)
                    .map(|&(code, _)| code)
                    .ok_or(SlcanError::DataBitrate { bitrate: rate })?,
            ),
        };
        let port = open_tty(
            Path::new(device),
            LineSettings::n81(options.baud),
            options.reply_timeout,
        )?;
        // Whatever arrived before anyone read it belongs to an earlier session.
        if let Err(e) = port.clear(ClearBuffer::Input) {
            tracing::debug!("{device}: cannot discard its input queue: {e}");
        }
        let channel = device.rsplit('/').next().unwrap_or(device).to_string();
        let mut bus = Self {
            port,
            device: device.to_string(),
            channel,
            splitter: LineSplitter::with_limit(MAX_REPLY_LINE),
            inbox: VecDeque::new(),
            owed: 0,
            acknowledges: true,
            stray_acks: 0,
            filters: Vec::new(),
            clock: DeviceClock::new(),
            firmware: None,
            serial: None,
            refused: 0,
            acceptance: AcceptanceAnswer::NotSent,
            fd: options.fd || data_bitrate.is_some(),
            wake: None,
        };
        let plan = Plan {
            bitrate,
            listen_only: options.listen_only,
            data_bitrate,
        };
        let (hs, after) = bus.handshake(plan, options, acceptance)?;
        bus.acceptance = hs.acceptance_answer();
        bus.acknowledges = hs.acknowledges();
        bus.stray_acks = usize::from(hs.trailing_ack());
        bus.firmware = hs.firmware().cloned();
        bus.serial = hs.serial();
        // What came in the same read after the last answer is the open channel's.
        for parsed in after {
            match parsed {
                Ok(Reply::Frame {
                    frame,
                    timestamp_ms,
                }) => bus.keep_frame(frame, timestamp_ms),
                Ok(Reply::FdFrame {
                    frame,
                    timestamp_ms,
                }) => bus.keep_fd(frame, timestamp_ms),
                Ok(reply) => bus.later(reply),
                Err(e) => tracing::debug!("{device}: ignored from the adapter: {e}"),
            }
        }
        if hs.timestamps() == Some(false) {
            tracing::debug!("{device}: no timestamps (Z1 refused): frames get the host's time");
        }
        tracing::info!(
            "{device}: SLCAN adapter open{}{} (version {}, serial {}{}{})",
            if options.listen_only {
                " listen-only"
            } else {
                ""
            },
            if bus.fd { " for CAN FD" } else { "" },
            bus.version().unwrap_or("?"),
            bus.serial_number().unwrap_or("?"),
            if bus.acknowledges {
                ""
            } else {
                "; it answers no command"
            },
            match hs.leftovers() {
                0 => String::new(),
                n => format!("; {n} line(s) left from before ignored"),
            },
        );
        Ok(bus)
    }

    /// Runs the opening exchange to the end; what was read after its last answer.
    fn handshake(
        &mut self,
        plan: Plan,
        options: &SlcanOptions,
        acceptance: Option<(u32, u32)>,
    ) -> Result<(Handshake, Vec<Result<Reply, CodecError>>), SlcanError> {
        let mut hs = Handshake::new(plan);
        if let Some((code, mask)) = acceptance {
            hs = hs.with_acceptance(code, mask);
        }
        let char_time = Duration::from_secs_f64(10.0 / f64::from(options.baud.max(1)));
        let settle = SETTLE.max(char_time * SETTLE_CHARS);
        let mut deadline = Instant::now() + options.reply_timeout;
        // A line that never stops talking does not hold the opening forever.
        let mut settle_end = None;
        loop {
            if let Some(bytes) = hs.poll_transmit() {
                self.port.write_all(&bytes).map_err(|e| self.io(e))?;
                deadline = Instant::now() + options.reply_timeout;
            }
            let wait = match hs.status() {
                Status::Open => return Ok((hs, Vec::new())),
                Status::Failed(source) => {
                    return Err(SlcanError::Handshake {
                        device: self.device.clone(),
                        source,
                    });
                }
                Status::Settling => {
                    let end = *settle_end.get_or_insert(Instant::now() + options.reply_timeout);
                    (Instant::now() + settle).min(end)
                }
                Status::Waiting { .. } => deadline,
            };
            let Some(replies) = self.read_replies(wait).map_err(|e| self.io(e))? else {
                match hs.status() {
                    Status::Settling => hs.settled(),
                    Status::Waiting { command } => {
                        return Err(SlcanError::NoAnswer {
                            device: self.device.clone(),
                            command,
                            timeout: options.reply_timeout,
                        });
                    }
                    Status::Open | Status::Failed(_) => {}
                }
                continue;
            };
            let mut replies = replies.into_iter();
            for parsed in replies.by_ref() {
                let kept = match parsed {
                    Ok(reply) => hs.handle(reply),
                    Err(e) => {
                        tracing::debug!("{}: ignored while opening: {e}", self.device);
                        hs.handle_garbage();
                        None
                    }
                };
                match kept {
                    Some(Reply::Frame {
                        frame,
                        timestamp_ms,
                    }) => self.keep_frame(frame, timestamp_ms),
                    Some(Reply::FdFrame {
                        frame,
                        timestamp_ms,
                    }) => self.keep_fd(frame, timestamp_ms),
                    _ => {}
                }
                if matches!(hs.status(), Status::Open | Status::Failed(_)) {
                    break;
                }
            }
            if hs.status() == Status::Open {
                return Ok((hs, replies.collect()));
            }
        }
    }

    /// What the adapter did with the acceptance code and mask asked when it was opened.
    pub fn acceptance_answer(&self) -> AcceptanceAnswer {
        self.acceptance
    }

    /// The adapter's `V` answer (`1013`, or CANable's text), if it gave one.
    pub fn version(&self) -> Option<&str> {
        self.firmware.as_ref().map(Firmware::as_str)
    }

    /// What the adapter said it is.
    pub fn firmware(&self) -> Option<&Firmware> {
        self.firmware.as_ref()
    }

    /// Whether the adapter answers commands and frames (CANable's firmware does not).
    pub fn acknowledges(&self) -> bool {
        self.acknowledges
    }

    /// The adapter's `N` answer, if it gave one.
    pub fn serial_number(&self) -> Option<&str> {
        self.serial
            .as_ref()
            .and_then(|v| std::str::from_utf8(v).ok())
    }

    /// Reads the status flags (`F`).
    pub fn status_flags(&mut self, timeout: Duration) -> Result<StatusFlags, SlcanError> {
        if !self.acknowledges {
            return Err(SlcanError::NoStatus {
                device: self.device.clone(),
            });
        }
        match self.request(&Command::Status, timeout)? {
            Reply::Status(flags) => Ok(flags),
            _ => Err(self.refused(&Command::Status)),
        }
    }

    fn refused(&self, command: &Command) -> SlcanError {
        SlcanError::Refused {
            device: self.device.clone(),
            command: shown(command),
        }
    }

    fn io(&self, source: io::Error) -> SlcanError {
        SlcanError::Io {
            device: self.device.clone(),
            source,
        }
    }

    /// Sends a command and waits for its answer; frames received meanwhile are kept.
    fn request(&mut self, command: &Command, timeout: Duration) -> Result<Reply, SlcanError> {
        let mut bytes = Vec::with_capacity(32);
        format_command(command, &mut bytes);
        self.port.write_all(&bytes).map_err(|e| self.io(e))?;
        let deadline = Instant::now() + timeout;
        loop {
            let Some(replies) = self.read_some(Some(deadline)).map_err(|e| self.io(e))? else {
                return Err(SlcanError::NoAnswer {
                    device: self.device.clone(),
                    command: shown(command),
                    timeout,
                });
            };
            let mut answer = None;
            for reply in replies {
                if answer.is_some() {
                    self.later(reply);
                    continue;
                }
                match (&reply, command) {
                    (Reply::Status(_), Command::Status)
                    | (Reply::Version(_), Command::Version)
                    | (Reply::DetailedVersion(_), Command::DetailedVersion)
                    | (Reply::SerialNumber(_), Command::SerialNumber) => answer = Some(reply),
                    // Answers to frames sent earlier come first.
                    (Reply::Ok, _) if self.stray_acks > 0 => self.stray_acks -= 1,
                    (Reply::Ok | Reply::Error | Reply::Queued { .. }, _) if self.owed > 0 => {
                        self.settle_owed(&reply)
                    }
                    (Reply::Ok | Reply::Error, _) => answer = Some(reply),
                    _ => tracing::debug!("{}: unexpected answer {reply:?}", self.device),
                }
            }
            if let Some(reply) = answer {
                return Ok(reply);
            }
        }
    }

    /// An answer to a frame sent earlier.
    fn settle_owed(&mut self, reply: &Reply) {
        self.owed = self.owed.saturating_sub(1);
        if *reply == Reply::Error {
            self.refused += 1;
            tracing::warn!(
                "{}: the adapter refused a frame (BEL; {} so far): closed, listen-only or its queue full?",
                self.device,
                self.refused
            );
        }
    }

    /// Waits for bytes until `deadline` (`None`: as long as it takes) and reads what came:
    /// received frames go to the inbox, the other replies are returned in order. `None` when
    /// the deadline passed with nothing read.
    fn read_some(&mut self, deadline: Option<Instant>) -> io::Result<Option<Vec<Reply>>> {
        let Some(lines) = self.read_lines(deadline)? else {
            return Ok(None);
        };
        let mut replies = Vec::new();
        for parsed in lines {
            match parsed {
                Ok(Reply::Frame {
                    frame,
                    timestamp_ms,
                }) => self.keep_frame(frame, timestamp_ms),
                Ok(Reply::FdFrame {
                    frame,
                    timestamp_ms,
                }) => self.keep_fd(frame, timestamp_ms),
                Ok(reply) => replies.push(reply),
                Err(e) => tracing::debug!("{}: ignored from the adapter: {e}", self.device),
            }
        }
        Ok(Some(replies))
    }

    /// [`read_some`](Self::read_some) for the handshake, which decides about every line.
    fn read_replies(
        &mut self,
        deadline: Instant,
    ) -> io::Result<Option<Vec<Result<Reply, CodecError>>>> {
        self.read_lines(Some(deadline))
    }

    /// Waits for bytes until `deadline` and parses the lines they end.
    fn read_lines(
        &mut self,
        deadline: Option<Instant>,
    ) -> io::Result<Option<Vec<Result<Reply, CodecError>>>> {
        let mut buf = [0u8; 512];
        let n = loop {
            let now = Instant::now();
            let wait = match deadline {
                Some(d) if d <= now => return Ok(None),
                Some(d) => d - now,
                None => Duration::from_secs(3600),
            };
            self.port.set_timeout(wait)?;
            match self.port.read(&mut buf) {
                Ok(0) => {
                    return Err(io::Error::new(
                        io::ErrorKind::UnexpectedEof,
                        "the adapter went away",
                    ));
                }
                Ok(n) => break n,
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(e),
            }
        };
        let mut lines = Vec::new();
        for &byte in &buf[..n] {
            lines.push(match self.splitter.push(byte) {
                None => continue,
                Some(Line::Text(t)) => parse_reply(t, false),
                Some(Line::Bell(t)) => parse_reply(t, true),
                Some(Line::TooLong) => Err(CodecError::TooLong),
            });
        }
        Ok(Some(lines))
    }

    /// A received frame, stamped now (refined by the adapter's counter).
    fn keep_frame(&mut self, frame: Frame, timestamp_ms: Option<u16>) {
        let t = self.clock.stamp(wall_clock(), timestamp_ms);
        self.keep(Message::rx(t, self.channel.clone(), frame).into_record());
    }

    /// A received FD frame, stamped as frames are.
    fn keep_fd(&mut self, frame: FdFrame, timestamp_ms: Option<u16>) {
        let t = self.clock.stamp(wall_clock(), timestamp_ms);
        self.keep(Message::fd(t, self.channel.clone(), frame));
    }

    /// A reply nobody waits for: only answers to sent frames are expected.
    fn later(&mut self, reply: Reply) {
        match reply {
            Reply::Ok if self.stray_acks > 0 => self.stray_acks -= 1,
            Reply::Ok | Reply::Error | Reply::Queued { .. } if self.owed > 0 => {
                self.settle_owed(&reply)
            }
            other => tracing::debug!("{}: unexpected answer {other:?}", self.device),
        }
    }

    fn keep(&mut self, m: Message) {
        if !passes(&self.filters, &m) {
            return;
        }
        if self.inbox.len() == MAX_INBOX {
            self.inbox.pop_front();
            tracing::warn!(
                "{}: {MAX_INBOX} received frames not read; dropping the oldest",
                self.device
            );
        }
        self.inbox.push_back(m);
    }
}

/// Whether a received frame (classic or FD) passes the filters.
fn passes(filters: &[Filter], m: &Message) -> bool {
    m.record.id().is_none_or(|id| matches_any_id(filters, id))
}

/// `S6`, `t1230`: a command as written, for messages.
fn shown(command: &Command) -> String {
    let mut bytes = Vec::new();
    format_command(command, &mut bytes);
    bytes.pop();
    String::from_utf8_lossy(&bytes).into_owned()
}

impl SlcanBus {
    /// With a wake line: waits until the port has bytes (`true`), or `deadline` passed or a
    /// wake came (`false`). Without one: `true`, the read waits.
    fn wait_for_bytes(&self, deadline: Option<Instant>) -> io::Result<bool> {
        let Some(wake) = &self.wake else {
            return Ok(true);
        };
        loop {
            let left = deadline.map(|d| d.saturating_duration_since(Instant::now()));
            match wait_readable(tty_fd(&self.port), Some(wake), left) {
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                other => return other,
            }
        }
    }

    /// Writes a frame command; its answer is owed.
    fn transmit(&mut self, command: &Command) -> Result<(), BusError> {
        let mut bytes = Vec::with_capacity(160);
        format_command(command, &mut bytes);
        self.port.write_all(&bytes)?;
        if self.acknowledges {
            self.owed += 1;
        }
        Ok(())
    }

    /// The next received frame or FD frame, or `None` after `timeout` or when woken
    /// ([`CanBus::recv_waker`]).
    fn next_record(&mut self, timeout: Option<Duration>) -> Result<Option<Message>, BusError> {
        let deadline = timeout.map(|t| Instant::now() + t);
        loop {
            if let Some(m) = self.inbox.pop_front() {
                return Ok(Some(m));
            }
            if !self.wait_for_bytes(deadline)? {
                return Ok(None);
            }
            match self.read_some(deadline)? {
                Some(replies) => replies.into_iter().for_each(|r| self.later(r)),
                None => return Ok(None),
            }
        }
    }
}

impl CanBus for SlcanBus {
    fn fd_support(&self) -> FdSupport {
        if self.fd {
            FdSupport::Carried
        } else {
            FdSupport::Classic(NoFd::ClassicAdapter)
        }
    }

    fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
        self.transmit(&Command::Transmit(*frame))
    }

    /// `d`/`D`, or `b`/`B` with BRS (SLCAN has no ESI: it is left out).
    fn send_fd(&mut self, frame: &FdFrame) -> Result<(), BusError> {
        if !self.fd {
            return Err(BusError::ClassicOnly {
                bus: self.channel_info(),
                why: NoFd::ClassicAdapter,
            });
        }
        self.transmit(&Command::TransmitFd(*frame))
    }

    /// Classic frames; FD frames received meanwhile are passed by.
    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
        let deadline = timeout.map(|t| Instant::now() + t);
        loop {
            let left = deadline.map(|d| d.saturating_duration_since(Instant::now()));
            let Some(m) = self.next_record(left)? else {
                return Ok(None);
            };
            if let Some(m) = m.into_frame() {
                return Ok(Some(m));
            }
        }
    }

    fn recv_event(&mut self, timeout: Option<Duration>) -> Result<Option<Message>, BusError> {
        self.next_record(timeout)
    }

    fn set_filters(&mut self, filters: &[Filter]) -> Result<(), BusError> {
        self.filters = filters.to_vec();
        self.inbox.retain(|m| passes(filters, m));
        Ok(())
    }

    /// From the status flags (`F`): error-passive when the adapter says so, else active
    /// (Lawicel's flags have no bus-off).
    fn state(&mut self) -> Result<ErrorState, BusError> {
        let flags = self
            .status_flags(Duration::from_secs(2))
            .map_err(|e| BusError::Protocol(Box::new(e)))?;
        Ok(if flags.contains(StatusFlags::ERROR_PASSIVE) {
            ErrorState::Passive
        } else {
            ErrorState::Active
        })
    }

    fn channel_info(&self) -> String {
        format!("SLCAN adapter on {}", self.device)
    }

    fn recv_waker(&mut self) -> Option<Arc<dyn RecvWaker>> {
        let bus = self.channel_info();
        WakeLine::opened_waker(&mut self.wake, &bus)
    }
}

impl Drop for SlcanBus {
    /// Waits (up to 2 s) for the adapter to answer the frames sent, so closing does not cut
    /// them off, then closes the channel.
    fn drop(&mut self) {
        let deadline = Instant::now() + Duration::from_secs(2);
        while self.owed > 0 {
            match self.read_some(Some(deadline)) {
                Ok(Some(replies)) => replies.into_iter().for_each(|r| self.later(r)),
                _ => break,
            }
        }
        let mut bytes = Vec::new();
        format_command(&Command::Close, &mut bytes);
        let _ = self.port.write_all(&bytes);
        let _ = self.port.flush();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_rates_become_s_codes_or_registers() {
        assert_eq!(bitrate_command(500_000).unwrap(), Command::Bitrate(6));
        assert_eq!(bitrate_command(10_000).unwrap(), Command::Bitrate(0));
        // 33.333 kbit/s (GMLAN) is no S code: SJA1000 registers at 8 MHz.
        let Command::Btr { btr0, btr1 } = bitrate_command(33_333).unwrap() else {
            panic!("not registers");
        };
        assert_eq!(
            BitTiming::from_registers(btr0, btr1).bitrate(BTR_CLOCK_HZ),
            33_333
        );
        let err = bitrate_command(999_999).unwrap_err().to_string();
        assert!(
            err.starts_with(
                "bit rate 999999 bit/s cannot be set: not a standard rate (10000, 20000"
            ),
            "{err}"
        );
    }
}
