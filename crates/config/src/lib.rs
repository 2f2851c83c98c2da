//! `buslab.toml`, the configuration file (JerryCAN's `jerrycan.properties`, seed 002 §5.4.1):
//! the default bus, the log file, the loader's and the mail notifier's identifiers, the mail
//! server, the MQTT broker's credentials, the manager's polling interval and the SJA1000
//! controller (docs/config.md).
//!
//! Every value comes from one of four places, each overriding the one before: the built-in
//! default, the configuration file, an environment variable `BUSLAB_<KEY>` and `--set KEY=VALUE`
//! on the command line. [`load`] reads them and says where each value came from;
//! [`load_text`] does the same from a file's text already read (what the fuzz target feeds).
//! The binary keeps what needs a process or a terminal: the configuration loaded once for the
//! whole run, the password prompt, the wizard and `config show`'s printing.

pub mod duration;
pub mod filter;
mod keys;
mod lookup;
mod render;
mod value;

use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Duration;

use buslab_backends::BusUrl;
use buslab_canbus::{ControllerSettings, ManagerConfig, Sja1000Config};

pub use keys::{DEFAULT_BUS_BITRATE, FilterKind, KEYS, Key, MODE_NAMES, SECRET_KEYS, Settings};
pub use lookup::{Found, Lookup, load, load_text};
pub use render::{registers, render_file, render_show};
pub use value::{Raw, integer_text};

/// The largest configuration file read (a hand-written file is a few hundred bytes).
pub const MAX_FILE_BYTES: u64 = 64 * 1024;
/// The file's name in the current directory and in the user's configuration directory.
pub const FILE_NAME: &str = "buslab.toml";
/// The environment variable naming the configuration file.
pub const ENV_FILE: &str = "BUSLAB_CONFIG";
/// The environment variable holding the mailbox's password (never in the file or on the
/// command line, where `ps` would show it).
pub const ENV_MAIL_PASSWORD: &str = "BUSLAB_MAIL_PASSWORD";

/// The effective configuration, every value checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// The bus a command uses when none is given (`--bus`, IFACE).
    pub bus: BusUrl,
    /// The bus as written (`vcan0`, `can0`, a URL): what `--bus` shows as its default.
    pub bus_name: String,
    /// The log `buslab dump -w` writes (JerryCAN's `logfile`); `~/` is the home folder.
    pub log_file: Option<PathBuf>,
    /// The identifier of the loader handshake's remote frame (JerryCAN's `idloader`).
    pub loader_id: u16,
    /// The identifier the mail notifier announces mail on (JerryCAN's `idmail`).
    pub mail_id: u16,
    pub mail: MailSettings,
    /// The user name and password `mqtt://` buses log in with (`[mqtt]`, the environment
    /// overriding the file; never `--set`), and where they were read.
    pub mqtt_credentials: Option<buslab_backends::mqtt::Credentials>,
    /// How long the host library's manager pauses between polls of the chip when no request
    /// arrives (JerryCAN's `managersleepingtime`; zero polls without pause).
    pub manager_poll_interval: Duration,
    /// The SJA1000 configuration (JerryCAN's configuration assistant), validated.
    pub controller: Sja1000Config,
    /// The parts of it that were given, as commands apply them to their own node when they
    /// open a bus (the others stay as the bus or the adapter has them).
    pub controller_settings: ControllerSettings,
}

/// The mail server the notifier polls.
#[derive(Clone, Debug, PartialEq)]
pub struct MailSettings {
    /// The IMAP server's host name (JerryCAN's `host`); none configured by default.
    pub host: Option<String>,
    /// The IMAP server's port. Default 143.
    pub port: u16,
    pub user: Option<String>,
    /// From `$BUSLAB_MAIL_PASSWORD` only; the binary's `password_or_prompt` asks for it
    /// otherwise. Never printed.
    pub password: Option<Password>,
    /// How often the mailbox is checked (JerryCAN's `mailsleepingtime`). Default 60 s.
    pub interval: Duration,
}

/// A password: shown as `********` by `Debug`, read with [`Password::expose`].
#[derive(Clone, PartialEq, Eq)]
pub struct Password(String);

impl Password {
    pub fn new(text: impl Into<String>) -> Self {
        Self(text.into())
    }

    /// The password itself, for the code that logs in.
    pub fn expose(&self) -> &str {
        &self.0
    }
}

impl fmt::Debug for Password {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Password(********)")
    }
}

impl Config {
    /// The bit rate the controller configuration sets, if it sets one (its timing and
    /// crystal).
    pub fn controller_bitrate(&self) -> Option<u32> {
        self.controller_settings.timing.map(|t| t.bitrate())
    }

    /// The host library's manager as configured: `Manager::start(driver,
    /// config.manager_config())`.
    pub fn manager_config(&self) -> ManagerConfig {
        ManagerConfig {
            poll_interval: self.manager_poll_interval,
            ..ManagerConfig::default()
        }
    }
}

impl Default for Config {
    fn default() -> Self {
        Settings::default()
            .finish(&keys::Sources::defaults())
            .expect("the defaults are valid")
    }
}

/// Where a value came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Source {
    Default,
    /// A line of a configuration file.
    File {
        path: PathBuf,
        line: usize,
    },
    /// An environment variable.
    Env(String),
    /// `--set KEY=VALUE`.
    CommandLine,
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Source::Default => f.write_str("default"),
            Source::File { path, line } => write!(f, "{}:{line}", path.display()),
            Source::Env(var) => write!(f, "environment {var}"),
            Source::CommandLine => f.write_str("--set"),
        }
    }
}

/// The configuration, the file it was read from, and where each value came from.
#[derive(Clone, Debug)]
pub struct Loaded {
    pub config: Config,
    /// The typed values per key, as the wizard edits them.
    pub settings: Settings,
    /// The file read, and how it was found; `None` when there is none.
    pub file: Option<(PathBuf, Found)>,
    sources: keys::Sources,
}

impl Loaded {
    /// Where `key` (`mail.host`) got its value.
    pub fn source(&self, key: &str) -> Option<&Source> {
        keys::index(key).map(|i| self.sources.get(i))
    }
}

/// A configuration that cannot be used; the message names where the value came from (file
/// and line, environment variable or command line), the key, the value and what is allowed.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("{origin}: {key} = {value}: {allowed}")]
    Value {
        origin: Source,
        key: &'static str,
        value: String,
        allowed: String,
    },
    #[error("{origin}: unknown key {key}{hint}")]
    UnknownKey {
        origin: Source,
        key: String,
        /// ` (did you mean mail.host?)`, or empty.
        hint: String,
    },
    #[error("{}:{line}:{column}: {message}", path.display())]
    Syntax {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
    #[error(
        "{origin}: the mail password is never read from a file or the command line: set $BUSLAB_MAIL_PASSWORD, or let the command ask for it"
    )]
    PasswordNotHere { origin: Source },
    #[error(
        "--set {0}: the MQTT user name and password are never taken from the command line (ps shows it to every user): put them under [mqtt] in the configuration file, or set $BUSLAB_MQTT_USERNAME and $BUSLAB_MQTT_PASSWORD"
    )]
    SecretOnCommandLine(&'static str),
    #[error("--set {0:?}: expected KEY=VALUE, e.g. --set mail.interval=30s")]
    SetSyntax(String),
    #[error("configuration file {} ({found}): {source}", path.display())]
    Read {
        path: PathBuf,
        found: Found,
        #[source]
        source: buslab_fs::ReadError,
    },
    /// Two keys that cannot be given together.
    #[error("{first} ({first_source}) and {second} ({second_source}) {problem}")]
    Conflict {
        first: &'static str,
        first_source: Source,
        second: &'static str,
        second_source: Source,
        problem: &'static str,
    },
}

/// `~/x` → the home folder's `x`; anything else as it is.
fn expand_home(text: &str) -> PathBuf {
    match (text.strip_prefix("~/"), dirs::home_dir()) {
        (Some(rest), Some(home)) => home.join(rest),
        _ => Path::new(text).to_path_buf(),
    }
}

#[cfg(test)]
mod tests;
