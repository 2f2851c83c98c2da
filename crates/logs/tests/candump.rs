//! candump log lines: what can-utils and python-can write, round trips, and garbage.

use std::io::Cursor;
use std::time::Duration;

use buslab_bus::{CanError, ErrorFrame};
use buslab_can::{Frame, Id};
use buslab_logs::Timestamp;
use buslab_logs::candump::{LineError, MAX_LINE, Reader, Writer, format_line, parse_line};
use buslab_logs::{Direction, Location, Message, Problem, ReadError, Record};
use proptest::prelude::*;

#[path = "support/fd.rs"]
mod fd;

/// A bad line `line` whose error passes `check`.
fn is_line(err: &ReadError, line: u64, check: impl Fn(&LineError) -> bool) -> bool {
    err.at() == Some(Location::Line(line))
        && matches!(err.problem(), Problem::Candump(e) if check(e))
}

fn frame(text: &str) -> Frame {
    text.parse().unwrap()
}

#[test]
fn lines_as_can_utils_writes_them() {
    let e = parse_line("(1700000000.123456) can1 12345678#DEADBEEF").unwrap();
    assert_eq!(
        e,
        Message {
            at: Timestamp::since_epoch(Duration::new(1_700_000_000, 123_456_000)),
            channel: "can1".into(),
            record: Record::Frame(frame("12345678#DEADBEEF")),
            direction: None,
        }
    );
    assert_eq!(
        parse_line("(1700000000.200000) can0 7FF#R").unwrap().record,
        Record::Frame(frame("7FF#R"))
    );
    // candump -x, interface names right-aligned to the longest, -N nanoseconds, -t z zero.
    let x = parse_line("(1700000000.500000)  can0 123#112233 T").unwrap();
    assert_eq!(x.direction, Some(Direction::Tx));
    assert_eq!(
        parse_line("(1700000000.000000001) vcan0 5A1#11.2233.44556677.88")
            .unwrap()
            .at,
        Timestamp::since_epoch(Duration::new(1_700_000_000, 1))
    );
    assert_eq!(
        parse_line("(000.000000) vcan0 123#").unwrap().at,
        Timestamp::EPOCH
    );
    // python-can's writer: any number of decimals up to 9.
    assert_eq!(
        parse_line("(1.5) vcan0 123#").unwrap().at,
        Timestamp::since_epoch(Duration::from_millis(1500))
    );
}

#[test]
fn error_frames_decode() {
    let e = parse_line("(1700000000.400000) can0 20000080#0000000000000000").unwrap();
    assert_eq!(
        e.record,
        Record::Error(ErrorFrame::new(vec![CanError::BusError], None))
    );
    let e = parse_line("(1.000000) can0 20000204#0020000000008005 R").unwrap();
    let Record::Error(err) = &e.record else {
        panic!("{e:?}")
    };
    assert_eq!(
        err.to_string(),
        "controller-problem{tx-error-passive},error-counter-tx-rx{{128}{5}}"
    );
    assert_eq!(
        format_line(&e, true),
        "(0000000001.000000) can0 20000204#0020000000008005 R"
    );
}

/// Issue 25: reading a candump log rewrote error frames: `20000088#…` with counters in
/// data[6..8] came out as `20000288#…` (the counters class added), and
/// `20000080#0000040200000001` lost its protocol bytes (no protocol class claims them). Every
/// error frame is written back byte for byte, its length too.
#[test]
fn error_frames_read_and_written_back_byte_for_byte() {
    for line in [
        "(1700000000.004000) can0 20000088#0000020A00000102",
        "(1700000000.005000) can0 20000080#0000040200000001",
        "(1700000000.006000) can0 20000004#0004",
        "(1700000000.007000) can0 20000040#",
        "(1700000000.008000) can0 3FFFFFFF#FFFFFFFFFFFFFFFF",
        "(1700000000.009000) can0 20000000#0102030405060708",
    ] {
        let e = parse_line(line).unwrap();
        assert!(matches!(e.record, Record::Error(_)), "{line}");
        assert_eq!(format_line(&e, false), line);
    }
}

#[test]
fn lines_round_trip() {
    for line in [
        "(1700000000.000000) vcan0 123#1122334455667788",
        "(0000000001.500000) can1 12345678#",
        "(1700000000.200000) can0 7FF#R",
        "(1700000000.200000) can0 00000123#R3",
        "(1700000000.400000) can0 20000288#0000080A00000800",
        "(1700000000.500000) can0 321##1112233",
        "(1700000000.500000) can0 1F334455##3",
        "(1700000000.500000) can0 7FF##0000102030405060708090A0B",
    ] {
        assert_eq!(format_line(&parse_line(line).unwrap(), false), line);
    }
}

/// The flags nibble as can-utils writes it: `0`..`3` (python-can, can-utils before v2025.01),
/// `4`..`7` with FDF (v2025.01 and later); read masked to BRS and ESI, written `0`..`3`.
#[test]
fn fd_lines_with_any_flags_nibble() {
    for (nibble, brs, esi) in [
        ('0', false, false),
        ('1', true, false),
        ('2', false, true),
        ('3', true, true),
        ('4', false, false),
        ('5', true, false),
        ('6', false, true),
        ('7', true, true),
        ('F', true, true),
        ('d', true, false),
    ] {
        let line = format!("(1700000000.000001) can0 12345678##{nibble}00112233445566778899AABB T");
        let entry = parse_line(&line).unwrap();
        let Record::Fd(fd) = entry.record else {
            panic!("{line}: {entry:?}")
        };
        assert_eq!((fd.brs(), fd.esi()), (brs, esi), "{line}");
        assert_eq!(fd.id(), Id::extended(0x1234_5678).unwrap());
        assert_eq!(fd.payload().len(), 12);
        assert_eq!(entry.direction, Some(Direction::Tx));
        let written = format_line(&entry, true);
        let want = u8::from(brs) | u8::from(esi) << 1;
        assert_eq!(
            written,
            format!("(1700000000.000001) can0 12345678##{want}00112233445566778899AABB T")
        );
    }
}

/// Every FD length, BRS/ESI combination and ID kind through the writer and the reader.
#[test]
fn every_fd_frame_round_trips() {
    let entries = fd::every_fd_entry();
    let mut w = Writer::new(Vec::new()).with_direction(true);
    for e in &entries {
        w.write(e).unwrap();
    }
    let text = String::from_utf8(w.into_inner()).unwrap();
    assert!(
        text.contains("(1700000000.001500) can1 1ABC0001##0 R\n"),
        "{text}"
    );
    let back: Vec<Message> = Reader::new(Cursor::new(text)).map(Result::unwrap).collect();
    assert_eq!(back, entries);
}

#[test]
fn garbage_lines_name_what_is_wrong() {
    for (line, want) in [
        ("", LineError::Empty),
        ("   ", LineError::Empty),
        ("(1.5)", LineError::NoInterface),
        ("(1.5) vcan0", LineError::NoFrame("vcan0".into())),
        ("1.5 vcan0 123#", LineError::Timestamp("1.5".into())),
        ("(1) vcan0 123#", LineError::Timestamp("(1)".into())),
        ("(1.) vcan0 123#", LineError::Timestamp("(1.)".into())),
        (
            "(1.1234567890) vcan0 123#",
            LineError::Timestamp("(1.1234567890)".into()),
        ),
        ("(-1.5) vcan0 123#", LineError::Timestamp("(-1.5)".into())),
        (
            "(99999999999999999999.0) vcan0 123#",
            LineError::Timestamp("(99999999999999999999.0)".into()),
        ),
        ("(1.5) vcan0 123#11 X", LineError::Trailing("X".into())),
        (
            "(1.5) vcan0 123#11 R extra",
            LineError::Trailing("extra".into()),
        ),
    ] {
        assert_eq!(parse_line(line), Err(want), "{line:?}");
    }
    for (line, want) in [
        ("(1.5) vcan0 123", "has no '#'"),
        ("(1.5) vcan0 123##", "one hex flags digit"),
        ("(1.5) vcan0 123##G11", "one hex flags digit"),
        ("(1.5) vcan0 123##0112", "odd number"),
        ("(1.5) vcan0 123##0112233445566778899", "9 data bytes given"),
        ("(1.5) vcan0 123##01122334455667788991", "odd number"),
        ("(1.5) vcan0 123##0ZZ", "not valid hexadecimal"),
        ("(1.5) vcan0 800##0", "out of range"),
        ("(1.5) vcan0 0123##0", "3 hex digits"),
        ("(1.5) vcan0 123##1112233 X", "only R or T"),
        ("(1.5) vcan0 800#", "out of range"),
        ("(1.5) vcan0 123#112", "odd number"),
        ("(1.5) vcan0 123#11223344556677889900", "0..8"),
        ("(1.5) vcan0 20000080#000", "pairs of hex digits"),
        ("(1.5) vcan0 20000080#GG", "pairs of hex digits"),
        (
            "(1.5) vcan0 20000080#000000000000000000",
            "at most 8 data bytes",
        ),
        ("(1.5) vcan0 60000080#00", "wider than a 29-bit"),
    ] {
        let err = parse_line(line).unwrap_err().to_string();
        assert!(err.contains(want), "{line:?}: {err}");
    }
}

#[test]
fn the_reader_skips_notes_and_names_bad_lines() {
    let log = "(1.000000) vcan0 123#11\n\
               DROPCOUNT: dropped 3 CAN frames on 'vcan0' socket (total drops 3)\n\
               \n\
               (2.000000) vcan0 nonsense\n\
               (3.000000) vcan0 124#22\r\n\
               (4.000000) vcan0 125#33";
    let mut reader = Reader::new(Cursor::new(log));
    let first = reader.next().unwrap().unwrap();
    assert_eq!(first.record, Record::Frame(frame("123#11")));
    let err = reader.next().unwrap().unwrap_err();
    assert!(
        is_line(&err, 4, |e| matches!(e, LineError::Frame(_))),
        "{err}"
    );
    assert!(err.to_string().starts_with("line 4: "), "{err}");
    // Reading goes on after a bad line; CRLF and a missing last newline are fine.
    let rest: Vec<Message> = reader.by_ref().map(Result::unwrap).collect();
    assert_eq!(rest.len(), 2);
    assert_eq!(rest[1].record, Record::Frame(frame("125#33")));
    assert_eq!(reader.skipped(), 2);
}

#[test]
fn the_reader_bounds_lines_and_refuses_binary() {
    let mut input = vec![b'('; MAX_LINE * 3];
    input.extend_from_slice(b"\n(1.0) vcan0 123#\n\xFF\xFE(\n");
    let mut reader = Reader::new(Cursor::new(input));
    assert!(is_line(&reader.next().unwrap().unwrap_err(), 1, |e| *e
        == LineError::TooLong));
    assert!(reader.next().unwrap().is_ok());
    assert!(is_line(&reader.next().unwrap().unwrap_err(), 3, |e| *e
        == LineError::NotText));
    assert!(reader.next().is_none());
}

#[test]
fn the_writer_writes_what_the_reader_reads() {
    let entries = vec![
        Message {
            at: Timestamp::since_epoch(Duration::new(1_700_000_000, 123_456_789)),
            channel: "vcan0".into(),
            record: Record::Frame(frame("1ABCDEF0#DEADBEEF")),
            direction: Some(Direction::Rx),
        },
        Message {
            at: Timestamp::since_epoch(Duration::new(1_700_000_001, 0)),
            channel: "vcan0".into(),
            record: Record::Error(ErrorFrame::new(vec![CanError::BusOff], None)),
            direction: Some(Direction::Tx),
        },
    ];
    let mut w = Writer::new(Vec::new()).with_direction(true);
    for e in &entries {
        w.write(e).unwrap();
    }
    let text = String::from_utf8(w.into_inner()).unwrap();
    assert_eq!(
        text,
        "(1700000000.123456) vcan0 1ABCDEF0#DEADBEEF R\n(1700000001.000000) vcan0 20000040#0000000000000000 T\n"
    );
    let back: Vec<Message> = Reader::new(Cursor::new(text)).map(Result::unwrap).collect();
    // Microseconds, as candump writes them.
    assert_eq!(
        back[0].at,
        Timestamp::since_epoch(Duration::new(1_700_000_000, 123_456_000))
    );
    assert_eq!(back[1], entries[1]);
}

fn any_frame() -> impl Strategy<Value = Frame> {
    (
        any::<bool>(),
        any::<u32>(),
        any::<bool>(),
        proptest::collection::vec(any::<u8>(), 0..=8),
    )
        .prop_map(|(ext, raw, remote, data)| {
            let id = if ext {
                Id::extended(raw & 0x1FFF_FFFF).unwrap()
            } else {
                Id::standard((raw & 0x7FF) as u16).unwrap()
            };
            if remote {
                Frame::remote(id, data.len() as u8).unwrap()
            } else {
                Frame::data(id, &data).unwrap()
            }
        })
}

proptest! {
    /// Fuzz-friendly: any text is an entry or an error, never a panic.
    #[test]
    fn any_text_parses_without_panic(line in "\\PC{0,80}") {
        let _ = parse_line(&line);
    }

    #[test]
    fn lines_that_look_almost_right_parse_without_panic(
        secs in "[0-9]{0,22}", frac in "[0-9]{0,11}", iface in "[a-z0-9]{0,6}",
        id in "[0-9A-Fa-f]{0,9}", data in "[0-9A-Fa-fR.#_]{0,20}", tail in "( [RTX])?",
    ) {
        let _ = parse_line(&format!("({secs}.{frac}) {iface} {id}#{data}{tail}"));
    }

    #[test]
    fn any_fd_frame_round_trips(f in fd::fd_frame(), secs in 0u64..10_000_000_000, micros in 0u32..1_000_000) {
        let e = Message {
            at: Timestamp::since_epoch(Duration::new(secs, micros * 1000)),
            channel: "can0".into(),
            record: Record::Fd(f),
            direction: None,
        };
        prop_assert_eq!(parse_line(&format_line(&e, false)).unwrap(), e);
    }

    #[test]
    fn any_frame_round_trips(f in any_frame(), secs in 0u64..10_000_000_000, micros in 0u32..1_000_000) {
        let e = Message {
            at: Timestamp::since_epoch(Duration::new(secs, micros * 1000)),
            channel: "can0".into(),
            record: Record::Frame(f),
            direction: None,
        };
        prop_assert_eq!(parse_line(&format_line(&e, false)).unwrap(), e);
    }
}
