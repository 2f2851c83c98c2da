//! `send --dbc FILE [IFACE] MESSAGE SIGNAL=VALUE… [MESSAGE SIGNAL=VALUE…]…`: the words after
//! the interface turned into frames. A word with `#` is a frame in can-utils syntax, a word
//! with `=` gives a signal of the message named before it, any other word names a message.
//! Each message is encoded by the database (`Message::encode`), which refuses values out of
//! the signal's range and signals of an inactive multiplexer branch.

use std::path::Path;

use anyhow::{Context, bail};
use buslab_can::Frame;
use buslab_dbc::{Database, Message, Signal};
use buslab_logs::Record;

use crate::dbc::{message_named, signal_named};

/// The frames the words ask for, in their order. `iface` is the first word when it was taken
/// as the interface (named in the error when no message comes before a signal).
pub fn frames(
    database: &Database,
    path: &Path,
    words: &[String],
    iface: Option<&str>,
) -> anyhow::Result<Vec<Record>> {
    let mut frames = Vec::new();
    let mut pending: Option<Pending> = None;
    for word in words {
        if word.contains('#') {
            if let Some(p) = pending.take() {
                frames.push(p.encode()?);
            }
            frames.push(super::parse_frame(word)?);
        } else if let Some((name, value)) = assignment(word) {
            let Some(p) = &mut pending else {
                let hint = match iface.map(|i| (i, message_named(database, path, i))) {
                    Some((iface, Err(not_a_message))) => {
                        format!(" ({iface} was taken as the interface: {not_a_message})")
                    }
                    _ => String::new(),
                };
                bail!("{word}: no message named before it, e.g. `Engine {word}`{hint}");
            };
            p.give(database, path, name, value)?;
        } else {
            if let Some(p) = pending.take() {
                // `Engine Speed`: a signal without its value.
                if database.message_by_name(word).is_none()
                    && p.message.signal_by_name(word).is_some()
                {
                    bail!(
                        "{word} is a signal of {}: give its value, e.g. {word}=1",
                        p.message.name()
                    );
                }
                frames.push(p.encode()?);
            }
            pending = Some(Pending {
                message: message_named(database, path, word)?,
                values: Vec::new(),
            });
        }
    }
    if let Some(p) = pending {
        frames.push(p.encode()?);
    }
    Ok(frames)
}

/// `SIGNAL=VALUE`: a word whose part before the first `=` could be a signal's name (a DBC
/// name is a C identifier), so that a URL with a query (`slcan:/dev/ttyACM0?bitrate=500000`)
/// is not one.
pub fn assignment(word: &str) -> Option<(&str, &str)> {
    let (name, value) = word.split_once('=')?;
    name.bytes()
        .all(|b| b.is_ascii_alphanumeric() || b == b'_')
        .then_some((name, value))
}

/// A message being given its signals.
struct Pending<'a> {
    message: &'a Message,
    /// Signal names and physical values, in the order given.
    values: Vec<(&'a str, f64)>,
}

impl<'a> Pending<'a> {
    /// `name=value`: the signal checked, the value read (a number or a label).
    fn give(
        &mut self,
        database: &'a Database,
        path: &Path,
        name: &str,
        value: &str,
    ) -> anyhow::Result<()> {
        let full = format!("{}.{name}", self.message.name());
        let signal = signal_named(database, path, &full)?.signal();
        let name = signal.name();
        if self.values.iter().any(|(given, _)| *given == name) {
            bail!("{full} is given twice");
        }
        self.values.push((name, physical(signal, &full, value)?));
        Ok(())
    }

    /// The frame: the payload the database encodes, at the message's ID; a CAN FD frame for a
    /// message the database sends as FD (`VFrameFormat`) or longer than 8 bytes, without BRS.
    fn encode(self) -> anyhow::Result<Record> {
        let message = self.message;
        let payload = message.encode(&self.values)?;
        let record = if message.is_fd() || payload.len() > 8 {
            Record::Fd(
                super::fd_frame(message.id(), &payload)
                    .with_context(|| format!("message {}", message.name()))?,
            )
        } else {
            Record::Frame(
                Frame::data(message.id(), &payload)
                    .with_context(|| format!("message {}", message.name()))?,
            )
        };
        tracing::info!("{} → {record}", message.name());
        Ok(record)
    }
}

/// A value as written after `=`: a number in the signal's unit, or a label of its value table
/// (the physical value of its raw value).
fn physical(signal: &Signal, full: &str, text: &str) -> anyhow::Result<f64> {
    if let Ok(number) = text.trim().parse::<f64>() {
        return Ok(number);
    }
    if let Some((raw, _)) = signal.choices().iter().find(|(_, label)| label == text) {
        return Ok(*raw as f64 * signal.factor() + signal.offset());
    }
    let (min, max) = signal.allowed();
    let unit = match signal.unit() {
        "" => String::new(),
        unit => format!(" {unit}"),
    };
    let labels: Vec<&str> = signal.choices().iter().map(|(_, l)| l.as_str()).collect();
    if labels.is_empty() {
        bail!("{full}={text}: not a number (allowed {min} ..= {max}{unit})");
    }
    bail!(
        "{full}={text}: neither a number (allowed {min} ..= {max}{unit}) nor a label of its \
         value table ({})",
        labels.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const DBC: &str = r#"
BO_ 291 Engine: 8 ECU
 SG_ Speed : 0|16@1+ (0.1,0) [0|6553.5] "km/h" Vector__XXX
 SG_ Mode : 16|2@1+ (1,0) [0|3] "" Vector__XXX
BO_ 1024 Muxed: 2 ECU
 SG_ Sel M : 0|8@1+ (1,0) [0|0] "" Vector__XXX
 SG_ A m0 : 8|8@1+ (1,0) [0|0] "" Vector__XXX
 SG_ B m1 : 8|8@1+ (1,0) [0|0] "" Vector__XXX
BO_ 1025 Wide: 64 ECU
 SG_ X : 0|8@1+ (1,0) [0|0] "" Vector__XXX
VAL_ 291 Mode 0 "Off" 1 "On" 2 "Eco" ;
"#;

    fn run(words: &[&str]) -> anyhow::Result<Vec<String>> {
        let db = Database::parse(DBC).unwrap();
        let words: Vec<String> = words.iter().map(|w| w.to_string()).collect();
        Ok(frames(&db, Path::new("car.dbc"), &words, None)?
            .iter()
            .map(Record::to_string)
            .collect())
    }

    fn error(words: &[&str]) -> String {
        format!("{:#}", run(words).unwrap_err())
    }

    #[test]
    fn a_signal_after_a_word_taken_as_the_interface_says_so() {
        let db = Database::parse(DBC).unwrap();
        let words = vec!["Speed=1".to_string()];
        let e = frames(&db, Path::new("car.dbc"), &words, Some("Engien")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "Speed=1: no message named before it, e.g. `Engine Speed=1` (Engien was taken as \
             the interface: car.dbc has no message \"Engien\"; close names: Engine)"
        );
    }

    #[test]
    fn messages_are_encoded_from_numbers_and_labels_between_plain_frames() {
        assert_eq!(
            run(&[
                "Engine",
                "Speed=88.5",
                "Mode=On",
                "7FF#01",
                "Muxed",
                "Sel=1",
                "B=7"
            ])
            .unwrap(),
            ["123#7503010000000000", "7FF#01", "400#0107"]
        );
        // Nothing given: every signal 0.
        assert_eq!(run(&["Engine"]).unwrap(), ["123#0000000000000000"]);
    }

    #[test]
    fn bad_values_are_refused_with_what_is_allowed() {
        assert_eq!(
            error(&["Engine", "Speed=7000"]),
            "Engine.Speed = 7000 is out of range: allowed 0 ..= 6553.5"
        );
        assert_eq!(
            error(&["Engine", "Speed=fast"]),
            "Engine.Speed=fast: not a number (allowed 0 ..= 6553.5 km/h)"
        );
        assert_eq!(
            error(&["Engine", "Mode=Fast"]),
            "Engine.Mode=Fast: neither a number (allowed 0 ..= 3) nor a label of its value table (Off, On, Eco)"
        );
        assert_eq!(
            error(&["Engine", "Sped=1"]),
            "message Engine of car.dbc has no signal \"Sped\"; close names: Speed"
        );
        assert_eq!(
            error(&["Engin", "Speed=1"]),
            "car.dbc has no message \"Engin\"; close names: Engine"
        );
        assert_eq!(
            error(&["Engine", "Speed=1", "Speed=2"]),
            "Engine.Speed is given twice"
        );
        assert_eq!(
            error(&["Engine", "Speed"]),
            "Speed is a signal of Engine: give its value, e.g. Speed=1"
        );
        assert_eq!(
            error(&["Speed=1"]),
            "Speed=1: no message named before it, e.g. `Engine Speed=1`"
        );
        assert_eq!(
            error(&["Muxed", "Sel=0", "B=1"]),
            "Muxed.B is not sent when Sel = 0"
        );
    }

    #[test]
    fn messages_longer_than_eight_bytes_are_sent_as_can_fd_frames() {
        let sent = run(&["Wide", "X=171", "123##1AB"]).unwrap();
        assert_eq!(
            sent,
            [format!("401##0AB{}", "00".repeat(63)), "123##1AB".into()]
        );
    }
}
