//! pcap captures of SocketCAN frames (`pcap::Reader`, `buslab play/dump` on a `.pcap` file): no panic, the reader ends (going on after a bad record, stopping after a fatal error),
//! and what it read, written by the same format's writer, reads back and writes again to the
//! same bytes.
#![no_main]

use buslab_fuzz::logs::{assert_writes_back, read_all};
use buslab_logs::pcap::{Reader, Writer};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let entries = read_all(
        Reader::new(data), // A record takes at least its 16-byte header, plus the end.
        data.len() / 16 + 2,
    );
    assert_writes_back(
        &entries,
        |entries| {
            let mut writer = Writer::new(Vec::new()).expect("writing to memory");
            for entry in entries {
                // A time the format cannot hold is refused and left out, in both passes.
                if let Err(e) = writer.write(entry) {
                    assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput, "{e}");
                }
            }
            writer.finish().expect("writing to memory")
        },
        Reader::new,
    );
});
