//! `buslab mail`: the mail notifier (seed 002 §5.4.5, JerryCAN's `MailWatcher`). It polls an
//! IMAP mailbox every `--interval` (`mailsleepingtime`); each mail that arrives while it runs
//! is announced with a remote frame on `--id` (`idmail`); MoniCAN shows `you've got mail !`,
//! and when the user presses Ctrl R it answers with a remote frame on the same ID: then the
//! mail (sender, subject, text) goes with the file protocol.
//!
//! The password comes from `BUSLAB_MAIL_PASSWORD` or a prompt, never from the command line
//! (the seed's `MailWatcher user password` shows it to `ps`).

use std::sync::atomic::Ordering;
use std::sync::mpsc::{self, Receiver, Sender};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_can::Id;
use buslab_canbus::Filter;
use buslab_mail::{Announcer, mail_text};

use super::busopt::{BusOpt, open};
use crate::units::Human;

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub bus: BusOpt,
    /// The IMAP server, HOST[:PORT] (default: `mail.host` and `mail.port` of buslab.toml;
    /// port 143 unless given; 993 is TLS).
    #[arg(long, value_name = "HOST[:PORT]")]
    pub imap: Option<String>,
    /// The IMAP user (default: `mail.user`; the password: $BUSLAB_MAIL_PASSWORD or a prompt).
    #[arg(long)]
    pub user: Option<String>,
    /// auto: TLS on port 993, else STARTTLS when the server offers it, else plain; tls,
    /// starttls: required; plain: never.
    #[arg(long, value_enum, default_value_t = TlsMode::Auto)]
    pub tls: TlsMode,
    /// The mailbox watched.
    #[arg(long, default_value = "INBOX")]
    pub mailbox: String,
    /// How often the mailbox is polled (JerryCAN's `mailsleepingtime`), with a unit
    /// (default: `mail.interval`, 60 s).
    #[arg(long, value_name = "DURATION", value_parser = crate::units::duration)]
    pub interval: Option<Duration>,
    /// The identifier mail is announced and sent on (JerryCAN's `idmail`; MoniCAN's
    /// `--mail-id`; hex with 0x, or decimal).
    #[arg(long, value_name = "ID", default_value_t = crate::config::get().mail_id, value_parser = super::monican::parse_id)]
    pub id: u16,
    /// Bytes of a mail sent at most (MoniCAN keeps 2048 by default); a longer mail is cut
    /// and says how much was left out.
    #[arg(long, value_name = "BYTES", default_value_t = buslab_monican::DEFAULT_MAIL_LIMIT as u32, value_parser = clap::value_parser!(u32).range(64..=65536))]
    pub limit: u32,
    /// Stop once this many mails were delivered (scripts and tests); default: run until
    /// Ctrl-C.
    #[arg(long, value_name = "N")]
    pub count: Option<usize>,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum TlsMode {
    Auto,
    Tls,
    Starttls,
    Plain,
}

/// What the IMAP thread reports.
enum Polled {
    /// The first look: the mails already there (not announced).
    Watching {
        existing: usize,
    },
    Mail(Vec<u8>),
    Failed(String),
}

struct Imap {
    host: String,
    port: u16,
    user: String,
    password: String,
    mode: TlsMode,
    mailbox: String,
    limit: usize,
}

impl Imap {
    fn session(&self) -> anyhow::Result<imap::Session<imap::Connection>> {
        let mode = match self.mode {
            TlsMode::Auto => imap::ConnectionMode::Auto,
            TlsMode::Tls => imap::ConnectionMode::Tls,
            TlsMode::Starttls => imap::ConnectionMode::StartTls,
            TlsMode::Plain => imap::ConnectionMode::Plaintext,
        };
        let client = imap::ClientBuilder::new(&self.host, self.port)
            .mode(mode)
            .connect()
            .with_context(|| format!("cannot reach the IMAP server {}:{}", self.host, self.port))?;
        let mut session = client
            .login(&self.user, &self.password)
            .map_err(|(e, _)| e)
            .with_context(|| format!("IMAP login as {:?} refused", self.user))?;
        session
            .select(&self.mailbox)
            .with_context(|| format!("cannot open the mailbox {:?}", self.mailbox))?;
        Ok(session)
    }

    /// Mails with a UID above `after`, as MoniCAN texts (left unread: BODY.PEEK), the
    /// highest UID seen and how many mails the mailbox holds.
    fn poll(&self, after: Option<u32>) -> anyhow::Result<(Vec<Vec<u8>>, u32, usize)> {
        let mut session = self.session()?;
        let mut uids: Vec<u32> = session.uid_search("ALL")?.into_iter().collect();
        uids.sort_unstable();
        let highest = uids.last().copied().unwrap_or(0);
        let count = uids.len();
        let mut texts = Vec::new();
        if let Some(after) = after {
            for uid in uids.into_iter().filter(|&u| u > after) {
                let fetches = session.uid_fetch(uid.to_string(), "BODY.PEEK[]")?;
                for fetch in fetches.iter() {
                    if let Some(body) = fetch.body() {
                        texts.push(mail_text(body, self.limit));
                    }
                }
            }
            let _ = session.logout();
            return Ok((texts, highest.max(after), count));
        }
        let _ = session.logout();
        Ok((texts, highest, count))
    }

    /// Polls every `interval` until the receiver goes away.
    fn run(self, interval: Duration, tx: Sender<Polled>) {
        let mut after: Option<u32> = None;
        loop {
            match self.poll(after) {
                Ok((texts, highest, existing)) => {
                    if after.is_none() {
                        let _ = tx.send(Polled::Watching { existing });
                    }
                    after = Some(highest);
                    for text in texts {
                        if tx.send(Polled::Mail(text)).is_err() {
                            return;
                        }
                    }
                }
                Err(e) => {
                    if tx.send(Polled::Failed(format!("{e:#}"))).is_err() {
                        return;
                    }
                }
            }
            std::thread::sleep(interval);
        }
    }
}

/// The password: `$BUSLAB_MAIL_PASSWORD`, else a prompt on the terminal.
fn password(host: &str, user: &str) -> anyhow::Result<String> {
    let mut settings = crate::config::get().mail.clone();
    settings.host = Some(host.to_string());
    settings.user = Some(user.to_string());
    let password = crate::config::password_or_prompt(&settings)?;
    Ok(password.expose().to_string())
}

fn host_port(text: &str, default_port: u16) -> anyhow::Result<(String, u16)> {
    match text.rsplit_once(':') {
        Some((host, port)) if !host.contains(':') || host.starts_with('[') => {
            let port = port
                .parse()
                .with_context(|| format!("--imap {text:?}: the port must be 1..65535"))?;
            Ok((host.trim_matches(['[', ']']).to_string(), port))
        }
        _ => Ok((text.to_string(), default_port)),
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let settings = &crate::config::get().mail;
    let (host, port) = match (&args.imap, &settings.host) {
        (Some(imap), _) => host_port(imap, settings.port)?,
        (None, Some(host)) => (host.clone(), settings.port),
        (None, None) => bail!("no IMAP server: --imap HOST[:PORT], or mail.host in buslab.toml"),
    };
    let Some(user) = args.user.clone().or_else(|| settings.user.clone()) else {
        bail!("no IMAP user: --user NAME, or mail.user in buslab.toml");
    };
    let interval = args.interval.unwrap_or(settings.interval);
    let imap = Imap {
        password: password(&host, &user)?,
        host: host.clone(),
        port,
        user: user.clone(),
        mode: args.tls,
        mailbox: args.mailbox.clone(),
        limit: args.limit as usize,
    };
    let stop = super::interrupted()?;
    let url = &args.bus.bus;
    let mut bus = open(url)?;
    bus.set_filters(&[Filter::standard(args.id)])?;
    let id = Id::standard(args.id).context("the mail identifier")?;
    let mut announcer = Announcer::new(id);
    let (tx, polled): (Sender<Polled>, Receiver<Polled>) = mpsc::channel();
    std::thread::Builder::new()
        .name("imap-poll".into())
        .spawn(move || imap.run(interval, tx))?;
    let mut watching = false;
    let mut next_reminder = Instant::now() + interval;
    loop {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        if args.count.is_some_and(|n| announcer.delivered() >= n) {
            break;
        }
        while let Ok(event) = polled.try_recv() {
            match event {
                Polled::Watching { existing } => {
                    watching = true;
                    eprintln!(
                        "watching {} of {user} on {host}:{port} every {} ({existing} mails there; new ones are announced on ID {:03X})",
                        args.mailbox,
                        Human(interval),
                        args.id
                    );
                }
                Polled::Mail(text) => {
                    tracing::info!("new mail ({} bytes): announced on the bus", text.len());
                    announcer.push_mail(text);
                }
                Polled::Failed(e) if !watching => bail!("{e}"),
                Polled::Failed(e) => tracing::warn!("{e}; trying again in {}", Human(interval)),
            }
        }
        if Instant::now() >= next_reminder {
            announcer.remind();
            next_reminder = Instant::now() + interval;
        }
        while let Some(frame) = announcer.poll_transmit() {
            bus.send(&frame)?;
        }
        if let Some(message) = bus.recv(Some(Duration::from_millis(100)))? {
            let before = announcer.delivered();
            announcer.handle_frame(&message.frame);
            if announcer.delivered() > before {
                eprintln!(
                    "mail {} asked for and sent ({} waiting)",
                    announcer.delivered(),
                    announcer.waiting()
                );
            }
        }
    }
    // The last mail's frames leave before the node does.
    while let Some(frame) = announcer.poll_transmit() {
        bus.send(&frame)?;
    }
    if let Some(admin) = bus.admin() {
        let _ = admin.flush(Duration::from_secs(10));
    }
    Ok(())
}
