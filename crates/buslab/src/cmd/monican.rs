//! `buslab monican --bus URL`: MoniCAN in the user's terminal, driving SLIOs on any bus.
//!
//! The same sans-IO application as on the PowerPC node ([`buslab_monican::MoniCan`]): this
//! adapter owns the terminal (raw mode and the alternate screen, restored on every way out),
//! the bus, and the wall clock. Keys go to MoniCAN as the bytes the terminal sends; Ctrl-Q or
//! Ctrl-C quit (SIGTERM, SIGINT and SIGHUP too).

use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_backends::DynBus;
use buslab_can::Nanos;
use buslab_canbus::slio::{SingleShot, send_single_shot};
use buslab_monican::{Config, MoniCan, Transmit};

use super::busopt::{self, BusOpt};
use crate::terminal::{Cursor, RawScreen, read_keys};
use crate::units::Human;

/// Keys that leave `buslab monican` (MoniCAN itself gives them no meaning).
const CTRL_C: u8 = 0x03;
const CTRL_Q: u8 = 0x11;

/// The longest the loop waits for a frame before looking at keys and signals again.
const SLICE: Duration = Duration::from_millis(20);
/// How long a calibration frame may wait to reach the wire on a buslab bus before MoniCAN
/// gives it up unsent (one on the wire without an acknowledgement is aborted at once).
const SINGLE_SHOT_WITHIN: Duration = Duration::from_secs(2);

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub bus: BusOpt,
    /// The bus's bit rate, when the bus cannot tell (a buslab bus tells): the calibration
    /// frames go every 5000 bit-times.
    #[arg(long, default_value_t = 125_000)]
    pub bitrate: u32,
    /// The 11-bit identifier a supervisor's mail arrives on (hex with 0x, or decimal).
    #[arg(long, value_name = "ID", default_value = "0x700", value_parser = parse_id)]
    pub mail_id: u16,
}

/// A protocol identifier option (`--mail-id`, `--id`): hex with 0x, or decimal, within CAN
/// 2.0A's range as `buslab.toml` takes them.
pub fn parse_id(text: &str) -> Result<u16, String> {
    buslab_can::StandardId::parse_protocol_id(text)
        .map(|id| id.as_raw())
        .map_err(|e| e.to_string())
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if !std::io::stdin().is_terminal() || !std::io::stdout().is_terminal() {
        bail!("buslab monican needs a terminal (its keys and its VT100 screen)");
    }
    let mut bus = busopt::open(&args.bus.bus)?;
    let bitrate = match bus.admin() {
        Some(admin) => {
            let _ = admin.set_name("monican");
            admin.node_status(None)?.bus.bitrate
        }
        None => args.bitrate,
    };
    let config = Config {
        bitrate,
        mail_id: args.mail_id,
        ..Config::default()
    };
    config.validate()?;
    let quit = super::interrupted()?;
    let terminal = RawScreen::enter(Cursor::Shown)?;
    let keys = read_keys();
    let result = session(&mut bus, config, &keys, &quit);
    drop(terminal);
    result
}

fn session(
    bus: &mut DynBus,
    config: Config,
    keys: &Receiver<Vec<u8>>,
    quit: &AtomicBool,
) -> anyhow::Result<()> {
    let epoch = Instant::now();
    let now = || Nanos::from_duration(epoch.elapsed());
    let bitrate = config.bitrate;
    let mut app = MoniCan::new(config, now())?;
    if let Ok((cols, rows)) = crossterm::terminal::size()
        && (cols < 80 || rows < 24)
    {
        app.set_notice(format!(
            "this terminal is {cols} x {rows}; MoniCAN needs 80 x 24"
        ));
    }
    let mut stdout = std::io::stdout();
    while !quit.load(Ordering::Relaxed) {
        loop {
            match keys.try_recv() {
                Ok(bytes) => {
                    for byte in bytes {
                        if byte == CTRL_Q || byte == CTRL_C {
                            return Ok(());
                        }
                        app.handle_key(now(), byte);
                    }
                }
                Err(TryRecvError::Empty) => break,
                // The terminal is gone.
                Err(TryRecvError::Disconnected) => return Ok(()),
            }
        }
        if app.next_deadline().is_some_and(|t| t <= now()) {
            app.handle_timeout(now());
        }
        let mut start_up = false;
        while let Some(t) = app.poll_transmit(now()) {
            send(bus, t, bitrate)?;
            start_up |= t.single_shot;
        }
        if start_up {
            app.start_up_sent(now());
        }
        let screen = app.take_screen();
        if !screen.is_empty() {
            stdout.write_all(&screen)?;
            stdout.flush()?;
        }
        let wait = app
            .next_deadline()
            .map_or(SLICE, |t| t.saturating_sub(now()).as_duration())
            .min(SLICE);
        let mut timeout = wait;
        while let Some(message) = bus.recv(Some(timeout)).context("receiving from the bus")? {
            app.handle_frame(now(), &message.record);
            // Take what already arrived, then look at keys and timers again.
            timeout = Duration::ZERO;
        }
    }
    Ok(())
}

/// Sends MoniCAN's frames. A single-shot frame (calibration) is tried once
/// ([`send_single_shot`]: on a buslab bus, aborted once on the wire without an
/// acknowledgement, the seed's CMR.AT), so an unacknowledged frame never holds up the next
/// ones. Other backends just send: their adapters retry until a SLIO acknowledges.
fn send(bus: &mut DynBus, t: Transmit, bitrate: u32) -> anyhow::Result<()> {
    if !t.single_shot {
        return bus
            .send(&t.frame)
            .with_context(|| format!("cannot send {}", t.frame));
    }
    let outcome = send_single_shot(&mut **bus, &t.frame, bitrate, SINGLE_SHOT_WITHIN)
        .with_context(|| format!("cannot send {}", t.frame))?;
    if outcome == SingleShot::NotTried {
        tracing::debug!(
            "calibration frame not on the wire within {}: given up",
            Human(SINGLE_SHOT_WITHIN)
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mail_ids_parse_in_hex_or_decimal() {
        assert_eq!(parse_id("0x700"), Ok(0x700));
        assert_eq!(parse_id("1792"), Ok(0x700));
        assert_eq!(parse_id("0"), Ok(0));
        // The range buslab.toml takes: CAN 2.0A's.
        assert_eq!(parse_id("0x7EF"), Ok(0x7EF));
        for bad in ["0x7F0", "0x800", "mail", "0x", "", "+5", "0x+f", "-1"] {
            let e = parse_id(bad).unwrap_err();
            assert!(e.contains("0x000..=0x7EF"), "{bad}: {e}");
        }
    }
}
