//! One module per subcommand.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context;

pub mod bridge;
pub mod bus;
pub mod busopt;
pub mod config;
pub mod cpu196;
pub mod dump;
pub mod r#gen;
pub mod lab;
pub mod load;
pub mod log;
pub mod mail;
pub mod monican;
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
pub mod web;
pub mod wire;
pub mod zelle;

/// A flag set by Ctrl-C, SIGTERM or SIGHUP, so a long-running command stops as cleanly for
/// each of them.
pub fn interrupted() -> anyhow::Result<Arc<AtomicBool>> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst))
        .context("cannot install the Ctrl-C handler")?;
    Ok(stop)
}
