//! A live log reads at every flush, before its writer finishes (a writer killed at that
//! instant leaves exactly this file): every format, from creation on.

use std::time::Duration;

use buslab_logs::Timestamp;
use buslab_logs::{Format, Message, Record, create_writer, open_reader};

fn entry(i: u64) -> Message {
    Message {
        at: Timestamp::since_epoch(Duration::from_micros(1_700_000_000_000_000 + i * 1000)),
        channel: "can0".into(),
        record: Record::Frame(
            format!("{:03X}#{:02X}", i % 0x800, i % 256)
                .parse()
                .unwrap(),
        ),
        direction: None,
    }
}

/// Every entry the file holds now, with the reader's error if one stopped it.
fn read(path: &std::path::Path, format: Format) -> (Vec<Message>, Option<String>) {
    let mut got = Vec::new();
    for e in open_reader(path, format).unwrap() {
        match e {
            Ok(e) => got.push(e),
            Err(e) => return (got, Some(e.to_string())),
        }
    }
    (got, None)
}

/// The frames (and their times to the microsecond: SQLite keeps float seconds).
fn frames(entries: &[Message]) -> Vec<(u128, Record)> {
    entries
        .iter()
        .map(|e| (e.at.as_micros(), e.record.clone()))
        .collect()
}

#[test]
fn every_format_reads_at_every_flush_before_its_writer_finishes() {
    let dir = tempfile::tempdir().unwrap();
    for format in Format::ALL {
        let path = dir.path().join(format!("live.{}", format.extension()));
        let mut writer = create_writer(&path, format).unwrap();
        // Created: a valid empty log (BLF's header, pcap's and pcapng's are there at once).
        let (got, error) = read(&path, format);
        assert_eq!((got.len(), error), (0, None), "{format} just created");
        let mut written = Vec::new();
        for batch in [1u64, 7, 300, 5000] {
            for i in written.len() as u64..written.len() as u64 + batch {
                let e = entry(i);
                writer.write(&e).unwrap();
                written.push(e);
            }
            writer.flush().unwrap();
            let (got, error) = read(&path, format);
            assert_eq!(error, None, "{format} after {} entries", written.len());
            assert_eq!(
                frames(&got),
                frames(&written),
                "{format} after {} entries",
                written.len()
            );
        }
        writer.finish().unwrap();
        assert_eq!(frames(&read(&path, format).0), frames(&written), "{format}");
    }
}

/// The bug: a live BLF log had a header of zeros until `finish` (buslab: "not a BLF file";
/// python-can: BLFParseError), so a killed writer lost every frame.
#[test]
fn a_live_blf_log_has_a_header_that_counts_what_was_flushed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("live.blf");
    let mut writer = create_writer(&path, Format::Blf).unwrap();
    for i in 0..10 {
        writer.write(&entry(i)).unwrap();
    }
    writer.flush().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(&bytes[..4], b"LOGG");
    let u64_at = |i: usize| u64::from_le_bytes(bytes[i..i + 8].try_into().unwrap());
    let objects = u32::from_le_bytes(bytes[32..36].try_into().unwrap());
    assert_eq!(u64_at(16), bytes.len() as u64, "file size");
    assert_eq!(objects, 10, "object count");
    // The start time (SYSTEMTIME year, month) of the first entry, 2023-11.
    assert_eq!(&bytes[40..44], &[0xE7, 0x07, 11, 0]);
    drop(writer); // as a killed writer: never finished
    assert_eq!(read(&path, Format::Blf).0.len(), 10);
}
