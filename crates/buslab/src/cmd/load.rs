//! `buslab load PROG.s37 --bus URL`: JerryCAN's "send a program" (seed 002 §5.4.4.6) to the
//! PowerPC node's CAN loader (§4.4).
//!
//! 1. The file is checked as the loader will check it (every record, every address inside
//!    the node's memory): a bad line is named with its number and nothing is sent.
//! 2. The handshake: a remote frame with the loader's ID and DLC 0; the loader answers with an
//!    empty frame on the same ID — a data frame (§4.4.1.1, what buslab's node sends) or a
//!    remote frame (§5.4.4.6, what JerryCAN waited for): both are taken (docs/decisions.md).
//! 3. The text goes as ASCII, 8 bytes a frame, the last shorter (the file protocol).
//! 4. The node's loader jumps to the entry point (the S7/S8/S9 record), as the seed's does;
//!    `--no-run` sends the file without that record: loaded, not run.
//! 5. With `--verify SOCKET` (the node's control socket), the node's verdict is awaited, every
//!    loaded byte is read back and compared, and the node's state after the jump is printed
//!    (`running pc=…`; a program that stopped at once is an error).

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use buslab_can::{Frame, Id};
use buslab_canbus::Filter;
use buslab_loader::{MemoryMap, Program};

use super::busopt::{BusOpt, open};
use super::transfer;
use crate::units::Human;

/// `--id`'s default (the configuration's `loader_id`), in hex as help shows identifiers.
static DEFAULT_ID: std::sync::LazyLock<String> =
    std::sync::LazyLock::new(|| crate::units::hex_id(crate::config::get().loader_id));

#[derive(clap::Args)]
pub struct Args {
    /// The S-record file (S19/S28/S37 and the other kinds; .s29 as the seed's).
    pub file: PathBuf,
    #[command(flatten)]
    pub bus: BusOpt,
    /// The loader's identifier (JerryCAN's `idloader`, `loader_id` in buslab.toml; hex with
    /// 0x, or decimal).
    #[arg(long, value_name = "N", default_value = DEFAULT_ID.as_str(), value_parser = parse_loader_id)]
    pub id: u16,
    /// How long to wait for the loader's answer (`2s`, `500ms`).
    #[arg(long, value_name = "DURATION", default_value = "5s", value_parser = crate::units::duration)]
    pub timeout: Duration,
    /// The PowerPC node's control socket (`buslab bus serve --ppc-control`, DIR/ppc.sock of
    /// `buslab lab --dir DIR`): wait for the node's verdict and read the memory back.
    #[arg(long, value_name = "SOCKET")]
    pub verify: Option<PathBuf>,
    /// Only check the file (the first step), send nothing.
    #[arg(long)]
    pub check: bool,
    /// Load without running: the file is sent without its entry point record (S7/S8/S9), so
    /// the node's loader does not jump to it and MoniCAN starts again.
    #[arg(long)]
    pub no_run: bool,
}

/// The loader's ID: 0 (the seed's) up to 0x7EF, as `loader_id` in buslab.toml.
fn parse_loader_id(text: &str) -> Result<u16, String> {
    super::monican::parse_id(text)
}

/// The largest S-record file the node's receive buffer takes.
const MAX_TEXT: u64 = buslab_loader::memory::TEXT_BUFFER as u64;

/// Whether `line` is an entry point record (S7, S8, S9).
fn is_entry_record(line: &[u8]) -> bool {
    let line = line.trim_ascii_start();
    matches!(line, [b'S' | b's', b'7'..=b'9', ..])
}

/// The text without its entry point records (`--no-run`): every other byte as it was.
fn without_entry(text: &[u8]) -> Vec<u8> {
    text.split_inclusive(|&b| b == b'\n')
        .filter(|line| !is_entry_record(line))
        .flatten()
        .copied()
        .collect()
}

/// Reads and checks the file as the loader will (without its entry point if `no_run`).
fn checked_program(path: &Path, no_run: bool) -> anyhow::Result<(Vec<u8>, Program)> {
    let text = buslab_link::fs::read_limited(path, MAX_TEXT).with_context(|| {
        format!("the loader's receive buffer takes {MAX_TEXT} bytes of S-records at most")
    })?;
    let text = if no_run { without_entry(&text) } else { text };
    match buslab_loader::check(&MemoryMap::ppc403(), &text) {
        Ok(program) => Ok((text, program)),
        Err(errors) => bail!(
            "{}: {} bad line(s), nothing sent:\n{errors}",
            path.display(),
            errors.count()
        ),
    }
}

fn describe(program: &Program) -> String {
    let ranges: Vec<String> = program
        .ranges()
        .iter()
        .map(|&(a, b)| format!("{a:08X}-{b:08X}"))
        .collect();
    let entry = program.start.map_or_else(
        || "no entry point: loaded, not run".to_string(),
        |e| format!("entry {e:08X}"),
    );
    format!(
        "{} bytes in {} ({entry})",
        program.data_bytes(),
        ranges.join(" ")
    )
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (text, program) = checked_program(&args.file, args.no_run)?;
    eprintln!("{}: {}", args.file.display(), describe(&program));
    if args.check {
        return Ok(());
    }
    let stop = super::interrupted()?;
    let mut control = args.verify.as_deref().map(Control::connect).transpose()?;
    let (loads_before, running) = match &mut control {
        Some(c) => {
            let state = c.ask("state")?;
            let running = (state.starts_with("running") || state.starts_with("stopped"))
                .then(|| format!("{state}: a program owns the SJA1000, so a load request is its business; `reset` on {} gives the board back to the firmware", c.path.display()));
            (c.load_number()?, running)
        }
        None => (0, None),
    };
    let url = &args.bus.bus;
    let mut bus = open(url)?;
    let id = Id::standard(args.id).context("the loader's identifier")?;
    bus.set_filters(&[Filter::standard(args.id)])?;
    handshake(&mut bus, id, args.timeout).map_err(|e| match running {
        Some(note) => e.context(format!("the node's state was {note}")),
        None => e,
    })?;
    let started = Instant::now();
    let bar = transfer::bar(text.len() as u64, "sending");
    let stall = Some(buslab_loader::loader::IDLE_TIMEOUT.as_duration());
    let sent = transfer::send_data(&mut bus, url, id, &text, &bar, stall, &stop);
    bar.finish_and_clear();
    sent?;
    eprintln!(
        "sent {} bytes of S-records in {}",
        text.len(),
        Human(started.elapsed())
    );
    if let Some(control) = &mut control {
        // The transfer may have outlasted the control socket's idle time (it closes clients
        // that say nothing): a fresh connection.
        *control = Control::connect(&control.path)?;
        // The loader checks the records once the last frame is in: a few ms of node time.
        let verdict = control.wait_load(loads_before, Duration::from_secs(30))?;
        if !verdict.contains(" ok ") {
            bail!("the node refused the program: {verdict}");
        }
        control.verify(&program)?;
        eprintln!(
            "verified: the node's memory holds every byte ({})",
            verdict.trim_start_matches("load ")
        );
        if program.start.is_some() {
            // The loader jumped as it reported: the state says what the program does.
            let state = control.ask("state")?;
            if state.starts_with("stopped") {
                bail!("the program {state}");
            }
            eprintln!("the node {}", describe_state(&state));
        }
    }
    Ok(())
}

/// The node's `state` after a jump, as a sentence's end.
fn describe_state(state: &str) -> String {
    if state.starts_with("running") {
        format!("runs the program: {state}")
    } else if state.starts_with("exited") {
        format!("ran the program, which already {state}")
    } else {
        format!("says {state}")
    }
}

/// The remote frame that asks for the loader, and its answer: an empty frame on the same ID,
/// data (§4.4.1.1) or remote (§5.4.4.6).
fn handshake(bus: &mut buslab_backends::DynBus, id: Id, timeout: Duration) -> anyhow::Result<()> {
    bus.send(&Frame::remote(id, 0)?)?;
    let deadline = Instant::now() + timeout;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            bail!(
                "no loader answered on ID {:03X} within {} (is the PowerPC node on this bus, showing MoniCAN or just powered on? `buslab bus serve --ppc` or `buslab lab` put one there)",
                id.as_raw(),
                Human(timeout)
            );
        }
        let Some(message) = bus.recv(Some(left))? else {
            continue;
        };
        let frame = &message.record;
        if frame.id() == id && frame.dlc() == 0 {
            tracing::debug!(
                "the loader answered with a {} frame",
                if frame.is_remote() { "remote" } else { "data" }
            );
            return Ok(());
        }
    }
}

/// The node's control socket, one command a line.
struct Control {
    path: PathBuf,
    reader: BufReader<UnixStream>,
    writer: UnixStream,
}

impl Control {
    fn connect(path: &Path) -> anyhow::Result<Self> {
        let stream = UnixStream::connect(path).with_context(|| {
            format!(
                "cannot reach the PowerPC node's control socket {}",
                path.display()
            )
        })?;
        Ok(Self {
            path: path.to_path_buf(),
            reader: BufReader::new(stream.try_clone()?),
            writer: stream,
        })
    }

    fn ask(&mut self, command: &str) -> anyhow::Result<String> {
        writeln!(self.writer, "{command}")?;
        let mut line = String::new();
        self.reader.read_line(&mut line)?;
        let line = line.trim_end().to_string();
        if line.is_empty() {
            bail!("{}: the node's control socket closed", self.path.display());
        }
        if let Some(e) = line.strip_prefix("error: ") {
            bail!("{}: {command}: {e}", self.path.display());
        }
        Ok(line)
    }

    /// The number of the last transfer the loader finished (0: none yet).
    fn load_number(&mut self) -> anyhow::Result<u64> {
        let answer = self.ask("load")?;
        Ok(answer
            .split_whitespace()
            .nth(1)
            .and_then(|n| n.parse().ok())
            .unwrap_or(0))
    }

    /// Waits until a transfer after `before` is finished (its report shown: the image saved,
    /// the program started), and returns its line.
    fn wait_load(&mut self, before: u64, timeout: Duration) -> anyhow::Result<String> {
        let deadline = Instant::now() + timeout;
        loop {
            if self.load_number()? > before {
                return self.ask("load");
            }
            if Instant::now() >= deadline {
                bail!(
                    "the node reported no finished load within {} (state: {})",
                    Human(timeout),
                    self.ask("state")?
                );
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Reads every byte `program` loaded back from the node and compares.
    fn verify(&mut self, program: &Program) -> anyhow::Result<()> {
        const CHUNK: usize = buslab_served::ppc::MAX_READ;
        for segment in &program.segments {
            for (i, chunk) in segment.data.chunks(CHUNK).enumerate() {
                let address = segment.address + (i * CHUNK) as u32;
                let hex = self.ask(&format!("read {address:08X} {}", chunk.len()))?;
                let read: Vec<u8> = (0..hex.len() / 2)
                    .filter_map(|j| u8::from_str_radix(hex.get(2 * j..2 * j + 2)?, 16).ok())
                    .collect();
                if let Some(k) = (0..chunk.len()).find(|&k| read.get(k) != Some(&chunk[k])) {
                    bail!(
                        "verify failed at {:08X}: the file has {:02X}, the node {}",
                        address + k as u32,
                        chunk[k],
                        read.get(k)
                            .map_or_else(|| "nothing".to_string(), |b| format!("{b:02X}"))
                    );
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_run_drops_only_the_entry_records() {
        let text =
            b"S00600004844521B\r\nS1070000010203F2\n  S9030000FC\ns705000320003F\nS5030001FB";
        assert_eq!(
            without_entry(text),
            b"S00600004844521B\r\nS1070000010203F2\nS5030001FB"
        );
        assert!(!is_entry_record(b"S3"));
        assert!(!is_entry_record(b""));
    }
}
