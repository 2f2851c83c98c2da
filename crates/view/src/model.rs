//! The model: state, inputs, and deltas since a cursor.

use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;
use std::time::Duration;

use buslab_bus::{ErrorFrame, ErrorState, Message, NodeStatus, Record, Timestamp};
use buslab_can::{FdFrame, Frame, Id};
use buslab_dbc::Database;
use serde::Serialize;

use crate::filter::LogFilter;
use crate::signals::{MessageRow, Series, SignalError, SignalKey, SignalTable, candump_id};
use buslab_can::wire::frame_bits;

/// Sizes and times of a view.
#[derive(Clone, Debug)]
pub struct ViewConfig {
    /// Frames kept in the log ring.
    pub log_capacity: usize,
    /// Rows of the per-ID table; frames of further IDs are counted in
    /// [`Delta::ids_dropped`] only.
    pub max_ids: usize,
    /// How long a changed byte stays highlighted.
    pub highlight: Duration,
    /// Load samples kept (one per second).
    pub load_points: usize,
    /// TEC/REC samples kept per node at most (a run of equal samples is kept as its first
    /// and last).
    pub history_points: usize,
    /// How far back the load, the TEC/REC histories and the fault marks go: the longest
    /// window a chart can ask for.
    pub retention: Duration,
    /// The bus's bit rate when the bus cannot tell, for estimating the load from frames.
    pub bitrate: Option<u32>,
    /// A DBC database: the frames of its messages are also shown as signals
    /// ([`BusView::messages_page`], [`Delta::messages`], [`BusView::series`]).
    pub dbc: Option<Arc<Database>>,
    /// Signal samples kept over all signals' histories; each signal keeps at least
    /// [`crate::MIN_SIGNAL_POINTS`].
    pub signal_points: usize,
}

impl Default for ViewConfig {
    fn default() -> Self {
        Self {
            log_capacity: 4096,
            max_ids: 4096,
            highlight: Duration::from_secs(1),
            load_points: 600,
            history_points: 4096,
            retention: Duration::from_secs(600),
            bitrate: None,
            dbc: None,
            signal_points: 1 << 18,
        }
    }
}

/// Where a consumer is: everything with a larger sequence number is new to it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Cursor {
    seq: u64,
    at: Duration,
    fresh: bool,
    /// Frames logged when the cursor was taken.
    logged: u64,
}

impl Cursor {
    /// A consumer that has seen nothing: its first delta is the whole view.
    pub fn start() -> Self {
        Self::default()
    }
}

/// One row of the per-ID table.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IdRow {
    /// `0C0` or `18FF0010`, as candump writes it.
    pub id: String,
    pub extended: bool,
    pub count: u64,
    /// Time between the last two frames (by their timestamps), in milliseconds.
    pub period_ms: Option<f64>,
    pub dlc: u8,
    pub remote: bool,
    /// The data bytes in hex, two digits each, no spaces.
    pub data: String,
    /// Bit i set: byte i changed within the highlight time.
    pub changed: u8,
    /// Milliseconds since the last frame of this ID.
    pub age_ms: u64,
    #[serde(skip)]
    key: Id,
}

impl IdRow {
    pub fn key(&self) -> Id {
        self.key
    }
}

/// A frame or an error frame in the log.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LogEntry {
    pub seq: u64,
    /// The frame's own time (in JSON: `time`, seconds).
    #[serde(rename = "time", serialize_with = "seconds")]
    pub at: Timestamp,
    /// can-utils' compact form, `123#1122`; an error frame as candump logs it,
    /// `20000088#0000000000000000`.
    pub frame: String,
    /// What an error frame says (`None` for a frame).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorEntry>,
    #[serde(skip)]
    pub record: Record,
}

/// A time as JSON seconds.
fn seconds<S: serde::Serializer>(at: &Timestamp, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(at.as_secs_f64())
}

/// An error frame's class and meaning, in the words `buslab dump -e` prints (can-utils').
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ErrorEntry {
    /// The class bits (the CAN ID without the error flag), `0x088` as 136.
    pub class: u32,
    /// One entry per class with its details: `protocol-violation{{single-bit-error}{data-field}}`,
    /// `bus-error`.
    pub classes: Vec<String>,
    /// The TX and RX error counters, when the frame carries them.
    pub tec: Option<u8>,
    pub rec: Option<u8>,
}

impl ErrorEntry {
    fn of(error: &ErrorFrame) -> Self {
        let mut classes: Vec<String> = error.describe("\n").lines().map(str::to_string).collect();
        // The counters are fields of their own.
        if error.counters.is_some() {
            classes.pop();
        }
        Self {
            class: error.class(),
            classes,
            tec: error.counters.map(|c| c.tx),
            rec: error.counters.map(|c| c.rx),
        }
    }
}

/// A fault put on the wire from this view's server, as a band on the time charts.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FaultMark {
    /// Stays the same when the mark changes (a repair ends it early): replace by `id`.
    pub id: u64,
    /// Seconds since the view started.
    pub t: f64,
    /// When it ends (or ended); `None`: until repaired.
    pub until: Option<f64>,
    /// What it is, in a few words for the chart: `cut at engine`.
    pub label: String,
    /// What it is, in a sentence: `the wire cut: engine on the far side, …`.
    pub what: String,
    #[serde(skip)]
    seq: u64,
}

/// The bus load over one second.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LoadSample {
    /// Seconds since the view started, at the end of the second measured.
    pub t: f64,
    /// Per cent of the bit-times the bus was busy, when known.
    pub percent: Option<f64>,
    pub frames: u64,
    #[serde(skip)]
    seq: u64,
}

/// A node's counters at one instant.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ErrorSample {
    /// Seconds since the view started.
    pub t: f64,
    pub tec: u8,
    pub rec: u8,
    /// `active`, `passive` or `bus-off`.
    pub state: &'static str,
    #[serde(skip)]
    seq: u64,
}

impl ErrorSample {
    fn same_values(&self, other: &ErrorSample) -> bool {
        (self.tec, self.rec, self.state) == (other.tec, other.rec, other.state)
    }
}

/// A node: its latest status in words, and the new part of its TEC/REC history.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NodeView {
    pub number: u32,
    pub name: String,
    /// `error-active`, `error-passive`, `bus-off`.
    pub state: String,
    pub tec: Option<u8>,
    pub rec: Option<u8>,
    /// `SR=0x0C: …` every STATUS bit in words, for SJA1000 nodes.
    pub status: Option<String>,
    pub sr: Option<u8>,
    /// The last captured arbitration-lost and error-code registers, in words.
    pub alc: Option<String>,
    pub ecc: Option<String>,
    pub sent: u64,
    pub received: u64,
    pub bus_errors: u64,
    pub bus_off: u64,
    pub arbitration_lost: u64,
    /// Samples newer than the cursor (for a new consumer: those of the window asked for,
    /// with the one before it, so that a chart's line enters from its left edge).
    pub history: Vec<ErrorSample>,
}

/// What changed since a cursor.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Delta {
    /// `true`: this is the whole view (replace, do not merge).
    pub full: bool,
    /// Seconds since the view started.
    pub t: f64,
    /// Rows that changed (their count, data, or highlight), sorted by ID.
    pub ids: Vec<IdRow>,
    /// With a DBC database: the messages that changed (a frame, or a highlight that ran
    /// out), sorted by ID; each with all its signals in a whole view, else with those whose
    /// value, highlight or activity changed (merge them by name).
    pub messages: Vec<MessageRow>,
    /// Frames of IDs beyond the table's size, counted only.
    pub ids_dropped: u64,
    /// New log frames that pass the consumer's filter, oldest first (at most the asked
    /// number, the newest ones).
    pub log: Vec<LogEntry>,
    /// New frames that passed the filter but were left out of `log` for its size limit, and
    /// new frames that left the view's log (its capacity) before the consumer asked, whatever
    /// the filter: what the consumer missed.
    pub log_skipped: u64,
    pub load: Vec<LoadSample>,
    pub nodes: Vec<NodeView>,
    /// Fault marks new or changed since the cursor (for a new consumer: those in the window).
    pub faults: Vec<FaultMark>,
    /// Frames seen since the view started.
    pub frames: u64,
    /// Error frames seen since the view started.
    pub error_frames: u64,
    /// Frames per second over the last complete second.
    pub frames_per_s: u64,
    pub bitrate: Option<u32>,
}

#[derive(Clone, Debug)]
struct Row {
    frame: Frame,
    count: u64,
    last_time: Timestamp,
    period: Option<Duration>,
    seen_at: Duration,
    changed_at: [Option<Duration>; 8],
    seq: u64,
}

#[derive(Clone, Debug)]
struct Node {
    status: NodeStatus,
    history: VecDeque<ErrorSample>,
    seq: u64,
}

/// The bus as a person watches it (see the crate docs).
#[derive(Clone, Debug)]
pub struct BusView {
    config: ViewConfig,
    seq: u64,
    rows: BTreeMap<Id, Row>,
    ids_dropped: u64,
    log: VecDeque<Logged>,
    load: VecDeque<LoadSample>,
    nodes: BTreeMap<u32, Node>,
    faults: VecDeque<FaultMark>,
    next_fault: u64,
    frames: u64,
    error_frames: u64,
    /// The current second: its start, frames and estimated bits.
    window_start: Duration,
    window_frames: u64,
    window_bits: u64,
    last_frames_per_s: u64,
    /// The bus's own load figure (a buslab bus reports it with every status).
    reported: Option<(f64, u32)>,
    /// The sequence number of the last [`BusView::clear`].
    cleared_at: u64,
    /// Frames ever put in the log (those that left it included).
    logged: u64,
    /// The frames of the DBC database's messages as signals.
    signals: Option<SignalTable>,
}

impl BusView {
    pub fn new(config: ViewConfig) -> Self {
        let signals = config
            .dbc
            .clone()
            .map(|db| SignalTable::new(db, config.signal_points, config.retention, config.max_ids));
        Self {
            signals,
            config,
            seq: 0,
            rows: BTreeMap::new(),
            ids_dropped: 0,
            log: VecDeque::new(),
            load: VecDeque::new(),
            nodes: BTreeMap::new(),
            faults: VecDeque::new(),
            next_fault: 0,
            frames: 0,
            error_frames: 0,
            window_start: Duration::ZERO,
            window_frames: 0,
            window_bits: 0,
            last_frames_per_s: 0,
            reported: None,
            cleared_at: 0,
            logged: 0,
        }
    }

    pub fn config(&self) -> &ViewConfig {
        &self.config
    }

    fn next_seq(&mut self) -> u64 {
        self.seq += 1;
        self.seq
    }

    /// A frame or an error frame seen at `now`.
    pub fn message(&mut self, now: Duration, message: &Message) {
        match &message.record {
            Record::Frame(frame) => self.frame(now, message.at, *frame),
            Record::Fd(frame) => self.fd_frame(now, message.at, frame),
            Record::Error(error) => self.error_frame(now, message.at, error),
        }
    }

    /// A frame with its own time `at`, seen at `now`.
    pub fn frame(&mut self, now: Duration, at: Timestamp, frame: Frame) {
        self.tick(now);
        let seq = self.next_seq();
        self.frames += 1;
        self.window_frames += 1;
        if self.config.bitrate.is_some() && self.reported.is_none() {
            self.window_bits += frame_bits(&frame);
        }
        let id = frame.id();
        let limit = self.config.max_ids;
        let rows_len = self.rows.len();
        match self.rows.get_mut(&id) {
            Some(row) => {
                let old = row.frame.payload();
                let new = frame.payload();
                for i in 0..8 {
                    if old.get(i) != new.get(i) && i < new.len().max(old.len()) {
                        row.changed_at[i] = Some(now);
                    }
                }
                row.period = (at >= row.last_time).then(|| at.saturating_since(row.last_time));
                row.last_time = at;
                row.frame = frame;
                row.count += 1;
                row.seen_at = now;
                row.seq = seq;
            }
            None if rows_len < limit => {
                self.rows.insert(
                    id,
                    Row {
                        frame,
                        count: 1,
                        last_time: at,
                        period: None,
                        seen_at: now,
                        changed_at: [None; 8],
                        seq,
                    },
                );
            }
            None => self.ids_dropped += 1,
        }
        if let Some(signals) = &mut self.signals
            && !frame.is_remote()
        {
            signals.frame(now, at, id, frame.payload(), seq);
        }
        self.log(Logged {
            seq,
            at,
            record: Record::Frame(frame),
        });
    }

    /// A CAN FD frame with its own time `at`, seen at `now`: counted, logged and decoded by
    /// the database. The per-ID table and the bus load are classic CAN's (8 byte columns; an
    /// FD frame's time on the wire depends on a data bit rate no source tells).
    pub fn fd_frame(&mut self, now: Duration, at: Timestamp, frame: &FdFrame) {
        self.tick(now);
        let seq = self.next_seq();
        self.frames += 1;
        self.window_frames += 1;
        if let Some(signals) = &mut self.signals {
            signals.frame(now, at, frame.id(), frame.payload(), seq);
        }
        self.log(Logged {
            seq,
            at,
            record: Record::Fd(*frame),
        });
    }

    /// An error frame with its own time `at`, seen at `now`: logged (it is no frame of the
    /// table or the load).
    pub fn error_frame(&mut self, now: Duration, at: Timestamp, e: &ErrorFrame) {
        self.tick(now);
        let seq = self.next_seq();
        self.error_frames += 1;
        self.log(Logged {
            seq,
            at,
            record: Record::Error(e.clone()),
        });
    }

    fn log(&mut self, entry: Logged) {
        if self.log.len() >= self.config.log_capacity.max(1) {
            self.log.pop_front();
        }
        self.logged += 1;
        self.log.push_back(entry);
    }

    /// A fault put on the wire at `now` for `lasting` (`None`: until repaired), named by
    /// `label` and described by `what`; its mark's id.
    pub fn fault(
        &mut self,
        now: Duration,
        label: String,
        what: String,
        lasting: Option<Duration>,
    ) -> u64 {
        self.tick(now);
        let seq = self.next_seq();
        self.next_fault += 1;
        if self.faults.len() >= MAX_FAULT_MARKS {
            self.faults.pop_front();
        }
        self.faults.push_back(FaultMark {
            id: self.next_fault,
            t: now.as_secs_f64(),
            until: lasting.map(|d| (now + d).as_secs_f64()),
            label,
            what,
            seq,
        });
        self.next_fault
    }

    /// Every fault ended at `now` (a repair): marks still running end there.
    pub fn repaired(&mut self, now: Duration) {
        self.tick(now);
        let seq = self.next_seq();
        let t = now.as_secs_f64();
        for mark in &mut self.faults {
            if mark.until.is_none_or(|u| u > t) {
                mark.until = Some(t);
                mark.seq = seq;
            }
        }
    }

    /// Every node's status at `now` (nodes missing from the list have left).
    pub fn nodes(&mut self, now: Duration, statuses: Vec<NodeStatus>) {
        self.tick(now);
        let seq = self.next_seq();
        if let Some(first) = statuses.first() {
            self.reported = Some((first.bus.load_percent, first.bus.bitrate));
        }
        let present: Vec<u32> = statuses.iter().map(|s| s.number).collect();
        self.nodes.retain(|n, _| present.contains(n));
        let t = now.as_secs_f64();
        let cap = self.config.history_points.max(2);
        let oldest = now.saturating_sub(self.config.retention).as_secs_f64();
        for status in statuses {
            let node = self.nodes.entry(status.number).or_insert_with(|| Node {
                status: status.clone(),
                history: VecDeque::new(),
                seq,
            });
            if let Some(e) = status.errors {
                let sample = ErrorSample {
                    t,
                    tec: e.txerr,
                    rec: e.rxerr,
                    state: state_word(status.state),
                    seq,
                };
                keep_sample(&mut node.history, sample, oldest, cap);
            }
            node.status = status;
            node.seq = seq;
        }
    }

    /// Time passes: the load window closes every second.
    pub fn tick(&mut self, now: Duration) {
        let second = Duration::from_secs(1);
        if now < self.window_start + second {
            return;
        }
        let elapsed = (now - self.window_start).as_secs_f64();
        let percent = match (self.reported, self.config.bitrate) {
            (Some((load, _)), _) => Some(load),
            (None, Some(rate)) if rate > 0 => {
                Some(100.0 * self.window_bits as f64 / (f64::from(rate) * elapsed))
            }
            _ => None,
        };
        // A frames-per-second figure over the window actually measured.
        let frames_per_s = (self.window_frames as f64 / elapsed).round() as u64;
        self.last_frames_per_s = frames_per_s;
        let seq = self.next_seq();
        if self.load.len() >= self.config.load_points.max(1) {
            self.load.pop_front();
        }
        let oldest = now.saturating_sub(self.config.retention).as_secs_f64();
        while self
            .faults
            .front()
            .is_some_and(|f| f.until.is_some_and(|u| u < oldest))
        {
            self.faults.pop_front();
        }
        self.load.push_back(LoadSample {
            t: now.as_secs_f64(),
            percent: percent.map(|p| p.min(100.0)),
            frames: frames_per_s,
            seq,
        });
        self.window_start = now;
        self.window_frames = 0;
        self.window_bits = 0;
    }

    /// Frames seen since the view started.
    pub fn frame_count(&self) -> u64 {
        self.frames
    }

    /// Clears the table, the log and the load (the nodes stay): every consumer gets a whole
    /// view next.
    pub fn clear(&mut self) {
        self.rows.clear();
        self.log.clear();
        self.load.clear();
        self.ids_dropped = 0;
        self.frames = 0;
        if let Some(signals) = &mut self.signals {
            signals.clear();
        }
        self.next_seq();
        self.cleared_at = self.seq;
    }

    /// What changed since `cursor`, at `now`: rows, log frames passing `filter` (the newest
    /// `max_log`), load samples, nodes, fault marks; a new consumer gets everything kept.
    /// Call [`Cursor`] advancing through [`BusView::advance`] once the delta was delivered.
    pub fn delta(
        &self,
        cursor: &Cursor,
        now: Duration,
        filter: &LogFilter,
        max_log: usize,
    ) -> Delta {
        self.delta_within(cursor, now, filter, max_log, self.config.retention)
    }

    /// As [`BusView::delta`], but a new consumer gets the load, histories and fault marks of
    /// the last `window` only (what its charts show), each history with the sample before
    /// the window.
    pub fn delta_within(
        &self,
        cursor: &Cursor,
        now: Duration,
        filter: &LogFilter,
        max_log: usize,
        window: Duration,
    ) -> Delta {
        let full = !cursor.fresh || cursor.seq < self.cleared_at;
        // What a chart of the window shows (everything kept for a consumer that has the rest).
        let from = if full {
            now.saturating_sub(window).as_secs_f64()
        } else {
            f64::NEG_INFINITY
        };
        let since = if full { 0 } else { cursor.seq };
        let highlight = self.config.highlight;
        // A highlight that ran out since the last delta changes the row too.
        let expired = |row: &Row| {
            !full
                && row.changed_at.iter().flatten().any(|&c| {
                    let end = c + highlight;
                    end > cursor.at && end <= now
                })
        };
        let ids = self
            .rows
            .iter()
            .filter(|(_, r)| r.seq > since || expired(r))
            .map(|(&key, r)| self.row(key, r, now))
            .collect();
        let messages = self.signals.as_ref().map_or_else(Vec::new, |s| {
            s.changed(since, (!full).then_some(cursor.at), now, highlight)
        });
        let mut log = Vec::new();
        let mut passed = 0u64;
        let mut in_log = 0u64;
        for e in self.log.iter().rev().take_while(|e| e.seq > since) {
            in_log += 1;
            if e.passes(filter) {
                passed += 1;
                if log.len() < max_log {
                    log.push(e.entry());
                }
            }
        }
        log.reverse();
        // Frames that left the log (its capacity) before this consumer got them: missed too,
        // whatever its filter (they can no longer be looked at).
        let overrun = if full {
            0
        } else {
            self.logged
                .saturating_sub(cursor.logged)
                .saturating_sub(in_log)
        };
        let nodes = self
            .nodes
            .values()
            .map(|n| node_view(n, since, from))
            .collect();
        Delta {
            full,
            t: now.as_secs_f64(),
            ids,
            messages,
            ids_dropped: self.ids_dropped,
            log_skipped: passed - log.len() as u64 + overrun,
            log,
            load: self
                .load
                .iter()
                .filter(|s| s.seq > since && s.t >= from)
                .copied()
                .collect(),
            nodes,
            faults: self
                .faults
                .iter()
                .filter(|f| f.seq > since && f.until.is_none_or(|u| u >= from))
                .cloned()
                .collect(),
            frames: self.frames,
            error_frames: self.error_frames,
            frames_per_s: self.last_frames_per_s,
            bitrate: self.reported.map(|(_, b)| b).or(self.config.bitrate),
        }
    }

    /// The cursor after a delta taken at `now` was delivered.
    pub fn advance(&self, now: Duration) -> Cursor {
        Cursor {
            seq: self.seq,
            at: now,
            fresh: true,
            logged: self.logged,
        }
    }

    /// The whole table at `now`, sorted by ID.
    pub fn rows(&self, now: Duration) -> Vec<IdRow> {
        self.rows_page(now, 0, usize::MAX)
    }

    /// At most `n` rows of the table from the `skip`th, at `now`, sorted by ID: what a
    /// terminal shows, put in words without the thousands of rows it does not show.
    pub fn rows_page(&self, now: Duration, skip: usize, n: usize) -> Vec<IdRow> {
        self.rows
            .iter()
            .skip(skip)
            .take(n)
            .map(|(&key, r)| self.row(key, r, now))
            .collect()
    }

    /// The DBC database the view decodes with, if any.
    pub fn database(&self) -> Option<&Database> {
        self.signals.as_ref().map(SignalTable::database)
    }

    /// At most `n` messages of the database seen on the bus, from the `skip`th, sorted by ID,
    /// each with its signals, at `now` (none without a database).
    pub fn messages_page(&self, now: Duration, skip: usize, n: usize) -> Vec<MessageRow> {
        self.signals
            .as_ref()
            .map_or_else(Vec::new, |s| s.page(now, self.config.highlight, skip, n))
    }

    /// Messages of the database seen on the bus.
    pub fn message_count(&self) -> usize {
        self.signals.as_ref().map_or(0, SignalTable::len)
    }

    /// The signal a consumer names `Message.Signal`.
    pub fn signal(&self, name: &str) -> Result<SignalKey, SignalError> {
        self.signals
            .as_ref()
            .ok_or(SignalError::NoDatabase)?
            .key(name)
    }

    /// `key`'s values since `cursor`, at `now`: for a new consumer (as [`BusView::delta`]
    /// decides) those of the last `window` with the one before, else the new ones.
    pub fn series(
        &self,
        key: &SignalKey,
        cursor: &Cursor,
        now: Duration,
        window: Duration,
    ) -> Series {
        let full = !cursor.fresh || cursor.seq < self.cleared_at;
        let from = now.saturating_sub(window).as_secs_f64();
        let table = self
            .signals
            .as_ref()
            .expect("a signal key comes from the view's database");
        table.series(key, full, cursor.seq, from)
    }

    /// Frames per second over the last complete second.
    pub fn frames_per_s(&self) -> u64 {
        self.last_frames_per_s
    }

    /// Every node in words, as [`Delta::nodes`] has them but without their histories.
    pub fn node_views(&self) -> Vec<NodeView> {
        self.nodes
            .values()
            .map(|n| node_view(n, u64::MAX, f64::INFINITY))
            .collect()
    }

    /// The newest `n` log frames passing `filter`, oldest first.
    pub fn log_tail(&self, filter: &LogFilter, n: usize) -> Vec<LogEntry> {
        let mut tail: Vec<LogEntry> = self
            .log
            .iter()
            .rev()
            .filter(|e| e.passes(filter))
            .take(n)
            .map(Logged::entry)
            .collect();
        tail.reverse();
        tail
    }

    /// The load samples kept, oldest first.
    pub fn load(&self) -> impl DoubleEndedIterator<Item = &LoadSample> + ExactSizeIterator {
        self.load.iter()
    }

    /// Every node's latest status.
    pub fn node_statuses(&self) -> impl Iterator<Item = &NodeStatus> {
        self.nodes.values().map(|n| &n.status)
    }

    /// The fault marks kept, oldest first.
    pub fn faults(&self) -> impl Iterator<Item = &FaultMark> {
        self.faults.iter()
    }

    /// A node's kept TEC/REC history.
    pub fn history(&self, number: u32) -> impl Iterator<Item = &ErrorSample> {
        self.nodes
            .get(&number)
            .into_iter()
            .flat_map(|n| n.history.iter())
    }

    fn row(&self, key: Id, r: &Row, now: Duration) -> IdRow {
        let mut changed = 0u8;
        for (i, c) in r.changed_at.iter().enumerate() {
            if c.is_some_and(|c| now < c + self.config.highlight) {
                changed |= 1 << i;
            }
        }
        let id = candump_id(key);
        let data = r
            .frame
            .payload()
            .iter()
            .map(|b| format!("{b:02X}"))
            .collect();
        IdRow {
            id,
            extended: key.is_extended(),
            count: r.count,
            period_ms: r.period.map(|p| p.as_secs_f64() * 1000.0),
            dlc: r.frame.dlc(),
            remote: r.frame.is_remote(),
            data,
            changed,
            age_ms: now.saturating_sub(r.seen_at).as_millis() as u64,
            key,
        }
    }
}

/// Fault marks kept at most (ended ones also leave after the retention time).
const MAX_FAULT_MARKS: usize = 256;

/// A frame or an error frame as the log ring keeps it: the record only, put in words when a
/// consumer takes it (a busy bus logs far more frames than anyone reads).
#[derive(Clone, Debug)]
struct Logged {
    seq: u64,
    at: Timestamp,
    record: Record,
}

impl Logged {
    fn passes(&self, filter: &LogFilter) -> bool {
        match &self.record {
            Record::Frame(f) => filter.matches(f),
            Record::Fd(f) => filter.matches_id(f.id()),
            Record::Error(e) => filter.matches_error(e),
        }
    }

    fn entry(&self) -> LogEntry {
        let (frame, error) = match &self.record {
            Record::Frame(f) => (f.to_string(), None),
            Record::Fd(f) => (f.to_string(), None),
            Record::Error(e) => {
                let (_, data) = e.encode();
                let bytes: String = data[..e.data_len()]
                    .iter()
                    .map(|b| format!("{b:02X}"))
                    .collect();
                (
                    format!("{:08X}#{bytes}", e.can_id()),
                    Some(ErrorEntry::of(e)),
                )
            }
        };
        LogEntry {
            seq: self.seq,
            at: self.at,
            frame,
            error,
            record: self.record.clone(),
        }
    }
}

/// Appends `sample` to a node's history: a run of equal samples is kept as its first and last
/// (the last moves on), samples older than `oldest` leave but for the one before it (where a
/// chart's line comes from), and at most `cap` stay.
fn keep_sample(history: &mut VecDeque<ErrorSample>, sample: ErrorSample, oldest: f64, cap: usize) {
    let n = history.len();
    if n >= 2 && history[n - 1].same_values(&sample) && history[n - 2].same_values(&sample) {
        history[n - 1] = sample;
    } else {
        history.push_back(sample);
    }
    while history.len() > 1 && history[1].t <= oldest {
        history.pop_front();
    }
    while history.len() > cap {
        history.pop_front();
    }
}

fn state_word(state: ErrorState) -> &'static str {
    match state {
        ErrorState::Active => "active",
        ErrorState::Passive => "passive",
        ErrorState::BusOff => "bus-off",
    }
}

fn node_view(n: &Node, since: u64, from: f64) -> NodeView {
    let s = &n.status;
    let e = s.errors;
    NodeView {
        number: s.number,
        name: s.name.clone(),
        state: s.state.to_string(),
        tec: e.map(|e| e.txerr),
        rec: e.map(|e| e.rxerr),
        status: s.sr.map(|sr| sr.to_string()),
        sr: s.sr.map(|sr| sr.bits()),
        alc: e.and_then(|e| e.alc).map(|a| format!("0x{:02X} {a}", a.0)),
        ecc: e.and_then(|e| e.ecc).map(|c| format!("0x{:02X} {c}", c.0)),
        sent: s.counters.sent,
        received: s.counters.received,
        bus_errors: s.counters.bus_errors,
        bus_off: s.counters.bus_off,
        arbitration_lost: s.counters.arbitration_lost,
        history: {
            // The samples in the window, and the one before it.
            let first = n.history.partition_point(|h| h.t < from).saturating_sub(1);
            n.history
                .iter()
                .skip(first)
                .filter(|h| h.seq > since)
                .copied()
                .collect()
        },
    }
}
