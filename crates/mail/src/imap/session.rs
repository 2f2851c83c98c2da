//! One look at the mailbox, as a sans-IO IMAP client: bytes from the server and the time in,
//! bytes to send, "start TLS now" and the outcome out, and the instant by which the server must
//! have answered. The adapter owns the socket, TLS and the clock.
//!
//! The conversation: greeting → (CAPABILITY) → STARTTLS → [TLS] → LOGIN → EXAMINE (read-only:
//! nothing the user sees changes) → `UID SEARCH UID n:*` → `UID FETCH` of at most
//! [`PollConfig::fetch_at_most`] new mails, each only its first
//! [`super::fetch_bytes`] bytes (`BODY.PEEK[]<0.N>`: left unread) → LOGOUT.
//!
//! Every response goes through the [`Framer`] (caps on lines, literals, nesting and size)
//! before imap-codec parses it; each step must be answered within [`PollConfig::timeout`]
//! and in at most [`PollConfig::response_limit`] bytes.

use std::collections::{BTreeMap, VecDeque};
use std::fmt;
use std::time::{Duration, Instant};

use imap_codec::decode::Decoder;
use imap_codec::imap_types::fetch::MessageDataItem;
use imap_codec::imap_types::response::{Code, Data, Greeting, GreetingKind, Response, Status};
use imap_codec::{GreetingCodec, ResponseCodec};
use thiserror::Error;

use super::command::{Command, Unsendable};
use super::framer::{FrameError, Framer, Limits};
use crate::mail_text;

/// How the connection is protected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Security {
    /// TLS from the first byte (the adapter did the handshake).
    Tls,
    /// Clear text until STARTTLS, which the server must offer: nothing else is sent before.
    StartTls,
    /// Clear text throughout, the user's explicit choice.
    Plain,
}

/// Where the mailbox stood at the last look: mails with a higher UID are new.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Watermark {
    /// The mailbox's UIDVALIDITY: when it changes, UIDs were renumbered.
    pub uid_validity: Option<u32>,
    pub last_uid: u32,
}

/// What one look needs.
#[derive(Clone, Debug)]
pub struct PollConfig {
    pub user: String,
    pub password: String,
    pub mailbox: String,
    pub security: Security,
    /// The last look's watermark; `None` at the first look (nothing is fetched then).
    pub known: Option<Watermark>,
    /// New mails fetched at most (the others wait for the next look).
    pub fetch_at_most: usize,
    /// Bytes of a mail's text at most (`buslab mail --limit`).
    pub text_limit: usize,
    /// Each step (the greeting, each command) must be answered within this.
    pub timeout: Duration,
    pub limits: Limits,
    /// Bytes of all the responses to one command at most.
    pub response_limit: usize,
}

/// What a look found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Outcome {
    pub watermark: Watermark,
    /// Mails in the mailbox.
    pub existing: u32,
    /// New mails, oldest first, as MoniCAN's texts.
    pub mails: Vec<Vec<u8>>,
    /// More new mails wait than were fetched.
    pub more: bool,
    /// The mailbox's UIDs were renumbered since the last look (UIDVALIDITY changed): the
    /// watermark starts again from the mails there now, none of them announced.
    pub renumbered: bool,
}

/// What the adapter must do.
#[derive(Debug, PartialEq, Eq)]
pub enum Event {
    /// Start the TLS handshake now, before sending or reading anything else; then call
    /// [`Poll::tls_started`].
    StartTls,
    /// The look is complete (LOGOUT is queued; its answer does not matter).
    Done(Outcome),
}

/// A step of the conversation: what the server is expected to answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    Greeting,
    Capability,
    StartTls,
    Handshake,
    Login,
    Examine,
    LastUid,
    Search,
    Fetch,
    Done,
}

impl fmt::Display for Step {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Step::Greeting => "its greeting",
            Step::Capability => "the answer to CAPABILITY",
            Step::StartTls => "the answer to STARTTLS",
            Step::Handshake => "the TLS handshake",
            Step::Login => "the answer to LOGIN",
            Step::Examine => "the answer to EXAMINE",
            Step::LastUid => "the answer to FETCH",
            Step::Search => "the answer to UID SEARCH",
            Step::Fetch => "the answer to UID FETCH",
            Step::Done => "nothing",
        })
    }
}

/// Why a look failed. The connection is to be dropped.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum PollError {
    #[error("the server sent {error} (in {step})")]
    Refused { step: Step, error: FrameError },
    #[error("{step} exceeded {limit} bytes")]
    ResponseTooLarge { step: Step, limit: usize },
    #[error("the server sent something that is not IMAP (in {step}): \"{excerpt}\"")]
    NotImap { step: Step, excerpt: String },
    #[error("the server sent nothing for {timeout:?} (waiting for {step})")]
    Silent { step: Step, timeout: Duration },
    #[error("the server did not finish {step} within {timeout:?} ({received} bytes received)")]
    Unfinished {
        step: Step,
        timeout: Duration,
        received: usize,
    },
    #[error("the server closed the connection (waiting for {step})")]
    Closed { step: Step },
    #[error("the server ended the session (in {step}): {text}")]
    Bye { step: Step, text: String },
    #[error("the server does not offer STARTTLS: logging in would send the password in clear text")]
    NoStartTls,
    #[error("the server refused STARTTLS: {text}")]
    StartTlsRefused { text: String },
    #[error(
        "the server sent data after agreeing to STARTTLS, before the TLS handshake (refused: it would be taken as protected)"
    )]
    StartTlsInjection,
    #[error(
        "the server answered {step} before it was sent (a reply made up in advance, refused: it could stand for STARTTLS's or LOGIN's)"
    )]
    AnsweredBeforeAsked { step: Step },
    #[error("the server logged the connection in (PREAUTH) in clear text, before STARTTLS")]
    PreauthInClear,
    #[error("login as {user:?} refused: {text}")]
    LoginRefused { user: String, text: String },
    #[error("cannot open the mailbox {mailbox:?}: {text}")]
    MailboxRefused { mailbox: String, text: String },
    #[error("{step} is a refusal: {text}")]
    CommandRefused { step: Step, text: String },
    #[error(transparent)]
    Unsendable(#[from] Unsendable),
}

/// A tagged completion.
enum Completion {
    Ok,
    /// NO or BAD, with the server's text.
    Refused(String),
}

/// One look at the mailbox.
#[derive(Debug)]
pub struct Poll {
    config: PollConfig,
    framer: Framer,
    step: Step,
    tag: u32,
    /// Parts of the current command waiting for the server's `+`.
    pending: VecDeque<Vec<u8>>,
    transmit: VecDeque<Vec<u8>>,
    events: VecDeque<Event>,
    step_started: Instant,
    step_received: usize,
    capabilities: Vec<String>,
    exists: u32,
    uid_next: Option<u32>,
    uid_validity: Option<u32>,
    last_uid: u32,
    /// The new UIDs found, then the ones fetched.
    wanted: Vec<u32>,
    more: bool,
    texts: BTreeMap<u32, Vec<u8>>,
}

impl Poll {
    /// A look on a connection just opened (and, for [`Security::Tls`], handshaken) at `now`.
    pub fn new(config: PollConfig, now: Instant) -> Self {
        Self {
            framer: Framer::new(config.limits),
            config,
            step: Step::Greeting,
            tag: 0,
            pending: VecDeque::new(),
            transmit: VecDeque::new(),
            events: VecDeque::new(),
            step_started: now,
            step_received: 0,
            capabilities: Vec::new(),
            exists: 0,
            uid_next: None,
            uid_validity: None,
            last_uid: 0,
            wanted: Vec::new(),
            more: false,
            texts: BTreeMap::new(),
        }
    }

    pub fn step(&self) -> Step {
        self.step
    }

    /// Bytes from the server.
    pub fn handle_input(&mut self, data: &[u8], now: Instant) -> Result<(), PollError> {
        if self.step == Step::Done {
            return Ok(());
        }
        if self.step == Step::Handshake {
            return Err(PollError::StartTlsInjection);
        }
        self.step_received = self.step_received.saturating_add(data.len());
        if self.step_received > self.config.response_limit {
            return Err(PollError::ResponseTooLarge {
                step: self.step,
                limit: self.config.response_limit,
            });
        }
        let step = self.step;
        self.framer
            .push(data)
            .map_err(|error| PollError::Refused { step, error })?;
        while let Some(message) = self.framer.next_message() {
            self.handle_message(&message, now)?;
            if self.step == Step::Done {
                break;
            }
            if self.step == Step::Handshake && !self.framer.is_empty() {
                return Err(PollError::StartTlsInjection);
            }
        }
        Ok(())
    }

    /// The server closed the connection (end of stream).
    pub fn handle_eof(&mut self) -> Result<(), PollError> {
        match self.step {
            Step::Done => Ok(()),
            step => Err(PollError::Closed { step }),
        }
    }

    /// The TLS handshake asked for by [`Event::StartTls`] succeeded at `now`.
    pub fn tls_started(&mut self, now: Instant) -> Result<(), PollError> {
        debug_assert_eq!(self.step, Step::Handshake);
        // What the server said in clear text is forgotten (RFC 3501 §6.2.1).
        self.capabilities.clear();
        self.login(now)
    }

    /// The instant by which the server must have answered the current step.
    pub fn deadline(&self) -> Option<Instant> {
        (self.step != Step::Done).then(|| self.step_started + self.config.timeout)
    }

    /// The time is `now`: fails if the deadline passed.
    pub fn handle_timeout(&mut self, now: Instant) -> Result<(), PollError> {
        match self.deadline() {
            Some(deadline) if now >= deadline => {
                let (step, timeout) = (self.step, self.config.timeout);
                Err(if self.step_received == 0 {
                    PollError::Silent { step, timeout }
                } else {
                    PollError::Unfinished {
                        step,
                        timeout,
                        received: self.step_received,
                    }
                })
            }
            _ => Ok(()),
        }
    }

    /// Bytes to send to the server.
    pub fn poll_transmit(&mut self) -> Option<Vec<u8>> {
        self.transmit.pop_front()
    }

    pub fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    fn send(&mut self, step: Step, command: Command, now: Instant) {
        let mut parts = VecDeque::from(command.finish());
        self.transmit
            .push_back(parts.pop_front().expect("a command has a part"));
        self.pending = parts;
        self.step = step;
        self.step_started = now;
        self.step_received = 0;
    }

    fn command(&mut self, words: &str) -> Command {
        self.tag += 1;
        Command::new(&self.tag(), words)
    }

    fn tag(&self) -> String {
        format!("b{}", self.tag)
    }

    fn not_imap(&self, message: &[u8]) -> PollError {
        let end = message.len().min(80);
        PollError::NotImap {
            step: self.step,
            excerpt: message[..end].trim_ascii_end().escape_ascii().to_string(),
        }
    }

    fn handle_message(&mut self, message: &[u8], now: Instant) -> Result<(), PollError> {
        if self.step == Step::Greeting {
            return match GreetingCodec::default().decode(message) {
                Ok((&[], greeting)) => self.greeted(greeting, now),
                _ => Err(self.not_imap(message)),
            };
        }
        let response = match ResponseCodec::default().decode(message) {
            Ok((&[], response)) => response,
            _ => return self.undecoded(message, now),
        };
        match response {
            Response::CommandContinuationRequest(_) => {
                // The server takes the literal announced; a `+` not asked for is ignored.
                if let Some(part) = self.pending.pop_front() {
                    self.transmit.push_back(part);
                }
                Ok(())
            }
            Response::Data(data) => {
                self.data(data);
                Ok(())
            }
            Response::Status(status) => match status {
                Status::Bye { text, .. } => Err(PollError::Bye {
                    step: self.step,
                    text: text.inner().to_string(),
                }),
                Status::Ok {
                    tag: None, code, ..
                } => {
                    if let Some(code) = code {
                        self.code(code);
                    }
                    Ok(())
                }
                Status::No { tag: None, .. } | Status::Bad { tag: None, .. } => Ok(()),
                Status::Ok { tag: Some(tag), .. } => {
                    self.check_tag(tag.inner(), message)?;
                    self.completed(Completion::Ok, now)
                }
                Status::No {
                    tag: Some(tag),
                    text,
                    ..
                }
                | Status::Bad {
                    tag: Some(tag),
                    text,
                    ..
                } => {
                    self.check_tag(tag.inner(), message)?;
                    self.completed(Completion::Refused(text.inner().to_string()), now)
                }
            },
        }
    }

    /// A response imap-codec does not know (an extension, a server's quirk): an untagged one
    /// is skipped, our tag's completion is still read; anything else is not IMAP.
    fn undecoded(&mut self, message: &[u8], now: Instant) -> Result<(), PollError> {
        if message.starts_with(b"* ") {
            return Ok(());
        }
        let tag = self.tag();
        let rest = message
            .strip_prefix(tag.as_bytes())
            .and_then(|r| r.strip_prefix(b" "));
        let Some(rest) = rest else {
            return Err(self.not_imap(message));
        };
        let word: Vec<u8> = rest
            .iter()
            .take_while(|b| b.is_ascii_alphabetic())
            .map(u8::to_ascii_uppercase)
            .collect();
        let text = || String::from_utf8_lossy(rest).trim_end().to_string();
        match word.as_slice() {
            b"OK" => self.completed(Completion::Ok, now),
            b"NO" | b"BAD" => self.completed(Completion::Refused(text()), now),
            _ => Err(self.not_imap(message)),
        }
    }

    fn check_tag(&self, tag: &str, message: &[u8]) -> Result<(), PollError> {
        if tag == self.tag() {
            Ok(())
        } else {
            Err(self.not_imap(message))
        }
    }

    fn greeted(&mut self, greeting: Greeting, now: Instant) -> Result<(), PollError> {
        if let Some(code) = greeting.code {
            self.code(code);
        }
        match greeting.kind {
            GreetingKind::Bye => Err(PollError::Bye {
                step: Step::Greeting,
                text: greeting.text.inner().to_string(),
            }),
            GreetingKind::PreAuth if self.config.security == Security::StartTls => {
                Err(PollError::PreauthInClear)
            }
            GreetingKind::PreAuth => self.examine(now),
            GreetingKind::Ok => match self.config.security {
                Security::StartTls if self.capabilities.is_empty() => {
                    let command = self.command("CAPABILITY");
                    self.send(Step::Capability, command, now);
                    Ok(())
                }
                Security::StartTls => self.start_tls(now),
                Security::Tls | Security::Plain => self.login(now),
            },
        }
    }

    fn start_tls(&mut self, now: Instant) -> Result<(), PollError> {
        if !self.has_capability("STARTTLS") {
            return Err(PollError::NoStartTls);
        }
        let command = self.command("STARTTLS");
        self.send(Step::StartTls, command, now);
        Ok(())
    }

    fn has_capability(&self, name: &str) -> bool {
        self.capabilities
            .iter()
            .any(|c| c.eq_ignore_ascii_case(name))
    }

    fn login(&mut self, now: Instant) -> Result<(), PollError> {
        let command = self
            .command("LOGIN")
            .string(&self.config.user, "the user name")?
            .string(&self.config.password, "the password")?;
        self.send(Step::Login, command, now);
        Ok(())
    }

    fn examine(&mut self, now: Instant) -> Result<(), PollError> {
        let command = self
            .command("EXAMINE")
            .string(&self.config.mailbox, "the mailbox name")?;
        self.send(Step::Examine, command, now);
        Ok(())
    }

    fn code(&mut self, code: Code) {
        match code {
            Code::Capability(list) => {
                self.capabilities = list.as_ref().iter().map(|c| c.to_string()).collect();
            }
            Code::UidNext(n) => self.uid_next = Some(n.get()),
            Code::UidValidity(n) => self.uid_validity = Some(n.get()),
            _ => {}
        }
    }

    fn data(&mut self, data: Data) {
        match data {
            Data::Capability(list) => {
                self.capabilities = list.as_ref().iter().map(|c| c.to_string()).collect();
            }
            Data::Exists(n) if self.step == Step::Examine => self.exists = n,
            Data::Search(uids) if self.step == Step::Search => {
                let after = self.watermark_in().last_uid;
                self.wanted
                    .extend(uids.iter().map(|u| u.get()).filter(|&u| u > after));
                // Only the oldest ones are fetched: at most one more is kept, to know there
                // are more (however many SEARCH lines a server sends).
                let keep = self.config.fetch_at_most + 1;
                if self.wanted.len() > 2 * keep {
                    self.wanted.sort_unstable();
                    self.wanted.dedup();
                    self.wanted.truncate(keep);
                }
            }
            Data::Fetch { items, .. } if matches!(self.step, Step::LastUid | Step::Fetch) => {
                self.fetched(items.as_ref());
            }
            _ => {}
        }
    }

    /// A FETCH response: the last UID (while finding it), or a wanted mail.
    fn fetched(&mut self, items: &[MessageDataItem]) {
        let uid = items.iter().find_map(|i| match i {
            MessageDataItem::Uid(uid) => Some(uid.get()),
            _ => None,
        });
        let Some(uid) = uid else { return };
        if self.step == Step::LastUid {
            self.last_uid = self.last_uid.max(uid);
            return;
        }
        if !self.wanted.contains(&uid) {
            return;
        }
        let size = items.iter().find_map(|i| match i {
            MessageDataItem::Rfc822Size(size) => Some(u64::from(*size)),
            _ => None,
        });
        let body = items.iter().find_map(|i| match i {
            MessageDataItem::BodyExt {
                section: None,
                data,
                ..
            } => Some(data.0.as_ref().map(|s| s.as_ref()).unwrap_or(b"")),
            _ => None,
        });
        if let Some(body) = body {
            let size = size.unwrap_or(body.len() as u64);
            self.texts
                .insert(uid, mail_text(body, size, self.config.text_limit));
        }
    }

    /// The watermark this look started from (at the first look: none yet).
    fn watermark_in(&self) -> Watermark {
        self.config.known.unwrap_or(Watermark {
            uid_validity: None,
            last_uid: 0,
        })
    }

    fn completed(&mut self, completion: Completion, now: Instant) -> Result<(), PollError> {
        let step = self.step;
        // The command (or its literal) is still waiting to go out: whatever the server says
        // about it now was written before it could know it.
        if !self.transmit.is_empty() || !self.pending.is_empty() {
            return Err(PollError::AnsweredBeforeAsked { step });
        }
        if let Completion::Refused(text) = completion {
            return Err(match step {
                Step::StartTls => PollError::StartTlsRefused { text },
                Step::Login => PollError::LoginRefused {
                    user: self.config.user.clone(),
                    text,
                },
                Step::Examine => PollError::MailboxRefused {
                    mailbox: self.config.mailbox.clone(),
                    text,
                },
                step => PollError::CommandRefused { step, text },
            });
        }
        match step {
            Step::Capability => self.start_tls(now),
            Step::StartTls => {
                self.step = Step::Handshake;
                self.step_started = now;
                self.step_received = 0;
                self.events.push_back(Event::StartTls);
                Ok(())
            }
            Step::Login => self.examine(now),
            Step::Examine => {
                self.examined(now);
                Ok(())
            }
            Step::LastUid => {
                self.finish(now, self.last_uid);
                Ok(())
            }
            Step::Search => {
                self.search_done(now);
                Ok(())
            }
            Step::Fetch => {
                let last = self.wanted.last().copied().unwrap_or(0);
                self.finish(now, last.max(self.watermark_in().last_uid));
                Ok(())
            }
            Step::Greeting | Step::Handshake | Step::Done => Ok(()),
        }
    }

    /// UIDVALIDITY changed since the last look.
    fn renumbered(&self) -> bool {
        matches!(
            (self.config.known, self.uid_validity),
            (Some(Watermark { uid_validity: Some(was), .. }), Some(is)) if was != is
        )
    }

    fn examined(&mut self, now: Instant) {
        if self.config.known.is_none() || self.renumbered() {
            // Mails there now are not new: the watermark is the highest UID.
            if let Some(next) = self.uid_next {
                self.finish(now, next - 1);
            } else if self.exists == 0 {
                self.finish(now, 0);
            } else {
                let command = self.command(&format!("FETCH {} (UID)", self.exists));
                self.send(Step::LastUid, command, now);
            }
            return;
        }
        let after = self.watermark_in().last_uid;
        if self.config.fetch_at_most == 0 || after == u32::MAX {
            self.finish(now, after);
            return;
        }
        let command = self.command(&format!("UID SEARCH UID {}:*", after + 1));
        self.send(Step::Search, command, now);
    }

    fn search_done(&mut self, now: Instant) {
        self.wanted.sort_unstable();
        self.wanted.dedup();
        let after = self.watermark_in().last_uid;
        if self.wanted.is_empty() {
            self.finish(now, after);
            return;
        }
        self.more = self.wanted.len() > self.config.fetch_at_most;
        self.wanted.truncate(self.config.fetch_at_most);
        let set: Vec<String> = self.wanted.iter().map(u32::to_string).collect();
        let command = self.command(&format!(
            "UID FETCH {} (UID RFC822.SIZE BODY.PEEK[]<0.{}>)",
            set.join(","),
            super::fetch_bytes(self.config.text_limit)
        ));
        self.send(Step::Fetch, command, now);
    }

    fn finish(&mut self, now: Instant, last_uid: u32) {
        let renumbered = self.renumbered();
        let outcome = Outcome {
            watermark: Watermark {
                uid_validity: self.uid_validity,
                last_uid,
            },
            existing: self.exists,
            mails: std::mem::take(&mut self.texts).into_values().collect(),
            more: self.more,
            renumbered,
        };
        let command = self.command("LOGOUT");
        self.send(Step::Done, command, now);
        self.events.push_back(Event::Done(outcome));
    }
}
