//! The host side: every cell command as a typed method over any [`Port`].
//!
//! Timing rules the client keeps for the cell: a pause after commands 1, 2, 3 and 5 (the cell
//! is setting up its address pointer), ten zeros 2 ms apart to reset, and one analog reading
//! at a time (command 4 cannot be pipelined: a conversion plus its reply take longer than the
//! next request on the line). Data RAM transfers are pipelined: the client keeps a window of
//! requests on the line ahead of the replies instead of waiting for each.

mod series;

use std::io;
use std::time::Duration;

pub use buslab_device::Port;
use buslab_device::{Human, Nanos};
pub use series::{Measurement, Row, SeriesError, SeriesParams};

use crate::Command;
use crate::cell::{COUNT_HIGH_REGISTER, COUNT_LOW_REGISTER};
use crate::memory::{DATA_AREA, EXT_RAM_SIZE, PARAMS_LEN};
use crate::timing::{BYTE_NS, RESET_GAP_NS};

/// How long the client waits after commands 1 and 2 before sending more. The cell needs 1 ms
/// after the command byte has arrived; on a pseudo-terminal `drain` returns before the byte
/// has crossed the emulated line, and the server stamps bytes when it gets to read them, so
/// a generous margin keeps the two apart on a busy machine (the server thread must be late by
/// this much for the next byte to fall into the set-up). Commands 3 and 5 need no pause: the
/// client waits for the cell's first timing byte, which comes after the set-up.
pub const SETUP_PAUSE: Duration = Duration::from_millis(50);

/// Requests kept on the line ahead of the replies in pipelined transfers. Two would keep a
/// 9600 baud line busy if the host answered at once; 256 requests are 293 ms of line, which
/// outlasts the round trips of a loaded host (the reply through a pseudo-terminal's kernel
/// side, the client descheduled, the request back): with 4 busy loops on 2 cores 16 ahead
/// (18 ms) delivered 92 % of the line rate, 128 (147 ms) 92 to 99.7 %, stalls of up to 185 ms
/// remaining (docs/lab.md). The cell answers each request as it arrives, so the depth costs it
/// nothing.
pub const WINDOW: usize = 256;

/// Added by default to each block's length before the next START or the stop in
/// [`Client::measure`] ([`Client::set_block_margin`] changes it).
pub const BLOCK_MARGIN: Duration = Duration::from_millis(250);

/// How RAM transfers pace themselves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Transfer {
    /// Requests run ahead of the replies by up to [`WINDOW`].
    #[default]
    Pipelined,
    /// One request, then wait for its reply (the way the seed describes the exchange).
    StopAndWait,
}

/// What went wrong talking to the cell.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("serial I/O: {0}")]
    Io(#[from] io::Error),
    #[error(
        "the cell did not answer within {} while {during} (got {got} of {wanted} bytes); \
         is it switched on, at 9600 8N2, and in the ready state (try `reset`)?",
        Human(*timeout)
    )]
    Timeout {
        during: &'static str,
        got: usize,
        wanted: usize,
        timeout: Duration,
    },
    #[error(
        "the cell did not answer within {} after ten zeros and command 13 (a reset); is it \
         switched on, at 9600 8N2? A program that masks the RxD interrupt (EA or EX0 off) or \
         waits in Empf cannot be stopped from the line: hold the START key about 5 s after a \
         RESET (served model: control lines `key down`, `reset`, then `key up` after 5 s)",
        Human(*timeout)
    )]
    ResetUnanswered { timeout: Duration },
    #[error("analog channel {0} is out of range 1..4")]
    Channel(u8),
    #[error("register address {0} is out of range 0..127")]
    Register(u8),
    #[error("bus address {0} is out of range 0..127")]
    BusAddress(u8),
    #[error("{during}: the cell answered {byte}, expected {expected}")]
    UnexpectedReply {
        during: &'static str,
        byte: u8,
        expected: &'static str,
    },
    #[error("{len} bytes from {start:04X}h do not fit below the end of RAM at 8000h")]
    TooLong { start: u16, len: usize },
    #[error(transparent)]
    Series(#[from] SeriesError),
    #[error(
        "the parameters at 0800h ({found:?}) are not the ones this series started with \
         ({sent:?}); did something else use the cell?"
    )]
    ParamsChanged { sent: [u8; 8], found: [u8; 8] },
}

/// Result of client calls.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Progress of a running measurement, for a progress bar.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Progress {
    /// Waiting for block `block` (0-based) of `blocks`; `done_ns` of `total_ns` have passed.
    Measuring {
        block: u32,
        blocks: u32,
        done_ns: Nanos,
        total_ns: Nanos,
    },
    /// Reading the values back: `done` of `total` bytes.
    Reading { done: usize, total: usize },
}

/// A cell on the other end of `port`.
pub struct Client<P: Port> {
    port: P,
    timeout: Duration,
    block_margin: Duration,
}

/// The default allowance for an answer, beyond its bytes' time on the line.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_millis(500);

/// Bytes a reset may find still coming from before it (a series' block is at most this) before
/// it gives up on the line falling quiet.
const MAX_STALE_AFTER_RESET: usize = 64 * 1024;

impl<P: Port> Client<P> {
    /// A client on `port` with [`DEFAULT_TIMEOUT`].
    pub fn new(port: P) -> Self {
        Self::with_timeout(port, DEFAULT_TIMEOUT)
    }

    /// A client that waits for each answer its bytes' time on the line (and that of the
    /// requests it answers) plus `timeout`.
    pub fn with_timeout(port: P, timeout: Duration) -> Self {
        Client {
            port,
            timeout,
            block_margin: BLOCK_MARGIN,
        }
    }

    /// How long [`measure`](Self::measure) waits beyond each block's length before the next
    /// START or the stop (the cell sends no "block done"): the time the host and the line may
    /// be late without cutting a block short.
    pub fn set_block_margin(&mut self, margin: Duration) {
        self.block_margin = margin;
    }

    /// The port.
    pub fn port(&mut self) -> &mut P {
        &mut self.port
    }

    /// Gives the port back.
    pub fn into_port(self) -> P {
        self.port
    }

    // ----- plumbing -------------------------------------------------------------------------

    fn send(&mut self, bytes: &[u8]) -> Result<()> {
        self.port.send(bytes)?;
        Ok(())
    }

    /// How long `bytes` answer bytes may take: the requests' and the answers' time on the
    /// line, plus the allowance.
    fn budget(&self, bytes: usize) -> Duration {
        BYTE_NS.saturating_mul(2 * bytes as u64).as_duration() + self.timeout
    }

    /// Sends a command that expects no answer and returns once the cell has received it: the
    /// port is drained, then the bytes' time on the line passes (a pseudo-terminal's drain
    /// returns before the emulated line has carried them), plus a millisecond.
    fn send_all(&mut self, bytes: &[u8]) -> Result<()> {
        self.send(bytes)?;
        self.port.drain()?;
        self.port
            .pause((BYTE_NS * bytes.len() as u64 + crate::timing::MS).as_duration());
        Ok(())
    }

    /// Sends a command that makes the cell set up a pointer, and waits the set-up out.
    fn send_with_setup(&mut self, cmd: Command) -> Result<()> {
        debug_assert!(cmd.needs_setup_pause());
        self.send(&[cmd as u8])?;
        self.port.drain()?;
        self.port.pause(SETUP_PAUSE);
        Ok(())
    }

    /// Reads exactly `buf.len()` bytes, or fails naming what it was waiting for.
    fn read_into(&mut self, buf: &mut [u8], during: &'static str) -> Result<()> {
        let budget = self.budget(buf.len());
        let deadline = self.port.now() + budget;
        let mut got = 0;
        while got < buf.len() {
            let left = deadline.saturating_sub(self.port.now());
            if left.is_zero() {
                return Err(self.timeout_error(during, got, buf.len(), budget));
            }
            got += self.port.recv(&mut buf[got..], left)?;
        }
        Ok(())
    }

    /// Reads whatever of up to `buf.len()` bytes arrives first (at least one); `got` of
    /// `wanted` name the progress in a time-out.
    fn read_some(
        &mut self,
        buf: &mut [u8],
        during: &'static str,
        got: usize,
        wanted: usize,
    ) -> Result<usize> {
        let budget = self.budget(buf.len());
        let deadline = self.port.now() + budget;
        loop {
            let left = deadline.saturating_sub(self.port.now());
            if left.is_zero() {
                return Err(self.timeout_error(during, got, wanted, budget));
            }
            match self.port.recv(buf, left)? {
                0 => {}
                n => return Ok(n),
            }
        }
    }

    fn read_byte(&mut self, during: &'static str) -> Result<u8> {
        let mut b = [0];
        self.read_into(&mut b, during)?;
        Ok(b[0])
    }

    fn timeout_error(
        &self,
        during: &'static str,
        got: usize,
        wanted: usize,
        waited: Duration,
    ) -> Error {
        Error::Timeout {
            during,
            got,
            wanted,
            timeout: waited,
        }
    }

    // ----- commands -------------------------------------------------------------------------

    /// Brings the cell to the ready state from any state: ten `0` bytes, 2 ms apart, then
    /// confirms it with command 13. Replies still on their way are thrown away.
    pub fn reset(&mut self) -> Result<()> {
        const DURING: &str = "confirming a reset (command 13 after ten zeros)";
        let gap = RESET_GAP_NS.as_duration();
        for _ in 0..10 {
            self.port.pause(gap);
            self.send(&[0])?;
            self.port.drain()?;
        }
        self.port.pause(gap + BYTE_NS.as_duration());
        self.port.discard_input()?;
        // Replies to what came before the zeros (or to a zero taken as a command's data) may
        // still come, later still from a cell behind a loaded machine. The cell answers command
        // 13 only once it is ready, after everything it sent before: its answer is the last
        // byte on a line that then stays quiet.
        self.send(&[Command::ReadKey as u8])?;
        let quiet = (self.timeout / 4).max((BYTE_NS * 20).as_duration());
        let mut last = self.read_byte(DURING).map_err(|e| match e {
            Error::Timeout { timeout, .. } => Error::ResetUnanswered { timeout },
            e => e,
        })?;
        let mut stale = 0usize;
        let mut buf = [0u8; 64];
        loop {
            match self.port.recv(&mut buf, quiet)? {
                0 => break,
                n => {
                    last = buf[n - 1];
                    stale += n;
                }
            }
            if stale > MAX_STALE_AFTER_RESET {
                return Err(Error::UnexpectedReply {
                    during: DURING,
                    byte: last,
                    expected: "the line to fall quiet after the reset",
                });
            }
        }
        match last {
            0 | 1 => Ok(()),
            byte => Err(Error::UnexpectedReply {
                during: DURING,
                byte,
                expected: "0 or 1, the START key",
            }),
        }
    }

    /// Sends one `0`: stops a running series or program (start byte becomes 0).
    pub fn interrupt(&mut self) -> Result<()> {
        self.send_all(&[0])?;
        self.port.pause(RESET_GAP_NS.as_duration());
        Ok(())
    }

    /// Command 7: one reading of analog `channel` (1..4), 0..255 for 0..5 V.
    pub fn analog(&mut self, channel: u8) -> Result<u8> {
        check_channel(channel)?;
        self.send(&[Command::Analog as u8, channel])?;
        self.read_byte("reading an analog channel")
    }

    /// Command 4: one reading per entry of `channels`, then `0` to end. The seed lets the
    /// channel bytes go at full line speed (the cell converts within their stop bits), so they
    /// are sent back to back, a batch at a time (the cell waits for the next channel byte as
    /// long as it takes), and the readings read back.
    pub fn analog_repeat(&mut self, channels: &[u8]) -> Result<Vec<u8>> {
        /// Channel bytes in flight at once: well inside any port's buffers.
        const BATCH: usize = 64;
        for &c in channels {
            check_channel(c)?;
        }
        self.send(&[Command::AnalogRepeat as u8])?;
        let mut values = Vec::with_capacity(channels.len());
        for batch in channels.chunks(BATCH) {
            self.send(batch)?;
            for _ in batch {
                values.push(self.read_byte("reading analog channels repeatedly")?);
            }
        }
        self.send(&[0])?;
        Ok(values)
    }

    /// Command 8, read: the byte at parallel-bus address `addr` (0..127).
    pub fn bus_read(&mut self, addr: u8) -> Result<u8> {
        check_bus(addr)?;
        self.send(&[Command::Bus as u8, addr | 0x80])?;
        self.read_byte("reading the parallel bus")
    }

    /// Command 8, write: `value` to parallel-bus address `addr` (0..127).
    pub fn bus_write(&mut self, addr: u8, value: u8) -> Result<()> {
        check_bus(addr)?;
        self.send_all(&[Command::Bus as u8, addr, value])
    }

    /// Command 9: START the next block of the armed series.
    pub fn start_block(&mut self) -> Result<()> {
        self.send_all(&[Command::Start as u8])
    }

    /// Command 10: arm a series with the parameters already at 0800h.
    pub fn repeat_series(&mut self) -> Result<()> {
        self.send_all(&[Command::RepeatSeries as u8])
    }

    /// Command 11: sets port 1's latch. Keep bits 0..3 high (A/D lines; bit 0 low lights the
    /// LED) and bits used as inputs high.
    pub fn write_port1(&mut self, value: u8) -> Result<()> {
        self.send_all(&[Command::WritePort1 as u8, value])
    }

    /// Command 12: port 1's pins.
    pub fn read_port1(&mut self) -> Result<u8> {
        self.send(&[Command::ReadPort1 as u8])?;
        self.read_byte("reading port 1")
    }

    /// Command 13: whether the START key is pressed.
    pub fn key_pressed(&mut self) -> Result<bool> {
        self.send(&[Command::ReadKey as u8])?;
        match self.read_byte("reading the START key")? {
            0 => Ok(true),
            1 => Ok(false),
            byte => Err(Error::UnexpectedReply {
                during: "reading the START key",
                byte,
                expected: "0 (pressed) or 1 (not pressed)",
            }),
        }
    }

    /// Command 14: sets P2.6.
    pub fn write_p26(&mut self, high: bool) -> Result<()> {
        self.send_all(&[Command::WriteP26 as u8, u8::from(high)])
    }

    /// Command 15: the level of P2.6.
    pub fn read_p26(&mut self) -> Result<bool> {
        self.send(&[Command::ReadP26 as u8])?;
        match self.read_byte("reading P2.6")? {
            0 => Ok(false),
            1 => Ok(true),
            byte => Err(Error::UnexpectedReply {
                during: "reading P2.6",
                byte,
                expected: "0 or 1",
            }),
        }
    }

    /// Command 16: internal RAM at `addr` (0..127), or a special function register (80h..FFh,
    /// see [`crate::sfr`]).
    pub fn read_register(&mut self, addr: u8) -> Result<u8> {
        self.send(&[Command::ReadRegister as u8, addr])?;
        self.read_byte("reading a register")
    }

    /// Command 17: writes internal RAM at `addr` (0..127).
    pub fn write_register(&mut self, addr: u8, value: u8) -> Result<()> {
        check_register(addr)?;
        self.send_all(&[Command::WriteRegister as u8, addr, value])
    }

    /// Command 18: the RAM byte at `addr`.
    pub fn peek(&mut self, addr: u16) -> Result<u8> {
        let [h, l] = addr.to_be_bytes();
        self.send(&[Command::Peek as u8, h, l])?;
        self.read_byte("reading a RAM address")
    }

    /// Command 19: writes the RAM byte at `addr`.
    pub fn poke(&mut self, addr: u16, value: u8) -> Result<()> {
        let [h, l] = addr.to_be_bytes();
        self.send_all(&[Command::Poke as u8, h, l, value])
    }

    /// Command 1: arms a series. Each block then starts with [`start_block`](Self::start_block)
    /// or the START key; [`interrupt`](Self::interrupt) stops it.
    pub fn start_series(&mut self, params: &SeriesParams) -> Result<()> {
        let bytes = params.to_bytes()?;
        self.send_with_setup(Command::Measure)?;
        self.send(&bytes)
    }

    /// The number of values the last series stored (registers R6:R7, via command 16).
    pub fn value_count(&mut self) -> Result<u16> {
        let high = self.read_register(COUNT_HIGH_REGISTER)?;
        let low = self.read_register(COUNT_LOW_REGISTER)?;
        Ok(u16::from_be_bytes([high, low]))
    }

    /// Command 2: the first `len` bytes of the data area (parameters, then values).
    pub fn read_data(&mut self, len: usize, mode: Transfer) -> Result<Vec<u8>> {
        self.read_data_with_progress(len, mode, |_, _| {})
    }

    /// [`read_data`](Self::read_data), calling `progress(done, total)` as bytes come in.
    pub fn read_data_with_progress(
        &mut self,
        len: usize,
        mode: Transfer,
        mut progress: impl FnMut(usize, usize),
    ) -> Result<Vec<u8>> {
        check_fits(DATA_AREA, len)?;
        const DURING: &str = "reading data RAM";
        self.send_with_setup(Command::ReadData)?;
        let mut data = vec![0; len];
        let mut got = 0;
        match mode {
            Transfer::StopAndWait => {
                while got < len {
                    self.send(&[1])?;
                    self.read_into(&mut data[got..got + 1], DURING)?;
                    got += 1;
                    progress(got, len);
                }
            }
            Transfer::Pipelined => {
                let mut asked = 0;
                while got < len {
                    let ahead = asked - got;
                    if asked < len && ahead < WINDOW {
                        let more = (WINDOW - ahead).min(len - asked);
                        self.send(&[1; WINDOW][..more])?;
                        asked += more;
                    }
                    got += self.read_some(&mut data[got..asked], DURING, got, len)?;
                    progress(got, len);
                }
            }
        }
        self.send(&[0])?;
        Ok(data)
    }

    /// Command 3: writes `bytes` into the data area from 0800h.
    pub fn write_data(&mut self, bytes: &[u8], mode: Transfer) -> Result<()> {
        check_fits(DATA_AREA, bytes.len())?;
        self.upload(Command::WriteData, bytes, mode, "writing data RAM")
    }

    /// Command 5: loads `program` at 0400h; it runs after [`run_program`](Self::run_program),
    /// a reset or a power cycle.
    pub fn load_program(&mut self, program: &[u8], mode: Transfer) -> Result<()> {
        check_fits(crate::PROGRAM_AREA, program.len())?;
        self.upload(Command::LoadProgram, program, mode, "loading a program")
    }

    /// The exchange of commands 3 and 5: before each byte the cell sends a timing byte; the
    /// host answers `1` and the byte, or `0` to end. Pipelined, pairs run ahead of the timing
    /// bytes; either way every timing byte is read, so the call returns once the cell has
    /// stored everything.
    fn upload(
        &mut self,
        cmd: Command,
        bytes: &[u8],
        mode: Transfer,
        during: &'static str,
    ) -> Result<()> {
        // The first timing byte comes when the set-up is over: waiting for it keeps the pause
        // even when the line's timing is blurred (a loaded PTY server reads late).
        self.send(&[cmd as u8])?;
        let wanted = bytes.len() + 1;
        let mut scratch = [0u8; WINDOW + 1];
        self.read_into(&mut scratch[..1], during)?;
        let mut timing: usize = 1; // timing bytes seen
        match mode {
            Transfer::StopAndWait => {
                for (i, &b) in bytes.iter().enumerate() {
                    if i > 0 {
                        self.read_into(&mut scratch[..1], during)?;
                        timing += 1;
                    }
                    self.send(&[1, b])?;
                }
            }
            Transfer::Pipelined => {
                let mut sent = 0;
                let mut pairs = Vec::with_capacity(2 * WINDOW);
                while sent < bytes.len() {
                    // Timing byte k (k >= 1) confirms pair k - 1.
                    let unconfirmed = sent.saturating_sub(timing.saturating_sub(1));
                    if unconfirmed < WINDOW {
                        let more = (WINDOW - unconfirmed).min(bytes.len() - sent);
                        pairs.clear();
                        for &b in &bytes[sent..sent + more] {
                            pairs.extend_from_slice(&[1, b]);
                        }
                        self.send(&pairs)?;
                        sent += more;
                    } else {
                        let room = (wanted - timing).min(scratch.len());
                        timing += self.read_some(&mut scratch[..room], during, timing, wanted)?;
                    }
                }
            }
        }
        self.send(&[0])?;
        while timing < wanted {
            let room = (wanted - timing).min(scratch.len());
            timing += self.read_some(&mut scratch[..room], during, timing, wanted)?;
        }
        Ok(())
    }

    /// Command 6: runs the program at 0400h (start byte 130).
    pub fn run_program(&mut self) -> Result<()> {
        self.send_all(&[Command::RunProgram as u8])
    }

    /// A whole series: arms it, starts `blocks` blocks one after the other (waiting each one
    /// out), stops it, reads the values back and splits them into channels.
    pub fn measure(
        &mut self,
        params: &SeriesParams,
        blocks: u32,
        mut progress: impl FnMut(Progress),
    ) -> Result<Measurement> {
        let sent = params.to_bytes()?;
        self.start_series(params)?;
        // The cell has no "block done" signal: wait the block's length plus a margin for the
        // START byte's way to the cell.
        let block_ns = params.block_ns();
        let spacing = block_ns.saturating_add(Nanos::from(self.block_margin));
        // Saturating: 65535 cycles of 65 s times u32::MAX blocks is past u64 nanoseconds.
        let total_ns = spacing.saturating_mul(u64::from(blocks));
        let step = Duration::from_millis(100);
        let mut starts = Vec::new();
        for block in 0..blocks {
            self.start_block()?;
            let start = spacing.saturating_mul(u64::from(block));
            starts.push(start);
            let mut waited = Nanos::ZERO;
            while waited < spacing {
                let chunk = (spacing - waited).min(Nanos::from(step));
                self.port.pause(chunk.as_duration());
                waited += chunk;
                progress(Progress::Measuring {
                    block,
                    blocks,
                    done_ns: start.saturating_add(waited),
                    total_ns,
                });
            }
        }
        self.interrupt()?;
        let count = usize::from(self.value_count()?);
        let total = usize::from(PARAMS_LEN) + count;
        let data = self.read_data_with_progress(total, Transfer::Pipelined, |done, total| {
            progress(Progress::Reading { done, total })
        })?;
        let found: [u8; 8] = data[..8].try_into().expect("8 parameter bytes");
        if found != sent {
            return Err(Error::ParamsChanged { sent, found });
        }
        Ok(Measurement::split(*params, &data[8..], &starts))
    }
}

fn check_channel(channel: u8) -> Result<()> {
    match channel {
        1..=4 => Ok(()),
        _ => Err(Error::Channel(channel)),
    }
}

fn check_register(addr: u8) -> Result<()> {
    if addr < 128 {
        Ok(())
    } else {
        Err(Error::Register(addr))
    }
}

fn check_bus(addr: u8) -> Result<()> {
    if addr < 128 {
        Ok(())
    } else {
        Err(Error::BusAddress(addr))
    }
}

fn check_fits(start: u16, len: usize) -> Result<()> {
    if usize::from(start) + len > EXT_RAM_SIZE {
        Err(Error::TooLong { start, len })
    } else {
        Ok(())
    }
}
