//! The IMAP adapter: a TCP connection (and TLS) per look, driving `buslab_mail::imap::Poll`
//! with the socket and the clock, and the thread that looks every interval, backing off
//! after failures.

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::Sender;
use std::time::{Duration, Instant};

use anyhow::{Context, anyhow, bail};
use buslab_mail::MAX_WAITING;
use buslab_mail::imap::{Event, Limits, Outcome, Poll, PollConfig, PollError, Security, Watermark};
use rustls::ClientConfig;

use super::tls::{self, TlsStream};
use crate::units::Human;

/// Bytes of all the responses to one command at most: 16 new mails of the largest fetch
/// ([`buslab_mail::imap::FETCH_MAX`], 192 KiB) are 3 MiB; a server still talking after 16 MiB
/// is not answering.
pub const RESPONSE_LIMIT: usize = 16 << 20;

/// New mails fetched in one look at most (the others at the next looks).
pub const FETCH_AT_MOST: usize = 16;

/// After failures, the wait grows from one interval, doubling, to at most this many.
pub const BACKOFF_INTERVALS: u32 = 8;

/// How the IMAP connection is protected, as the user chose it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TlsMode {
    /// TLS from the start on port 993, else STARTTLS (required).
    Auto,
    /// TLS from the start (IMAPS).
    Tls,
    /// STARTTLS, required: no login on a server that does not offer it.
    Starttls,
    /// No TLS: the password travels in clear text.
    Plain,
}

/// Where and how to look.
pub struct Server {
    pub host: String,
    pub port: u16,
    pub mode: TlsMode,
    /// The TLS configuration (`None` for `--tls plain`).
    pub tls: Option<Arc<ClientConfig>>,
    /// Each step (connecting, the handshake, each command) within this.
    pub timeout: Duration,
}

impl Server {
    fn implicit_tls(&self) -> bool {
        self.mode == TlsMode::Tls || (self.mode == TlsMode::Auto && self.port == 993)
    }

    fn security(&self) -> Security {
        match self.mode {
            TlsMode::Plain => Security::Plain,
            _ if self.implicit_tls() => Security::Tls,
            _ => Security::StartTls,
        }
    }
}

/// The account and what is made of its mails.
pub struct Account {
    pub user: String,
    pub password: String,
    pub mailbox: String,
    pub text_limit: usize,
}

/// What the poll thread reports.
pub enum Polled {
    /// The first look: the mails already there (not announced).
    Watching {
        existing: u32,
    },
    Mail(Vec<u8>),
    /// UIDVALIDITY changed: the mails there now are taken as seen.
    Renumbered,
    /// A look failed; the next one is in `retry_in`.
    Failed {
        error: anyhow::Error,
        retry_in: Duration,
        first: bool,
    },
    /// A look succeeded after `failures` failed ones.
    Recovered {
        failures: u32,
    },
}

/// The connection of one look.
enum Transport {
    Plain(TcpStream),
    Tls(Box<TlsStream>),
}

impl Transport {
    fn tcp(&self) -> &TcpStream {
        match self {
            Transport::Plain(tcp) => tcp,
            Transport::Tls(tls) => tls.get_ref(),
        }
    }

    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self {
            Transport::Plain(tcp) => tcp.read(buf),
            Transport::Tls(tls) => tls.read(buf),
        }
    }

    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        match self {
            Transport::Plain(tcp) => tcp.write_all(bytes),
            Transport::Tls(tls) => tls.write_all(bytes).and_then(|_| tls.flush()),
        }
    }
}

fn timed_out(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
    )
}

impl Server {
    /// A TCP connection to the first address that answers within the timeout.
    fn connect(&self) -> anyhow::Result<TcpStream> {
        let addrs: Vec<SocketAddr> = (self.host.as_str(), self.port)
            .to_socket_addrs()
            .with_context(|| format!("cannot resolve {}", self.host))?
            .collect();
        let mut last = None;
        for addr in addrs {
            match TcpStream::connect_timeout(&addr, self.timeout) {
                Ok(tcp) => return Ok(tcp),
                Err(e) if timed_out(&e) => {
                    last = Some(anyhow!(
                        "no connection to {addr} within {} (--timeout)",
                        Human(self.timeout)
                    ))
                }
                Err(e) => last = Some(anyhow!(e).context(format!("cannot connect to {addr}"))),
            }
        }
        Err(last.unwrap_or_else(|| anyhow!("{} has no address", self.host)))
    }

    fn handshake(&self, tcp: TcpStream) -> anyhow::Result<Transport> {
        let config = self
            .tls
            .as_ref()
            .expect("TLS is configured unless --tls plain");
        let deadline = Instant::now() + self.timeout;
        let tls = tls::handshake(config, &self.host, tcp, deadline)
            .with_context(|| format!("TLS with {}", self.host))?;
        Ok(Transport::Tls(Box::new(tls)))
    }

    /// One look: connect, log in, find and fetch new mails, log out.
    pub fn look(
        &self,
        account: &Account,
        known: Option<Watermark>,
        fetch_at_most: usize,
    ) -> anyhow::Result<Outcome> {
        let tcp = self.connect()?;
        let _ = tcp.set_nodelay(true);
        let transport = if self.implicit_tls() {
            self.handshake(tcp)?
        } else {
            Transport::Plain(tcp)
        };
        let config = PollConfig {
            user: account.user.clone(),
            password: account.password.clone(),
            mailbox: account.mailbox.clone(),
            security: self.security(),
            known,
            fetch_at_most,
            text_limit: account.text_limit,
            timeout: self.timeout,
            limits: Limits::DEFAULT,
            response_limit: RESPONSE_LIMIT,
        };
        let poll = Poll::new(config, Instant::now());
        self.drive(transport, poll).map_err(|e| self.explain(e))
    }

    /// The session's error with what the user can do about it.
    fn explain(&self, e: anyhow::Error) -> anyhow::Error {
        let hint = match e.downcast_ref::<PollError>() {
            Some(PollError::NoStartTls | PollError::PreauthInClear) => {
                "use --tls tls if it speaks TLS from the start (IMAPS, usually port 993), or --tls plain to log in without TLS (the password in clear text)"
            }
            Some(PollError::Silent { .. } | PollError::Unfinished { .. }) => {
                "--timeout sets how long each step may take"
            }
            _ => return e,
        };
        anyhow!("{e:#}; {hint}")
    }

    fn drive(&self, mut transport: Transport, mut poll: Poll) -> anyhow::Result<Outcome> {
        let mut buf = vec![0u8; 16 * 1024];
        loop {
            while let Some(bytes) = poll.poll_transmit() {
                let left = poll
                    .deadline()
                    .map(|d| d.saturating_duration_since(Instant::now()))
                    .unwrap_or(self.timeout)
                    .max(Duration::from_millis(1));
                transport.tcp().set_write_timeout(Some(left))?;
                if let Err(e) = transport.write_all(&bytes) {
                    if poll.deadline().is_none() {
                        // Only LOGOUT was left to say.
                        break;
                    }
                    return Err(if timed_out(&e) {
                        anyhow!(
                            "the server accepted nothing sent for {} (--timeout)",
                            Human(self.timeout)
                        )
                    } else {
                        anyhow!(e).context("cannot write to the server")
                    });
                }
            }
            let mut upgraded = false;
            while let Some(event) = poll.poll_event() {
                match event {
                    Event::StartTls => {
                        transport = match transport {
                            Transport::Plain(tcp) => self.handshake(tcp)?,
                            Transport::Tls(_) => {
                                bail!("STARTTLS on a connection that has TLS already")
                            }
                        };
                        poll.tls_started(Instant::now())?;
                        upgraded = true;
                    }
                    Event::Done(outcome) => {
                        // LOGOUT goes out if the server takes it; its answer is not awaited.
                        while let Some(bytes) = poll.poll_transmit() {
                            let _ = transport.tcp().set_write_timeout(Some(self.timeout));
                            let _ = transport.write_all(&bytes);
                        }
                        return Ok(outcome);
                    }
                }
            }
            if upgraded {
                // LOGIN goes out first.
                continue;
            }
            let now = Instant::now();
            poll.handle_timeout(now)?;
            let deadline = poll.deadline().expect("a look not done has a deadline");
            let left = deadline
                .saturating_duration_since(now)
                .max(Duration::from_millis(1));
            transport.tcp().set_read_timeout(Some(left))?;
            match transport.read(&mut buf) {
                Ok(0) => poll.handle_eof()?,
                Ok(n) => poll.handle_input(&buf[..n], Instant::now())?,
                Err(e) if timed_out(&e) || e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => poll.handle_eof()?,
                Err(e) => return Err(anyhow!(e).context("cannot read from the server")),
            }
        }
    }
}

/// The wait before the next look after `failures` failed ones in a row.
pub fn backoff(interval: Duration, failures: u32) -> Duration {
    let doubling = 1u32 << failures.saturating_sub(1).min(BACKOFF_INTERVALS.ilog2());
    interval * doubling.min(BACKOFF_INTERVALS)
}

/// Looks every `interval` until the receiver goes away. `queued` counts the mails handed over
/// and not yet read: no more are fetched while [`MAX_WAITING`] wait.
pub fn run(
    server: Server,
    account: Account,
    interval: Duration,
    queued: Arc<AtomicUsize>,
    tx: Sender<Polled>,
) {
    let mut known: Option<Watermark> = None;
    let mut failures = 0u32;
    loop {
        let room = MAX_WAITING.saturating_sub(queued.load(Ordering::SeqCst));
        let fetch_at_most = room.min(FETCH_AT_MOST);
        let mut reports = Vec::new();
        let wait = match server.look(&account, known, fetch_at_most) {
            Ok(outcome) => {
                if known.is_none() {
                    reports.push(Polled::Watching {
                        existing: outcome.existing,
                    });
                }
                if outcome.renumbered {
                    reports.push(Polled::Renumbered);
                }
                if failures > 0 {
                    reports.push(Polled::Recovered { failures });
                    failures = 0;
                }
                if outcome.more {
                    tracing::info!(
                        "more new mails than one look fetches ({fetch_at_most}): the others at the next looks"
                    );
                }
                known = Some(outcome.watermark);
                queued.fetch_add(outcome.mails.len(), Ordering::SeqCst);
                reports.extend(outcome.mails.into_iter().map(Polled::Mail));
                // More new mails than one look takes wait for the next look: a reader takes
                // one mail at a time, and a server that always has more gets no busy loop.
                interval
            }
            Err(error) => {
                failures += 1;
                let retry_in = backoff(interval, failures);
                reports.push(Polled::Failed {
                    error,
                    retry_in,
                    first: known.is_none(),
                });
                retry_in
            }
        };
        for report in reports {
            if tx.send(report).is_err() {
                return;
            }
        }
        std::thread::sleep(wait);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_backoff_doubles_up_to_eight_intervals() {
        let s = Duration::from_secs(1);
        let waits: Vec<u64> = (1..=7).map(|f| backoff(s, f).as_secs()).collect();
        assert_eq!(waits, [1, 2, 4, 8, 8, 8, 8]);
        assert_eq!(backoff(s, u32::MAX), 8 * s);
    }
}
