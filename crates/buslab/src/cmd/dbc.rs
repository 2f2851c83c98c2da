//! `buslab dbc show|skeleton`: a DBC database as a person checks it (every signal's bits,
//! Intel or Motorola, drawn on the payload's bytes), and a first database written from a
//! captured log (one message per ID seen, its length, its period).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, bail};
use buslab_dbc::{ByteOrder, Database, Message, Multiplexing, Signal, ValueKind};
use buslab_logs::{Format, Record, open_reader};

#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: DbcCommand,
}

#[derive(clap::Subcommand)]
pub enum DbcCommand {
    /// Messages and signals of a DBC file, each message's bits drawn byte by byte.
    Show(ShowArgs),
    /// Write a first DBC from a log: one message per ID seen, one 8-bit signal per byte, the
    /// period it was seen at as GenMsgCycleTime.
    Skeleton(SkeletonArgs),
}

#[derive(clap::Args)]
pub struct ShowArgs {
    /// The DBC file.
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    /// Only these messages (by name or by ID in hex, e.g. 1F0).
    #[arg(value_name = "MESSAGE")]
    pub messages: Vec<String>,
}

#[derive(clap::Args)]
pub struct SkeletonArgs {
    /// The log to learn from (any format `buslab log` reads).
    #[arg(value_name = "LOG")]
    pub log: PathBuf,
    /// The log's format when its extension does not tell.
    #[arg(long, value_name = "FORMAT")]
    pub from: Option<Format>,
    /// Where to write the DBC (written whole, atomically); standard output without it.
    #[arg(short, long, value_name = "OUT.dbc")]
    pub output: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        DbcCommand::Show(args) => show(&args),
        DbcCommand::Skeleton(args) => skeleton(&args),
    }
}

fn show(args: &ShowArgs) -> anyhow::Result<()> {
    let db = crate::dbc::load(&args.file)?;
    let mut chosen = Vec::new();
    for wanted in &args.messages {
        let found = db.message_by_name(wanted).or_else(|| {
            u32::from_str_radix(wanted.trim_start_matches("0x"), 16)
                .ok()
                .and_then(|raw| db.messages().iter().find(|m| m.id().as_raw() == raw))
        });
        match found {
            Some(m) => chosen.push(m),
            None => bail!(
                "{}: no message {wanted:?} (its messages: {})",
                args.file.display(),
                names(db.messages().iter().map(Message::name))
            ),
        }
    }
    if args.messages.is_empty() {
        chosen = db.messages().iter().collect();
    }
    let mut out = String::new();
    writeln!(
        out,
        "{}: {} messages{}",
        args.file.display(),
        db.messages().len(),
        if db.nodes().is_empty() {
            String::new()
        } else {
            format!(", nodes {}", db.nodes().join(" "))
        }
    )?;
    for message in chosen {
        out.push('\n');
        describe(&mut out, message)?;
    }
    print!("{out}");
    Ok(())
}

fn names<'a>(names: impl Iterator<Item = &'a str>) -> String {
    let all: Vec<&str> = names.collect();
    if all.len() > 20 {
        format!("{} … ({} in all)", all[..20].join(", "), all.len())
    } else {
        all.join(", ")
    }
}

/// A message: its header line, one line per signal, its bytes drawn.
fn describe(out: &mut String, message: &Message) -> std::fmt::Result {
    write!(
        out,
        "{} {}  {} bytes",
        message.id(),
        message.name(),
        message.length()
    )?;
    if let Some(node) = message.transmitter() {
        write!(out, "  from {node}")?;
    }
    if let Some(cycle) = message.cycle_time() {
        write!(out, "  every {} ms", cycle.as_millis())?;
    }
    if message.is_fd() {
        out.push_str("  CAN FD");
    }
    out.push('\n');
    if let Some(comment) = message.comment() {
        writeln!(out, "  \"{comment}\"")?;
    }
    let letters = legend_letters(message.signals().len());
    for (signal, letter) in message.signals().iter().zip(&letters) {
        describe_signal(out, message, signal, *letter)?;
    }
    draw_bytes(out, message, &letters)
}

/// A, B, … Z, a, … z, then digits: one mark per signal in the drawing.
fn legend_letters(n: usize) -> Vec<char> {
    ('A'..='Z')
        .chain('a'..='z')
        .chain('0'..='9')
        .cycle()
        .take(n)
        .collect()
}

/// (byte, bit) of each of the signal's bits, most significant first.
fn signal_bits(signal: &Signal) -> Vec<(usize, u32)> {
    let (start, size) = (signal.start_bit(), signal.size());
    match signal.byte_order() {
        ByteOrder::LittleEndian => (start..start + size)
            .rev()
            .map(|k| ((k / 8) as usize, k % 8))
            .collect(),
        ByteOrder::BigEndian => {
            let msb = 8 * (start / 8) + 7 - start % 8;
            (msb..msb + size)
                .map(|k| ((k / 8) as usize, 7 - k % 8))
                .collect()
        }
    }
}

fn describe_signal(
    out: &mut String,
    message: &Message,
    signal: &Signal,
    letter: char,
) -> std::fmt::Result {
    let bits = signal_bits(signal);
    let (msb, lsb) = (bits[0], bits[bits.len() - 1]);
    let order = match signal.byte_order() {
        ByteOrder::LittleEndian => "@1 Intel",
        ByteOrder::BigEndian => "@0 Motorola",
    };
    let kind = match signal.kind() {
        ValueKind::Unsigned => "unsigned",
        ValueKind::Signed => "signed",
        ValueKind::Float32 => "float",
        ValueKind::Float64 => "double",
    };
    write!(
        out,
        "  {letter} {}  start {} size {} {order} {kind}, MSB byte {} bit {}, LSB byte {} bit {}; ×{} +{}",
        signal.name(),
        signal.start_bit(),
        signal.size(),
        msb.0,
        msb.1,
        lsb.0,
        lsb.1,
        signal.factor(),
        signal.offset()
    )?;
    if let Some((min, max)) = signal.range() {
        write!(out, " [{min} .. {max}]")?;
    }
    if !signal.unit().is_empty() {
        write!(out, " {}", signal.unit())?;
    }
    match signal.multiplexing() {
        Multiplexing::Plain => {}
        Multiplexing::Multiplexor => out.push_str("; multiplexor"),
        Multiplexing::Multiplexed {
            multiplexor,
            values,
            selects,
        } => {
            let when: Vec<String> = values
                .iter()
                .map(|r| {
                    if r.start() == r.end() {
                        r.start().to_string()
                    } else {
                        format!("{}..{}", r.start(), r.end())
                    }
                })
                .collect();
            write!(
                out,
                "; when {} = {}",
                message.signals()[*multiplexor].name(),
                when.join(", ")
            )?;
            if *selects {
                out.push_str(", itself a multiplexor");
            }
        }
    }
    out.push('\n');
    if !signal.choices().is_empty() {
        let shown: Vec<String> = signal
            .choices()
            .iter()
            .take(12)
            .map(|(v, label)| format!("{v} {label:?}"))
            .collect();
        let more = signal.choices().len().saturating_sub(12);
        write!(out, "      values: {}", shown.join(", "))?;
        if more > 0 {
            write!(out, " … ({more} more)")?;
        }
        out.push('\n');
    }
    Ok(())
}

/// The payload byte by byte, bit 7 on the left, each bit marked with its signal's letter
/// (`*` where multiplexed branches share it, `.` where no signal is).
fn draw_bytes(out: &mut String, message: &Message, letters: &[char]) -> std::fmt::Result {
    let length = message.length();
    let mut cells = vec!['.'; length * 8];
    for (signal, &letter) in message.signals().iter().zip(letters) {
        for (byte, bit) in signal_bits(signal) {
            if byte < length {
                let cell = &mut cells[byte * 8 + (7 - bit as usize)];
                *cell = if *cell == '.' { letter } else { '*' };
            }
        }
    }
    writeln!(out, "  byte  7 6 5 4 3 2 1 0")?;
    for (byte, row) in cells.chunks(8).enumerate() {
        let row: Vec<String> = row.iter().map(char::to_string).collect();
        writeln!(out, "  {byte:>4}  {}", row.join(" "))?;
    }
    Ok(())
}

/// What a log says of one ID.
#[derive(Default)]
struct Seen {
    count: u64,
    length: usize,
    fd: bool,
    last: Option<Duration>,
    intervals: Vec<Duration>,
}

/// Intervals kept per ID for the period (a median over the first ones is enough).
const MAX_INTERVALS: usize = 4096;
/// IDs a skeleton holds at most (a log of random IDs is not a database).
const MAX_IDS: usize = 4096;

fn skeleton(args: &SkeletonArgs) -> anyhow::Result<()> {
    let format = match args.from {
        Some(f) => f,
        None => Format::from_path(&args.log)?,
    };
    let mut seen: BTreeMap<(bool, u32), Seen> = BTreeMap::new();
    for entry in open_reader(&args.log, format)? {
        let entry = entry?;
        let (id, length, fd) = match &entry.record {
            Record::Frame(f) => (f.id(), f.payload().len(), false),
            Record::Fd(f) => (f.id(), f.payload().len(), true),
            Record::Error(_) => continue,
        };
        let key = (id.is_extended(), id.as_raw());
        if !seen.contains_key(&key) && seen.len() == MAX_IDS {
            bail!(
                "{}: more than {MAX_IDS} IDs; a skeleton database is for a bus's regular traffic",
                args.log.display()
            );
        }
        let s = seen.entry(key).or_default();
        let at = entry.at.since_epoch_duration();
        if let Some(last) = s.last
            && s.intervals.len() < MAX_INTERVALS
        {
            s.intervals.push(at.saturating_sub(last));
        }
        s.last = Some(at);
        s.count += 1;
        s.length = s.length.max(length);
        s.fd |= fd;
    }
    if seen.is_empty() {
        bail!("{}: no frames to learn a database from", args.log.display());
    }
    let text = skeleton_text(&seen, &args.log.display().to_string());
    // What we write must read back.
    Database::parse(&text).context("the skeleton written does not read back (a bug)")?;
    match &args.output {
        Some(path) => buslab_link::fs::write_atomic(path, text.as_bytes())?,
        None => print!("{text}"),
    }
    Ok(())
}

/// The period a message is sent at: the median interval, when most intervals are within a
/// quarter of it (event-driven messages get none).
fn period(intervals: &mut [Duration]) -> Option<Duration> {
    if intervals.len() < 2 {
        return None;
    }
    intervals.sort_unstable();
    let median = intervals[intervals.len() / 2];
    if median < Duration::from_millis(1) {
        return None;
    }
    let near = intervals
        .iter()
        .filter(|&&i| i.abs_diff(median) <= median / 4)
        .count();
    (near * 5 >= intervals.len() * 4).then_some(median)
}

fn skeleton_text(seen: &BTreeMap<(bool, u32), Seen>, source: &str) -> String {
    let mut out = String::from(
        "VERSION \"\"\n\nNS_ :\n\tCM_\n\tBA_DEF_\n\tBA_\n\tBA_DEF_DEF_\n\nBS_:\n\nBU_:\n",
    );
    let mut comments = String::new();
    let mut attributes = String::new();
    for (&(extended, raw), s) in seen {
        let dbc_id = if extended { raw | 1 << 31 } else { raw };
        let name = if extended {
            format!("MSG_X{raw:08X}")
        } else {
            format!("MSG_{raw:03X}")
        };
        let _ = write!(out, "\nBO_ {dbc_id} {name}: {} Vector__XXX\n", s.length);
        for byte in 0..s.length {
            let _ = writeln!(
                out,
                " SG_ B{byte} : {}|8@1+ (1,0) [0|255] \"\" Vector__XXX",
                8 * byte
            );
        }
        let _ = writeln!(
            comments,
            "CM_ BO_ {dbc_id} \"seen {} times in {}\";",
            s.count,
            source.replace('"', "'")
        );
        let mut intervals = s.intervals.clone();
        if let Some(p) = period(&mut intervals) {
            let _ = writeln!(
                attributes,
                "BA_ \"GenMsgCycleTime\" BO_ {dbc_id} {};",
                ((p.as_micros() + 500) / 1000).min(65_535)
            );
        }
        let format = match (s.fd, extended) {
            (false, false) => 0,
            (false, true) => 1,
            (true, false) => 2,
            (true, true) => 3,
        };
        if format != 0 {
            let _ = writeln!(attributes, "BA_ \"VFrameFormat\" BO_ {dbc_id} {format};");
        }
    }
    out.push('\n');
    out.push_str(&comments);
    out.push_str(
        "BA_DEF_ BO_ \"GenMsgCycleTime\" INT 0 65535;\n\
         BA_DEF_ BO_ \"VFrameFormat\" ENUM \"StandardCAN\",\"ExtendedCAN\",\"StandardCAN_FD\",\"ExtendedCAN_FD\";\n\
         BA_DEF_DEF_ \"GenMsgCycleTime\" 0;\n\
         BA_DEF_DEF_ \"VFrameFormat\" \"StandardCAN\";\n",
    );
    out.push_str(&attributes);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_regular_period_is_found_and_an_irregular_one_is_not() {
        let ms = Duration::from_millis;
        let mut regular = vec![ms(100), ms(101), ms(99), ms(100), ms(250)];
        assert_eq!(period(&mut regular), Some(ms(100)));
        let mut events = vec![ms(10), ms(700), ms(35), ms(2000)];
        assert_eq!(period(&mut events), None);
    }

    #[test]
    fn motorola_bits_run_from_the_msb_into_the_next_byte() {
        let db = Database::parse(
            "BO_ 1 M: 2 X\n SG_ S : 3|8@0+ (1,0) [0|0] \"\" X\n SG_ I : 8|4@1+ (1,0) [0|0] \"\" X\n",
        )
        .unwrap();
        let m = db.message_by_name("M").unwrap();
        assert_eq!(
            signal_bits(&m.signals()[0]),
            [
                (0, 3),
                (0, 2),
                (0, 1),
                (0, 0),
                (1, 7),
                (1, 6),
                (1, 5),
                (1, 4)
            ]
        );
        let mut out = String::new();
        draw_bytes(&mut out, m, &legend_letters(2)).unwrap();
        assert_eq!(
            out,
            "  byte  7 6 5 4 3 2 1 0\n     0  . . . . A A A A\n     1  A A A A B B B B\n"
        );
    }
}
