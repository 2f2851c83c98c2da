//! Vector BLF logs with their zlib containers (`blf::Reader`, `buslab play/dump` on a `.blf` file): no panic, the reader ends (going on after a bad record, stopping after a fatal error),
//! and what it read, written by the same format's writer (which refuses times it cannot hold),
//! reads back and writes again to the same bytes.
#![no_main]

use buslab_fuzz::logs::{assert_writes_back, read_all};
use buslab_logs::blf::{Reader, Writer};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let entries = read_all(
        Reader::new(data), // zlib inflates at most about 1032:1 and an object takes at least 16 bytes.
        (data.len() + 1) * 1032 / 16 + 2,
    );
    assert_writes_back(
        &entries,
        |entries| {
            let mut writer =
                Writer::new(std::io::Cursor::new(Vec::new())).expect("writing to memory");
            for entry in entries {
                // A time the format cannot hold (after the year 65535, or 584 years after the
                // first entry) is refused and left out, the same way in both passes.
                if let Err(e) = writer.write(entry) {
                    assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput, "{e}");
                }
            }
            writer.finish().expect("writing to memory").into_inner()
        },
        Reader::new,
    );
});
