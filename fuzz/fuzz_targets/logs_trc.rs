//! PEAK TRC logs 1.0 to 2.1 (`trc::Reader`, `buslab play/dump` on a `.trc` file): no panic,
//! the reader ends (going on after a bad line, stopping after a fatal error), and what it read,
//! written by the TRC writer in either version, reads back and writes again to the same bytes.
#![no_main]

use buslab_fuzz::logs::{assert_writes_back, read_all};
use buslab_logs::trc::{Reader, Version, Writer};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // A reader call takes at least one line (at least one byte), plus the end.
    let entries = read_all(Reader::new(data), data.len() + 2);
    for version in [Version::V1_1, Version::V2_1] {
        // TRC 1.1 has no CAN FD: its writer refuses an FD frame, naming TRC 2.1.
        let (held, fd): (Vec<_>, Vec<_>) = entries.iter().cloned().partition(|e| {
            version == Version::V2_1 || !matches!(e.record, buslab_logs::Record::Fd(_))
        });
        if let Some(frame) = fd.first() {
            let err = Writer::new(Vec::new(), version).write(frame).unwrap_err();
            assert_eq!(err.kind(), std::io::ErrorKind::InvalidInput, "{err}");
        }
        assert_writes_back(
            &held,
            |entries| {
                let mut writer = Writer::new(Vec::new(), version);
                for entry in entries {
                    writer.write(entry).expect("writing to memory");
                }
                writer.finish().expect("writing to memory")
            },
            Reader::new,
        );
    }
});
