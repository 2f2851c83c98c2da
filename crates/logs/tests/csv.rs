//! python-can CSV rows: error rows keep their bytes, garbage rows name what is wrong.

use std::io::Cursor;

use buslab_logs::csv::{HEADER, Reader, Writer};
use buslab_logs::{Message, ReadError};

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
