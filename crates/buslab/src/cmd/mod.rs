//! One module per subcommand.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use anyhow::Context;

pub mod absent;
pub mod bridge;
pub mod bus;
pub mod busopt;
pub mod config;
pub mod cpu196;
pub mod dbc;
pub mod dump;
pub mod r#gen;
pub mod lab;
pub mod load;
pub mod log;
#[cfg(not(feature = "mail"))]
pub use absent::mail;
#[cfg(feature = "mail")]
pub mod mail;
pub mod monican;
#[cfg(not(feature = "tui"))]
pub use absent::monitor;
#[cfg(feature = "tui")]
pub mod monitor;
pub mod play;
pub mod plot;
pub mod recvfile;
pub mod regs;
pub mod send;
pub mod sendfile;
pub mod sim;
pub mod slcan;
pub mod slio;
pub mod status;
pub mod transfer;
#[cfg(not(feature = "web"))]
pub use absent::web;
#[cfg(feature = "web")]
pub mod web;
pub mod wire;
pub mod zelle;

/// A flag set by Ctrl-C, SIGTERM or SIGHUP, so a long-running command stops as cleanly for
/// each of them: writers finish, nothing read or acknowledged is lost. Safe to call more than
/// once (each call registers one more flag).
pub fn interrupted() -> anyhow::Result<Arc<AtomicBool>> {
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [
        signal_hook::consts::SIGINT,
        signal_hook::consts::SIGTERM,
        signal_hook::consts::SIGHUP,
    ] {
        signal_hook::flag::register(signal, stop.clone())
            .with_context(|| format!("cannot handle signal {signal}"))?;
    }
    Ok(stop)
}

/// A channel that hears Ctrl-C (SIGINT), SIGTERM and SIGHUP, for commands that wait on it.
pub fn stop_requests() -> anyhow::Result<std::sync::mpsc::Receiver<()>> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])
        .context("cannot handle termination signals")?;
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for _ in signals.forever() {
            if tx.send(()).is_err() {
                break;
            }
        }
    });
    Ok(rx)
}

/// Makes a file-size limit (`ulimit -f`, RLIMIT_FSIZE) fail the write that crosses it with
/// EFBIG, which a log writer reports like a full disk, instead of letting SIGXFSZ kill the
/// process (its default) with the file unfinished.
pub fn file_size_limit_as_error() -> anyhow::Result<()> {
    // A handler that only sets a flag nobody reads: the signal no longer kills.
    let ignored = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGXFSZ, ignored)
        .context("cannot handle SIGXFSZ")?;
    Ok(())
}
