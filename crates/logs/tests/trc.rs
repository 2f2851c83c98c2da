//! PEAK TRC and CAN FD: 2.x records of type FD (neither flag), FB (BRS), FE (ESI), BI (both),
//! their `L` column the DLC (0..15) or their `l` column the length; version 1.x has none.

use std::io::Cursor;

use buslab_logs::trc::{Reader, Version, Writer};
use buslab_logs::{Location, Message, ReadError};

#[path = "support/fd.rs"]
mod fd;

fn read(text: &str) -> Vec<Result<Message, ReadError>> {
    let mut reader = Reader::new(Cursor::new(text.as_bytes().to_vec()));
    let mut out = Vec::new();
    for _ in 0..=text.lines().count() {
        let mut e = Message::default();
        match reader.read_into(&mut e) {
            Ok(true) => out.push(Ok(e)),
            Ok(false) => return out,
            Err(err) => out.push(Err(err)),
        }
    }
    panic!("the reader does not end");
}

fn records(text: &str) -> Vec<String> {
    read(text)
        .into_iter()
        .map(|r| match r {
            Ok(e) => format!("{} {}", e.channel, e.record),
            Err(e) => format!("error: {e}"),
        })
        .collect()
}

/// PCAN-View's 2.1 layout (`L` the DLC) and a 2.0 file with a data length column (`l`).
#[test]
fn fd_records_of_each_type() {
    let v21 = ";$FILEVERSION=2.1\r\n;$STARTTIME=45000.5\r\n;$COLUMNS=N,O,T,B,I,d,R,L,D\r\n\
      1         1.000 FD 1      0123 Rx -  9    00 01 02 03 04 05 06 07 08 09 0A 0B\r\n\
      2         2.000 FB 2  1ABCDEF0 Tx -  0\r\n\
      3         3.000 FE 1      07FF Rx -  2    AA BB\r\n\
      4         4.000 BI 1      0100 Rx -  15   00 01 02 03 04 05 06 07 08 09 0A 0B 0C 0D 0E 0F 10 11 12 13 14 15 16 17 18 19 1A 1B 1C 1D 1E 1F 20 21 22 23 24 25 26 27 28 29 2A 2B 2C 2D 2E 2F 30 31 32 33 34 35 36 37 38 39 3A 3B 3C 3D 3E 3F\r\n\
      5         5.000 DT 1      0100 Rx -  2    11 22\r\n";
    let mut all: String = (0..64).map(|i| format!("{i:02X}")).collect();
    all.insert_str(0, "can0 100##3");
    assert_eq!(
        records(v21),
        [
            "can0 123##0000102030405060708090A0B".to_string(),
            "can1 1ABCDEF0##1".into(),
            "can0 7FF##2AABB".into(),
            all,
            "can0 100#1122".into(),
        ]
    );
    let v20 = ";$FILEVERSION=2.0\r\n;$COLUMNS=N,O,T,I,d,l,D\r\n\
      1         1.000 FB     0123 Rx 12   00 01 02 03 04 05 06 07 08 09 0A 0B\r\n";
    assert_eq!(records(v20), ["can0 123##1000102030405060708090A0B"]);
}

/// Every FD length, BRS/ESI combination and ID kind through the 2.1 writer and the reader.
#[test]
fn every_fd_frame_round_trips_in_trc_2_1() {
    let entries = fd::every_fd_entry();
    let mut w = Writer::new(Vec::new(), Version::V2_1);
    for e in &entries {
        w.write(e).unwrap();
    }
    let text = String::from_utf8(w.finish().unwrap()).unwrap();
    // The 12-byte extended frame with BRS and ESI: type BI, DLC 9.
    assert!(
        text.contains(
            "     80       118.500 BI 2  1ABC004F Rx -  9    4F 48 41 5A 53 6C 65 7E 77 70 09 02\r\n"
        ),
        "{text}"
    );
    let back: Vec<Message> = read(&text).into_iter().map(Result::unwrap).collect();
    assert_eq!(back, entries);
}

/// TRC 1.1 has no CAN FD: the writer refuses an FD frame by name and writes nothing for it.
#[test]
fn trc_1_1_refuses_fd_frames_by_name() {
    let entries = fd::every_fd_entry();
    let mut w = Writer::new(Vec::new(), Version::V1_1);
    let err = w.write(&entries[5]).unwrap_err();
    assert_eq!(err.kind(), std::io::ErrorKind::InvalidInput);
    let text = err.to_string();
    assert!(
        text.contains("TRC 1.1 has no CAN FD records") && text.contains("TRC 2.1"),
        "{text}"
    );
    let written = String::from_utf8(w.finish().unwrap()).unwrap();
    assert!(!written.lines().any(|l| !l.starts_with(';')), "{written}");
}

#[test]
fn garbage_fd_records_name_what_is_wrong() {
    let v21 = ";$FILEVERSION=2.1\r\n;$COLUMNS=N,O,T,B,I,d,R,L,D\r\n\
      1         1.000 FD 1      0123 Rx -  16   00\r\n\
      2         1.000 DT 1      0123 Rx -  12   00 01 02 03 04 05 06 07 08 09 0A 0B\r\n\
      3         1.000 FB 1      0123 Rx -  9    00 01 02\r\n\
      4         1.000 FE 1      0123 Rx -  x    00\r\n";
    let v20 = ";$FILEVERSION=2.0\r\n;$COLUMNS=N,O,T,I,d,l,D\r\n\
      1         1.000 FB     0123 Rx 10   00 01 02 03 04 05 06 07 08 09\r\n\
      2         1.000 FB     0123 Rx 65   00\r\n";
    let v11 = ";$FILEVERSION=1.1\r\n\
     1)      1.0  Rx         0123  12  00 01 02 03 04 05 06 07 08 09 0A 0B\r\n";
    let cases = [
        (v21, 3, "a CAN FD DLC 0..15, found \"16\""),
        (
            v21,
            4,
            "a data length 0..8 (a CAN FD record's type is FD, FB, FE or BI), found \"12\"",
        ),
        (
            v21,
            5,
            "as many data bytes (2 hex digits each) as the length",
        ),
        (v21, 6, "found \"x\""),
        (v20, 3, "10 data bytes given; a CAN FD frame carries"),
        (
            v20,
            4,
            "a CAN FD data length 0..8, 12, 16, 20, 24, 32, 48 or 64, found \"65\"",
        ),
        (
            v11,
            2,
            "a data length 0..8 (TRC 1.x has no CAN FD), found \"12\"",
        ),
    ];
    for (text, line, want) in cases {
        let got = read(text);
        let err = got
            .iter()
            .filter_map(|r| r.as_ref().err())
            .find(|e| e.at() == Some(Location::Line(line)))
            .unwrap_or_else(|| panic!("no error at line {line}: {got:?}"));
        assert!(err.to_string().contains(want), "line {line}: {err}");
    }
    // A bad record is stepped over: the reader goes on.
    assert!(read(v21).iter().all(Result::is_err));
}
