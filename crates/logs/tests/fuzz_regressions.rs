//! Inputs the fuzz targets (`fuzz/`, docs/fuzzing.md) found that a reader got wrong; each
//! input is also kept under `fuzz/corpus/TARGET/regression-…` so every fuzz run replays it.

use std::path::Path;
use std::time::Duration;

use buslab_can::Frame;
use buslab_logs::Timestamp;
use buslab_logs::{LogReader, Message, Record, blf, pcap, pcapng, sqlite, trc};

/// Every entry, or the errors, of a reader that must end within `max_calls` reads.
fn read_all(mut reader: impl LogReader, max_calls: usize) -> (Vec<Message>, Vec<String>) {
    let (mut entries, mut errors) = (Vec::new(), Vec::new());
    for _ in 0..max_calls {
        let mut entry = Message::default();
        match reader.read_into(&mut entry) {
            Ok(true) => entries.push(entry),
            Ok(false) => return (entries, errors),
            Err(e) => errors.push(e.to_string()),
        }
    }
    panic!("the reader did not end within {max_calls} reads: {errors:?}");
}

/// `logs_sqlite`: a corrupt database whose rows all have rowid 0 was read again and again
/// (`buslab play` never ended); the reader now stops with an error naming the corruption.
#[test]
fn sqlite_with_repeating_rowids_ends_with_an_error() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/sqlite-rowids-repeat.db");
    let reader = sqlite::Reader::open(&path).expect("the file opens as a database");
    let (entries, errors) = read_all(reader, 1_000);
    assert!(entries.is_empty(), "{entries:?}");
    assert!(
        errors
            .last()
            .is_some_and(|e| e.contains("rowids in increasing order")),
        "{errors:?}"
    );
}

fn block(kind: u32, body: &[u8]) -> Vec<u8> {
    let mut body = body.to_vec();
    body.resize(body.len().next_multiple_of(4), 0);
    let len = (12 + body.len()) as u32;
    let mut out = kind.to_le_bytes().to_vec();
    out.extend(len.to_le_bytes());
    out.extend(body);
    out.extend(len.to_le_bytes());
    out
}

/// `logs_pcapng`: an interface name padded with NULs and then a space (`"can1\0\0 "`) was read
/// as `"can1\0\0"`, a name with NULs in it that a written file no longer gave back. A name
/// ends at its first NUL.
#[test]
fn pcapng_interface_name_ends_at_its_first_nul() {
    let mut file = block(
        0x0A0D_0D0A,
        &[
            0x4D, 0x3C, 0x2B, 0x1A, 1, 0, 0, 0, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF,
        ],
    );
    let name = b"can1\0\0 ";
    let mut idb = vec![227, 0, 0, 0, 0, 0, 0, 0, 2, 0, name.len() as u8, 0];
    idb.extend(name);
    idb.resize(idb.len().next_multiple_of(4), 0);
    idb.extend([0, 0, 0, 0]);
    file.extend(block(1, &idb));
    let mut epb = vec![0u8; 4];
    epb.extend(0u32.to_le_bytes());
    epb.extend(1_000u32.to_le_bytes());
    epb.extend(16u32.to_le_bytes());
    epb.extend(16u32.to_le_bytes());
    epb.extend([0, 0, 0x01, 0x23, 2, 0, 0, 0, 0x11, 0x22, 0, 0, 0, 0, 0, 0]);
    file.extend(block(6, &epb));

    let (entries, errors) = read_all(pcapng::Reader::new(&file[..]), 10);
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(entries.len(), 1);
    assert_eq!(entries[0].channel, "can1");
    assert_eq!(
        entries[0].record,
        Record::Frame("123#1122".parse::<Frame>().unwrap())
    );
    assert_eq!(
        entries[0].at,
        Timestamp::since_epoch(Duration::from_millis(1))
    );
}

/// `logs_trc`: an entry 1.56e16 s after the first one was written with a 20-digit millisecond
/// offset that the TRC reader refused (it read at most 19 digits): the writer's own file did
/// not read back.
#[test]
fn trc_offsets_of_twenty_digits_read_back() {
    let frame: Frame = "123#11".parse().unwrap();
    let at = |secs| Message {
        at: Timestamp::since_epoch(Duration::from_secs(secs)),
        channel: "can0".into(),
        record: Record::Frame(frame),
        direction: None,
    };
    let entries = [at(0), at(15_633_973_094_558_642)];
    for version in [trc::Version::V1_1, trc::Version::V2_1] {
        let mut writer = trc::Writer::new(Vec::new(), version);
        for entry in &entries {
            writer.write(entry).unwrap();
        }
        let file = writer.finish().unwrap();
        let (read, errors) = read_all(trc::Reader::new(&file[..]), 100);
        assert!(errors.is_empty(), "{errors:?}");
        let times: Vec<_> = read.iter().map(|e| e.at).collect();
        assert_eq!(times, [entries[0].at, entries[1].at]);
    }
}

/// `round_trip::readers_survive_bytes_that_look_like_their_format` (a stress run): a damaged
/// database with TEXT that is not UTF-8 made rusqlite panic while the reader took the row. The
/// row is now refused, naming the column, and the reader goes on.
#[test]
fn sqlite_text_that_is_not_utf8_is_a_bad_row_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad-text.db");
    {
        let conn = rusqlite::Connection::open(&path).unwrap();
        conn.execute_batch(sqlite::CREATE_TABLE).unwrap();
        conn.execute_batch(
            "INSERT INTO messages VALUES (CAST(x'41ff42' AS TEXT), 291, 0, 0, 0, 1, x'01');
             INSERT INTO messages VALUES (1.5, 291, 0, 0, 0, 1, CAST(x'c3' AS TEXT));
             INSERT INTO messages VALUES (2.0, 291, 0, 0, 0, 1, x'02');",
        )
        .unwrap();
    }
    let reader = sqlite::Reader::open(&path).expect("the file opens as a database");
    let (entries, errors) = read_all(reader, 100);
    assert_eq!(errors.len(), 2, "{errors:?}");
    assert!(errors[0].contains("ts in seconds"), "{errors:?}");
    assert!(errors[1].contains("data as a BLOB"), "{errors:?}");
    assert_eq!(entries.len(), 1, "{entries:?}");
    assert_eq!(entries[0].record, Record::Frame("123#02".parse().unwrap()));
}

/// A BLF writer, a pcap writer and a pcapng writer in memory.
fn blf_writer() -> blf::Writer<std::io::Cursor<Vec<u8>>> {
    blf::Writer::new(std::io::Cursor::new(Vec::new())).expect("memory")
}

fn frame_at(timestamp: Duration) -> Message {
    Message {
        at: Timestamp::since_epoch(timestamp),
        channel: "can0".into(),
        record: Record::Frame("123#1122".parse::<Frame>().unwrap()),
        direction: None,
    }
}

/// `logs_blf`: a BLF file whose header starts in the year 65534 and whose entry lies 169 days
/// and then years later read back as an entry after the year 65535; written back, its year was
/// cut to 65535 (a SYSTEMTIME's year is 16 bits) and the file named another time. A writer now
/// refuses a time its format cannot hold, naming it, and writes nothing for it.
#[test]
fn blf_entry_after_the_year_65535_is_refused_not_moved() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/blf-start-in-65534.blf");
    let bytes = std::fs::read(path).unwrap();
    let (entries, _) = read_all(blf::Reader::new(&bytes[..]), 1_000);
    assert!(!entries.is_empty());
    let mut writer = blf_writer();
    let late = entries.iter().find(|e| e.at.as_secs() > 2_006_000_000_000);
    let late = late.expect("the input has an entry after the year 65535");
    let err = writer.write(late).expect_err("after the year 65535");
    assert_eq!(err.kind(), std::io::ErrorKind::InvalidInput);
    let text = err.to_string();
    assert!(
        text.contains(&late.at.as_secs().to_string()) && text.contains("65535"),
        "{text}"
    );

    // The last second of 65535 is written and reads back as itself, to the millisecond.
    let last = Duration::from_secs(2_005_949_145_599) + Duration::from_millis(250);
    let mut writer = blf_writer();
    writer.write(&frame_at(last)).unwrap();
    assert!(
        writer
            .write(&frame_at(last + Duration::from_secs(1)))
            .is_err()
    );
    let bytes = writer.finish().unwrap().into_inner();
    let (back, errors) = read_all(blf::Reader::new(&bytes[..]), 10);
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(
        back.iter()
            .map(|e| e.at.since_epoch_duration())
            .collect::<Vec<_>>(),
        [last]
    );

    // Offsets are nanoseconds in 64 bits: 584 years after the first entry is the most.
    let mut writer = blf_writer();
    writer.write(&frame_at(Duration::from_secs(1))).unwrap();
    let err = writer
        .write(&frame_at(Duration::from_secs(18_446_744_074)))
        .expect_err("585 years after the start");
    assert!(err.to_string().contains("584 years"), "{err}");
}

/// pcap's seconds are 32 bits and pcapng's nanoseconds 64: a later time is refused, naming
/// it, instead of being written as the last time the format holds.
#[test]
fn pcap_and_pcapng_refuse_times_they_cannot_hold() {
    let mut pcap = pcap::Writer::new(Vec::new()).unwrap();
    pcap.write(&frame_at(Duration::from_secs(u64::from(u32::MAX))))
        .unwrap();
    let err = pcap
        .write(&frame_at(Duration::from_secs(u64::from(u32::MAX) + 1)))
        .expect_err("after 2106");
    assert_eq!(err.kind(), std::io::ErrorKind::InvalidInput);
    assert!(err.to_string().contains("4294967296.000000000 s"), "{err}");
    let bytes = pcap.finish().unwrap();
    let (back, errors) = read_all(pcap::Reader::new(&bytes[..]), 10);
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(back.len(), 1);

    let mut pcapng = pcapng::Writer::new(Vec::new()).unwrap();
    let last = Duration::from_nanos(u64::MAX);
    pcapng.write(&frame_at(last)).unwrap();
    let err = pcapng
        .write(&frame_at(last + Duration::from_nanos(1)))
        .expect_err("after 2554");
    assert!(err.to_string().contains("18446744073.709551616 s"), "{err}");
    let bytes = pcapng.finish().unwrap();
    let (back, errors) = read_all(pcapng::Reader::new(&bytes[..]), 10);
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(
        back.iter()
            .map(|e| e.at.since_epoch_duration())
            .collect::<Vec<_>>(),
        [last]
    );
}
