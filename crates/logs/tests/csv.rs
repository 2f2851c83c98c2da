//! python-can CSV rows: error rows keep their bytes, CAN FD frames as python-can writes them,
//! garbage rows name what is wrong.

use std::io::Cursor;

use buslab_logs::csv::{HEADER, Reader, Writer};
use buslab_logs::{Message, ReadError, Record};

fn read(body: &str) -> Vec<Result<Message, ReadError>> {
    let text = format!("{HEADER}\n{body}");
    let mut reader = Reader::new(Cursor::new(text.clone().into_bytes()));
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

fn line(e: &Result<Message, ReadError>) -> String {
    buslab_logs::candump::format_line(e.as_ref().unwrap(), false)
}

#[test]
fn error_rows_keep_their_bytes_and_length() {
    // As python-can writes error frames: the class as the ID, error 1, the data bytes.
    let got = read(
        "1700000000.5,0x88,0,0,1,8,AAACCgAAAQI=\n\
         1700000000.6,0x4,0,0,1,2,AAQ=\n\
         1700000000.7,0x0,1,0,1,0,\n",
    );
    let lines: Vec<String> = got.iter().map(line).collect();
    assert_eq!(
        lines,
        [
            "(1700000000.500000) can0 20000088#0000020A00000102",
            "(1700000000.600000) can0 20000004#0004",
            "(1700000000.700000) can0 20000000#",
        ]
    );
    let mut w = Writer::new(Vec::new());
    for e in &got {
        w.write(e.as_ref().unwrap()).unwrap();
    }
    let text = String::from_utf8(w.finish().unwrap()).unwrap();
    assert!(
        text.contains("1700000000.5,0x88,0,0,1,8,AAACCgAAAQI=\n")
            && text.contains("1700000000.6,0x4,0,0,1,2,AAQ=\n"),
        "{text}"
    );
}

/// python-can's columns have no FD mark, BRS or ESI: an FD frame is a row of its length and
/// data (as python-can's writer makes one); a row of more than 8 bytes reads back as CAN FD
/// without BRS and ESI, one of 8 or fewer as a classic frame.
#[test]
fn fd_frames_are_rows_as_python_can_writes_them() {
    let mut w = Writer::new(Vec::new());
    let mut entries = Vec::new();
    for (i, fd) in [
        "1ABCDEF0##3000102030405060708090A0B",
        "123##10011",
        "7FF##0",
    ]
    .iter()
    .enumerate()
    {
        let e = Message {
            at: buslab_logs::Timestamp::from_micros(1_700_000_000_000_000 + i as u64),
            channel: "can0".into(),
            direction: None,
            record: Record::Fd(fd.parse().unwrap()),
        };
        w.write(&e).unwrap();
        entries.push(e);
    }
    let text = String::from_utf8(w.finish().unwrap()).unwrap();
    assert_eq!(
        text,
        format!(
            "{HEADER}\n\
             1700000000.0,0x1abcdef0,1,0,0,12,AAECAwQFBgcICQoL\n\
             1700000000.000001,0x123,0,0,0,2,ABE=\n\
             1700000000.000002,0x7ff,0,0,0,0,\n"
        )
    );
    let back: Vec<String> = read(text.split_once('\n').unwrap().1)
        .iter()
        .map(line)
        .collect();
    assert_eq!(
        back,
        [
            "(1700000000.000000) can0 1ABCDEF0##0000102030405060708090A0B",
            "(1700000000.000001) can0 123#0011",
            "(1700000000.000002) can0 7FF#",
        ]
    );
    // 64 bytes, as python-can writes an FD frame of 64.
    let row = format!(
        "1.0,0x100,0,0,0,64,{}\n",
        base64::Engine::encode(&base64::engine::general_purpose::STANDARD, [0xA5; 64])
    );
    let got = read(&row);
    assert_eq!(
        got[0].as_ref().unwrap().fd_frame().unwrap().payload(),
        [0xA5; 64]
    );
}

#[test]
fn garbage_fd_rows_name_what_is_wrong() {
    let cases = [
        (
            "1.0,0x100,0,0,0,10,AAECAwQFBgcICQ==",
            "10 data bytes given; a CAN FD frame carries",
        ),
        (
            "1.0,0x100,0,0,0,65,AA==",
            "a dlc 0..8 (or a CAN FD length up to 64)",
        ),
        ("1.0,0x100,0,0,0,12,AAECAw==", "dlc 12 with 4 bytes"),
        ("1.0,0x100,0,1,0,12,", "a remote frame's dlc 0..8"),
    ];
    let body: String = cases.iter().map(|(row, _)| format!("{row}\n")).collect();
    let got = read(&body);
    assert_eq!(got.len(), cases.len());
    for ((row, want), result) in cases.iter().zip(&got) {
        let err = result.as_ref().unwrap_err().to_string();
        assert!(err.contains(want), "{row}: {err}");
    }
}

#[test]
fn garbage_rows_are_bad_rows_not_a_stop() {
    let got = read(
        "1700000000.5,0x88,0,0,1,9,AAACCgAAAQIA\n\
         x,0x1,0,0,0,0,\n\
         1.0,123,0,0,0,0,\n\
         1.0,0x800,0,0,0,0,\n\
         1.0,0x1,2,0,0,0,\n\
         1.0,0x1,0,0,0,2,AA==\n\
         1.0,0x1,0,0,0,1,!!!!\n\
         1.0,0x1,0,0,0,1,AA==,extra\n\
         1.0,0x1\n\
         1.0,0x123,0,0,0,1,EQ==\n",
    );
    assert_eq!(got.len(), 10);
    let err = got[0].as_ref().unwrap_err().to_string();
    assert!(
        err.contains("line 2") && err.contains("at most 8 data bytes, not 9"),
        "{err}"
    );
    assert!(got[1..9].iter().all(Result::is_err), "{got:?}");
    assert_eq!(line(&got[9]), "(0000000001.000000) can0 123#11");
}
