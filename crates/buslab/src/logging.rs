//! Log output: every library and adapter logs through `tracing`; this is where it goes.
//!
//! Warnings and errors are shown by default, on stderr, one line each. `-v` adds what the
//! tools do (connections, devices, state changes), `-vv` details, `-vvv` everything; `-q`
//! keeps errors only. `RUST_LOG` (e.g. `RUST_LOG=buslab_vbus=debug`) overrides both.

use tracing_subscriber::EnvFilter;

/// `-v`/`-q`, on every subcommand.
#[derive(clap::Args, Clone, Copy, Debug, Default)]
pub struct Verbosity {
    /// More log lines on stderr: -v what happens, -vv details, -vvv everything
    /// (RUST_LOG overrides).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    /// Fewer log lines: errors only (RUST_LOG overrides).
    // The commands that also print less say how in their own `-q` help ([`QUIET_HELP`]).
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
}

/// What `-q` does besides the log, for the commands that print less with it: their `-q` help
/// (the global flag's help is one text for every command; [`quiet_help`] puts these in place).
pub const QUIET_HELP: &[(&[&str], &str)] = &[
    (
        &["lab"],
        "Fewer log lines: errors only (RUST_LOG overrides); no status line and no `Ctrl-C to stop` (the banner stays)",
    ),
    (
        &["sim"],
        "Print only the summary, not the trace of frames and errors; errors only in the log (RUST_LOG overrides)",
    ),
    (
        &["log", "convert"],
        "No progress bar and no summary line; errors only in the log (RUST_LOG overrides)",
    ),
    (
        &["play"],
        "No summary line at the end; errors only in the log (RUST_LOG overrides)",
    ),
    (
        &["web"],
        "Fewer log lines: errors only (RUST_LOG overrides); no `Ctrl-C to stop` (the addresses stay)",
    ),
    (
        &["cpu196", "serve"],
        "Fewer log lines: errors only (RUST_LOG overrides); no `Ctrl-C to stop`",
    ),
    (
        &["cpu196", "monitor"],
        "Fewer log lines: errors only (RUST_LOG overrides); no `Ctrl-C to stop`",
    ),
];

/// `command` with each [`QUIET_HELP`] text on its command's `-q`: that command gets its own
/// copy of the global flag (clap then leaves the global one out there, and the value reaches
/// [`Verbosity`] as from the global one). `command` must not be built yet.
pub fn quiet_help(mut command: clap::Command) -> clap::Command {
    fn set(command: clap::Command, path: &[&str], quiet: clap::Arg) -> clap::Command {
        match path {
            [] => command.arg(quiet),
            [first, rest @ ..] => command.mut_subcommand(first, |sub| set(sub, rest, quiet)),
        }
    }
    let global = command
        .get_arguments()
        .find(|a| a.get_id() == "quiet")
        .cloned()
        .expect("the global -q");
    for (path, help) in QUIET_HELP {
        command = set(command, path, global.clone().help(*help));
    }
    command
}

impl Verbosity {
    /// `-q` was given (some commands also print less then, e.g. `sim` only its summary).
    pub fn quiet(&self) -> bool {
        self.quiet
    }

    /// The filter directive these flags ask for; `chatty` commands (servers) show what they
    /// do without `-v`.
    fn directive(&self, chatty: bool) -> &'static str {
        match (self.quiet, self.verbose + chatty as u8) {
            (true, _) => "error",
            (false, 0) => "warn",
            (false, 1) => "info",
            (false, 2) => "debug",
            (false, _) => "trace",
        }
    }
}

/// Installs the subscriber: plain lines on stderr (`WARN …`), no timestamps unless verbose,
/// colour only on a terminal. `chatty`: the command is a server whose routine log (clients,
/// devices) is shown by default.
pub fn init(verbosity: &Verbosity, chatty: bool) {
    let filter = EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| EnvFilter::new(verbosity.directive(chatty)));
    let verbose = verbosity.verbose > 0 || std::env::var_os("RUST_LOG").is_some();
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(crate::status_line::LogWriter)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()));
    // Ignored if a subscriber is already installed (cannot happen in the binary).
    if verbose {
        let _ = builder.with_target(true).try_init();
    } else {
        let _ = builder
            .without_time()
            .with_target(false)
            .with_level(true)
            .try_init();
    }
}
