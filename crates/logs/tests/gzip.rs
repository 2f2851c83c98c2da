//! gzip-compressed logs (python-can reads and writes `.asc.gz`, `.log.gz`, …): read through
//! gzip whatever their name, refused where they cannot be (SQLite, writing).

use std::io::Write;
use std::path::Path;

use buslab_logs::{Format, LogError, Message, create_writer, create_writer_atomic, open_reader};
use flate2::Compression;
use flate2::write::GzEncoder;

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut z = GzEncoder::new(Vec::new(), Compression::default());
    z.write_all(bytes).unwrap();
    z.finish().unwrap()
}

fn read(path: &Path, format: Format) -> Vec<Message> {
    open_reader(path, format)
        .unwrap()
        .collect::<Result<Vec<_>, _>>()
        .unwrap()
}

const LOG: &str = "(1700000000.000000) can0 123#1122\n\
    (1700000000.250000) can0 12345678##3112233445566778899AABBCC\n\
    (1700000000.500000) can1 20000088#0000020A00000102\n";

#[test]
fn compressed_logs_read_as_their_format() {
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("a.log");
    std::fs::write(&plain, LOG).unwrap();
    let want = read(&plain, Format::Candump);
    assert_eq!(want.len(), 3);
    assert!(matches!(want[1].record, buslab_logs::Record::Fd(_)));
    for format in [
        Format::Candump,
        Format::Asc,
        Format::Blf,
        Format::Trc21,
        Format::Csv,
        Format::Pcap,
        Format::Pcapng,
    ] {
        // Written plain by buslab, compressed, read back by its `.EXT.gz` name.
        let path = dir.path().join(format!("b.{}", format.extension()));
        let mut w = create_writer(&path, format).unwrap();
        for e in &want {
            w.write(e).unwrap();
        }
        w.finish().unwrap();
        let expected = read(&path, format);
        // CAN FD frames too, where the format keeps them (CSV keeps the bytes).
        assert!(
            expected
                .iter()
                .any(|e| e.record.payload() == want[1].record.payload()),
            "{format}"
        );
        let gz = dir.path().join(format!("b.{}.gz", format.extension()));
        std::fs::write(&gz, gzip(&std::fs::read(&path).unwrap())).unwrap();
        assert_eq!(Format::from_path(&gz).unwrap(), format);
        assert_eq!(read(&gz, format), expected, "{format}");
    }
    // Two gzip members one after the other (`cat a.gz b.gz`) read as one log.
    let two = dir.path().join("two.log.gz");
    let mut bytes = gzip(LOG.as_bytes());
    bytes.extend(gzip(LOG.as_bytes()));
    std::fs::write(&two, bytes).unwrap();
    assert_eq!(read(&two, Format::Candump).len(), 6);
}

#[test]
fn damaged_compressed_logs_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.log.gz");
    let bytes = gzip(LOG.repeat(200).as_bytes());
    std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    let results: Vec<_> = open_reader(&path, Format::Candump).unwrap().collect();
    let last = results.last().unwrap().as_ref().unwrap_err();
    assert!(
        last.is_fatal() && last.to_string().contains("cut.log.gz"),
        "{last}"
    );
    assert!(results[..results.len() - 1].iter().all(Result::is_ok));
    // Garbage after the magic number.
    let junk = dir.path().join("junk.asc.gz");
    std::fs::write(&junk, b"\x1f\x8bnot deflate at all").unwrap();
    let results: Vec<_> = open_reader(&junk, Format::Asc).unwrap().collect();
    assert!(results.len() == 1 && results[0].is_err(), "{results:?}");
}

#[test]
fn compressed_sqlite_and_compressed_output_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("x.db.gz");
    std::fs::write(&db, gzip(b"SQLite format 3\0")).unwrap();
    let err = open_reader(&db, Format::Sqlite).err().unwrap();
    assert!(matches!(err, LogError::Gzip { .. }), "{err}");
    assert!(err.to_string().contains("gunzip"), "{err}");
    for atomic in [false, true] {
        let out = dir.path().join("out.asc.gz");
        let err = if atomic {
            create_writer_atomic(&out, Format::Asc).err().unwrap()
        } else {
            create_writer(&out, Format::Asc).err().unwrap()
        };
        assert!(
            matches!(err, LogError::Gzip { .. }) && err.to_string().contains("uncompressed"),
            "{err}"
        );
        assert!(!out.exists());
    }
}
