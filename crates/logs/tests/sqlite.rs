//! python-can SQLite logs: what is not such a log is refused before any row is read, with the
//! reason; values longer than a CAN row needs are errors naming the row and the size.

use std::path::{Path, PathBuf};

use buslab_logs::sqlite::{MAX_VALUE, Reader};
use buslab_logs::{Format, Location, Message, Problem, ReadError, Record, open_reader};
use rusqlite::Connection;

const PYTHON_CAN_TABLE: &str = "CREATE TABLE messages (ts REAL, arbitration_id INTEGER, \
    extended INTEGER, remote INTEGER, error INTEGER, dlc INTEGER, data BLOB)";

fn database(dir: &Path, name: &str, sql: &str) -> PathBuf {
    let path = dir.join(name);
    let conn = Connection::open(&path).unwrap();
    conn.execute_batch(sql).unwrap();
    conn.close().unwrap();
    path
}

/// The error opening `path` (as `buslab log …` opens it: the message names the file).
fn refused(path: &Path) -> String {
    assert!(Reader::open(path).is_err_and(|e| e.is_fatal()));
    match open_reader(path, Format::Sqlite) {
        Ok(_) => panic!("{} was opened", path.display()),
        Err(e) => e.to_string(),
    }
}

fn read_all(mut reader: Reader) -> Vec<Result<Message, ReadError>> {
    let mut out = Vec::new();
    for _ in 0..100 {
        let mut e = Message::default();
        match reader.read_into(&mut e) {
            Ok(true) => out.push(Ok(e)),
            Ok(false) => return out,
            Err(err) => out.push(Err(err)),
        }
    }
    panic!("the reader does not end");
}

/// python-can's columns have no FD mark, BRS or ESI: an FD frame is a row of its length and
/// data, as python-can's writer stores one; more than 8 bytes read back as CAN FD without
/// BRS and ESI, 8 or fewer as a classic frame.
#[test]
fn fd_frames_are_rows_as_python_can_writes_them() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fd.db");
    let mut w = buslab_logs::create_writer(&path, Format::Sqlite).unwrap();
    for (i, fd) in ["1ABCDEF0##3000102030405060708090A0B", "123##10011"]
        .iter()
        .enumerate()
    {
        w.write(&Message {
            at: buslab_logs::Timestamp::from_micros(1_700_000_000_000_000 + i as u64),
            channel: "can0".into(),
            direction: None,
            record: Record::Fd(fd.parse().unwrap()),
        })
        .unwrap();
    }
    w.finish().unwrap();
    let conn = Connection::open(&path).unwrap();
    let rows: Vec<(i64, i64, i64, i64, i64, Vec<u8>)> = conn
        .prepare("SELECT arbitration_id, extended, remote, error, dlc, data FROM messages")
        .unwrap()
        .query_map([], |r| {
            Ok((
                r.get(0)?,
                r.get(1)?,
                r.get(2)?,
                r.get(3)?,
                r.get(4)?,
                r.get(5)?,
            ))
        })
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert_eq!(
        rows,
        [
            (0x1ABC_DEF0, 1, 0, 0, 12, (0..12).collect()),
            (0x123, 0, 0, 0, 2, vec![0x00, 0x11]),
        ]
    );
    let back: Vec<String> = read_all(Reader::open(&path).unwrap())
        .iter()
        .map(|e| e.as_ref().unwrap().record.to_string())
        .collect();
    assert_eq!(back, ["1ABCDEF0##0000102030405060708090A0B", "123#0011"]);
}

/// Issue 25: an 8 KB database whose `data` is a generated column (`zeroblob(100000000)`)
/// made `buslab log info` take 11.6 s and 2.2 GB, more with every row: the expression was
/// computed at every read. Generated columns are refused from the schema, before any row.
#[test]
fn sqlite_log_with_a_generated_column_is_refused_before_any_row() {
    let dir = tempfile::tempdir().unwrap();
    let mut inserts = String::new();
    for i in 0..50 {
        inserts.push_str(&format!(
            "INSERT INTO messages (ts, arbitration_id, extended, remote, error, dlc) VALUES ({i}, 1, 0, 0, 0, 8);"
        ));
    }
    for (name, kind) in [("virtual.db", "VIRTUAL"), ("stored.db", "STORED")] {
        let sql = format!(
            "CREATE TABLE messages (ts REAL, arbitration_id INTEGER, extended INTEGER, \
             remote INTEGER, error INTEGER, dlc INTEGER, \
             data BLOB GENERATED ALWAYS AS (zeroblob(1000)) {kind}); {inserts}"
        );
        let path = database(dir.path(), name, &sql);
        let err = refused(&path);
        assert!(
            err.contains(name)
                && err.contains("column \"data\"")
                && err.contains(&format!("generated ({kind})")),
            "{err}"
        );
    }
}

#[test]
fn what_is_not_a_can_log_table_is_refused_saying_why() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases = [
        ("none.db", "CREATE TABLE other (x);".to_string(), "no table \"messages\""),
        (
            "view.db",
            "CREATE VIEW messages AS WITH RECURSIVE r(x) AS (SELECT 1 UNION ALL SELECT x + 1 FROM r) \
             SELECT x AS ts, 1 AS arbitration_id, 0 AS extended, 0 AS remote, 0 AS error, 0 AS dlc, \
             x'00' AS data FROM r;"
                .to_string(),
            "is a view",
        ),
        (
            "fts.db",
            "CREATE VIRTUAL TABLE messages USING fts5(ts, arbitration_id, extended, remote, error, dlc, data);"
                .to_string(),
            "is a virtual",
        ),
        (
            "norowid.db",
            "CREATE TABLE messages (ts REAL PRIMARY KEY, arbitration_id INTEGER, extended INTEGER, \
             remote INTEGER, error INTEGER, dlc INTEGER, data BLOB) WITHOUT ROWID;"
                .to_string(),
            "WITHOUT ROWID",
        ),
        (
            "rowid.db",
            format!("{PYTHON_CAN_TABLE}; ALTER TABLE messages ADD COLUMN rowid TEXT;"),
            "column \"rowid\" hides",
        ),
        (
            "chat.db",
            "CREATE TABLE messages (id INTEGER PRIMARY KEY, body TEXT);".to_string(),
            "no column \"ts\"",
        ),
    ];
    for (name, sql, want) in cases {
        let err = refused(&database(d, name, &sql));
        assert!(err.contains(name) && err.contains(want), "{name}: {err}");
    }
    // Not a database at all, and an empty file (an empty database).
    let junk = d.join("junk.db");
    std::fs::write(
        &junk,
        b"SQLite format 3\0 but nothing after it, really".repeat(100),
    )
    .unwrap();
    assert!(refused(&junk).contains("junk.db"));
    let empty = d.join("empty.db");
    std::fs::write(&empty, b"").unwrap();
    assert!(refused(&empty).contains("no table"));
}

/// A value longer than [`MAX_VALUE`] is an error naming its row and size, found without
/// loading it (a 50 MB blob costs nothing); the rows after it are read.
#[test]
fn long_values_are_errors_naming_the_row_and_size() {
    let dir = tempfile::tempdir().unwrap();
    let path = database(
        dir.path(),
        "long.db",
        &format!(
            "{PYTHON_CAN_TABLE};
             INSERT INTO messages VALUES (1.0, 291, 0, 0, 0, 1, x'11');
             INSERT INTO messages VALUES (2.0, 291, 0, 0, 0, 8, zeroblob(50000000));
             INSERT INTO messages VALUES (printf('%.*c', 100, 'x'), 291, 0, 0, 0, 1, x'11');
             INSERT INTO messages VALUES (4.0, 291, 0, 0, 0, 12, zeroblob(12));
             INSERT INTO messages VALUES (5.0, 136, 0, 0, 1, 9, zeroblob(9));
             INSERT INTO messages VALUES (6.0, 136, 0, 0, 1, 8, x'0000040200000001');
             INSERT INTO messages VALUES (7.0, 64, 0, 0, 1, 0, NULL);
             INSERT INTO messages VALUES (1e99, 291, 0, 0, 0, 1, x'11');"
        ),
    );
    let got = read_all(Reader::open(&path).unwrap());
    assert_eq!(got.len(), 8);
    let err = |i: usize| got[i].as_ref().unwrap_err();
    assert_eq!(err(1).at(), Some(Location::Row(2)));
    assert!(
        matches!(err(1).problem(), Problem::TooBig { claimed: 50_000_000, limit, .. } if *limit == MAX_VALUE as u64),
        "{}",
        err(1)
    );
    assert!(
        err(1)
            .to_string()
            .contains("the data value claims 50000000 bytes")
    );
    assert!(
        err(2)
            .to_string()
            .contains("row 3: the ts value claims 100 bytes"),
        "{}",
        err(2)
    );
    // 12 data bytes: a CAN FD frame, as python-can stores one (without BRS and ESI).
    assert_eq!(
        buslab_logs::candump::format_line(got[3].as_ref().unwrap(), false),
        "(0000000004.000000) can0 123##0000000000000000000000000"
    );
    // An error frame has at most 8 data bytes: more is refused, not cut.
    assert!(
        err(4).to_string().contains("at most 8 data bytes, not 9"),
        "{}",
        err(4)
    );
    let record = |i: usize| &got[i].as_ref().unwrap().record;
    assert!(matches!(record(0), Record::Frame(_)));
    let line = |i: usize| buslab_logs::candump::format_line(got[i].as_ref().unwrap(), false);
    assert_eq!(
        line(5),
        "(0000000006.000000) can0 20000088#0000040200000001"
    );
    assert_eq!(line(6), "(0000000007.000000) can0 20000040#");
    // A time beyond 64-bit microseconds is refused, not clamped.
    assert!(
        err(7)
            .to_string()
            .contains("row 8: expected ts a time in seconds"),
        "{}",
        err(7)
    );
}
