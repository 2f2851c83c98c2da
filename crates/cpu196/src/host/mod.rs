//! The host side: a client that talks to a board (or the model) over any [`Port`], the
//! monitor session of the original PC program, and a sample recorder. No clock, sleep or
//! file in here: time comes from the port (the wall clock on a serial line, virtual time on
//! [`SimPort`](buslab_device::SimPort)), files from the caller.

mod monitor;
mod recorder;

use std::collections::VecDeque;
use std::io;
use std::time::Duration;

pub use buslab_device::Port;
use buslab_device::{Human, LineSettings, Nanos};
pub use monitor::{FileRequests, LOST_AFTER, Monitor, MonitorError, PING_EVERY};
pub use recorder::{CsvSamples, Recorder, Sample, SampleSink, SampleSource};

use crate::acquisition::LogTable;
use crate::adconfig::{AdConfig, AdRefusal};
use crate::codes::MsgCode;
use crate::decoder::{Decoder, Event, PIC_CHUNK};
use crate::image::{BootConfig, encrypt_serial};
use crate::message::*;
use crate::wire::{FLASH_BLOCK, PIC_BLOCK, PIC_EEPROM};

/// Flash block reads kept on the line ahead of the replies in [`Client::flash_read_bank`]:
/// sixteen 262-byte replies are 364 ms of a 115200 baud line, which outlasts the round trips of
/// a loaded host (with 4 busy loops on 2 cores two ahead, 45 ms, delivered 81 to 87 % of the
/// line rate, eight, 182 ms, 91 to 99.6 %: stalls of up to 190 ms remained; docs/lab.md). The
/// board queues replies far beyond that (`board::TX_BACKLOG`, 64 KiB).
pub const FLASH_READ_AHEAD: usize = 16;

/// How many times [`Client::pic_write`] writes a block the board timed out on.
pub const PIC_WRITE_ATTEMPTS: u32 = 3;

/// What went wrong talking to a board.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    #[error("serial I/O: {0}")]
    Io(#[from] io::Error),
    #[error("the board answered {0}")]
    Board(MsgCode),
    #[error(
        "no answer from the board within {} (board lost? is it switched on, and at {line} like \
         this client? its boot configuration sets its rate)",
        Human(*waited)
    )]
    Lost {
        waited: Duration,
        line: LineSettings,
    },
    #[error("the board answered msg_ad_config_error{}", why.as_ref().map(|w| format!(": {w}")).unwrap_or_default())]
    AdConfig {
        bank: u8,
        config: u8,
        /// Why, as the set's CFGAD tells; `None` if it could not be read.
        why: Option<AdRefusal>,
    },
    /// A START the board refused with `msg_invalid_parameter_value`, with the reason it gave
    /// on the THREAD display (a set whose program cannot be made).
    #[error("the board answered msg_invalid_parameter_value: {why}")]
    StartRefused { why: String },
    #[error("unexpected answer: {0}")]
    Unexpected(String),
    #[error("verification failed: {0}")]
    Verify(String),
    #[error(transparent)]
    Encode(#[from] EncodeError),
}

/// Frame errors on the board's stream: how many, the first, and the last
/// [`FrameErrors::KEPT`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FrameErrors {
    count: u64,
    first: Option<String>,
    recent: VecDeque<String>,
}

impl FrameErrors {
    /// How many of the latest errors are kept.
    pub const KEPT: usize = 8;

    pub fn push(&mut self, error: String) {
        self.count += 1;
        if self.first.is_none() {
            self.first = Some(error.clone());
        }
        if self.recent.len() == Self::KEPT {
            self.recent.pop_front();
        }
        self.recent.push_back(error);
    }

    /// Errors seen in all.
    pub fn count(&self) -> u64 {
        self.count
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The first error seen.
    pub fn first(&self) -> Option<&str> {
        self.first.as_deref()
    }

    /// The latest errors, oldest first (at most [`KEPT`](Self::KEPT)).
    pub fn recent(&self) -> impl Iterator<Item = &str> {
        self.recent.iter().map(String::as_str)
    }
}

/// Messages the board sends on its own (THREAD, alerts, samples, watchdog, ...), kept while
/// the client waits for a reply.
pub type Backlog = VecDeque<Message>;

/// Talks to one board.
pub struct Client<P: Port> {
    port: P,
    decoder: Decoder,
    /// The line as this client set it (8N1 at the given rate), for reply deadlines and hints.
    line: LineSettings,
    /// How long a reply may take beyond its bytes' time on the line.
    pub timeout: Duration,
    backlog: Backlog,
    /// Decoded, not yet looked at.
    inbox: Backlog,
    /// Frame errors seen on the board's stream (reported, not fatal): counted, the first and
    /// the last few kept, so a noisy line does not grow the client.
    pub frame_errors: FrameErrors,
    /// The decoder's clock: the silence this client has seen on the line, in nanoseconds. It
    /// moves only while a `recv` waits and gets nothing, never while the client is busy or
    /// descheduled: a client that reads late (a loaded machine) finds a frame's bytes in two
    /// reads far apart, though the board sent them back to back, and must not take that for
    /// a pause inside the frame.
    silence_ns: Nanos,
}

/// The default allowance for a reply beyond its bytes' time on the line.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(2);

impl<P: Port> Client<P> {
    /// A client on `port`, whose line runs at `baud` 8N1, with [`DEFAULT_TIMEOUT`].
    pub fn new(port: P, baud: u32) -> Self {
        Self {
            port,
            decoder: Decoder::new(),
            line: LineSettings::n81(baud),
            timeout: DEFAULT_TIMEOUT,
            backlog: Backlog::new(),
            inbox: Backlog::new(),
            frame_errors: FrameErrors::default(),
            silence_ns: Nanos::ZERO,
        }
    }

    /// The port's clock (see [`Port::now`]).
    pub fn now(&self) -> Duration {
        self.port.now()
    }

    /// The port.
    pub fn port(&mut self) -> &mut P {
        &mut self.port
    }

    /// Gives the port back.
    pub fn into_port(self) -> P {
        self.port
    }

    /// Declares the parameter count of a user command's replies.
    pub fn set_user_len(&mut self, cmd: u8, len: u8) {
        self.decoder.set_user_len(cmd, len);
    }

    /// The decoder's current `FA` length.
    pub fn adcont_len(&self) -> Option<usize> {
        self.decoder.adcont_len()
    }

    pub fn send(&mut self, m: &Message) -> Result<(), ClientError> {
        self.port.send(&m.to_bytes()?)?;
        Ok(())
    }

    /// Sends raw bytes (tests, user commands with odd formats).
    pub fn send_raw(&mut self, bytes: &[u8]) -> Result<(), ClientError> {
        self.port.send(bytes)?;
        Ok(())
    }

    /// How long a reply of `n` bytes may take: twice its time on the line (the request's
    /// time is counted by the caller), plus [`timeout`](Self::timeout).
    fn budget(&self, n: usize) -> Duration {
        self.timeout
            + self
                .line
                .byte_time()
                .saturating_mul(2 * n as u64)
                .as_duration()
    }

    /// The next message from the board (queued ones first), or `None` after `wait`.
    pub fn next(&mut self, wait: Duration) -> Result<Option<Message>, ClientError> {
        if let Some(m) = self.backlog.pop_front() {
            return Ok(Some(m));
        }
        let deadline = self.port.now() + wait;
        self.read_one(deadline)
    }

    fn read_one(&mut self, deadline: Duration) -> Result<Option<Message>, ClientError> {
        let mut buf = [0u8; 512];
        loop {
            if let Some(m) = self.inbox.pop_front() {
                return Ok(Some(m));
            }
            // Checked before reading, not only when nothing came: a board that keeps talking
            // (an acquisition, watchdogs) must not hold a caller past its deadline.
            let left = deadline.saturating_sub(self.port.now());
            if left.is_zero() {
                return Ok(None);
            }
            let before = self.port.now();
            let n = self.port.recv(&mut buf, left)?;
            if n == 0 {
                // Nothing came while waiting: the line was silent that long.
                let waited = self.port.now().saturating_sub(before);
                self.silence_ns = self.silence_ns.saturating_add(Nanos::from(waited));
                if let Some(Event::Error(e)) = self.decoder.poll(self.silence_ns) {
                    self.frame_errors.push(e.to_string());
                }
            }
            for &b in &buf[..n] {
                match self.decoder.push(self.silence_ns, b) {
                    Some(Event::Message(m)) => self.inbox.push_back(m),
                    Some(Event::Error(e)) => self.frame_errors.push(e.to_string()),
                    // Only a PC sends PIC block writes.
                    Some(Event::PicChunk { .. }) | None => {}
                }
            }
        }
    }

    /// Sends `m` and waits for the first reply `want` accepts; board error messages end the
    /// wait with [`ClientError::Board`]; other traffic goes to the backlog.
    pub fn request<T>(
        &mut self,
        m: &Message,
        reply_len: usize,
        mut want: impl FnMut(&Message) -> Option<T>,
    ) -> Result<T, ClientError> {
        self.send(m)?;
        let budget = self.budget(reply_len + m.to_bytes()?.len());
        self.wait_for(budget, &mut want)
    }

    fn wait_for<T>(
        &mut self,
        budget: Duration,
        want: &mut impl FnMut(&Message) -> Option<T>,
    ) -> Result<T, ClientError> {
        let deadline = self.port.now() + budget;
        let mut held = Backlog::new();
        let result = loop {
            let Some(msg) = self.read_one(deadline)? else {
                break Err(ClientError::Lost {
                    waited: budget,
                    line: self.line,
                });
            };
            if let Some(t) = want(&msg) {
                break Ok(t);
            }
            match msg {
                Message::Msg(code) if code != MsgCode::NO_ERROR && code != MsgCode::COMPLETED => {
                    break Err(ClientError::Board(code));
                }
                other => held.push_back(other),
            }
        };
        // Unrelated traffic stays available, in order.
        held.append(&mut self.backlog);
        self.backlog = held;
        result
    }

    /// Pings with a watchdog; any error message arriving first is returned. Confirms commands
    /// that have no reply of their own (PWM, bridge writes, user commands).
    pub fn sync(&mut self) -> Result<(), ClientError> {
        self.request(&Message::Watchdog, 2, |m| {
            (*m == Message::Watchdog).then_some(())
        })
    }

    fn completed(&mut self, m: &Message) -> Result<(), ClientError> {
        self.request(m, 3, |r| {
            (*r == Message::Msg(MsgCode::COMPLETED)).then_some(())
        })
    }

    pub fn info(&mut self) -> Result<CpuInfo, ClientError> {
        self.request(&Message::CpuInfoRequest, 25, |m| match m {
            Message::CpuInfo(i) => Some(i.clone()),
            _ => None,
        })
    }

    /// START. A refused acquisition (`msg_ad_config_error`) comes back as
    /// [`ClientError::AdConfig`] with the reason, found from the set's CFGAD.
    pub fn start(&mut self, s: Start) -> Result<(), ClientError> {
        match self.completed(&Message::Start(s)) {
            Err(ClientError::Board(MsgCode::AD_CONFIG_ERROR)) => {
                let why = self
                    .cfgad(s.bank(), s.config())
                    .ok()
                    .and_then(|(c196, _)| AdConfig::check_start(&c196, self.line).err());
                Err(ClientError::AdConfig {
                    bank: s.bank(),
                    config: s.config(),
                    why,
                })
            }
            Err(ClientError::Board(MsgCode::INVALID_PARAMETER_VALUE)) => {
                match self.take_start_reason(s.config()) {
                    Some(why) => Err(ClientError::StartRefused { why }),
                    None => Err(ClientError::Board(MsgCode::INVALID_PARAMETER_VALUE)),
                }
            }
            other => other,
        }
    }

    /// The line a refusing kernel shows before its `FE 04` (`configuration N: …`), taken out
    /// of the backlog.
    fn take_start_reason(&mut self, config: u8) -> Option<String> {
        let prefix = format!("configuration {config}: ");
        let at = self.backlog.iter().position(|m| {
            matches!(m, Message::Thread(Thread::Display { format: DisplayFormat::Text, data, .. })
                if data.starts_with(prefix.as_bytes()))
        })?;
        match self.backlog.remove(at) {
            Some(Message::Thread(Thread::Display { data, .. })) => {
                Some(String::from_utf8_lossy(&data[prefix.len()..]).into_owned())
            }
            _ => None,
        }
    }

    pub fn stop(&mut self) -> Result<(), ClientError> {
        self.completed(&Message::Stop)
    }

    pub fn power_down(&mut self) -> Result<(), ClientError> {
        self.request(&Message::Power(Power::PowerDown), 3, |m| {
            (*m == Message::Power(Power::PoweredDown)).then_some(())
        })
    }

    pub fn reset(&mut self) -> Result<(), ClientError> {
        self.request(&Message::Power(Power::Reset), 3, |m| {
            (*m == Message::Power(Power::WasReset)).then_some(())
        })
    }

    pub fn flash_read(
        &mut self,
        bank: u8,
        block: u8,
    ) -> Result<Box<[u8; FLASH_BLOCK]>, ClientError> {
        self.request(
            &Message::FlashReadRequest { bank, block },
            259,
            |m| match m {
                Message::FlashData(d) => Some(d.clone()),
                _ => None,
            },
        )
    }

    /// Reads a whole bank (256 blocks). Requests are pipelined, [`FLASH_READ_AHEAD`] ahead, so
    /// the board's transmitter never waits for the next request.
    pub fn flash_read_bank(
        &mut self,
        bank: u8,
        progress: &mut dyn FnMut(usize),
    ) -> Result<Vec<u8>, ClientError> {
        const AHEAD: usize = FLASH_READ_AHEAD;
        let mut out = Vec::with_capacity(256 * FLASH_BLOCK);
        let mut asked = 0usize;
        while asked < AHEAD {
            self.send(&Message::FlashReadRequest {
                bank,
                block: asked as u8,
            })?;
            asked += 1;
        }
        let budget = self.budget((AHEAD + 1) * 262);
        while out.len() < 256 * FLASH_BLOCK {
            let data = self.wait_for(budget, &mut |m| match m {
                Message::FlashData(d) => Some(d.clone()),
                _ => None,
            })?;
            out.extend_from_slice(&data[..]);
            progress(out.len());
            if asked < 256 {
                self.send(&Message::FlashReadRequest {
                    bank,
                    block: asked as u8,
                })?;
                asked += 1;
            }
        }
        Ok(out)
    }

    /// Writes a block and reads it back.
    pub fn flash_write(
        &mut self,
        bank: u8,
        block: u8,
        data: &[u8; FLASH_BLOCK],
    ) -> Result<(), ClientError> {
        self.completed(&Message::FlashWrite {
            bank,
            block,
            data: Box::new(*data),
        })?;
        let back = self.flash_read(bank, block)?;
        if *back != *data {
            let at = back.iter().zip(data).position(|(a, b)| a != b).unwrap_or(0);
            return Err(ClientError::Verify(format!(
                "bank {bank} block {block:#04x} reads back {:02X}h at offset {at}, wrote {:02X}h",
                back[at], data[at]
            )));
        }
        Ok(())
    }

    pub fn flash_erase(&mut self, bank: u8) -> Result<(), ClientError> {
        self.completed(&Message::FlashErase { bank })
    }

    pub fn pic_read(&mut self, block: u8) -> Result<Box<[u8; PIC_BLOCK]>, ClientError> {
        self.request(
            &Message::PicReadRequest { block },
            PIC_BLOCK + 3,
            |m| match m {
                Message::PicData(d) => Some(d.clone()),
                _ => None,
            },
        )
    }

    /// Writes a PIC block and reads it back. The board acknowledges every 256 bytes
    /// (`msg_completed`, 16 times) as they arrive; the next 256 go when the acknowledgement is
    /// in (flow control). `progress` sees the bytes acknowledged, never going back.
    ///
    /// The board drops a message whose next byte is more than 200 ms late (`msg_time_out`).
    /// Only this message waits for the board between its own bytes, so a host that stalls
    /// while an acknowledgement travels (a loaded machine) can cause one; the block is then
    /// written again from its start, up to [`PIC_WRITE_ATTEMPTS`] times (writing a block twice
    /// leaves the same block).
    pub fn pic_write(
        &mut self,
        block: u8,
        data: &[u8; PIC_BLOCK],
        progress: &mut dyn FnMut(usize),
    ) -> Result<(), ClientError> {
        let bytes = Message::PicWrite {
            block,
            data: Box::new(*data),
        }
        .to_bytes()?;
        let mut acknowledged = 0;
        let mut attempt = 1;
        loop {
            match self.pic_write_once(&bytes, &mut |n| {
                if n > acknowledged {
                    acknowledged = n;
                    progress(n);
                }
            }) {
                Err(ClientError::Board(code @ (MsgCode::TIME_OUT | MsgCode::RECEPTION_ERROR)))
                    if attempt < PIC_WRITE_ATTEMPTS =>
                {
                    tracing::warn!(
                        block,
                        attempt,
                        "the board answered {code} inside a PIC block write; writing it again"
                    );
                    attempt += 1;
                    self.resync_after_broken_message()?;
                }
                result => break result?,
            }
        }
        let back = self.pic_read(block)?;
        if *back != *data {
            return Err(ClientError::Verify(format!(
                "PIC block {block} does not read back as written"
            )));
        }
        Ok(())
    }

    /// After `msg_time_out` or `msg_reception_error` inside a message, the bytes the host sent
    /// after its stall are a frame of garbage to the board, dropped after its own inter-byte
    /// time-out: let that pass, forget what came back meanwhile, and see the board answer a
    /// watchdog. Error messages before that answer are the garbage's (a loaded machine may
    /// deliver them after the pause), not the watchdog's; a watchdog swallowed by a garbage
    /// frame still in progress is sent again after the board's time-out.
    fn resync_after_broken_message(&mut self) -> Result<(), ClientError> {
        let garbage = self.budget(PIC_CHUNK);
        let board_time_out = crate::decoder::DEFAULT_TIMEOUT_NS.as_duration();
        let mut attempt = 1;
        loop {
            self.port.pause(board_time_out + garbage);
            self.port.discard_input()?;
            self.decoder = Decoder::new();
            self.send(&Message::Watchdog)?;
            let deadline = self.port.now() + self.budget(8);
            let answered = loop {
                match self.read_one(deadline)? {
                    Some(Message::Watchdog) => break true,
                    Some(Message::Msg(code)) if code != MsgCode::COMPLETED => {
                        tracing::debug!("{code} left over from the broken message");
                    }
                    Some(other) => self.backlog.push_back(other),
                    None => break false,
                }
            };
            if answered {
                return Ok(());
            }
            if attempt == PIC_WRITE_ATTEMPTS {
                return Err(ClientError::Lost {
                    waited: self.budget(8),
                    line: self.line,
                });
            }
            attempt += 1;
        }
    }

    /// One pass of a PIC block write: 256 bytes per acknowledgement, the message's head first.
    fn pic_write_once(
        &mut self,
        bytes: &[u8],
        progress: &mut dyn FnMut(usize),
    ) -> Result<(), ClientError> {
        // Command, complement, sub-code and block go in one write with the first chunk: a
        // stall between them would break the message before any data.
        let head = bytes.len() - PIC_BLOCK;
        let budget = self.budget(PIC_CHUNK + 64);
        for i in 0..PIC_BLOCK / PIC_CHUNK {
            let start = if i == 0 { 0 } else { head + i * PIC_CHUNK };
            self.send_raw(&bytes[start..head + (i + 1) * PIC_CHUNK])?;
            self.wait_for(budget, &mut |r| {
                (*r == Message::Msg(MsgCode::COMPLETED)).then_some(())
            })?;
            progress((i + 1) * PIC_CHUNK);
        }
        Ok(())
    }

    pub fn eeprom_read(&mut self) -> Result<Box<[u8; PIC_EEPROM]>, ClientError> {
        self.request(&Message::EepromReadRequest, 259, |m| match m {
            Message::EepromData(d) => Some(d.clone()),
            _ => None,
        })
    }

    pub fn eeprom_write(&mut self, data: &[u8; PIC_EEPROM]) -> Result<(), ClientError> {
        self.completed(&Message::EepromWrite(Box::new(*data)))?;
        if *self.eeprom_read()? != *data {
            return Err(ClientError::Verify(
                "the EEPROM does not read back as written".into(),
            ));
        }
        Ok(())
    }

    pub fn cfgad(&mut self, bank: u8, config: u8) -> Result<([u8; 18], [u8; 3]), ClientError> {
        self.request(&Message::CfgAdRequest { bank, config }, 24, |m| match m {
            Message::CfgAd { c196, pic } => Some((*c196, *pic)),
            _ => None,
        })
    }

    /// CPUFORMAT `04`: a boot flash block (5..31).
    pub fn boot_block(&mut self, block: u8) -> Result<Box<[u8; 256]>, ClientError> {
        self.request(
            &Message::Format(Format::ReadBootBlock { block }),
            259,
            |m| match m {
                Message::Format(Format::BootBlock(d)) => Some(d.clone()),
                _ => None,
            },
        )
    }

    /// The board's 16 → 8 bit log table (boot blocks 6 and 7, at 600h).
    pub fn log_table(&mut self) -> Result<LogTable, ClientError> {
        let mut bytes = [0u8; 512];
        bytes[..256].copy_from_slice(&self.boot_block(6)?[..]);
        bytes[256..].copy_from_slice(&self.boot_block(7)?[..]);
        Ok(LogTable::from_bytes(&bytes))
    }

    /// The boot configuration (boot block 5); `None` if erased or not valid.
    pub fn boot_config(&mut self) -> Result<Option<(BootConfig, Vec<u8>)>, ClientError> {
        Ok(BootConfig::from_csboot(&*self.boot_block(5)?))
    }

    /// Erases the boot flash (`F7 07`) and writes a new boot configuration (`F7 06`), then
    /// reads it back. It applies from the board's next reset.
    pub fn set_boot_config(&mut self, boot: &BootConfig, user: &[u8]) -> Result<(), ClientError> {
        let block = boot.to_csboot(user);
        self.completed(&Message::Format(Format::EraseBoot))?;
        self.completed(&Message::Format(Format::WriteBootBlock(Box::new(block))))?;
        if *self.boot_block(5)? != block {
            return Err(ClientError::Verify(
                "boot block 5 does not read back as written".into(),
            ));
        }
        Ok(())
    }

    /// New serial number (`F7 03`): erases all flash banks and the PIC. `current` is the
    /// board's serial number (its encrypted form is the guard).
    pub fn set_serial(&mut self, current: &[u8; 8], new: &[u8; 8]) -> Result<(), ClientError> {
        let m = Message::Format(Format::NewSerial {
            nsc: encrypt_serial(current),
            new: *new,
        });
        self.completed(&m)
    }

    pub fn pic_kernel_read(
        &mut self,
        serial: &[u8; 8],
    ) -> Result<Box<[u8; PIC_BLOCK]>, ClientError> {
        let m = Message::Format(Format::ReadPicKernel {
            nsc: encrypt_serial(serial),
        });
        self.request(&m, PIC_BLOCK + 3, |r| match r {
            Message::Format(Format::PicKernel(d)) => Some(d.clone()),
            _ => None,
        })
    }

    /// Writes the PIC kernel (16 × `msg_completed`) and reads it back.
    pub fn pic_kernel_write(
        &mut self,
        serial: &[u8; 8],
        data: &[u8; PIC_BLOCK],
    ) -> Result<(), ClientError> {
        let m = Message::Format(Format::WritePicKernel {
            nsc: encrypt_serial(serial),
            data: Box::new(*data),
        });
        self.send(&m)?;
        let budget = self.budget(PIC_BLOCK + 64);
        for _ in 0..PIC_BLOCK / 256 {
            self.wait_for(budget, &mut |r| {
                (*r == Message::Msg(MsgCode::COMPLETED)).then_some(())
            })?;
        }
        if *self.pic_kernel_read(serial)? != *data {
            return Err(ClientError::Verify(
                "the PIC kernel does not read back as written".into(),
            ));
        }
        Ok(())
    }

    /// Emergency erase (`F7 55 AA xy`): resets the board and sends it within its 100 ms window.
    pub fn emergency_erase(&mut self, xy: u8) -> Result<(), ClientError> {
        self.reset()?;
        self.completed(&Message::Format(Format::Emergency { xy }))
    }

    /// Sends a command without a reply of its own, then [`sync`](Self::sync)s.
    pub fn command(&mut self, m: &Message) -> Result<(), ClientError> {
        self.send(m)?;
        self.sync()
    }

    /// A bridge command and the report it causes (SPI/SCI loop back, parallel read).
    pub fn bridge(&mut self, b: Bridge) -> Result<Option<Bridge>, ClientError> {
        self.send(&Message::Bridge(b))?;
        let answer = match b {
            Bridge::SpiSend(_) | Bridge::SciSend(_) | Bridge::ParallelReadRequest => {
                let got = self.wait_for(self.budget(8), &mut |m| match m {
                    Message::Bridge(
                        r @ (Bridge::SpiReceived(_)
                        | Bridge::SciReceived(_)
                        | Bridge::ParallelRead(_)),
                    ) => Some(*r),
                    _ => None,
                });
                match got {
                    Ok(r) => Some(r),
                    Err(ClientError::Lost { .. }) => None,
                    Err(e) => return Err(e),
                }
            }
            _ => None,
        };
        self.sync()?;
        Ok(answer)
    }

    /// Messages received while waiting for replies, drained.
    pub fn take_backlog(&mut self) -> Backlog {
        core::mem::take(&mut self.backlog)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A board that never stops talking: a watchdog `FF 00` every millisecond of its clock.
    struct Chatty {
        now: Duration,
    }

    impl Port for Chatty {
        fn send(&mut self, _bytes: &[u8]) -> io::Result<()> {
            Ok(())
        }
        fn recv(&mut self, buf: &mut [u8], _timeout: Duration) -> io::Result<usize> {
            self.now += Duration::from_millis(1);
            buf[..2].copy_from_slice(&[0xFF, 0x00]);
            Ok(2)
        }
        fn now(&self) -> Duration {
            self.now
        }
        fn pause(&mut self, d: Duration) {
            self.now += d;
        }
        fn drain(&mut self) -> io::Result<()> {
            Ok(())
        }
        fn discard_input(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    /// Hands out the board's bytes in the chunks given, each after the client was away (busy,
    /// or descheduled) for the time given; then silence.
    struct LateReader {
        chunks: VecDeque<(Duration, Vec<u8>)>,
        now: Duration,
    }

    impl Port for LateReader {
        fn send(&mut self, _bytes: &[u8]) -> io::Result<()> {
            Ok(())
        }
        fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
            match self.chunks.pop_front() {
                Some((away, bytes)) => {
                    self.now += away;
                    buf[..bytes.len()].copy_from_slice(&bytes);
                    Ok(bytes.len())
                }
                None => {
                    self.now += timeout;
                    Ok(0)
                }
            }
        }
        fn now(&self) -> Duration {
            self.now
        }
        fn pause(&mut self, d: Duration) {
            self.now += d;
        }
        fn drain(&mut self) -> io::Result<()> {
            Ok(())
        }
        fn discard_input(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_client_that_reads_late_does_not_cut_a_frame_in_two() {
        // The bug behind `no answer from the board within 2.06 s` on a loaded machine: the
        // client was descheduled in the middle of a 259-byte reply; its decoder stamped the
        // rest with the time it got to read it, saw a 200 ms pause inside the frame, dropped
        // it, and waited for a reply that had come.
        let data: [u8; 256] = core::array::from_fn(|i| i as u8);
        let reply = Message::FlashData(Box::new(data)).to_bytes().unwrap();
        let (head, tail) = reply.split_at(100);
        let port = LateReader {
            chunks: [
                (Duration::ZERO, head.to_vec()),
                (Duration::from_millis(500), tail.to_vec()),
            ]
            .into(),
            now: Duration::ZERO,
        };
        let mut c = Client::new(port, 115_200);
        assert_eq!(*c.flash_read(3, 0x60).unwrap(), data);
        assert!(c.frame_errors.is_empty(), "{:?}", c.frame_errors);
    }

    #[test]
    fn a_frame_that_stops_on_a_silent_line_is_dropped_and_the_next_one_is_read() {
        // Silence the client waited through is a real pause: the half frame goes, as on the
        // board, and the stream resynchronises.
        let data: [u8; 256] = [7; 256];
        let reply = Message::FlashData(Box::new(data)).to_bytes().unwrap();
        let mut c = Client::new(
            LateReader {
                chunks: [(Duration::ZERO, reply[..100].to_vec())].into(),
                now: Duration::ZERO,
            },
            115_200,
        );
        assert_eq!(c.next(Duration::from_millis(300)).unwrap(), None);
        assert_eq!(c.frame_errors.count(), 1, "{:?}", c.frame_errors);
        c.port().chunks.push_back((Duration::ZERO, reply.clone()));
        assert_eq!(
            c.next(Duration::from_millis(300)).unwrap(),
            Some(Message::FlashData(Box::new(data)))
        );
    }

    /// A line that delivers only garbage.
    struct Noise {
        now: Duration,
        seed: u32,
    }

    impl Port for Noise {
        fn send(&mut self, _bytes: &[u8]) -> io::Result<()> {
            Ok(())
        }
        fn recv(&mut self, buf: &mut [u8], _timeout: Duration) -> io::Result<usize> {
            self.now += Duration::from_millis(1);
            for b in buf.iter_mut() {
                self.seed = self.seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                *b = (self.seed >> 16) as u8;
            }
            Ok(buf.len())
        }
        fn now(&self) -> Duration {
            self.now
        }
        fn pause(&mut self, d: Duration) {
            self.now += d;
        }
        fn drain(&mut self) -> io::Result<()> {
            Ok(())
        }
        fn discard_input(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn frame_errors_on_a_noisy_line_are_counted_not_kept() {
        // `cpu196 monitor` on a noisy line grew ~1.1 MB/s: every error string was kept.
        let mut c = Client::new(
            Noise {
                now: Duration::ZERO,
                seed: 1,
            },
            115_200,
        );
        // A megabyte of noise.
        for _ in 0..2048 {
            let _ = c.read_one(c.port.now() + Duration::from_millis(1));
        }
        assert!(
            c.frame_errors.count() > 10_000,
            "{}",
            c.frame_errors.count()
        );
        assert_eq!(c.frame_errors.recent().count(), FrameErrors::KEPT);
        assert!(c.frame_errors.first().is_some());
    }

    #[test]
    fn a_reply_that_never_comes_times_out_even_while_the_board_streams() {
        let mut c = Client::new(
            Chatty {
                now: Duration::ZERO,
            },
            115_200,
        );
        c.timeout = Duration::from_millis(100);
        let err = c.info().unwrap_err();
        assert!(matches!(err, ClientError::Lost { .. }), "{err}");
        // The deadline is the allowance plus the exchange's time on the line, by the port's
        // clock.
        let line = 2 * (2 + 25) * LineSettings::n81(115_200).byte_time();
        let waited = Nanos::from(c.now());
        let allowance = Nanos::from_millis(100);
        assert!(
            waited >= allowance + line && waited <= allowance + line + Nanos::from_millis(1),
            "{waited}"
        );
        assert!(
            err.to_string()
                .starts_with("no answer from the board within 105 ms (board lost?"),
            "{err}"
        );
    }
}
