//! Every format: what a writer writes, the reader reads back identical, as far as the format
//! keeps it (`kept` says what each one keeps), CAN FD frames included; no reader panics or
//! hangs on arbitrary bytes.

use std::io::Cursor;
use std::path::Path;
use std::time::Duration;

use buslab_bus::ErrorFrame;
use buslab_can::{FdFrame, Frame, Id};
use buslab_logs::Timestamp;
use buslab_logs::{
    ChannelMap, Direction, Format, LogWriter, Message, Record, create_writer, create_writer_atomic,
    open_reader, reader,
};
use proptest::prelude::*;

#[path = "support/fd.rs"]
mod fd;

fn frame() -> impl Strategy<Value = Frame> {
    let id = prop_oneof![
        (0u16..=0x7FF).prop_map(|v| Id::standard(v).unwrap()),
        (0u32..=0x1FFF_FFFF).prop_map(|v| Id::extended(v).unwrap()),
    ];
    (
        id,
        any::<bool>(),
        prop::collection::vec(any::<u8>(), 0..=8),
        0u8..=8,
    )
        .prop_map(|(id, remote, data, dlc)| {
            if remote {
                Frame::remote(id, dlc).unwrap()
            } else {
                Frame::data(id, &data).unwrap()
            }
        })
}

/// Error frames of any class and any bytes, of any length (every format that holds error
/// frames keeps them byte for byte).
fn error_frame() -> impl Strategy<Value = ErrorFrame> {
    let class = prop_oneof![0u32..=0x3FF, 0u32..=0x1FFF_FFFF];
    (class, prop::collection::vec(any::<u8>(), 0..=8))
        .prop_map(|(class, data)| ErrorFrame::decode(class, &data).unwrap())
}

fn record() -> impl Strategy<Value = Record> {
    prop_oneof![
        4 => frame().prop_map(Record::Frame),
        2 => fd::fd_frame().prop_map(Record::Fd),
        1 => error_frame().prop_map(Record::Error),
    ]
}

/// Whether `format` holds `record` (TRC holds no error frames, TRC 1.1 no CAN FD frames).
fn holds(format: Format, record: &Record) -> bool {
    !matches!(
        (format, record),
        (Format::Trc11 | Format::Trc21, Record::Error(_)) | (Format::Trc11, Record::Fd(_))
    )
}

/// Writes `e`; a TRC 1.1 writer must refuse a CAN FD frame by name.
fn write_entry(w: &mut dyn LogWriter, format: Format, e: &Message) {
    match w.write(e) {
        Err(err) if format == Format::Trc11 && matches!(e.record, Record::Fd(_)) => {
            assert!(err.to_string().contains("TRC 1.1 has no CAN FD"), "{err}");
        }
        result => result.unwrap_or_else(|err| panic!("{format}: {err}")),
    }
}

fn direction() -> impl Strategy<Value = Option<Direction>> {
    prop_oneof![
        Just(None),
        Just(Some(Direction::Rx)),
        Just(Some(Direction::Tx))
    ]
}

/// Entries in time order (as logs are), from any start up to 2^32 s (pcap's limit).
fn entries() -> impl Strategy<Value = Vec<Message>> {
    (
        0u64..(1 << 32) * 1_000_000_000 / 2,
        prop::collection::vec(
            (
                0u64..5_000_000_000,
                prop::sample::select(vec!["can0", "vcan1", "can2", "lab"]),
                record(),
                direction(),
            ),
            0..40,
        ),
    )
        .prop_map(|(start, items)| {
            let mut t = start;
            items
                .into_iter()
                .map(|(step, iface, record, direction)| {
                    t += step;
                    Message {
                        at: Timestamp::since_epoch(Duration::from_nanos(t)),
                        channel: iface.to_string(),
                        record,
                        direction,
                    }
                })
                .collect()
        })
}

fn floor(t: Duration, unit_ns: u128) -> Duration {
    let ns = t.as_nanos() / unit_ns * unit_ns;
    Duration::new((ns / 1_000_000_000) as u64, (ns % 1_000_000_000) as u32)
}

fn floor_at(t: Timestamp, unit_ns: u128) -> Timestamp {
    Timestamp::since_epoch(floor(t.since_epoch_duration(), unit_ns))
}

/// What `format` keeps of `entries`.
fn kept(format: Format, entries: &[Message]) -> Vec<Message> {
    let mut channels = ChannelMap::new();
    let mut numbered = |e: &Message| format!("can{}", channels.number(&e.channel) - 1);
    let first = entries.iter().find(|e| holds(format, &e.record));
    let first_t = first.map(|e| e.at).unwrap_or_default();
    entries
        .iter()
        .filter(|e| holds(format, &e.record))
        .map(|e| {
            let mut k = e.clone();
            // python-can's CSV and SQLite columns: no FD mark, BRS or ESI.
            if let (Format::Csv | Format::Sqlite, Record::Fd(f)) = (format, &e.record) {
                k.record = match Frame::data(f.id(), f.payload()) {
                    Ok(classic) => Record::Frame(classic),
                    Err(_) => Record::Fd(FdFrame::new(f.id(), f.payload()).unwrap()),
                };
            }
            let rx = Some(e.direction.unwrap_or(Direction::Rx));
            match format {
                Format::Candump => {
                    k.at = floor_at(e.at, 1000);
                    k.direction = None;
                }
                Format::Asc => {
                    k.at = floor_at(e.at, 1000);
                    k.channel = numbered(e);
                    k.direction = if let Record::Error(_) = k.record {
                        Some(Direction::Rx)
                    } else {
                        rx
                    };
                }
                Format::Blf => {
                    k.channel = numbered(e);
                    k.direction = if let Record::Error(_) = k.record {
                        Some(Direction::Rx)
                    } else {
                        rx
                    };
                }
                Format::Trc11 | Format::Trc21 => {
                    let unit = if format == Format::Trc11 {
                        100_000
                    } else {
                        1000
                    };
                    k.at = first_t.saturating_add(floor(e.at.saturating_since(first_t), unit));
                    // TRC 1.1 has no bus column.
                    k.channel = if format == Format::Trc11 {
                        "can0".into()
                    } else {
                        numbered(e)
                    };
                    k.direction = rx;
                }
                Format::Csv | Format::Sqlite | Format::Pcap => {
                    k.channel = "can0".into();
                    k.direction = None;
                    k.at = match format {
                        Format::Sqlite => Timestamp::from_secs_f64(e.at.as_secs_f64()),
                        Format::Pcap => floor_at(e.at, 1000),
                        _ => e.at,
                    };
                }
                Format::Pcapng => {}
            }
            k
        })
        .collect()
}

fn write_then_read(dir: &Path, format: Format, entries: &[Message], atomic: bool) -> Vec<Message> {
    let path = dir.join(format!("log.{}", format.extension()));
    let mut w = if atomic {
        create_writer_atomic(&path, format).unwrap()
    } else {
        create_writer(&path, format).unwrap()
    };
    for e in entries {
        write_entry(w.as_mut(), format, e);
    }
    w.finish().unwrap();
    open_reader(&path, format)
        .unwrap()
        .collect::<Result<Vec<_>, _>>()
        .unwrap_or_else(|e| panic!("{format}: {e}"))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn every_format_reads_back_what_it_keeps(entries in entries(), atomic in any::<bool>()) {
        let dir = tempfile::tempdir().unwrap();
        for format in Format::ALL {
            let got = write_then_read(dir.path(), format, &entries, atomic);
            prop_assert_eq!(got, kept(format, &entries), "{}", format);
        }
    }

    #[test]
    fn no_reader_panics_on_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..2000)) {
        for format in Format::ALL {
            if format == Format::Sqlite {
                continue;
            }
            let mut r = reader(Cursor::new(bytes.clone()), format).unwrap();
            let mut e = Message::default();
            // Every read consumes input or ends: bounded by the input's size.
            for _ in 0..=bytes.len() + 1 {
                match r.read_into(&mut e) {
                    Ok(false) => break,
                    Err(err) if err.is_fatal() => break,
                    _ => {}
                }
            }
            prop_assert!(!r.read_into(&mut e).unwrap_or(false) || format.is_text());
        }
    }

    #[test]
    fn readers_survive_bytes_that_look_like_their_format(
        entries in entries(),
        flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
    ) {
        let dir = tempfile::tempdir().unwrap();
        for format in Format::ALL {
            let path = dir.path().join(format!("x.{}", format.extension()));
            let mut w = create_writer(&path, format).unwrap();
            for e in &entries {
                write_entry(w.as_mut(), format, e);
            }
            w.finish().unwrap();
            let mut bytes = std::fs::read(&path).unwrap();
            if bytes.is_empty() {
                continue;
            }
            for (i, v) in &flips {
                let i = i.index(bytes.len());
                bytes[i] = *v;
            }
            std::fs::write(&path, &bytes).unwrap();
            // SQLite too: a damaged database is an error, never a crash.
            if let Ok(entries) = open_reader(&path, format) {
                for _ in entries.take(10_000) {}
            }
        }
    }
}

/// Entries read from a file cut at `len` bytes: every whole record before the cut, then one
/// error naming the cut (or a clean end, when the cut falls between records).
fn read_cut(format: Format, bytes: &[u8], len: usize) -> (Vec<Message>, Option<String>) {
    let mut r = reader(Cursor::new(bytes[..len].to_vec()), format).unwrap();
    let mut got = Vec::new();
    let mut e = Message::default();
    loop {
        match r.read_into(&mut e) {
            Ok(true) => got.push(e.clone()),
            Ok(false) => return (got, None),
            Err(err) => {
                assert!(err.is_fatal(), "{format} cut at {len}: {err}");
                return (got, Some(err.to_string()));
            }
        }
    }
}

#[test]
fn truncated_binary_logs_give_every_record_before_the_cut() {
    let dir = tempfile::tempdir().unwrap();
    let entries: Vec<Message> = (0..3000u64)
        .map(|i| Message {
            at: Timestamp::since_epoch(Duration::from_micros(1_700_000_000_000_000 + i * 250)),
            channel: "can0".into(),
            record: Record::Frame(
                Frame::data(
                    Id::standard((i % 0x7FF) as u16).unwrap(),
                    &i.to_le_bytes()[..(i % 9) as usize],
                )
                .unwrap(),
            ),
            direction: Some(Direction::Rx),
        })
        .collect();
    for format in [Format::Blf, Format::Pcap, Format::Pcapng] {
        let path = dir.path().join(format!("cut.{}", format.extension()));
        let mut w = create_writer(&path, format).unwrap();
        for e in &entries {
            w.write(e).unwrap();
        }
        w.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let full = kept(format, &entries);
        let step = (bytes.len() / 97).max(1);
        let mut cut_errors = 0;
        for len in (FILE_HEADER.min(bytes.len())..bytes.len()).step_by(step) {
            let (got, error) = read_cut(format, &bytes, len);
            assert_eq!(got, full[..got.len()], "{format} cut at {len}");
            if let Some(error) = error {
                cut_errors += 1;
                assert!(
                    error.contains("ends inside"),
                    "{format} cut at {len}: {error}"
                );
            }
            if format != Format::Blf {
                // Record by record: all the records that fit before the cut.
                let record = if format == Format::Pcap { 32 } else { 60 };
                let header = if format == Format::Pcap { 24 } else { 0 };
                assert!(
                    got.len() + 1 >= (len.saturating_sub(header + 100)) / record,
                    "{format} cut at {len}: only {} entries",
                    got.len()
                );
            }
        }
        assert!(cut_errors > 50, "{format}: {cut_errors}");
        // BLF: a cut inside a compressed container still gives what inflates before it.
        if format == Format::Blf {
            let (got, error) = read_cut(format, &bytes, bytes.len() - 10);
            assert!(error.is_some());
            assert!(got.len() > 2500, "{}", got.len());
        }
    }
}

const FILE_HEADER: usize = 150;

#[test]
fn a_bad_candump_line_names_the_file_the_line_and_what_was_expected() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.log");
    std::fs::write(
        &path,
        "(1.000000) can0 123#11\n(2.000000) can0 123#1\n(3.000000) can0 7FF#R\n",
    )
    .unwrap();
    let results: Vec<_> = open_reader(&path, Format::Candump).unwrap().collect();
    assert_eq!(results.len(), 3);
    let err = results[1].as_ref().unwrap_err();
    assert!(!err.is_fatal());
    let text = err.to_string();
    assert!(
        text.contains("bad.log") && text.contains("line 2") && text.contains("odd number"),
        "{text}"
    );
    assert!(results[2].is_ok());
}

#[test]
fn only_regular_files_are_read() {
    let err = open_reader(Path::new("/dev/zero"), Format::Candump)
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("/dev/zero") && err.contains("character device"),
        "{err}"
    );
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("fifo.log");
    nix_mkfifo(&fifo);
    let err = open_reader(&fifo, Format::Candump)
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("fifo.log") && err.contains("a FIFO"), "{err}");
    let err = open_reader(dir.path(), Format::Candump)
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("a directory"), "{err}");
}

fn nix_mkfifo(path: &Path) {
    let status = std::process::Command::new("mkfifo")
        .arg(path)
        .status()
        .unwrap();
    assert!(status.success());
}

#[test]
fn an_atomic_writer_dropped_unfinished_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.asc");
    let mut w = create_writer_atomic(&path, Format::Asc).unwrap();
    w.write(&Message {
        at: Timestamp::since_epoch(Duration::from_secs(1)),
        channel: "can0".into(),
        record: Record::Frame("123#11".parse().unwrap()),
        direction: None,
    })
    .unwrap();
    drop(w);
    assert!(!path.exists());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn an_atomic_writer_gives_the_file_the_usual_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let atomic = dir.path().join("atomic.pcap");
    let direct = dir.path().join("direct.pcap");
    create_writer_atomic(&atomic, Format::Pcap)
        .unwrap()
        .finish()
        .unwrap();
    create_writer(&direct, Format::Pcap)
        .unwrap()
        .finish()
        .unwrap();
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode(&atomic), mode(&direct));
}
