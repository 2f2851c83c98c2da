//! The monitor session of the original PC program: keeps the link alive with watchdog pings,
//! shows what the board sends, answers its file requests, records samples, and notices when
//! the board falls silent. Output is text for the caller to print.

use std::fmt::Write as _;
use std::io;
use std::time::Duration;

use super::{Client, ClientError, Port, Recorder, SampleSink};
use crate::adconfig::{AdConfigError, AdRefusal};
use crate::codes::MsgCode;
use crate::message::{Message, Start, Thread};

/// How often the monitor pings the board (its watchdog, when on, stops a silent PC's run after
/// 3 s).
pub const PING_EVERY: Duration = Duration::from_millis(500);

/// After this long without a word from the board (which sends a watchdog every second when
/// idle) the monitor reports it lost.
pub const LOST_AFTER: Duration = Duration::from_secs(3);

/// Serves a board's file requests (THREAD `40/41/18/10/20`); where the files live is the
/// host's business.
pub trait FileRequests {
    /// Handles one THREAD file message: the messages to send back and a line for the log.
    fn handle(&mut self, request: &Thread) -> (Vec<Message>, Option<String>);
}

/// What ended a monitor session.
#[derive(Debug, thiserror::Error)]
pub enum MonitorError {
    #[error(transparent)]
    Client(#[from] ClientError),
    #[error("recording samples: {0}")]
    Record(#[source] io::Error),
}

/// One monitor session (see the module docs).
pub struct Monitor<S: SampleSink> {
    files: Option<Box<dyn FileRequests>>,
    recorder: Option<Recorder<S>>,
    last_ping: Option<Duration>,
    last_heard: Duration,
    lost: bool,
    /// A THREAD display without a newline left the line open.
    mid_line: bool,
}

impl<S: SampleSink> Monitor<S> {
    /// A session that answers file requests with `files` (refuses them without) and records
    /// samples with `recorder`; `now` is the client's clock.
    pub fn new(
        files: Option<Box<dyn FileRequests>>,
        recorder: Option<Recorder<S>>,
        now: Duration,
    ) -> Self {
        Self {
            files,
            recorder,
            last_ping: None,
            last_heard: now,
            lost: false,
            mid_line: false,
        }
    }

    /// STARTs `start`; returns the START performed. A set whose 80C196 A/D has no conversion
    /// sequence is started with the A/D off instead, so starting any set just works (the
    /// caller sees it in the START returned). What the program says from its start comes with
    /// the next turns.
    pub fn start<P: Port>(
        &mut self,
        c: &mut Client<P>,
        start: Start,
    ) -> Result<Start, MonitorError> {
        match c.start(start) {
            Err(ClientError::AdConfig {
                why: Some(AdRefusal::Config(AdConfigError::EmptySequence(_))),
                ..
            }) if start.ad196() => {
                let without = Start::run(start.bank(), start.config(), false);
                c.start(without)?;
                Ok(without)
            }
            other => {
                other?;
                Ok(start)
            }
        }
    }

    /// One turn: a watchdog ping if one is due, then the next message (waiting at most
    /// `wait`), shown, recorded and answered. Reports the board lost after [`LOST_AFTER`] of
    /// silence, and back when it speaks again.
    pub fn turn<P: Port>(
        &mut self,
        c: &mut Client<P>,
        wait: Duration,
        out: &mut String,
    ) -> Result<(), MonitorError> {
        let now = c.now();
        if self
            .last_ping
            .is_none_or(|t| now.saturating_sub(t) >= PING_EVERY)
        {
            c.send(&Message::Watchdog)?;
            self.last_ping = Some(now);
        }
        match c.next(wait)? {
            Some(m) => {
                self.last_heard = c.now();
                if self.lost {
                    out.push_str("board is back\n");
                    self.lost = false;
                }
                self.handle(c, &m, out)?;
            }
            None if !self.lost && c.now().saturating_sub(self.last_heard) > LOST_AFTER => {
                self.close_line(out);
                let _ = writeln!(
                    out,
                    "board lost: nothing heard for {}",
                    buslab_device::Human(LOST_AFTER)
                );
                self.lost = true;
            }
            None => {}
        }
        Ok(())
    }

    /// STOPs the run and shows the program's last words (closing files, say).
    pub fn stop<P: Port>(
        &mut self,
        c: &mut Client<P>,
        out: &mut String,
    ) -> Result<(), MonitorError> {
        c.stop()?;
        for m in c.take_backlog() {
            self.handle(c, &m, out)?;
        }
        self.close_line(out);
        Ok(())
    }

    /// Whether the board is reported lost now.
    pub fn board_lost(&self) -> bool {
        self.lost
    }

    /// Ends the session: the recorder's sink (flushed), frames and samples recorded.
    pub fn finish(self) -> io::Result<Option<(S, u64, u64)>> {
        match self.recorder {
            Some(r) => {
                let (frames, samples) = (r.frames, r.samples);
                Ok(Some((r.finish()?, frames, samples)))
            }
            None => Ok(None),
        }
    }

    fn handle<P: Port>(
        &mut self,
        c: &mut Client<P>,
        m: &Message,
        out: &mut String,
    ) -> Result<(), MonitorError> {
        if let Some(r) = self.recorder.as_mut() {
            r.record(m, c.now()).map_err(MonitorError::Record)?;
        }
        for reply in self.show(m, out) {
            c.send(&reply)?;
        }
        Ok(())
    }

    fn close_line(&mut self, out: &mut String) {
        if self.mid_line {
            out.push('\n');
            self.mid_line = false;
        }
    }

    /// Shows one board message the way the monitor does; returns the replies to send.
    fn show(&mut self, m: &Message, out: &mut String) -> Vec<Message> {
        if let Message::Thread(Thread::Display {
            format,
            newline,
            data,
        }) = m
        {
            // Displays without the newline bit continue the same line, as on the seed's monitor.
            let prefix = if self.mid_line { "" } else { "THREAD: " };
            let _ = write!(out, "{prefix}{}", format.render(data));
            if *newline {
                out.push('\n');
            }
            self.mid_line = !*newline;
            return Vec::new();
        }
        if !matches!(
            m,
            Message::Watchdog | Message::AdCont(_) | Message::AdSample(_)
        ) {
            self.close_line(out);
        }
        match m {
            Message::Thread(t) => match &mut self.files {
                Some(files) => {
                    let (replies, log) = files.handle(t);
                    if let Some(l) = log {
                        let _ = writeln!(out, "FILE: {l}");
                    }
                    replies
                }
                None => {
                    let _ = writeln!(out, "FILE: request refused (no --files DIR): {t:?}");
                    vec![Message::Msg(MsgCode::FILE_ERROR)]
                }
            },
            Message::Alert(a) => {
                let _ = writeln!(out, "ALERT: {a}");
                Vec::new()
            }
            Message::Msg(code) => {
                let _ = writeln!(out, "MSG: {code}");
                Vec::new()
            }
            Message::Power(p) => {
                let _ = writeln!(out, "POWER: {p:?}");
                Vec::new()
            }
            Message::Bridge(b) => {
                let _ = writeln!(out, "BRIDGE: {b:?}");
                Vec::new()
            }
            _ => Vec::new(),
        }
    }
}
