//! `--dbc FILE`: the DBC database every tool that shows frames can decode them with, and what
//! the command-line tools share around it: `--message NAME` (frames of named messages only),
//! the decoded text after a frame's line (cantools' `decode` layout), and names looked up with
//! the close ones offered when they are not there.

use std::collections::HashSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context, bail};
use buslab_can::Id;
use buslab_dbc::text::DecodedMessage;
use buslab_dbc::{Database, Decoded, Message};
use buslab_logs::Record;

/// A DBC file larger than this is refused: the largest real databases are a few MiB.
const MAX_DBC_BYTES: u64 = 64 << 20;

/// The option, for every command that takes a database.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct DbcArg {
    /// A DBC database: frames of its messages are shown as named, scaled signals.
    #[arg(long, value_name = "FILE")]
    pub dbc: Option<PathBuf>,
}

impl DbcArg {
    /// The database, if one was given.
    // Its users, the monitor and the web pages, are features of their own.
    #[cfg_attr(not(any(feature = "web", feature = "tui")), expect(dead_code))]
    pub fn load(&self) -> anyhow::Result<Option<Arc<Database>>> {
        self.dbc.as_deref().map(load).transpose()
    }
}

/// Reads and resolves a DBC file (a regular file, bounded); errors name the file and the line.
pub fn load(path: &Path) -> anyhow::Result<Arc<Database>> {
    let bytes = buslab_link::fs::read_limited(path, MAX_DBC_BYTES)?;
    let database =
        Database::from_bytes(&bytes).with_context(|| format!("DBC file {}", path.display()))?;
    Ok(Arc::new(database))
}

/// `--dbc FILE` with `--message NAME…`: the database and the messages a command keeps.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct Selection {
    #[command(flatten)]
    pub dbc: DbcArg,
    /// Only frames of this message of the --dbc database (by name; repeatable, or several
    /// separated by commas). Error frames are not messages: this does not filter them.
    #[arg(
        short = 'm',
        long = "message",
        value_name = "NAME",
        value_delimiter = ',',
        requires = "dbc"
    )]
    pub messages: Vec<String>,
}

/// A loaded `--dbc`, and the `--message` filter if one was given.
pub struct Selected {
    pub database: Arc<Database>,
    pub filter: Option<MessageFilter>,
}

impl Selection {
    /// The database and the filter, the names checked against it; `None` without `--dbc`.
    pub fn resolve(&self) -> anyhow::Result<Option<Selected>> {
        let Some(path) = &self.dbc.dbc else {
            return Ok(None);
        };
        let database = load(path)?;
        let filter = if self.messages.is_empty() {
            None
        } else {
            Some(MessageFilter::new(&database, path, &self.messages)?)
        };
        Ok(Some(Selected { database, filter }))
    }
}

/// `--message NAME…`: the IDs of the named messages.
#[derive(Clone, Debug)]
pub struct MessageFilter {
    ids: HashSet<Id>,
}

impl MessageFilter {
    /// Every name must be a message of `database` (read from `path`, for the error).
    pub fn new(database: &Database, path: &Path, names: &[String]) -> anyhow::Result<Self> {
        let mut ids = HashSet::with_capacity(names.len());
        for name in names {
            let message =
                message_named(database, path, name).with_context(|| format!("--message {name}"))?;
            ids.insert(message.id());
        }
        Ok(Self { ids })
    }

    /// Whether a frame's ID is one of the named messages'.
    pub fn passes_id(&self, id: Id) -> bool {
        self.ids.contains(&id)
    }

    /// Frames of the named messages (remote requests for them too); error frames pass (they
    /// are the bus's, not a message's; whether they are shown is -e's choice).
    pub fn passes(&self, record: &Record) -> bool {
        match record {
            Record::Frame(frame) => self.passes_id(frame.id()),
            Record::Fd(frame) => self.passes_id(frame.id()),
            Record::Error(_) => true,
        }
    }
}

/// The ID and payload a record carries for decoding: data frames only (a remote frame asks for
/// a message without carrying it; an error frame is not a message). CAN FD frames will be one
/// more arm here.
pub fn carried(record: &Record) -> Option<(Id, &[u8])> {
    match record {
        Record::Frame(frame) if !frame.is_remote() => Some((frame.id(), frame.payload())),
        _ => None,
    }
}

/// How the decoded message follows a frame's line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// `LINE ::` then the message with one signal per line (`cantools decode`).
    MultiLine,
    /// `LINE :: Name(Sig: 1.5 V, …)` (`cantools decode --single-line`).
    SingleLine,
}

/// Appends the decoded message after a frame's line, reusing its buffer of values.
pub struct Decoder {
    database: Arc<Database>,
    layout: Layout,
    values: Vec<Decoded>,
}

impl Decoder {
    pub fn new(database: Arc<Database>, layout: Layout) -> Self {
        Self {
            database,
            layout,
            values: Vec::new(),
        }
    }

    /// Appends ` ::` and the decoded message to `out` (which holds the frame's line, without
    /// its newline) when `record` is a data frame of a message of the database; otherwise
    /// leaves `out` as it is.
    pub fn append(&mut self, out: &mut Vec<u8>, record: &Record) {
        let Some((id, payload)) = carried(record) else {
            return;
        };
        let Some(message) = self.database.message(id) else {
            return;
        };
        message.decode_into(payload, &mut self.values);
        let decoded = DecodedMessage {
            message,
            values: &self.values,
        };
        // Writing into a Vec cannot fail.
        let _ = match self.layout {
            Layout::MultiLine => write!(out, " ::\n{decoded:#}"),
            Layout::SingleLine => write!(out, " :: {decoded}"),
        };
    }
}

/// The message called `name`, or an error naming the file and the close names (or all).
pub fn message_named<'a>(
    database: &'a Database,
    path: &Path,
    name: &str,
) -> anyhow::Result<&'a Message> {
    if let Some(message) = database.message_by_name(name) {
        return Ok(message);
    }
    let known: Vec<&str> = database.messages().iter().map(Message::name).collect();
    bail!(
        "{} has no message {name:?}; {}",
        path.display(),
        offer(name, &known, "messages")
    )
}

/// A signal found by `Message.Signal`, or by `Signal` alone when one message has it.
#[derive(Clone, Copy, Debug)]
pub struct SignalRef<'a> {
    pub message: &'a Message,
    /// Its index in the message's signals.
    pub index: usize,
}

impl<'a> SignalRef<'a> {
    pub fn signal(&self) -> &'a buslab_dbc::Signal {
        &self.message.signals()[self.index]
    }

    /// `Message.Signal`.
    pub fn full_name(&self) -> String {
        format!("{}.{}", self.message.name(), self.signal().name())
    }
}

/// `Message.Signal`, or `Signal` when exactly one message has a signal of that name.
/// Unknown or ambiguous names are refused with the candidates.
pub fn signal_named<'a>(
    database: &'a Database,
    path: &Path,
    name: &str,
) -> anyhow::Result<SignalRef<'a>> {
    if let Some((message_name, signal_name)) = name.split_once('.') {
        let message = message_named(database, path, message_name)?;
        return match message.signal_by_name(signal_name) {
            Some((index, _)) => Ok(SignalRef { message, index }),
            None => {
                let known: Vec<&str> = message.signals().iter().map(|s| s.name()).collect();
                bail!(
                    "message {message_name} of {} has no signal {signal_name:?}; {}",
                    path.display(),
                    offer(signal_name, &known, "signals")
                )
            }
        };
    }
    let found: Vec<SignalRef> = database
        .messages()
        .iter()
        .filter_map(|message| {
            message
                .signal_by_name(name)
                .map(|(index, _)| SignalRef { message, index })
        })
        .collect();
    match found[..] {
        [one] => Ok(one),
        [] => {
            let known: Vec<String> = database
                .messages()
                .iter()
                .flat_map(|m| {
                    m.signals()
                        .iter()
                        .map(|s| format!("{}.{}", m.name(), s.name()))
                })
                .collect();
            let known: Vec<&str> = known.iter().map(String::as_str).collect();
            // A bare name is compared with the signal part of each `Message.Signal`.
            let close = close_names(name, &known, |full| {
                full.split_once('.').map_or(full, |(_, s)| s)
            });
            let offered = if close.is_empty() {
                list("signals", &known)
            } else {
                format!("close names: {}", close.join(", "))
            };
            bail!("{} has no signal {name:?}; {offered}", path.display())
        }
        _ => {
            let names: Vec<String> = found.iter().map(SignalRef::full_name).collect();
            bail!(
                "{name} is a signal of {} messages: name one as {}",
                names.len(),
                names.join(" or ")
            )
        }
    }
}

/// The names close to `name` (a typo, another case), else the list of them all.
fn offer(name: &str, known: &[&str], what: &str) -> String {
    let close = close_names(name, known, |k| k);
    if close.is_empty() {
        list(what, known)
    } else {
        format!("close names: {}", close.join(", "))
    }
}

/// `its N messages: A, B, …` (the first [`LISTED`] of a long list).
fn list(what: &str, known: &[&str]) -> String {
    const LISTED: usize = 20;
    match known.len() {
        0 => format!("it has no {what}"),
        n if n <= LISTED => format!("its {what}: {}", known.join(", ")),
        n => format!(
            "its {n} {what} begin with: {}, …",
            known[..LISTED].join(", ")
        ),
    }
}

/// Up to five of `known` that look like `name` (compared through `key`), closest first: the
/// same letters in another case, one containing the other, or a Jaro-Winkler similarity of
/// at least 0.8 (a letter or two off).
fn close_names<'a>(
    name: &str,
    known: &[&'a str],
    key: impl Fn(&'a str) -> &'a str,
) -> Vec<&'a str> {
    let lower = name.to_lowercase();
    let mut scored: Vec<(f64, &str)> = known
        .iter()
        .filter_map(|&k| {
            let candidate = key(k).to_lowercase();
            let score = if candidate == lower {
                2.0
            } else if !lower.is_empty()
                && (candidate.contains(&lower) || lower.contains(&candidate))
            {
                1.5
            } else {
                strsim::jaro_winkler(&lower, &candidate)
            };
            (score >= 0.8).then_some((score, k))
        })
        .collect();
    scored.sort_by(|a, b| b.0.total_cmp(&a.0));
    scored.dedup_by(|a, b| a.1 == b.1);
    scored.into_iter().take(5).map(|(_, k)| k).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const DBC: &str = r#"
BO_ 291 Engine: 8 ECU
 SG_ Speed : 0|16@1+ (0.1,0) [0|6553.5] "km/h" Vector__XXX
 SG_ Mode : 16|2@1+ (1,0) [0|3] "" Vector__XXX
BO_ 292 Brake: 8 ECU
 SG_ Pressure : 0|16@1+ (0.1,0) [0|1000] "bar" Vector__XXX
 SG_ Mode : 16|2@1+ (1,0) [0|3] "" Vector__XXX
VAL_ 291 Mode 0 "Off" 1 "On" ;
"#;

    fn db() -> Database {
        Database::parse(DBC).unwrap()
    }

    fn path() -> &'static Path {
        Path::new("car.dbc")
    }

    #[test]
    fn a_signal_is_found_by_its_full_name_or_alone_when_one_message_has_it() {
        let db = db();
        assert_eq!(
            signal_named(&db, path(), "Engine.Mode")
                .unwrap()
                .full_name(),
            "Engine.Mode"
        );
        assert_eq!(
            signal_named(&db, path(), "Speed").unwrap().full_name(),
            "Engine.Speed"
        );
        let e = signal_named(&db, path(), "Mode").unwrap_err().to_string();
        assert_eq!(
            e,
            "Mode is a signal of 2 messages: name one as Engine.Mode or Brake.Mode"
        );
    }

    #[test]
    fn unknown_names_are_refused_with_the_close_ones_or_the_list() {
        let db = db();
        let e = message_named(&db, path(), "engine")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "car.dbc has no message \"engine\"; close names: Engine");
        let e = message_named(&db, path(), "Xyz").unwrap_err().to_string();
        assert_eq!(
            e,
            "car.dbc has no message \"Xyz\"; its messages: Engine, Brake"
        );
        let e = signal_named(&db, path(), "Engine.Sped")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "message Engine of car.dbc has no signal \"Sped\"; close names: Speed"
        );
        let e = signal_named(&db, path(), "Presure")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "car.dbc has no signal \"Presure\"; close names: Brake.Pressure"
        );
        let e = signal_named(&db, path(), "Nope.Speed")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("car.dbc has no message \"Nope\""), "{e}");
    }

    #[test]
    fn a_long_list_is_cut() {
        let names: Vec<String> = (0..30).map(|i| format!("M{i}")).collect();
        let known: Vec<&str> = names.iter().map(String::as_str).collect();
        let text = list("messages", &known);
        assert!(
            text.starts_with("its 30 messages begin with: M0, M1,") && text.ends_with("M19, …"),
            "{text}"
        );
    }

    #[test]
    fn the_decoded_text_follows_the_frame_line_as_cantools_decode_prints_it() {
        let db = Arc::new(db());
        // Mode 2 has no label: the test is about the layout, not about label spelling.
        let frame = Record::Frame("123#E803020000000000".parse().unwrap());
        let mut out = b"  vcan0  123   [8]  E8 03 02 00 00 00 00 00".to_vec();
        Decoder::new(db.clone(), Layout::MultiLine).append(&mut out, &frame);
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "  vcan0  123   [8]  E8 03 02 00 00 00 00 00 ::\nEngine(\n    Speed: 100.0 km/h,\n    Mode: 2\n)"
        );
        let mut out = b"line".to_vec();
        Decoder::new(db.clone(), Layout::SingleLine).append(&mut out, &frame);
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "line :: Engine(Speed: 100.0 km/h, Mode: 2)"
        );
        // Frames the database does not know, remote frames: the line as it was.
        for other in ["321#11", "123#R"] {
            let mut out = b"line".to_vec();
            Decoder::new(db.clone(), Layout::SingleLine)
                .append(&mut out, &Record::Frame(other.parse().unwrap()));
            assert_eq!(out, b"line", "{other}");
        }
    }
}
