//! The frames of a DBC database's messages as named, scaled signals: per message seen, its
//! signals' latest values (the value table's label, the number with the decimals its scaling
//! resolves, the unit), which changed lately, and each signal's values over time.
//!
//! A multiplexed message keeps what every branch last said: a register-by-register protocol
//! (the lab's SLIO replies) reads as its register file, and the signals of the branch the
//! last frame carried are marked active. Histories hold changes only (a signal's value holds
//! until the next sample), within the view's retention and a budget of samples shared by all
//! signals ([`crate::ViewConfig::signal_points`]). Remote frames carry no signals and leave
//! the table as it is. Decoding takes an identifier and a payload, classic or CAN FD.

use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;
use std::time::Duration;

use buslab_bus::Timestamp;
use buslab_can::Id;
use buslab_dbc::text::Number;
use buslab_dbc::{Database, Decoded, Message, Signal, ValueKind};
use serde::Serialize;

/// A signal's history keeps at least this many samples, whatever the number of signals.
pub const MIN_SIGNAL_POINTS: usize = 64;

/// A message of the database seen on the bus: its signals as last decoded.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MessageRow {
    /// `0C0` or `18FF0010`, as candump writes it.
    pub id: String,
    pub extended: bool,
    /// Its name in the database.
    pub name: String,
    /// Data frames seen.
    pub count: u64,
    /// Time between the last two frames (by their timestamps), in milliseconds.
    pub period_ms: Option<f64>,
    /// Milliseconds since its last frame.
    pub age_ms: u64,
    /// The signals decoded so far, in the database's order: all of them, or in a delta to a
    /// consumer that has the rest, those whose value, highlight or activity changed.
    pub signals: Vec<SignalRow>,
    #[serde(skip)]
    key: Id,
}

impl MessageRow {
    pub fn key(&self) -> Id {
        self.key
    }
}

/// A signal's latest value.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SignalRow {
    /// Its place among the message's signals in the database (a consumer that gets only the
    /// changed ones puts a new one in its place).
    pub position: usize,
    pub name: String,
    /// The physical value as a number alone, with the decimals its scaling resolves (`4000`,
    /// `83.6`, `2.502`).
    pub number: String,
    /// The value table's label for it (`DATA_OUTPUT`), if it has one.
    pub label: Option<String>,
    pub unit: String,
    /// Its raw bits.
    pub raw: u64,
    /// Its value changed within the highlight time.
    pub changed: bool,
    /// It was in the message's last frame (`false`: a multiplexed branch the last frame did
    /// not carry; the value is what that branch last said).
    pub active: bool,
}

impl SignalRow {
    /// The value as a person reads it: the label, or the number and its unit.
    pub fn text(&self) -> String {
        match &self.label {
            Some(label) => label.clone(),
            None if self.unit.is_empty() => self.number.clone(),
            None => format!("{} {}", self.number, self.unit),
        }
    }
}

/// A signal of the database, found by [`crate::BusView::signal`] from `Message.Signal`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SignalKey {
    pub(crate) message: Id,
    pub(crate) signal: usize,
}

/// A signal's values over time.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Series {
    /// `true`: the whole history of the window asked for (replace, do not merge).
    pub full: bool,
    pub message: String,
    pub signal: String,
    pub unit: String,
    /// `(seconds since the view started, physical value)`: each value holds until the next
    /// one; for a whole history, the samples of the window and the one before it.
    pub points: Vec<(f64, f64)>,
}

/// A `Message.Signal` that is not in the database.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SignalError {
    #[error("no DBC database: start with --dbc FILE to see signals")]
    NoDatabase,
    #[error(
        "signal {0:?}: expected MESSAGE.SIGNAL, as the database names them (Engine.EngineSpeed)"
    )]
    Syntax(String),
    #[error("no message {message:?} in the database (it has {known})")]
    NoMessage { message: String, known: String },
    #[error("message {message} has no signal {signal:?} (it has {known})")]
    NoSignal {
        message: String,
        signal: String,
        known: String,
    },
}

/// Names listed in an error at most.
const NAMES_LISTED: usize = 12;

fn some_names<'a>(names: impl Iterator<Item = &'a str>) -> String {
    let mut listed: Vec<&str> = Vec::new();
    let mut more = 0;
    for name in names {
        if listed.len() < NAMES_LISTED {
            listed.push(name);
        } else {
            more += 1;
        }
    }
    let mut text = listed.join(", ");
    if more > 0 {
        text += &format!(" and {more} more");
    }
    text
}

#[derive(Clone, Copy, Debug)]
struct Sample {
    t: f64,
    value: f64,
    seq: u64,
}

#[derive(Clone, Debug)]
struct Latest {
    raw: u64,
    physical: f64,
    /// The message's frame count when this signal was last in a frame.
    frame: u64,
    changed_at: Option<Duration>,
    /// When its row last changed (its value, or whether the last frame carried it).
    shown: u64,
    history: VecDeque<Sample>,
}

#[derive(Clone, Debug)]
struct Tracked {
    /// Its index in the database's messages.
    index: usize,
    count: u64,
    last_time: Timestamp,
    period: Option<Duration>,
    seen_at: Duration,
    seq: u64,
    values: Vec<Option<Latest>>,
}

/// The signal table of a view (see the module's docs).
#[derive(Clone, Debug)]
pub(crate) struct SignalTable {
    db: Arc<Database>,
    messages: BTreeMap<Id, Tracked>,
    /// Samples kept over all signals (each keeps at least [`MIN_SIGNAL_POINTS`]).
    budget: usize,
    /// Signals of the tracked messages.
    signals: usize,
    /// How far back histories go (the view's retention).
    retention: Duration,
    /// Messages tracked at most (the view's table size).
    max_messages: usize,
    decoded: Vec<Decoded>,
}

impl SignalTable {
    pub(crate) fn new(
        db: Arc<Database>,
        budget: usize,
        retention: Duration,
        max_messages: usize,
    ) -> Self {
        Self {
            db,
            messages: BTreeMap::new(),
            budget,
            signals: 0,
            retention,
            max_messages,
            decoded: Vec::new(),
        }
    }

    pub(crate) fn database(&self) -> &Database {
        &self.db
    }

    /// Samples each signal keeps at most now.
    fn cap(&self) -> usize {
        (self.budget / self.signals.max(1)).max(MIN_SIGNAL_POINTS)
    }

    pub(crate) fn clear(&mut self) {
        self.messages.clear();
        self.signals = 0;
    }

    /// A data frame of `id` with `payload`, its own time `at`, seen at `now`.
    pub(crate) fn frame(&mut self, now: Duration, at: Timestamp, id: Id, payload: &[u8], seq: u64) {
        let oldest = now.saturating_sub(self.retention).as_secs_f64();
        if !self.messages.contains_key(&id) {
            if self.db.message(id).is_none() || self.messages.len() >= self.max_messages {
                return;
            }
            let Some(index) = self.db.messages().iter().position(|m| m.id() == id) else {
                return;
            };
            let signals = self.db.messages()[index].signals().len();
            self.messages.insert(
                id,
                Tracked {
                    index,
                    count: 0,
                    last_time: at,
                    period: None,
                    seen_at: now,
                    seq,
                    values: vec![None; signals],
                },
            );
            self.signals += signals;
            // A new message's signals take their share of the budget from the others.
            let cap = self.cap();
            for tracked in self.messages.values_mut() {
                for latest in tracked.values.iter_mut().flatten() {
                    while latest.history.len() > cap {
                        latest.history.pop_front();
                    }
                }
            }
        }
        let cap = self.cap();
        let Self {
            db,
            messages,
            decoded,
            ..
        } = self;
        let Some(tracked) = messages.get_mut(&id) else {
            return;
        };
        let message = &db.messages()[tracked.index];
        if tracked.count > 0 {
            tracked.period =
                (at >= tracked.last_time).then(|| at.saturating_since(tracked.last_time));
        }
        let before = tracked.count;
        tracked.count += 1;
        tracked.last_time = at;
        tracked.seen_at = now;
        tracked.seq = seq;
        message.decode_into(payload, decoded);
        let t = now.as_secs_f64();
        for d in decoded.iter() {
            let sample = Sample {
                t,
                value: d.physical,
                seq,
            };
            match &mut tracked.values[d.signal] {
                slot @ None => {
                    *slot = Some(Latest {
                        raw: d.raw,
                        physical: d.physical,
                        frame: tracked.count,
                        changed_at: None,
                        shown: seq,
                        history: VecDeque::from([sample]),
                    });
                }
                Some(latest) => {
                    if latest.frame != before {
                        // Its branch is back.
                        latest.shown = seq;
                    }
                    latest.frame = tracked.count;
                    if latest.raw != d.raw {
                        latest.raw = d.raw;
                        latest.physical = d.physical;
                        latest.changed_at = Some(now);
                        latest.shown = seq;
                        latest.history.push_back(sample);
                        while latest.history.len() > cap {
                            latest.history.pop_front();
                        }
                    }
                    // The sample before the window says what the value was at its start.
                    while latest.history.len() > 1 && latest.history[1].t <= oldest {
                        latest.history.pop_front();
                    }
                }
            }
        }
        // The branches the last frame carried and this one does not.
        for latest in tracked.values.iter_mut().flatten() {
            if latest.frame == before && before > 0 {
                latest.shown = seq;
            }
        }
    }

    /// The messages with a frame since `since`, or a highlight that ran out since `after`
    /// (when given, the consumer has the rest), at `now`: for a consumer that has the rest,
    /// only the signals whose rows changed.
    pub(crate) fn changed(
        &self,
        since: u64,
        after: Option<Duration>,
        now: Duration,
        highlight: Duration,
    ) -> Vec<MessageRow> {
        let expired = |latest: &Latest| {
            after.is_some_and(|after| {
                latest.changed_at.is_some_and(|c| {
                    let end = c + highlight;
                    end > after && end <= now
                })
            })
        };
        let changed = |latest: &Latest| after.is_none() || latest.shown > since || expired(latest);
        self.messages
            .iter()
            .filter(|(_, t)| t.seq > since || t.values.iter().flatten().any(expired))
            .map(|(&id, t)| self.row(id, t, now, highlight, changed))
            .collect()
    }

    /// At most `n` messages from the `skip`th, sorted by ID.
    pub(crate) fn page(
        &self,
        now: Duration,
        highlight: Duration,
        skip: usize,
        n: usize,
    ) -> Vec<MessageRow> {
        self.messages
            .iter()
            .skip(skip)
            .take(n)
            .map(|(&id, t)| self.row(id, t, now, highlight, |_| true))
            .collect()
    }

    pub(crate) fn len(&self) -> usize {
        self.messages.len()
    }

    /// A message's row with the signals `shown` picks.
    fn row(
        &self,
        key: Id,
        tracked: &Tracked,
        now: Duration,
        highlight: Duration,
        shown: impl Fn(&Latest) -> bool,
    ) -> MessageRow {
        let message = &self.db.messages()[tracked.index];
        let signals = message
            .signals()
            .iter()
            .zip(&tracked.values)
            .enumerate()
            .filter_map(|(position, (signal, latest))| {
                let latest = latest.as_ref().filter(|l| shown(l))?;
                Some(SignalRow {
                    position,
                    name: signal.name().to_string(),
                    number: number_text(signal, latest.physical),
                    label: signal.choice(latest.raw).map(str::to_string),
                    unit: signal.unit().to_string(),
                    raw: latest.raw,
                    changed: latest.changed_at.is_some_and(|c| now < c + highlight),
                    active: latest.frame == tracked.count,
                })
            })
            .collect();
        MessageRow {
            id: candump_id(key),
            extended: key.is_extended(),
            name: message.name().to_string(),
            count: tracked.count,
            period_ms: tracked.period.map(|p| p.as_secs_f64() * 1000.0),
            age_ms: now.saturating_sub(tracked.seen_at).as_millis() as u64,
            signals,
            key,
        }
    }

    /// The signal `Message.Signal`.
    pub(crate) fn key(&self, name: &str) -> Result<SignalKey, SignalError> {
        let (message_name, signal_name) = name
            .split_once('.')
            .ok_or_else(|| SignalError::Syntax(name.to_string()))?;
        let message =
            self.db
                .message_by_name(message_name)
                .ok_or_else(|| SignalError::NoMessage {
                    message: message_name.to_string(),
                    known: some_names(self.db.messages().iter().map(Message::name)),
                })?;
        let (signal, _) =
            message
                .signal_by_name(signal_name)
                .ok_or_else(|| SignalError::NoSignal {
                    message: message.name().to_string(),
                    signal: signal_name.to_string(),
                    known: some_names(message.signals().iter().map(Signal::name)),
                })?;
        Ok(SignalKey {
            message: message.id(),
            signal,
        })
    }

    /// `key`'s samples newer than `since`, or (`full`) those from `from` on with the one
    /// before.
    pub(crate) fn series(&self, key: &SignalKey, full: bool, since: u64, from: f64) -> Series {
        let message = self
            .db
            .message(key.message)
            .expect("keys come from this database");
        let signal = &message.signals()[key.signal];
        let history = self
            .messages
            .get(&key.message)
            .and_then(|t| t.values[key.signal].as_ref())
            .map(|l| &l.history);
        let points = match history {
            None => Vec::new(),
            Some(h) if full => {
                let first = h.partition_point(|s| s.t < from).saturating_sub(1);
                h.iter().skip(first).map(|s| (s.t, s.value)).collect()
            }
            Some(h) => h
                .iter()
                .filter(|s| s.seq > since)
                .map(|s| (s.t, s.value))
                .collect(),
        };
        Series {
            full,
            message: message.name().to_string(),
            signal: signal.name().to_string(),
            unit: signal.unit().to_string(),
            points,
        }
    }

    /// Samples kept over all signals (for tests of the bound).
    #[cfg(test)]
    pub(crate) fn samples(&self) -> usize {
        self.messages
            .values()
            .flat_map(|t| t.values.iter().flatten())
            .map(|l| l.history.len())
            .sum()
    }
}

/// `0C0` or `18FF0010`, as candump writes an identifier.
pub(crate) fn candump_id(id: Id) -> String {
    match id {
        Id::Standard(s) => format!("{:03X}", s.as_raw()),
        Id::Extended(e) => format!("{:08X}", e.as_raw()),
    }
}

/// A physical value with the decimals the signal's scaling resolves: none for an integer
/// scaling, the factor's and offset's own decimals when they have a few (`0.25` → 2), else
/// down to the step's first digit (`5/1023` → 3); a float signal in its shortest form.
pub fn number_text(signal: &Signal, physical: f64) -> String {
    if !physical.is_finite() || matches!(signal.kind(), ValueKind::Float32 | ValueKind::Float64) {
        return Number::of(signal, physical).to_string();
    }
    let places = decimals(signal.factor()).max(decimals(signal.offset()));
    format!("{physical:.places$}")
}

/// The decimals that show steps of `x`.
fn decimals(x: f64) -> usize {
    if x == 0.0 || !x.is_finite() {
        return 0;
    }
    // Rust writes an f64 in full, without an exponent.
    let text = x.abs().to_string();
    let exact = text.split_once('.').map_or(0, |(_, f)| f.len());
    if exact <= 6 {
        exact
    } else {
        (-x.abs().log10()).ceil().clamp(0.0, 9.0) as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DBC: &str = r#"
BO_ 291 Engine: 8 ECU
 SG_ Speed : 0|16@1+ (0.1,0) [0|6553.5] "km/h" Vector__XXX
 SG_ Gear : 16|8@1+ (1,0) [0|8] "" Vector__XXX
BO_ 645 Slio: 3 SLIO
 SG_ Register M : 0|4@1+ (1,0) [0|8] "" Vector__XXX
 SG_ Input m0 : 15|16@0+ (1,0) [0|65535] "" Vector__XXX
 SG_ ADC m8 : 9|10@0+ (0.004887585532746823,0) [0|5] "V" Vector__XXX
VAL_ 291 Gear 0 "neutral" 1 "first" ;
"#;

    fn table(budget: usize) -> SignalTable {
        let db = Arc::new(Database::parse(DBC).unwrap());
        SignalTable::new(db, budget, Duration::from_secs(600), 100)
    }

    fn id(raw: u16) -> Id {
        Id::standard(raw).unwrap()
    }

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    fn feed(t: &mut SignalTable, now: u64, raw: u16, payload: &[u8], seq: u64) {
        let at = Timestamp::from_secs_f64(now as f64 / 1000.0);
        t.frame(ms(now), at, id(raw), payload, seq);
    }

    #[test]
    fn numbers_have_the_decimals_of_their_scaling() {
        let db = Database::parse(DBC).unwrap();
        let engine = db.message_by_name("Engine").unwrap();
        let slio = db.message_by_name("Slio").unwrap();
        assert_eq!(number_text(&engine.signals()[0], 83.60000000000001), "83.6");
        assert_eq!(number_text(&engine.signals()[1], 4000.0), "4000");
        assert_eq!(
            number_text(&slio.signals()[2], 512.0 * 5.0 / 1023.0),
            "2.502"
        );
        assert_eq!(decimals(0.25), 2);
        assert_eq!(decimals(0.0048828125), 3);
        assert_eq!(decimals(-40.0), 0);
    }

    #[test]
    fn a_row_has_labels_units_and_the_signals_that_changed() {
        let mut t = table(1 << 16);
        feed(&mut t, 0, 0x123, &[0x10, 0x27, 0, 0, 0, 0, 0, 0], 1);
        feed(&mut t, 10, 0x123, &[0x10, 0x27, 1, 0, 0, 0, 0, 0], 2);
        let rows = t.page(ms(20), ms(1000), 0, 10);
        assert_eq!(rows.len(), 1);
        let row = &rows[0];
        assert_eq!(
            (row.id.as_str(), row.name.as_str(), row.count),
            ("123", "Engine", 2)
        );
        assert!((row.period_ms.unwrap() - 10.0).abs() < 1e-6);
        let speed = &row.signals[0];
        assert_eq!(speed.text(), "1000.0 km/h");
        assert!(!speed.changed && speed.active);
        let gear = &row.signals[1];
        assert_eq!(
            (gear.text(), gear.raw, gear.changed),
            ("first".into(), 1, true)
        );
        // The highlight lasts its time, then goes.
        assert!(!t.page(ms(1_011), ms(1000), 0, 10)[0].signals[1].changed);
        // Frames of other IDs are no message of the database.
        feed(&mut t, 30, 0x7FF, &[1], 3);
        assert_eq!(t.len(), 1);
    }

    #[test]
    fn a_multiplexed_message_keeps_what_each_branch_last_said() {
        let mut t = table(1 << 16);
        feed(&mut t, 0, 0x285, &[0x20, 0x20, 0x05], 1);
        feed(&mut t, 10, 0x285, &[0x28, 0x02, 0x00], 2);
        let row = &t.page(ms(20), ms(1000), 0, 10)[0];
        let shown: Vec<(&str, String, bool)> = row
            .signals
            .iter()
            .map(|s| (s.name.as_str(), s.text(), s.active))
            .collect();
        assert_eq!(
            shown,
            [
                ("Register", "8".to_string(), true),
                ("Input", "8197".to_string(), false),
                ("ADC", "2.502 V".to_string(), true),
            ]
        );
    }

    #[test]
    fn histories_hold_changes_within_the_budget_and_the_window() {
        let mut t = table(0);
        // Equal values are one sample; each change one more.
        for k in 0..10u64 {
            feed(
                &mut t,
                k,
                0x123,
                &[0, 0, (k / 5) as u8, 0, 0, 0, 0, 0],
                k + 1,
            );
        }
        let key = t.key("Engine.Gear").unwrap();
        let whole = t.series(&key, true, 0, f64::NEG_INFINITY);
        assert_eq!(whole.points, [(0.0, 0.0), (0.005, 1.0)]);
        assert_eq!(t.series(&key, false, 6, 0.0).points, Vec::new());
        // A window from 7 ms on starts with the value then held (from 5 ms).
        assert_eq!(t.series(&key, true, 0, 0.007).points, [(0.005, 1.0)]);
        // A counter changing every frame: at most the minimum each (budget 0).
        for k in 0..1000u64 {
            let gear = (k % 256) as u8;
            feed(&mut t, 20 + k, 0x123, &[0, 0, gear, 0, 0, 0, 0, 0], 100 + k);
        }
        let gear = t.series(&key, true, 0, f64::NEG_INFINITY);
        assert_eq!(gear.points.len(), MIN_SIGNAL_POINTS);
        assert_eq!(
            gear.points.last(),
            Some(&(1.019, f64::from((999 % 256) as u8)))
        );
        // A new message's signals take their share from the others.
        let mut t = table(12);
        for k in 0..20u64 {
            feed(
                &mut t,
                k,
                0x123,
                &[k as u8, 0, k as u8, 0, 0, 0, 0, 0],
                k + 1,
            );
        }
        assert_eq!(t.samples(), 2 * MIN_SIGNAL_POINTS.min(20));
        let mut t = table(4 * 1024);
        for k in 0..2000u64 {
            feed(
                &mut t,
                k,
                0x123,
                &[k as u8, 0, k as u8, 0, 0, 0, 0, 0],
                k + 1,
            );
        }
        assert_eq!(t.samples(), 2 * 2000);
        feed(&mut t, 3000, 0x285, &[0x28, 0x02, 0x00], 3000);
        // 5 signals now share 4096 samples: 819 each at most.
        assert!(t.samples() <= 4 * 1024, "{}", t.samples());
    }

    #[test]
    fn signal_names_are_checked_against_the_database() {
        let t = table(0);
        assert!(t.key("Slio.ADC").is_ok());
        assert_eq!(
            t.key("Speed").unwrap_err().to_string(),
            "signal \"Speed\": expected MESSAGE.SIGNAL, as the database names them (Engine.EngineSpeed)"
        );
        assert_eq!(
            t.key("Brakes.Speed").unwrap_err().to_string(),
            "no message \"Brakes\" in the database (it has Engine, Slio)"
        );
        assert_eq!(
            t.key("Engine.Rpm").unwrap_err().to_string(),
            "message Engine has no signal \"Rpm\" (it has Speed, Gear)"
        );
    }
}
