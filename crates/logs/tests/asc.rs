//! Vector ASC lines as CANoe, python-can and log2asc write them, buslab's error-frame comment,
//! and garbage.

use std::io::Cursor;
use std::time::Duration;

use buslab_bus::{CanError, ErrorFrame};
use buslab_can::Frame;
use buslab_logs::Timestamp;
use buslab_logs::asc::{Reader, Writer};
use buslab_logs::{Direction, Location, Message, Problem, ReadError, Record};

/// An ASC file of `body` lines (times from 0: no date header).
fn asc(body: &str) -> String {
    format!("base hex  timestamps absolute\nBegin Triggerblock\n{body}End TriggerBlock\n")
}

fn read(text: &str) -> Vec<Result<Message, ReadError>> {
    let mut reader = Reader::new(Cursor::new(text.as_bytes().to_vec()));
    let mut out = Vec::new();
    // A read takes a line at least, plus the end.
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

fn frames(text: &str) -> Vec<(Timestamp, String, Frame, Option<Direction>)> {
    read(text)
        .into_iter()
        .map(|r| {
            let e = r.unwrap();
            let f = *e.frame().unwrap();
            (e.at, e.channel, f, e.direction)
        })
        .collect()
}

fn frame(text: &str) -> Frame {
    text.parse().unwrap()
}

/// Issue 25: `2.510001 2 100 Tx r` (no DLC, in three files of python-can's test data) stopped
/// the whole file; CANoe's `Length = … BitCount = … ID = …` after a remote frame did too.
#[test]
fn remote_lines_without_a_dlc_and_with_length_fields() {
    let got = frames(&asc("   2.510001 2 100 Tx r\n   \
         2.520002 3 200 Tx r Length = 1704000 BitCount = 145 ID = 88888888x\n   \
         2.584921 4 300 Rx r 8 Length = 1704000 BitCount = 145 ID = 88888888x\n   \
         2.600000 1 12345x Rx r 3\n"));
    assert_eq!(
        got,
        [
            (
                Timestamp::from_micros(2_510_001),
                "can1".into(),
                frame("100#R"),
                Some(Direction::Tx)
            ),
            (
                Timestamp::from_micros(2_520_002),
                "can2".into(),
                frame("200#R"),
                Some(Direction::Tx)
            ),
            (
                Timestamp::from_micros(2_584_921),
                "can3".into(),
                frame("300#R8"),
                Some(Direction::Rx)
            ),
            (
                Timestamp::from_micros(2_600_000),
                "can0".into(),
                frame("00012345#R3"),
                Some(Direction::Rx)
            ),
        ]
    );
}

#[test]
fn data_lines_with_length_and_bitcount_fields() {
    let got = frames(&asc(
        "  17.876708 1  6F9             Rx   d 8 05 0C 00 00 00 00 00 00  Length = 240015 BitCount = 124 ID = 1785\n   \
         3.098426 1  18EBFF00x       Rx d 8 01 A0 0F A6 60 3B D1 40    Length = 273910 BitCount = 141 ID = 418119424x\n   \
         4.000000 1  7FF             Tx   d 0  Length = 100000 BitCount = 50 ID = 2047\n",
    ));
    let frames: Vec<Frame> = got.iter().map(|g| g.2).collect();
    assert_eq!(
        frames,
        [
            frame("6F9#050C000000000000"),
            frame("18EBFF00#01A00FA6603BD140"),
            frame("7FF#")
        ]
    );
}

/// Classical CAN's DLC 9..15 means 8 data bytes (CANoe writes `d D`): read as an 8-byte frame.
/// A larger number is a CAN FD length in a classic line: refused as CAN FD.
#[test]
fn classic_dlc_above_8_and_fd_lengths() {
    let text = asc(
        "  13.258671 1  3FF             Tx   d D 55 AA 01 02 03 04 05 06  Length = 232016 BitCount = 119 ID = 1023\n \
         0.000000 1  123x            Rx   d 40 00 01 02 03 04 05 06 07 08 09 0A 0B 0C 0D 0E 0F 10 11 12 13 14 15 16 17 18 19 1A 1B 1C 1D 1E 1F 20 21 22 23 24 25 26 27 28 29 2A 2B 2C 2D 2E 2F 30 31 32 33 34 35 36 37 38 39 3A 3B 3C 3D 3E 3F\n \
         1.000000 1  100             Rx   r F\n \
         2.000000 1  100             Rx   d 41 00\n",
    );
    let got = read(&text);
    assert_eq!(
        got[0].as_ref().unwrap().frame(),
        Some(&frame("3FF#55AA010203040506"))
    );
    let err = got[1].as_ref().unwrap_err();
    assert!(matches!(err.problem(), Problem::CanFd), "{err}");
    assert_eq!(err.at(), Some(Location::Line(4)));
    assert_eq!(got[2].as_ref().unwrap().frame(), Some(&frame("100#R8")));
    let err = got[3].as_ref().unwrap_err().to_string();
    assert!(err.contains("a DLC 0..15") && err.contains("65"), "{err}");
    assert_eq!(got.len(), 4);
}

fn error_entry(e: ErrorFrame, micros: u64) -> Message {
    Message {
        at: Timestamp::since_epoch(Duration::from_micros(1_700_000_000_000_000 + micros)),
        channel: "can0".into(),
        record: Record::Error(e),
        direction: Some(Direction::Rx),
    }
}

/// Issue 25: an ASC `ErrorFrame` says nothing of what went wrong; buslab's comment before it
/// carries the SocketCAN frame, so every error frame comes back byte for byte.
#[test]
fn error_frames_come_back_byte_for_byte() {
    let entries = [
        error_entry(
            ErrorFrame::decode(0x088, &[0, 0, 0x02, 0x0A, 0, 0, 0x01, 0x02]).unwrap(),
            0,
        ),
        error_entry(
            ErrorFrame::decode(0x080, &[0, 0, 0x04, 0x02, 0, 0, 0, 0x01]).unwrap(),
            1,
        ),
        error_entry(ErrorFrame::decode(0x004, &[0, 0x04]).unwrap(), 2),
        error_entry(ErrorFrame::decode(0x040, &[]).unwrap(), 3),
    ];
    let mut w = Writer::new(Vec::new());
    for e in &entries {
        w.write(e).unwrap();
    }
    let text = String::from_utf8(w.finish().unwrap()).unwrap();
    assert!(
        text.contains(
            "// buslab error-frame 20000088#0000020A00000102\n   0.000000 1  ErrorFrame\n"
        ),
        "{text}"
    );
    let back: Vec<Message> = read(&text).into_iter().map(Result::unwrap).collect();
    assert_eq!(back, entries);
}

/// Without buslab's comment (CANoe, python-can, log2asc), `ErrorFrame` is a bus error, as
/// asc2log reads it; a comment applies to the event line right after it only.
#[test]
fn an_error_frame_without_the_comment_is_a_bus_error() {
    let bus_error = Record::Error(ErrorFrame::new(vec![CanError::BusError], None));
    let got = read(&asc("   2.501000 1 ErrorFrame\n   \
         2.501010 1 ErrorFrame ECC: 10100010\n\
         // buslab error-frame 20000004#0004\n   \
         2.600000 1  123 Rx d 1 11\n   \
         2.700000 2 ErrorFrame\n   \
         30.806898 CANFD   5 Tx ErrorFrame Not Acknowledge error, dominant error flag fffe c7 31ca Arb. 556 44 0 0 f 64\n"));
    let records: Vec<Record> = got.into_iter().map(|r| r.unwrap().record).collect();
    assert_eq!(
        records,
        [
            bus_error.clone(),
            bus_error.clone(),
            Record::Frame(frame("123#11")),
            bus_error.clone(),
            bus_error,
        ]
    );
}

#[test]
fn a_bad_error_comment_is_a_bad_line() {
    let got = read(&asc("// buslab error-frame 123#11\n   \
         1.000000 1 ErrorFrame\n\
         // buslab error-frame 20000004#0004000000000000FF\n\
         // buslab error-frame 20000004#0\n"));
    let err = got[0].as_ref().unwrap_err();
    assert_eq!(err.at(), Some(Location::Line(3)));
    assert!(err.to_string().contains("an error frame"), "{err}");
    assert!(matches!(got[1].as_ref().unwrap().record, Record::Error(_)));
    assert!(got[2].is_err() && got[3].is_err(), "{got:?}");
    assert_eq!(got.len(), 4);
}

/// Arbitrary bytes and mangled lines: errors naming the line, never a panic or a hang.
#[test]
fn garbage_lines_are_bad_lines_not_a_stop() {
    let text = asc("   1.0 1 100 Tx r 99\n   \
         1.0 1 100 Tx r x\n   \
         1.0 1 100 Tx d 2 11\n   \
         1.0 1 100 Tx q 2\n   \
         1.0 1 800 Tx d 0\n   \
         1.0 1 100 Tx d 1 1FF\n   \
         1.0 99999999 100 Tx d 0\n   \
         1.0 1 100 Tx d 1 11\n");
    let got = read(&text);
    assert_eq!(got.len(), 8);
    assert!(got[..7].iter().all(|r| r.is_err()), "{got:?}");
    assert_eq!(got[7].as_ref().unwrap().frame(), Some(&frame("100#11")));
    for bytes in [
        &b"\xFF\xFE\x00garbage\n"[..],
        b"   1.0 1 ErrorFrame\r\n// buslab error-frame \xFF\n",
        b"// buslab error-frame 2000000",
    ] {
        let text = String::from_utf8_lossy(bytes).into_owned();
        let _ = read(&text);
    }
}
