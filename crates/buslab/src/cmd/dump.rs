//! `buslab dump`: print every frame on a bus like candump; `-l FILE` also writes a candump log.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context;
use buslab_can::Frame;
use buslab_canbus::CanBus;

use super::bus::{BusOpt, open};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub bus: BusOpt,
    /// Also write every frame to this candump log file (`(SEC.USEC) IFACE ID#DATA`).
    #[arg(short = 'l', long = "log", value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// Prefix each line with the absolute time, as `candump -t a`.
    #[arg(short = 't', long)]
    pub timestamps: bool,
    /// Exit after this many frames.
    #[arg(short = 'n', long)]
    pub count: Option<u64>,
    /// Name this client's node on a buslab bus.
    #[arg(long)]
    pub name: Option<String>,
    /// Also show error frames: this node's bus errors, lost arbitrations and state changes
    /// (candump -e).
    #[arg(short = 'e', long)]
    pub errors: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match dump(args) {
        Err(e)
            if e.downcast_ref::<io::Error>()
                .is_some_and(|e| e.kind() == io::ErrorKind::BrokenPipe) =>
        {
            Ok(())
        }
        other => other,
    }
}

fn dump(args: Args) -> anyhow::Result<()> {
    let mut open = open(&args.bus.bus)?;
    if let (Some(name), true) = (&args.name, open.extensions) {
        open.bus.set_name(name)?;
    }
    if args.errors && open.extensions {
        open.bus.set_error_frames(true)?;
    }
    let channel = args.bus.bus.channel().to_string();
    let mut log = match &args.log {
        Some(path) => {
            Some(BufWriter::new(File::create(path).with_context(|| {
                format!("cannot create {}", path.display())
            })?))
        }
        None => None,
    };
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        let _ = ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst));
    }
    let stdout = io::stdout();
    let mut out = stdout.lock();
    let mut printer = Candump::default();
    let mut seen = 0u64;
    while !stop.load(Ordering::SeqCst) && args.count.is_none_or(|n| seen < n) {
        let received = match open.bus.recv_event(Some(Duration::from_millis(100)))? {
            Some(buslab_canbus::BusEvent::Frame(m)) => Some(m),
            Some(buslab_canbus::BusEvent::Error(e)) => {
                let (class, ts) = (e.error.class(), e.timestamp);
                let ts_shown = args.timestamps.then_some(ts);
                printer.error_line(&mut out, ts_shown, &channel, class)?;
                out.flush()?;
                if let Some(log) = &mut log {
                    writeln!(
                        log,
                        "{} {channel} {:08X}#0000000000000000",
                        log_timestamp(ts),
                        ERR_FLAG | class
                    )?;
                    log.flush()?;
                }
                None
            }
            None => None,
        };
        let Some(m) = received else {
            continue;
        };
        seen += 1;
        let ts = args.timestamps.then_some(m.timestamp);
        printer.line(&mut out, ts, &channel, &m.frame)?;
        out.flush()?;
        if let Some(log) = &mut log {
            writeln!(log, "{} {channel} {}", log_timestamp(m.timestamp), m.frame)?;
            log.flush()?;
        }
    }
    Ok(())
}

/// A candump log timestamp, `(%010u.%06u)` as candump writes it (a server's clock may start
/// near 0, and log readers expect the fixed width).
fn log_timestamp(seconds: f64) -> String {
    format!("({:017.6})", seconds.max(0.0))
}

/// The error-frame flag of a SocketCAN ID (as candump logs write error frames).
const ERR_FLAG: u32 = 0x2000_0000;

/// The SocketCAN error classes in words (`linux/can/error.h`).
pub fn error_class_words(class: u32) -> String {
    const NAMES: [(u32, &str); 9] = [
        (0x001, "tx-timeout"),
        (0x002, "lost-arbitration"),
        (0x004, "controller-problem"),
        (0x008, "protocol-violation"),
        (0x010, "transceiver-status"),
        (0x020, "no-acknowledgement"),
        (0x040, "bus-off"),
        (0x080, "bus-error"),
        (0x100, "restarted-after-bus-off"),
    ];
    let words: Vec<&str> = NAMES
        .iter()
        .filter(|(bit, _)| class & bit != 0)
        .map(|(_, name)| *name)
        .collect();
    if words.is_empty() {
        format!("class 0x{class:03X}")
    } else {
        words.join(",")
    }
}

/// ` (SSS.UUUUUU)`: seconds with at least 3 digits, as candump prints `-t a` (absolute) and
/// `-t z` (since the start) times.
fn write_timestamp(out: &mut impl Write, timestamp: Option<f64>) -> io::Result<()> {
    if let Some(t) = timestamp {
        let micros = (t.max(0.0) * 1e6).round() as u64;
        write!(
            out,
            " ({:03}.{:06})",
            micros / 1_000_000,
            micros % 1_000_000
        )?;
    }
    Ok(())
}

/// candump's terminal layout: once an extended frame was seen, standard IDs are indented to
/// eight columns.
#[derive(Default)]
pub struct Candump {
    extended_seen: bool,
}

impl Candump {
    pub fn line(
        &mut self,
        out: &mut impl Write,
        timestamp: Option<f64>,
        channel: &str,
        frame: &Frame,
    ) -> io::Result<()> {
        self.extended_seen |= frame.is_extended();
        write_timestamp(out, timestamp)?;
        // Once an extended ID was shown, standard IDs keep their 3 digits, right-aligned in 8.
        let id = frame.id().to_string();
        let id = if self.extended_seen && !frame.is_extended() {
            format!("{id:>8}")
        } else {
            id
        };
        write!(out, "  {channel}  {id}   [{}] ", frame.dlc())?;
        if frame.is_remote() {
            write!(out, " remote request")?;
        } else {
            for b in frame.payload() {
                write!(out, " {b:02X}")?;
            }
        }
        writeln!(out)
    }

    /// An error frame as `candump -e` shows it (socketcand's raw mode gives only the class).
    pub fn error_line(
        &mut self,
        out: &mut impl Write,
        timestamp: Option<f64>,
        channel: &str,
        class: u32,
    ) -> io::Result<()> {
        write_timestamp(out, timestamp)?;
        writeln!(
            out,
            "  {channel}  {:08X}   [8]  00 00 00 00 00 00 00 00   ERRORFRAME {}",
            ERR_FLAG | class,
            error_class_words(class)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn show(frames: &[&str], timestamp: Option<f64>) -> String {
        let mut c = Candump::default();
        let mut out = Vec::new();
        for f in frames {
            c.line(&mut out, timestamp, "vcan0", &f.parse().unwrap())
                .unwrap();
        }
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn candump_layout() {
        assert_eq!(
            show(&["123#112233", "07F#R", "12345678#DEADBEEF", "080#"], None),
            "  vcan0  123   [3]  11 22 33\n\
             \x20 vcan0  07F   [0]  remote request\n\
             \x20 vcan0  12345678   [4]  DE AD BE EF\n\
             \x20 vcan0       080   [0] \n"
        );
    }

    #[test]
    fn log_timestamps_have_candumps_fixed_width() {
        assert_eq!(log_timestamp(1.5), "(0000000001.500000)");
        assert_eq!(log_timestamp(1_795_251_323.218_691), "(1795251323.218691)");
    }

    #[test]
    fn candump_timestamps() {
        assert_eq!(
            show(&["123#11"], Some(1.2345678)),
            " (001.234568)  vcan0  123   [1]  11\n"
        );
        assert_eq!(
            show(&["123#11"], Some(1_795_251_323.218_691)),
            " (1795251323.218691)  vcan0  123   [1]  11\n"
        );
    }
}
