//! python-can's SQLite log: table `messages` with
//! `ts REAL, arbitration_id INTEGER, extended INTEGER, remote INTEGER, error INTEGER,
//! dlc INTEGER, data BLOB`.
//!
//! Seconds as a float (microseconds survive; a float cannot hold nanoseconds at today's
//! epoch), no interface and no direction (entries read back on `can0`). An error frame is a
//! row with `error` 1, the class as its ID and its SocketCAN data bytes (as many as it has).
//! A CAN FD frame is a row like any frame, its length as the `dlc` and its data, as
//! python-can's writer stores it: BRS, ESI and the FD mark have no column, so a row of more
//! than 8 data bytes reads back as a CAN FD frame without BRS and ESI and an FD frame of 8
//! bytes or fewer comes back classic (the columns stay python-can's, which reads every row).
//!
//! The writer keeps one transaction open and commits it at least every half second (from a
//! timer thread when idle, from `write` when busy), on [`Writer::commit`] and on
//! [`Writer::finish`]: a killed process loses at most what came after the last commit, a
//! stopped one nothing. A caller that must never lose what it showed commits before showing
//! it (`buslab dump` does). The reader fetches rows in batches by rowid, so memory stays
//! bounded whatever the table's size; it checks the schema first and never loads a value
//! longer than [`MAX_VALUE`] (see [`Reader`]).

use std::collections::VecDeque;
use std::io;
use std::path::Path;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::{Arc, LazyLock, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use buslab_bus::ErrorFrame;
use buslab_can::{Frame, Id};
use rusqlite::config::DbConfig;
use rusqlite::types::{Value, ValueRef};
use rusqlite::{Connection, OpenFlags, OptionalExtension, params};

use crate::codec::LogReader;
use crate::error::{Problem, ReadError};
use crate::{Location, Message, Record, Timestamp};

pub const TABLE: &str = "messages";
/// python-can's table, column for column.
pub const CREATE_TABLE: &str = "CREATE TABLE IF NOT EXISTS messages (
  ts REAL,
  arbitration_id INTEGER,
  extended INTEGER,
  remote INTEGER,
  error INTEGER,
  dlc INTEGER,
  data BLOB
)";
const INSERT: &str = "INSERT INTO messages VALUES (?, ?, ?, ?, ?, ?, ?)";
/// The interface name entries of a database get.
pub const INTERFACE: &str = "can0";
/// How often the writer commits at least.
pub const COMMIT_EVERY: Duration = Duration::from_millis(500);
const BATCH: i64 = 1024;

/// The most bytes a value of a row may hold: a CAN FD frame's 64 data bytes. A longer blob or
/// text is an error naming its row and size, found without reading the value.
pub const MAX_VALUE: i64 = 64;

/// python-can's columns, in its order, with how an error names each one's value.
const COLUMNS: [(&str, &str); 7] = [
    ("ts", "the ts value"),
    ("arbitration_id", "the arbitration_id value"),
    ("extended", "the extended value"),
    ("remote", "the remote value"),
    ("error", "the error value"),
    ("dlc", "the dlc value"),
    ("data", "the data value"),
];

/// A column as read: its size in bytes (`None` for NULL) and its value (NULL when larger than
/// [`MAX_VALUE`]).
struct Cell {
    size: Option<i64>,
    value: Value,
}

struct Row {
    rowid: i64,
    cells: [Cell; 7],
}

/// Reads python-can's `messages` table in insertion (rowid) order.
///
/// The database is checked before any row is read: `messages` must be an ordinary table with
/// a rowid and python-can's columns, none of them generated (a generated column is computed at
/// every read, and its expression can take any time and memory). SQLite's defensive mode is on
/// and the schema untrusted. Each value's size is asked for before the value, so a hostile
/// blob is never loaded.
pub struct Reader {
    conn: Connection,
    last_rowid: i64,
    batch: VecDeque<Row>,
    row: u64,
    done: bool,
}

/// The query of a batch: per column its size, then its value if it is small.
static BATCH_QUERY: LazyLock<String> = LazyLock::new(|| {
    let mut cols = String::new();
    for (name, _) in COLUMNS {
        cols.push_str(&format!(
            ", octet_length(\"{name}\"), CASE WHEN octet_length(\"{name}\") <= {MAX_VALUE} THEN \"{name}\" END"
        ));
    }
    format!("SELECT rowid{cols} FROM main.{TABLE} WHERE rowid > ?1 ORDER BY rowid LIMIT ?2")
});

fn not_a_log(reason: String) -> ReadError {
    ReadError::fatal(
        None,
        Problem::NotFormat {
            format: "python-can SQLite log",
            reason,
        },
    )
}

impl Reader {
    /// Opens a database read-only and checks its `messages` table (see [`Reader`]); a file
    /// that is not such a database is an error saying why.
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        let sql = |e: rusqlite::Error| ReadError::fatal(None, e);
        let conn = Connection::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(sql)?;
        conn.busy_timeout(Duration::from_secs(10)).map_err(sql)?;
        conn.set_db_config(DbConfig::SQLITE_DBCONFIG_DEFENSIVE, true)
            .map_err(sql)?;
        conn.set_db_config(DbConfig::SQLITE_DBCONFIG_TRUSTED_SCHEMA, false)
            .map_err(sql)?;
        check_schema(&conn).map_err(|e| match e {
            Refused::Sql(e) => sql(e),
            Refused::Reason(reason) => not_a_log(reason),
        })?;
        Ok(Self {
            conn,
            last_rowid: i64::MIN,
            batch: VecDeque::new(),
            row: 0,
            done: false,
        })
    }

    fn fetch(&mut self) -> Result<(), Problem> {
        let mut stmt = self.conn.prepare_cached(&BATCH_QUERY)?;
        let rows = stmt.query_map(params![self.last_rowid, BATCH], |r| {
            let cell = |i: usize| -> rusqlite::Result<Cell> {
                Ok(Cell {
                    size: r.get(1 + 2 * i)?,
                    value: value(r, 2 + 2 * i)?,
                })
            };
            Ok(Row {
                rowid: r.get(0)?,
                cells: [
                    cell(0)?,
                    cell(1)?,
                    cell(2)?,
                    cell(3)?,
                    cell(4)?,
                    cell(5)?,
                    cell(6)?,
                ],
            })
        })?;
        for row in rows {
            let row = row?;
            // A corrupt database can hand out the same rows again: stop rather than loop.
            if row.rowid <= self.last_rowid {
                return Err(Problem::Expected {
                    expected: "rowids in increasing order (the database is corrupt)",
                    found: row.rowid.to_string(),
                });
            }
            self.last_rowid = row.rowid;
            self.batch.push_back(row);
        }
        Ok(())
    }

    /// Reads the next entry into `entry`; `Ok(false)` at the end.
    pub fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        if self.done {
            return Ok(false);
        }
        if self.batch.is_empty() {
            if let Err(e) = self.fetch() {
                self.done = true;
                return Err(ReadError::fatal(Some(Location::Row(self.row + 1)), e));
            }
            if self.batch.is_empty() {
                self.done = true;
                return Ok(false);
            }
        }
        let Some(row) = self.batch.pop_front() else {
            return Ok(false);
        };
        self.row += 1;
        let at = Location::Row(self.row);
        decode_row(&row, entry).map_err(|p| ReadError::bad(at, p))?;
        Ok(true)
    }
}

/// Why a database is not read.
enum Refused {
    Sql(rusqlite::Error),
    Reason(String),
}

impl From<rusqlite::Error> for Refused {
    fn from(e: rusqlite::Error) -> Self {
        Refused::Sql(e)
    }
}

/// `messages` is an ordinary table with a rowid and python-can's columns, none generated.
fn check_schema(conn: &Connection) -> Result<(), Refused> {
    let refuse = |reason: String| Err(Refused::Reason(reason));
    let kind: Option<(String, bool)> = conn
        .query_row(
            "SELECT type, wr FROM pragma_table_list WHERE schema = 'main' AND name = ?1",
            [TABLE],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
        .optional()?;
    match kind {
        None => {
            return refuse(format!(
                "no table {TABLE:?} (python-can's SqliteWriter writes one)"
            ));
        }
        Some((kind, _)) if kind != "table" => {
            return refuse(format!("{TABLE:?} is a {kind}, not a table of stored rows"));
        }
        Some((_, true)) => {
            return refuse(format!(
                "{TABLE:?} is a WITHOUT ROWID table (rows are read by rowid)"
            ));
        }
        Some(_) => {}
    }
    let mut stmt = conn.prepare("SELECT name, hidden FROM pragma_table_xinfo(?1)")?;
    let mut names = Vec::new();
    let mut rows = stmt.query([TABLE])?;
    while let Some(r) = rows.next()? {
        let name: String = r.get(0)?;
        let hidden: i64 = r.get(1)?;
        if hidden != 0 {
            let how = match hidden {
                2 => "a generated (VIRTUAL) column",
                3 => "a generated (STORED) column",
                _ => "a hidden column",
            };
            return refuse(format!(
                "column {name:?} is {how}: buslab reads stored columns only (a generated value is computed at every read, at any cost)"
            ));
        }
        if ["rowid", "_rowid_", "oid"]
            .iter()
            .any(|r| name.eq_ignore_ascii_case(r))
        {
            return refuse(format!("column {name:?} hides the table's rowid"));
        }
        names.push(name);
    }
    for (want, _) in COLUMNS {
        if !names.iter().any(|n| n.eq_ignore_ascii_case(want)) {
            return refuse(format!(
                "{TABLE:?} has no column {want:?} (python-can's columns: ts, arbitration_id, extended, remote, error, dlc, data)"
            ));
        }
    }
    Ok(())
}

/// Column `i` as a value. rusqlite's own conversion panics on TEXT that is not UTF-8 (a
/// damaged or hostile file has such text); here it becomes text with replacement characters,
/// which no column accepts, so the row is refused with what was found.
fn value(r: &rusqlite::Row<'_>, i: usize) -> rusqlite::Result<Value> {
    Ok(match r.get_ref(i)? {
        ValueRef::Text(bytes) => Value::Text(String::from_utf8_lossy(bytes).into_owned()),
        other => Value::from(other),
    })
}

fn int(v: &Value, what: &'static str) -> Result<i64, Problem> {
    match v {
        Value::Integer(i) => Ok(*i),
        other => Err(Problem::Expected {
            expected: what,
            found: format!("{other:?}"),
        }),
    }
}

fn decode_row(row: &Row, entry: &mut Message) -> Result<(), Problem> {
    for (cell, (_, what)) in row.cells.iter().zip(COLUMNS) {
        if let Some(size) = cell.size
            && size > MAX_VALUE
        {
            return Err(Problem::TooBig {
                what,
                claimed: size as u64,
                limit: MAX_VALUE as u64,
            });
        }
    }
    let [ts, id, extended, remote, error, dlc, data] = &row.cells;
    let ts = match ts.value {
        Value::Real(f) => f,
        Value::Integer(i) => i as f64,
        ref other => {
            return Err(Problem::Expected {
                expected: "ts in seconds (REAL)",
                found: format!("{other:?}"),
            });
        }
    };
    // Microseconds in 64 bits: a later time would be clamped, not read.
    if !ts.is_finite() || !(0.0..1.8e13).contains(&ts) {
        return Err(Problem::Expected {
            expected: "ts a time in seconds, 0 up to 1.8e13",
            found: ts.to_string(),
        });
    }
    let raw = int(&id.value, "an integer arbitration_id")?;
    let raw = u32::try_from(raw).map_err(|_| Problem::Expected {
        expected: "an arbitration_id 0..0x1FFFFFFF",
        found: raw.to_string(),
    })?;
    let extended = int(&extended.value, "extended 0 or 1")? != 0;
    let remote = int(&remote.value, "remote 0 or 1")? != 0;
    let error = int(&error.value, "error 0 or 1")? != 0;
    let dlc = int(&dlc.value, "an integer dlc")?;
    let data: &[u8] = match &data.value {
        Value::Blob(b) => b,
        Value::Null => &[],
        other => {
            return Err(Problem::Expected {
                expected: "data as a BLOB",
                found: format!("{other:?}"),
            });
        }
    };
    let record = if error {
        Record::Error(ErrorFrame::decode(raw & 0x1FFF_FFFF, data)?)
    } else {
        let dlc_range = if remote { 0..=8 } else { 0..=MAX_VALUE };
        if !dlc_range.contains(&dlc) {
            return Err(Problem::Expected {
                expected: if remote {
                    "a remote frame's dlc 0..8"
                } else {
                    "a dlc 0..8 (or a CAN FD length up to 64)"
                },
                found: dlc.to_string(),
            });
        }
        let id = if extended {
            Id::extended(raw)?
        } else {
            Id::standard(u16::try_from(raw).map_err(|_| Problem::Expected {
                expected: "a standard arbitration_id 0..0x7FF",
                found: raw.to_string(),
            })?)?
        };
        if remote {
            Record::Frame(Frame::remote(id, dlc as u8)?)
        } else {
            if dlc != data.len() as i64 {
                return Err(Problem::Expected {
                    expected: "as many data bytes as the dlc",
                    found: format!("dlc {dlc} with {} bytes", data.len()),
                });
            }
            crate::csv::frame_of_row(id, data)?
        }
    };
    entry.at = Timestamp::from_secs_f64(ts);
    entry.channel.clear();
    entry.channel.push_str(INTERFACE);
    entry.record = record;
    entry.direction = None;
    Ok(())
}

impl LogReader for Reader {
    fn read_into(&mut self, entry: &mut Message) -> Result<bool, ReadError> {
        Reader::read_into(self, entry)
    }
}

struct State {
    fd_warned: bool,
    conn: Option<Connection>,
    pending: u64,
    last_commit: Instant,
    /// A commit of the timer thread that failed, reported by the next call.
    failed: Option<rusqlite::Error>,
}

impl State {
    fn commit(&mut self) -> Result<(), rusqlite::Error> {
        if let Some(e) = self.failed.take() {
            return Err(e);
        }
        if self.pending == 0 {
            return Ok(());
        }
        if let Some(conn) = &self.conn
            && let Err(e) = conn.execute_batch("COMMIT; BEGIN")
        {
            // A failed COMMIT (a full disk) rolls the transaction back: its rows are gone,
            // the database is as the last commit left it. Keep one transaction open, so the
            // next commit (or `finish`) says what failed instead of "no transaction".
            if conn.is_autocommit() {
                let _ = conn.execute_batch("BEGIN");
            }
            self.pending = 0;
            return Err(e);
        }
        self.pending = 0;
        self.last_commit = Instant::now();
        Ok(())
    }
}

/// Writes python-can's `messages` table, committing at least every [`COMMIT_EVERY`].
pub struct Writer {
    state: Arc<Mutex<State>>,
    stop: Option<mpsc::Sender<()>>,
    timer: Option<JoinHandle<()>>,
}

fn sql_io(e: rusqlite::Error) -> io::Error {
    io::Error::other(e)
}

impl Writer {
    /// Creates the table in the database at `path` (a new or empty file).
    pub fn create(path: &Path) -> Result<Self, rusqlite::Error> {
        let conn = Connection::open(path)?;
        conn.busy_timeout(Duration::from_secs(10))?;
        conn.execute_batch(CREATE_TABLE)?;
        conn.execute_batch("BEGIN")?;
        let state = Arc::new(Mutex::new(State {
            fd_warned: false,
            conn: Some(conn),
            pending: 0,
            last_commit: Instant::now(),
            failed: None,
        }));
        let (stop, stopped) = mpsc::channel::<()>();
        let shared = state.clone();
        let timer = std::thread::Builder::new()
            .name("sqlite-commit".into())
            .spawn(move || {
                while let Err(RecvTimeoutError::Timeout) = stopped.recv_timeout(COMMIT_EVERY) {
                    let mut state = lock(&shared);
                    if state.failed.is_none()
                        && let Err(e) = state.commit()
                    {
                        tracing::warn!("SQLite commit failed: {e}");
                        state.failed = Some(e);
                    }
                }
            })
            .map_err(|e| rusqlite::Error::InvalidParameterName(e.to_string()))?;
        Ok(Self {
            state,
            stop: Some(stop),
            timer: Some(timer),
        })
    }

    pub fn write(&mut self, entry: &Message) -> io::Result<()> {
        let mut state = lock(&self.state);
        if let Some(e) = state.failed.take() {
            return Err(sql_io(e));
        }
        let (raw, extended, remote, error, dlc, data): (u32, bool, bool, bool, u8, &[u8]);
        let error_bytes;
        match &entry.record {
            Record::Fd(f) => {
                crate::csv::warn_fd_loss(&mut state.fd_warned, "SQLite");
                (raw, extended, remote, error, dlc) = (
                    f.id().as_raw(),
                    f.is_extended(),
                    false,
                    false,
                    f.payload().len() as u8,
                );
                data = f.payload();
            }
            Record::Frame(f) => {
                (raw, extended, remote, error, dlc) = (
                    f.id().as_raw(),
                    f.is_extended(),
                    f.is_remote(),
                    false,
                    f.dlc(),
                );
                data = f.payload();
            }
            Record::Error(e) => {
                let (class, bytes) = e.encode();
                error_bytes = bytes;
                let len = e.data_len();
                (raw, extended, remote, error, dlc) = (class, false, false, true, len as u8);
                data = &error_bytes[..len];
            }
        }
        let ts = entry.at.since_epoch_duration().as_secs_f64();
        let Some(conn) = &state.conn else {
            return Err(io::Error::other("the SQLite writer is closed"));
        };
        conn.prepare_cached(INSERT)
            .and_then(|mut stmt| stmt.execute(params![ts, raw, extended, remote, error, dlc, data]))
            .map_err(sql_io)?;
        state.pending += 1;
        // The timer thread may not get the lock while entries stream in (a mutex is not
        // fair): the writer commits on time itself then.
        if state.last_commit.elapsed() >= COMMIT_EVERY {
            state.commit().map_err(sql_io)?;
        }
        Ok(())
    }

    /// Commits what was written so far.
    pub fn commit(&mut self) -> io::Result<()> {
        lock(&self.state).commit().map_err(sql_io)
    }

    /// Stops the timer, commits and closes the database.
    pub fn finish(mut self) -> io::Result<()> {
        self.stop_timer();
        let mut state = lock(&self.state);
        state.commit().map_err(sql_io)?;
        if let Some(conn) = state.conn.take() {
            conn.execute_batch("COMMIT").map_err(sql_io)?;
            conn.close().map_err(|(_, e)| sql_io(e))?;
        }
        Ok(())
    }

    fn stop_timer(&mut self) {
        drop(self.stop.take());
        if let Some(t) = self.timer.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Writer {
    /// Dropped without `finish`: still commits what was written.
    fn drop(&mut self) {
        self.stop_timer();
        let mut state = lock(&self.state);
        if let Err(e) = state.commit() {
            tracing::warn!("SQLite commit failed: {e}");
        }
        if let Some(conn) = state.conn.take() {
            let _ = conn.execute_batch("COMMIT");
        }
    }
}

fn lock(state: &Mutex<State>) -> MutexGuard<'_, State> {
    state.lock().unwrap_or_else(|p| p.into_inner())
}
