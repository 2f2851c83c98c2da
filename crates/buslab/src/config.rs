//! `buslab.toml` for this process: the parser and the checks are `buslab_config`'s; here the
//! configuration is loaded once before the arguments are parsed ([`init`]) so that options can
//! take their defaults from [`get`]:
//!
//! ```ignore
//! #[arg(long, default_value_t = crate::config::get().loader_id)]
//! pub id: u16,
//! ```
//!
//! and the options that choose the file, and the password prompt, live here too.

use std::path::PathBuf;
use std::sync::{LazyLock, OnceLock};

pub use buslab_config::*;

/// The options that choose the configuration. They come before the subcommand
/// (`buslab --config lab.toml status`): `cpu196 start --config N` is another option.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct ConfigArgs {
    /// Read the configuration from this file (default: $BUSLAB_CONFIG, ./buslab.toml, then
    /// ~/.config/buslab/buslab.toml; docs/config.md). Before the subcommand.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Read no configuration file: the defaults, the environment and --set only.
    #[arg(long, conflicts_with = "config")]
    pub no_config: bool,
    /// Set a configuration key for this run, over the file and the environment
    /// (e.g. --set controller.bitrate=125k: the bit rate of the node this command opens the
    /// bus with; `buslab config show` says which command uses each key); repeatable; before
    /// the subcommand.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

impl From<&ConfigArgs> for Lookup {
    fn from(args: &ConfigArgs) -> Self {
        Self {
            file: args.config.clone(),
            no_file: args.no_config,
            sets: args.set.clone(),
        }
    }
}

/// Why a password could not be had.
#[cfg(feature = "mail")]
#[derive(Debug, thiserror::Error)]
pub enum PromptError {
    #[error("no password: set ${0} or run on a terminal to be asked")]
    NoTerminal(&'static str),
    #[error("no password: {0}")]
    Prompt(String),
}

/// The mailbox's password: from `$BUSLAB_MAIL_PASSWORD`, else asked for on the terminal (not
/// echoed).
#[cfg(feature = "mail")]
pub fn password_or_prompt(mail: &MailSettings) -> Result<Password, PromptError> {
    if let Some(p) = &mail.password {
        return Ok(p.clone());
    }
    if !std::io::IsTerminal::is_terminal(&std::io::stdin()) {
        return Err(PromptError::NoTerminal(ENV_MAIL_PASSWORD));
    }
    let user = mail.user.as_deref().unwrap_or("the mailbox");
    let host = mail.host.as_deref().unwrap_or("the mail server");
    inquire::Password::new(&format!("Password of {user} on {host}:"))
        .without_confirmation()
        .with_display_mode(inquire::PasswordDisplayMode::Hidden)
        .prompt()
        .map(Password::new)
        .map_err(|e| PromptError::Prompt(e.to_string()))
}

static LOADED: OnceLock<Result<Loaded, ConfigError>> = OnceLock::new();
static DEFAULT: LazyLock<Config> = LazyLock::new(Config::default);

/// Loads the configuration for this process (once; later calls return the first result).
pub fn init(lookup: &Lookup) -> &'static Result<Loaded, ConfigError> {
    LOADED.get_or_init(|| {
        let cwd = std::env::current_dir().unwrap_or_else(|_| PathBuf::from("."));
        load(
            lookup,
            &|var| std::env::var(var).ok(),
            &cwd,
            user_file().as_deref(),
        )
    })
}

/// The configuration in effect: what [`init`] loaded, or the defaults if it was not called
/// or failed (the binary then stops with the error before running a command).
pub fn get() -> &'static Config {
    match LOADED.get() {
        Some(Ok(loaded)) => &loaded.config,
        _ => &DEFAULT,
    }
}

/// What [`init`] loaded, if it did.
pub fn loaded() -> Option<&'static Result<Loaded, ConfigError>> {
    LOADED.get()
}

/// `buslab.toml` in the user's configuration directory (`$XDG_CONFIG_HOME/buslab/` or
/// `~/.config/buslab/` on Linux).
pub fn user_file() -> Option<PathBuf> {
    dirs::config_dir().map(|d| d.join("buslab").join(FILE_NAME))
}
