//! The host side: a client that talks to a board (or the model) over any byte port, the file
//! service a monitor offers the board, and a sample recorder.

use std::collections::{HashMap, VecDeque};
use std::fs::File;
use std::io::{self, Read, Write};
use std::path::{Component, Path, PathBuf};
use std::time::{Duration, Instant};

use crate::acquisition::{LogTable, decode_frame};
use crate::adconfig::AdConfig;
use crate::codes::MsgCode;
use crate::decoder::{Decoder, Event};
use crate::image::{BootConfig, encrypt_serial};
use crate::message::*;
use crate::source::code10_to_volts;
use crate::wire::{FLASH_BLOCK, PIC_BLOCK, PIC_EEPROM};

/// A byte link to a board.
pub trait Port {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// Reads what is there, waiting at most the port's timeout; `Ok(0)` when nothing came.
    fn recv(&mut self, buf: &mut [u8]) -> io::Result<usize>;
}

impl Port for Box<dyn serialport::SerialPort> {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.write_all(bytes)?;
        self.flush()
    }

    fn recv(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self.read(buf) {
            Err(e) if e.kind() == io::ErrorKind::TimedOut => Ok(0),
            other => other,
        }
    }
}

/// What went wrong talking to a board.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    #[error("serial I/O: {0}")]
    Io(#[from] io::Error),
    #[error("the board answered {0}")]
    Board(MsgCode),
    #[error("no answer from the board within {0:?} (board lost?)")]
    Lost(Duration),
    #[error("unexpected answer: {0}")]
    Unexpected(String),
    #[error("verification failed: {0}")]
    Verify(String),
    #[error(transparent)]
    Encode(#[from] EncodeError),
}

/// Messages the board sends on its own (THREAD, alerts, samples, watchdog, ...), kept while
/// the client waits for a reply.
pub type Backlog = VecDeque<Message>;

/// Talks to one board.
pub struct Client<P: Port> {
    port: P,
    decoder: Decoder,
    /// One character time at the link's rate, for reply time-outs.
    byte_ns: u64,
    /// Base time-out for a reply.
    pub timeout: Duration,
    backlog: Backlog,
    /// Decoded, not yet looked at.
    inbox: Backlog,
    /// Frame errors seen on the board's stream (reported, not fatal).
    pub frame_errors: Vec<String>,
    epoch: Instant,
}

impl<P: Port> Client<P> {
    pub fn new(port: P, baud: u32) -> Self {
        Self {
            port,
            decoder: Decoder::new(),
            byte_ns: buslab_link::LineSettings::n81(baud).byte_time_ns(),
            timeout: Duration::from_secs(2),
            backlog: Backlog::new(),
            inbox: Backlog::new(),
            frame_errors: Vec::new(),
            epoch: Instant::now(),
        }
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

    /// Time a reply of `n` bytes takes on the line, plus the base time-out.
    fn budget(&self, n: usize) -> Duration {
        self.timeout + Duration::from_nanos(2 * n as u64 * self.byte_ns)
    }

    /// The next message from the board (queued ones first), or `None` after `wait`.
    pub fn next(&mut self, wait: Duration) -> Result<Option<Message>, ClientError> {
        if let Some(m) = self.backlog.pop_front() {
            return Ok(Some(m));
        }
        self.read_one(Instant::now() + wait)
    }

    fn read_one(&mut self, deadline: Instant) -> Result<Option<Message>, ClientError> {
        let mut buf = [0u8; 512];
        loop {
            if let Some(m) = self.inbox.pop_front() {
                return Ok(Some(m));
            }
            // Checked before reading, not only when nothing came: a board that keeps talking
            // (an acquisition, watchdogs) must not hold a caller past its deadline.
            if Instant::now() >= deadline {
                return Ok(None);
            }
            let n = self.port.recv(&mut buf)?;
            let now = self.epoch.elapsed().as_nanos() as u64;
            for &b in &buf[..n] {
                match self.decoder.push(now, b) {
                    Some(Event::Message(m)) => self.inbox.push_back(m),
                    Some(Event::Error(e)) => self.frame_errors.push(e.to_string()),
                    None => {}
                }
            }
            if let Some(Event::Error(e)) = self.decoder.poll(now) {
                self.frame_errors.push(e.to_string());
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
        let deadline = Instant::now() + budget;
        let mut held = Backlog::new();
        let result = loop {
            let Some(msg) = self.read_one(deadline)? else {
                break Err(ClientError::Lost(budget));
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

    pub fn start(&mut self, s: Start) -> Result<(), ClientError> {
        self.completed(&Message::Start(s))
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

    /// Reads a whole bank (256 blocks). Requests are pipelined, two ahead, so the board's
    /// transmitter never waits for the next request.
    pub fn flash_read_bank(
        &mut self,
        bank: u8,
        progress: &mut dyn FnMut(usize),
    ) -> Result<Vec<u8>, ClientError> {
        const AHEAD: usize = 2;
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

    /// Writes a PIC block (16 × `msg_completed`, one per 256 bytes; `progress` sees each) and
    /// reads it back.
    pub fn pic_write(
        &mut self,
        block: u8,
        data: &[u8; PIC_BLOCK],
        progress: &mut dyn FnMut(usize),
    ) -> Result<(), ClientError> {
        let m = Message::PicWrite {
            block,
            data: Box::new(*data),
        };
        self.send(&m)?;
        let budget = self.budget(PIC_BLOCK + 64);
        for i in 0..PIC_BLOCK / 256 {
            self.wait_for(budget, &mut |r| {
                (*r == Message::Msg(MsgCode::COMPLETED)).then_some(())
            })?;
            progress((i + 1) * 256);
        }
        let back = self.pic_read(block)?;
        if *back != *data {
            return Err(ClientError::Verify(format!(
                "PIC block {block} does not read back as written"
            )));
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
                    Err(ClientError::Lost(_)) => None,
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

/// Serves the board's file requests (THREAD `40/41/18/10/20`) from one folder, never outside
/// it.
pub struct FileService {
    root: PathBuf,
    files: HashMap<u8, File>,
}

/// Why a file name was refused.
#[derive(Debug, thiserror::Error)]
pub enum FileNameError {
    #[error("file name {0:?} is not UTF-8 text")]
    NotText(Vec<u8>),
    #[error(
        "file name `{0}` must be relative and stay inside the served folder (no `..`, no absolute path)"
    )]
    Escapes(String),
    #[error("file name `{0}` leads outside the served folder through a symbolic link")]
    Symlink(String),
}

impl FileService {
    pub fn new(root: &Path) -> io::Result<Self> {
        Ok(Self {
            root: root.canonicalize()?,
            files: HashMap::new(),
        })
    }

    /// Where `name` lives under the root, if it is allowed.
    pub fn resolve(&self, name: &[u8]) -> Result<PathBuf, FileNameError> {
        let text = std::str::from_utf8(name).map_err(|_| FileNameError::NotText(name.to_vec()))?;
        let rel = Path::new(text);
        if text.is_empty() || !rel.components().all(|c| matches!(c, Component::Normal(_))) {
            return Err(FileNameError::Escapes(text.to_string()));
        }
        let path = self.root.join(rel);
        // Follow symlinks as far as the path exists: it must stay under the root. A link counts
        // as existing even when it dangles (opening would follow it); one that cannot be
        // resolved cannot be shown to stay inside.
        let mut probe = path.clone();
        while probe.symlink_metadata().is_err() {
            match probe.parent() {
                Some(p) => probe = p.to_path_buf(),
                None => break,
            }
        }
        match probe.canonicalize() {
            Ok(real) if real.starts_with(&self.root) => Ok(path),
            _ => Err(FileNameError::Symlink(text.to_string())),
        }
    }

    /// Handles a THREAD file message; returns the messages to send back and a log line.
    pub fn handle(&mut self, t: &Thread) -> (Vec<Message>, Option<String>) {
        match t {
            Thread::Open { mode, name, file } => {
                let shown = String::from_utf8_lossy(name).into_owned();
                let opened = self
                    .resolve(name)
                    .map_err(|e| e.to_string())
                    .and_then(|path| {
                        match mode {
                            FileMode::Read => File::open(&path),
                            FileMode::Write => {
                                if let Some(dir) = path.parent() {
                                    std::fs::create_dir_all(dir).ok();
                                }
                                File::create(&path)
                            }
                        }
                        .map_err(|e| format!("{}: {e}", path.display()))
                    });
                match opened {
                    Ok(f) => {
                        self.files.insert(*file, f);
                        (
                            vec![Message::Msg(MsgCode::NO_ERROR)],
                            Some(format!("file {file}: opened `{shown}` ({mode:?})")),
                        )
                    }
                    Err(e) => (
                        vec![Message::Msg(MsgCode::FILE_ERROR)],
                        Some(format!("file {file}: refused: {e}")),
                    ),
                }
            }
            Thread::Close { file } => {
                let closed = self.files.remove(file).map(|f| f.sync_all());
                (
                    Vec::new(),
                    Some(format!(
                        "file {file}: closed{}",
                        if closed.is_none() {
                            " (was not open)"
                        } else {
                            ""
                        }
                    )),
                )
            }
            Thread::Write { data, file } => {
                match self.files.get_mut(file).map(|f| f.write_all(data)) {
                    Some(Ok(())) => (Vec::new(), None),
                    Some(Err(e)) => (
                        vec![Message::Msg(MsgCode::FILE_ERROR)],
                        Some(format!("file {file}: write failed: {e}")),
                    ),
                    None => (
                        vec![Message::Msg(MsgCode::FILE_ERROR)],
                        Some(format!("file {file}: write to a file that is not open")),
                    ),
                }
            }
            Thread::ReadRequest { len, file } => {
                let mut buf = vec![0u8; *len as usize];
                match self.files.get_mut(file).map(|f| f.read(&mut buf)) {
                    Some(Ok(n)) => {
                        buf.truncate(n);
                        (
                            vec![Message::Thread(Thread::ReadData {
                                data: buf,
                                file: *file,
                            })],
                            None,
                        )
                    }
                    _ => (
                        vec![Message::Msg(MsgCode::FILE_ERROR)],
                        Some(format!("file {file}: read failed")),
                    ),
                }
            }
            _ => (Vec::new(), None),
        }
    }
}

/// Turns `FA`/`FB` traffic into CSV rows `t_s,source,channel,value,volts`.
pub struct Recorder<W: Write> {
    out: W,
    layout: Option<AdConfig>,
    table: LogTable,
    scans: u64,
    started: Instant,
    pub frames: u64,
    pub samples: u64,
}

impl<W: Write> Recorder<W> {
    pub fn new(mut out: W) -> io::Result<Self> {
        writeln!(out, "t_s,source,channel,value,volts")?;
        Ok(Self {
            out,
            layout: None,
            table: LogTable::default(),
            scans: 0,
            started: Instant::now(),
            frames: 0,
            samples: 0,
        })
    }

    /// Feeds a message; returns whether it was a sample.
    pub fn record(&mut self, m: &Message) -> io::Result<bool> {
        match m {
            Message::CfgAd { c196, .. } => {
                self.layout = AdConfig::parse(c196).ok();
                self.scans = 0;
                Ok(false)
            }
            Message::AdCont(data) => {
                let Some(cfg) = &self.layout else {
                    return Ok(false);
                };
                self.frames += 1;
                for scan in decode_frame(cfg, data, &self.table) {
                    self.scans += 1;
                    let t = self.scans as f64 * cfg.period_ns() as f64 * 1e-9;
                    for (ch, v) in scan {
                        self.samples += 1;
                        writeln!(self.out, "{t:.6},c196,{ch},{v},{:.4}", code10_to_volts(v))?;
                    }
                }
                Ok(true)
            }
            Message::AdSample(s) => {
                let t = self.started.elapsed().as_secs_f64();
                self.samples += 1;
                match *s {
                    AdSample::Pic { channel, value } => writeln!(
                        self.out,
                        "{t:.6},pic,{channel},{value},{:.4}",
                        code10_to_volts(value as f64)
                    )?,
                    AdSample::Virtual { channel, value } => {
                        writeln!(self.out, "{t:.6},virtual,{channel},{value},")?
                    }
                }
                Ok(true)
            }
            _ => Ok(false),
        }
    }

    /// Expands log8 samples through this table (the board's, see [`Client::log_table`]).
    pub fn set_log_table(&mut self, table: LogTable) {
        self.table = table;
    }

    pub fn finish(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_service_stays_inside_its_folder() {
        let dir = tempfile::tempdir().unwrap();
        let outside = tempfile::tempdir().unwrap();
        std::os::unix::fs::symlink(outside.path(), dir.path().join("out")).unwrap();
        let fs = FileService::new(dir.path()).unwrap();
        assert!(fs.resolve(b"log.txt").is_ok());
        assert!(fs.resolve(b"sub/log.txt").is_ok());
        for bad in [
            &b"../x"[..],
            b"/etc/passwd",
            b"a/../../x",
            b"",
            b"./x/../..",
        ] {
            assert!(
                matches!(fs.resolve(bad), Err(FileNameError::Escapes(_))),
                "{bad:?}"
            );
        }
        assert!(matches!(
            fs.resolve(b"out/x"),
            Err(FileNameError::Symlink(_))
        ));
        // A dangling link: File::create would follow it and make the file outside.
        std::os::unix::fs::symlink(outside.path().join("new"), dir.path().join("dangling"))
            .unwrap();
        for bad in [&b"dangling"[..], b"dangling/x"] {
            assert!(
                matches!(fs.resolve(bad), Err(FileNameError::Symlink(_))),
                "{bad:?}"
            );
        }
        assert!(matches!(
            fs.resolve(&[0xFF, 0xFE]),
            Err(FileNameError::NotText(_))
        ));
    }

    /// A board that never stops talking: a watchdog `FF 00` on every read.
    struct Chatty;

    impl Port for Chatty {
        fn send(&mut self, _bytes: &[u8]) -> io::Result<()> {
            Ok(())
        }
        fn recv(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            std::thread::sleep(Duration::from_millis(1));
            buf[..2].copy_from_slice(&[0xFF, 0x00]);
            Ok(2)
        }
    }

    #[test]
    fn a_reply_that_never_comes_times_out_even_while_the_board_streams() {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut c = Client::new(Chatty, 115_200);
            c.timeout = Duration::from_millis(100);
            let _ = tx.send(c.info().map(|_| ()).map_err(|e| e.to_string()));
        });
        let result = rx
            .recv_timeout(Duration::from_secs(10))
            .expect("info() still waiting after 10 s with a 100 ms time-out");
        assert!(
            result.as_ref().is_err_and(|e| e.contains("no answer")),
            "{result:?}"
        );
    }

    #[test]
    fn file_service_writes_and_reads() {
        let dir = tempfile::tempdir().unwrap();
        let mut fs = FileService::new(dir.path()).unwrap();
        let (r, _) = fs.handle(&Thread::Open {
            mode: FileMode::Write,
            name: b"a.txt".to_vec(),
            file: 1,
        });
        assert_eq!(r, vec![Message::Msg(MsgCode::NO_ERROR)]);
        fs.handle(&Thread::Write {
            data: b"hello".to_vec(),
            file: 1,
        });
        fs.handle(&Thread::Close { file: 1 });
        assert_eq!(std::fs::read(dir.path().join("a.txt")).unwrap(), b"hello");
        fs.handle(&Thread::Open {
            mode: FileMode::Read,
            name: b"a.txt".to_vec(),
            file: 2,
        });
        let (r, _) = fs.handle(&Thread::ReadRequest { len: 3, file: 2 });
        assert_eq!(
            r,
            vec![Message::Thread(Thread::ReadData {
                data: b"hel".to_vec(),
                file: 2
            })]
        );
        let (r, _) = fs.handle(&Thread::Open {
            mode: FileMode::Write,
            name: b"../evil".to_vec(),
            file: 3,
        });
        assert_eq!(r, vec![Message::Msg(MsgCode::FILE_ERROR)]);
        assert!(!dir.path().parent().unwrap().join("evil").exists());
    }
}
