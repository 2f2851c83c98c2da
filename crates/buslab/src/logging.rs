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
    /// Fewer log lines: errors only (RUST_LOG overrides); `sim` prints only its summary,
    /// `lab` no status line.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
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
