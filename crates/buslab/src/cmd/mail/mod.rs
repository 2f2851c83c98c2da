//! `buslab mail`: the mail notifier (seed 002 §5.4.5, JerryCAN's `MailWatcher`). It polls an
//! IMAP mailbox every `--interval` (`mailsleepingtime`); each mail that arrives while it runs
//! is announced with a remote frame on `--id` (`idmail`); MoniCAN shows `you've got mail !`,
//! and when the user presses Ctrl R it answers with a remote frame on the same ID: then the
//! mail (sender, subject, text) goes with the file protocol.
//!
//! The password comes from `BUSLAB_MAIL_PASSWORD` or a prompt, never from the command line
//! (the seed's `MailWatcher user password` shows it to `ps`).
//!
//! `poller` owns the IMAP connection (TCP, `tls`, the clock) around the sans-IO look of
//! `buslab_mail::imap`; this module owns the bus.

mod poller;
mod tls;

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, LazyLock};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_can::Id;
use buslab_canbus::Filter;
use buslab_mail::Announcer;

use super::busopt::{BusOpt, open};
use crate::units::Human;
use poller::{Account, Polled, Server, TlsMode};

/// `--id`'s default (the configuration's `mail_id`), in hex as help shows identifiers.
static DEFAULT_ID: LazyLock<String> =
    LazyLock::new(|| crate::units::hex_id(crate::config::get().mail_id));

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
    /// auto: TLS from the start on port 993, else STARTTLS, required (a server that does not
    /// offer it is an error: nothing is sent); tls: TLS from the start; starttls: STARTTLS,
    /// required; plain: no TLS, the password in clear text.
    #[arg(long, value_enum, default_value_t = TlsMode::Auto)]
    pub tls: TlsMode,
    /// Trust only the certificates of this PEM file (the server's own CA, a self-signed
    /// server); default: the system's ($SSL_CERT_FILE and $SSL_CERT_DIR are honoured).
    #[arg(long, value_name = "PATH")]
    pub ca_file: Option<PathBuf>,
    /// Each step of a look (connecting, the TLS handshake, each IMAP command) must be done
    /// within this; a server that takes longer is warned about and tried again later.
    #[arg(long, value_name = "DURATION", default_value = "30s", value_parser = crate::units::duration)]
    pub timeout: Duration,
    /// The mailbox watched.
    #[arg(long, default_value = "INBOX")]
    pub mailbox: String,
    /// How often the mailbox is polled (JerryCAN's `mailsleepingtime`), with a unit
    /// (default: `mail.interval`, 60 s).
    #[arg(long, value_name = "DURATION", value_parser = crate::units::duration)]
    pub interval: Option<Duration>,
    /// The identifier mail is announced and sent on (JerryCAN's `idmail`; MoniCAN's
    /// `--mail-id`; hex with 0x, or decimal).
    #[arg(long, value_name = "ID", default_value = DEFAULT_ID.as_str(), value_parser = super::monican::parse_id)]
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
    if args.timeout.is_zero() {
        bail!("--timeout 0: give a duration above zero (e.g. 30s)");
    }
    if args.tls == TlsMode::Plain && args.ca_file.is_some() {
        bail!("--ca-file with --tls plain: there is no certificate to check without TLS");
    }
    let server = Server {
        tls: match args.tls {
            TlsMode::Plain => None,
            _ => Some(tls::client_config(args.ca_file.as_deref())?),
        },
        host: host.clone(),
        port,
        mode: args.tls,
        timeout: args.timeout,
    };
    if args.tls == TlsMode::Plain {
        tracing::warn!(
            "--tls plain: the password goes to {host}:{port} in clear text at every look"
        );
    }
    let account = Account {
        password: password(&host, &user)?,
        user: user.clone(),
        mailbox: args.mailbox.clone(),
        text_limit: args.limit as usize,
    };
    let stop = super::interrupted()?;
    let url = &args.bus.bus;
    let mut bus = open(url)?;
    bus.set_filters(&[Filter::standard(args.id)])?;
    let id = Id::standard(args.id).context("the mail identifier")?;
    let mut announcer = Announcer::new(id);
    let (tx, polled): (Sender<Polled>, Receiver<Polled>) = mpsc::channel();
    let queued = Arc::new(AtomicUsize::new(0));
    let poller_queued = queued.clone();
    std::thread::Builder::new()
        .name("imap-poll".into())
        .spawn(move || poller::run(server, account, interval, poller_queued, tx))?;
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
                Polled::Renumbered => tracing::warn!(
                    "the server renumbered the mailbox {} (UIDVALIDITY changed): its mails are taken as seen, new ones from now on are announced",
                    args.mailbox
                ),
                Polled::Failed { error, first, .. } if first => {
                    return Err(error.context(format!("IMAP server {host}:{port}")));
                }
                Polled::Failed {
                    error, retry_in, ..
                } => tracing::warn!(
                    "IMAP server {host}:{port}: {error:#}; trying again in {}",
                    Human(retry_in)
                ),
                Polled::Recovered { failures } => eprintln!(
                    "the IMAP server {host}:{port} answers again (after {failures} failed looks)"
                ),
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
            announcer.handle_frame(&message.record);
            if announcer.delivered() > before {
                queued.fetch_sub(1, Ordering::SeqCst);
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
