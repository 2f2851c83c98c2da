//! A status line refreshed in place on stderr (the lab's), and the log lines that must not
//! glue onto it: a log line first erases the status, then the status is drawn again under it.
//!
//! Everything written to stderr while a status is shown goes through [`StatusLine`]'s lock,
//! so a warning from a server thread and the status thread's refresh never interleave. Each
//! update is one write (stderr is unbuffered): a terminal never shows the erased line without
//! what replaces it.

use std::io::{self, Write};
use std::sync::{Mutex, MutexGuard};

use tracing_subscriber::fmt::MakeWriter;

/// Erase the terminal's current line and return to its start.
const ERASE: &str = "\r\x1b[2K";

/// The status shown on stderr now, if any.
static SHOWN: Mutex<Option<String>> = Mutex::new(None);

fn shown() -> MutexGuard<'static, Option<String>> {
    SHOWN.lock().unwrap_or_else(|e| e.into_inner())
}

/// The process's one status line on stderr.
pub struct StatusLine;

impl StatusLine {
    /// Replaces the status shown (a terminal only: the line stays open, without a newline).
    pub fn show(line: &str) -> io::Result<()> {
        let mut shown = shown();
        let mut err = io::stderr().lock();
        err.write_all(format!("{ERASE}{line}").as_bytes())?;
        err.flush()?;
        *shown = Some(line.to_string());
        Ok(())
    }

    /// Takes the status away (log lines plain again).
    pub fn clear() -> io::Result<()> {
        let mut shown = shown();
        if shown.take().is_some() {
            let mut err = io::stderr().lock();
            write!(err, "{ERASE}")?;
            err.flush()?;
        }
        Ok(())
    }

    /// Ends the status: `last` on a line of its own, and log lines plain again.
    pub fn finish(last: &str) -> io::Result<()> {
        let mut shown = shown();
        let mut err = io::stderr().lock();
        let erase = if shown.take().is_some() { ERASE } else { "" };
        err.write_all(format!("{erase}{last}\n").as_bytes())?;
        err.flush()
    }
}

/// The log's writer: stderr, around the status line when one is shown.
#[derive(Clone, Copy, Default)]
pub struct LogWriter;

impl<'a> MakeWriter<'a> for LogWriter {
    type Writer = LogLine;

    fn make_writer(&'a self) -> Self::Writer {
        LogLine(Vec::new())
    }
}

/// One log event's bytes, written out whole when the event is done.
pub struct LogLine(Vec<u8>);

impl Write for LogLine {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Drop for LogLine {
    fn drop(&mut self) {
        if self.0.is_empty() {
            return;
        }
        let shown = shown();
        let mut err = io::stderr().lock();
        // Nothing to do with an error here: stderr is where errors would go.
        let _ = match shown.as_deref() {
            Some(status) => {
                let mut all = Vec::with_capacity(ERASE.len() + self.0.len() + status.len());
                all.extend_from_slice(ERASE.as_bytes());
                all.extend_from_slice(&self.0);
                all.extend_from_slice(status.as_bytes());
                err.write_all(&all)
            }
            None => err.write_all(&self.0),
        };
        let _ = err.flush();
    }
}
