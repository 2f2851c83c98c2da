//! Vector ASC lines as CANoe, python-can and log2asc write them, buslab's error-frame comment,
//! and garbage.

use std::io::Cursor;
use std::time::Duration;

use buslab_bus::{CanError, ErrorFrame};
use buslab_can::{Frame, Id};
use buslab_logs::Timestamp;
use buslab_logs::asc::{Reader, Writer};
use buslab_logs::{Direction, Location, Message, ReadError, Record};

/// An ASC file of `body` lines (times from 0: no date header).
#[path = "support/fd.rs"]
mod fd;

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
/// A CAN FD length above 15 in a classic line is that CAN FD frame (python-can 3 wrote them so,
/// python-can's `single_frame.asc`); any other number is refused.
#[test]
fn classic_dlc_above_8_and_fd_lengths() {
    let text = asc(
        "  13.258671 1  3FF             Tx   d D 55 AA 01 02 03 04 05 06  Length = 232016 BitCount = 119 ID = 1023\n \
         0.000000 1  123x            Rx   d 40 00 01 02 03 04 05 06 07 08 09 0A 0B 0C 0D 0E 0F 10 11 12 13 14 15 16 17 18 19 1A 1B 1C 1D 1E 1F 20 21 22 23 24 25 26 27 28 29 2A 2B 2C 2D 2E 2F 30 31 32 33 34 35 36 37 38 39 3A 3B 3C 3D 3E 3F\n \
         1.000000 1  100             Rx   r F\n \
         2.000000 1  100             Rx   d 41 00\n \
         3.000000 1  100             Rx   d 11 00\n \
         4.000000 1  100             Rx   d 10 00 01 02\n",
    );
    let got = read(&text);
    assert_eq!(
        got[0].as_ref().unwrap().frame(),
        Some(&frame("3FF#55AA010203040506"))
    );
    let fd = got[1].as_ref().unwrap().fd_frame().unwrap();
    assert_eq!(fd.id(), Id::extended(0x123).unwrap());
    assert_eq!(fd.payload(), (0..64).collect::<Vec<u8>>());
    assert!(!fd.brs() && !fd.esi());
    assert_eq!(got[2].as_ref().unwrap().frame(), Some(&frame("100#R8")));
    for (i, dlc) in [(3, "41"), (4, "11")] {
        let err = got[i].as_ref().unwrap_err().to_string();
        assert!(
            err.contains("a DLC 0..15, or a CAN FD length 16..64") && err.contains(dlc),
            "{err}"
        );
    }
    // 16 bytes announced, 4 there.
    let err = got[5].as_ref().unwrap_err().to_string();
    assert!(err.contains("as many data bytes as the DLC"), "{err}");
    assert_eq!(got[5].as_ref().unwrap_err().at(), Some(Location::Line(8)));
    assert_eq!(got.len(), 6);
}

/// `CANFD` lines as CANoe writes them (python-can's test data: a symbolic name, the BRS and
/// ESI columns, flags with EDL, a 64-byte frame whose flags are 0, a classic remote frame) and
/// as python-can writes them (length 0 included, which python-can's own reader takes for a
/// remote frame).
#[test]
fn canfd_lines_as_canoe_and_python_can_write_them() {
    let long_line = format!(
        "  30.506898 CANFD   4 Rx        4EE                                   0 1 f 64 A1 02 03 04 {}64 1331984 11 0 46500250 460a0250 20011736 20010205\n",
        "00 ".repeat(59)
    );
    let text = asc(&[
        "  30.005021 CANFD   1 Rx        300                                   1 0 8  8 11 c2 03 04 05 06 07 08   102203  133   303000 e0006659 46500250 4b140250 20011736 2001040d\n",
        "  30.005041 CANFD   2 Tx        1C4D80A7x                                   0 1 8  8 12 c2 03 04 05 06 07 08   102203  133   303000 e0006659 46500250 4b140250 20011736 2001040d\n",
        "  30.005071 CANFD   3 Rx        30a  Generic_Name_12                  1 1 8  8 01 02 03 04 05 06 07 08   102203  133   303000 e0006659 46500250 4b140250 20011736 2001040d\n",
        "  30.300981 CANFD   3 Tx     50005x                                0 0 5 0 140000 73 200050 7a60 46500250 460a0250 20011736 20010205\n",
        &long_line,
        " 0.000000 CANFD   1 Tx        100                                   0 0 0  0         0    0     1000        0        0        0        0        0\n",
        " 0.001500 CANFD   2 Rx   1ABC0001x                                   1 1 9 12 00 01 02 03 04 05 06 07 08 09 0A 0B        0    0     7000        0        0        0        0        0\n",
    ]
    .join(""));
    let got: Vec<Message> = read(&text).into_iter().map(Result::unwrap).collect();
    let records: Vec<(String, Option<Direction>, String)> = got
        .iter()
        .map(|e| (e.channel.clone(), e.direction, e.record.to_string()))
        .collect();
    let mut long = String::from("4EE##2A1020304");
    long.push_str(&"00".repeat(59));
    long.push_str("64");
    assert_eq!(
        records,
        [
            (
                "can0".into(),
                Some(Direction::Rx),
                "300##111C2030405060708".into()
            ),
            (
                "can1".into(),
                Some(Direction::Tx),
                "1C4D80A7##212C2030405060708".into()
            ),
            (
                "can2".into(),
                Some(Direction::Rx),
                "30A##30102030405060708".into()
            ),
            ("can2".into(), Some(Direction::Tx), "00050005#R5".into()),
            ("can3".into(), Some(Direction::Rx), long),
            ("can0".into(), Some(Direction::Tx), "100##0".into()),
            (
                "can1".into(),
                Some(Direction::Rx),
                "1ABC0001##3000102030405060708090A0B".into()
            ),
        ]
    );
}

/// Every FD length, BRS/ESI combination and ID kind through the writer and the reader, in
/// python-can's columns.
#[test]
fn every_fd_frame_round_trips_in_canfd_lines() {
    let entries = fd::every_fd_entry();
    let mut w = Writer::new(Vec::new());
    for e in &entries {
        w.write(e).unwrap();
    }
    let text = String::from_utf8(w.finish().unwrap()).unwrap();
    // The 12-byte extended frame with BRS and ESI (n = 9 * 8 + 3 * 2 + 1).
    assert!(
        text.contains(
            "   0.118500 CANFD   2 Rx   1ABC004Fx                                   1 1 9 12 4F 48 41 5A 53 6C 65 7E 77 70 09 02        0    0     7000        0        0        0        0        0\n"
        ),
        "{text}"
    );
    let back: Vec<Message> = read(&text).into_iter().map(Result::unwrap).collect();
    assert_eq!(back, entries);
}

#[test]
fn garbage_canfd_lines_name_what_is_wrong() {
    let line = |rest: &str| {
        format!("  1.000000 CANFD   1 Rx        123                                   {rest}\n")
    };
    let cases = [
        (
            "1 0 a 10 00 01 02 03 04 05 06 07 08 09 0 0 1000",
            "10 data bytes given; a CAN FD frame carries",
        ),
        (
            "1 0 f 65 00",
            "a CAN FD data length 0..8, 12, 16, 20, 24, 32, 48 or 64, found \"65\"",
        ),
        ("2 0 1 1 00 0 0 1000", "BRS and ESI as 0 or 1"),
        ("1 0 1 1 00 0 0 1010", "without the remote flag 0x10"),
        ("1 0 c 12 00 01 02", "CANFD: BRS ESI DLC LENGTH DATA"),
        ("1 0 1 1 GG 0 0 1000", "a data byte, found \"GG\""),
        ("1 0 1 x 00", "a data length, found \"x\""),
    ];
    let text = asc(&cases.iter().map(|(rest, _)| line(rest)).collect::<String>());
    let got = read(&text);
    assert_eq!(got.len(), cases.len());
    for (i, ((rest, want), result)) in cases.iter().zip(&got).enumerate() {
        let err = result.as_ref().unwrap_err();
        assert_eq!(err.at(), Some(Location::Line(3 + i as u64)), "{rest}");
        assert!(err.to_string().contains(want), "{rest}: {err}");
    }
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
