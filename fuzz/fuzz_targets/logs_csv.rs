//! python-can CSV logs (`csv::Reader`, `buslab play/dump` on a `.csv` file): no panic, the reader ends (going on after a bad line, stopping after a fatal error),
//! and what it read, written by the same format's writer, reads back and writes again to the
//! same bytes.
#![no_main]

use buslab_fuzz::logs::{assert_writes_back, read_all};
use buslab_logs::csv::{Reader, Writer};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // A reader call takes at least one line (at least one byte), plus the end.
    let entries = read_all(Reader::new(data), data.len() + 2);
    assert_writes_back(
        &entries,
        |entries| {
            let mut writer = Writer::new(Vec::new());
            for entry in entries {
                writer.write(entry).expect("writing to memory");
            }
            writer.finish().expect("writing to memory")
        },
        Reader::new,
    );
});
