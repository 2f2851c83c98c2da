//! The served-device adapter: a toy device on a PTY, its state kept in a file, work from other
//! threads, control lines on a socket.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use buslab_device::{ChangeLog, Changes, Nanos, ReplayError};
use buslab_link::{
    ByteDevice, ControlSocket, LineSettings, Persistent, Port, SerialLine, Serve, ServedError,
    journal,
};

/// Far above any scheduling delay on a loaded machine; waits end as soon as things happen.
const ALLOWANCE: Duration = Duration::from_secs(30);

const LINE: LineSettings = LineSettings::n81(115_200);

/// Keeps every byte it receives: that is its persistent state. Echoes nothing, or each byte
/// once it is kept (an acknowledgement).
#[derive(Default)]
struct Recorder {
    state: Vec<u8>,
    generation: u64,
    changes: ChangeLog,
    echo: bool,
    acks: Vec<u8>,
}

impl Recorder {
    fn push(&mut self, bytes: &[u8]) {
        // A record sets bytes at an offset: `[offset (u32 BE), bytes…]`.
        let mut record = (self.state.len() as u32).to_be_bytes().to_vec();
        record.extend_from_slice(bytes);
        self.changes.record(record);
        self.state.extend_from_slice(bytes);
        self.generation += 1;
    }
}

impl ByteDevice for Recorder {
    fn receive(&mut self, _now_ns: Nanos, byte: u8) {
        self.push(&[byte]);
        if self.echo {
            self.acks.push(byte);
        }
    }
    fn poll(&mut self, _now_ns: Nanos, out: &mut Vec<u8>) {
        out.append(&mut self.acks);
    }
    fn next_deadline(&self) -> Option<Nanos> {
        None
    }
}

impl Persistent for Recorder {
    type Snapshot = Vec<u8>;
    fn state_generation(&self) -> u64 {
        self.generation
    }
    fn snapshot(&self) -> Vec<u8> {
        self.state.clone()
    }
    fn file_bytes(snapshot: &Vec<u8>) -> Vec<u8> {
        snapshot.clone()
    }
    fn take_changes(&mut self) -> Changes {
        self.changes.take()
    }
    fn replay(snapshot: &mut Vec<u8>, record: &[u8]) -> Result<(), ReplayError> {
        let Some((offset, bytes)) = record.split_first_chunk::<4>() else {
            return Err(ReplayError::new(record, "no offset"));
        };
        let at = u32::from_be_bytes(*offset) as usize;
        if snapshot.len() < at + bytes.len() {
            snapshot.resize(at + bytes.len(), 0);
        }
        snapshot[at..at + bytes.len()].copy_from_slice(bytes);
        Ok(())
    }
}

/// Waits until `path` holds `want`.
fn wait_for_file(path: &Path, want: &[u8]) {
    let until = Instant::now() + ALLOWANCE;
    loop {
        if std::fs::read(path).is_ok_and(|got| got == want) {
            return;
        }
        assert!(
            Instant::now() < until,
            "{} never held {:?}: {:?}",
            path.display(),
            String::from_utf8_lossy(want),
            std::fs::read(path).map(|b| String::from_utf8_lossy(&b).into_owned())
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn state_is_saved_at_start_on_change_on_request_and_at_stop() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("state.bin");
    let mut device = Recorder::default();
    device.push(b"start;");
    let served = Serve::new(device, LINE)
        .name("recorder")
        .persist(Some(path.clone()), "state", Duration::from_millis(10))
        .spawn()
        .unwrap();
    // Written before serving starts.
    assert_eq!(std::fs::read(&path).unwrap(), b"start;");
    // Bytes from a client change the state: saved by the periodic look.
    let mut port = SerialLine::open(served.path(), LINE).unwrap();
    port.send(b"ab").unwrap();
    wait_for_file(&path, b"start;ab");
    // Work from another thread, then a save on request: written when `save` returns.
    served.with(|d, _| d.push(b"!")).unwrap();
    assert_eq!(served.save().unwrap(), Some(path.clone()));
    assert_eq!(std::fs::read(&path).unwrap(), b"start;ab!");
    // The last change is saved when serving stops.
    served.with(|d, _| d.push(b"end")).unwrap();
    served.stop().unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"start;ab!end");
    assert_eq!(
        files_in(dir.path()),
        ["state.bin"],
        "a temporary file was left"
    );
}

#[test]
fn a_state_file_that_cannot_be_written_is_an_error_at_start_naming_it() {
    let err = Serve::new(Recorder::default(), LINE)
        .persist(
            Some("/nonexistent/dir/state.bin".into()),
            "state file",
            Duration::from_secs(1),
        )
        .spawn()
        .err()
        .expect("served with a file it cannot write");
    assert!(matches!(err, ServedError::Save { .. }), "{err}");
    assert!(
        err.to_string()
            .starts_with("cannot write state file /nonexistent/dir/state.bin: "),
        "{err}"
    );
}

#[test]
fn dropping_stops_the_device_saves_it_and_removes_the_link() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("state.bin");
    let link = dir.path().join("ttyREC");
    let served = Serve::new(Recorder::default(), LINE)
        .link(Some(link.clone()))
        .persist(Some(path.clone()), "state", Duration::from_secs(3600))
        .spawn()
        .unwrap();
    assert_eq!(std::fs::read_link(&link).unwrap(), served.path());
    let handle = served.handle();
    handle.with(|d, _| d.push(b"kept")).unwrap();
    drop(served);
    assert!(std::fs::symlink_metadata(&link).is_err(), "the link stayed");
    assert_eq!(std::fs::read(&path).unwrap(), b"kept");
    assert!(matches!(handle.with(|_, _| ()), Err(ServedError::Stopped)));
    assert!(matches!(handle.save(), Err(ServedError::Stopped)));
}

#[test]
fn saves_from_many_threads_at_once_write_whole_snapshots_in_order() {
    // Before, every save went through one fixed `.NAME.tmp`: two at once corrupted it.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("state.bin");
    let served = Serve::new(Recorder::default(), LINE)
        .persist(Some(path.clone()), "state", Duration::from_millis(1))
        .spawn()
        .unwrap();
    std::thread::scope(|s| {
        for t in 0..4u8 {
            let handle = served.handle();
            s.spawn(move || {
                for _ in 0..25 {
                    handle.with(move |d, _| d.push(&[b'a' + t; 1000])).unwrap();
                    handle.save().unwrap();
                }
            });
        }
    });
    let last = served.with(|d, _| d.state.clone()).unwrap();
    served.stop().unwrap();
    assert_eq!(last.len(), 100 * 1000);
    assert_eq!(std::fs::read(&path).unwrap(), last);
    assert_eq!(files_in(dir.path()), ["state.bin"]);
}

#[test]
fn what_the_device_acknowledged_is_in_the_journal_before_the_client_sees_it() {
    // No periodic snapshot: only the journal holds the changes while serving.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("state.bin");
    std::fs::write(&path, b"old;").unwrap();
    let mut state = std::fs::read(&path).unwrap();
    journal::replay::<Recorder>(&path, &mut state).unwrap();
    let device = Recorder {
        state,
        echo: true,
        ..Recorder::default()
    };
    let served = Serve::new(device, LINE)
        .persist(Some(path.clone()), "state", Duration::from_secs(3600))
        .spawn()
        .unwrap();
    let mut port = SerialLine::open(served.path(), LINE).unwrap();
    for (i, byte) in (b'a'..=b'z').enumerate() {
        port.send(&[byte]).unwrap();
        let mut ack = [0u8];
        let n = port.recv(&mut ack, ALLOWANCE).unwrap();
        assert_eq!((n, ack[0]), (1, byte));
        // Acknowledged: the state file and its journal hold it (a kill now would keep it).
        let mut recovered = std::fs::read(&path).unwrap();
        let replayed = journal::replay::<Recorder>(&path, &mut recovered).unwrap();
        assert_eq!(replayed.torn_bytes, 0);
        let mut want = b"old;".to_vec();
        want.extend(b'a'..=byte);
        assert_eq!(recovered, want, "after {} acknowledgements", i + 1);
    }
    served.stop().unwrap();
    // Stopped: everything is in the state file, the journals are gone.
    assert_eq!(files_in(dir.path()), ["state.bin"]);
    let mut want = b"old;".to_vec();
    want.extend(b'a'..=b'z');
    assert_eq!(std::fs::read(&path).unwrap(), want);
}

#[test]
fn journals_left_by_a_crash_are_replayed_then_folded_into_the_state_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("state.bin");
    std::fs::write(&path, b"0123").unwrap();
    // What a killed server left: two journals, the second cut in the middle of a record.
    let frame = |record: &[u8]| {
        let mut f = (record.len() as u32).to_le_bytes().to_vec();
        f.extend(crc32fast::hash(record).to_le_bytes());
        f.extend(record);
        f
    };
    std::fs::write(
        journal::journal_path(&path, 4),
        frame(&[0, 0, 0, 4, b'x', b'y']),
    )
    .unwrap();
    let mut second = frame(&[0, 0, 0, 1, b'A']);
    second.extend(&frame(&[0, 0, 0, 6, b'z'])[..7]);
    std::fs::write(journal::journal_path(&path, 5), second).unwrap();
    let mut state = std::fs::read(&path).unwrap();
    let replayed = journal::replay::<Recorder>(&path, &mut state).unwrap();
    assert_eq!(
        replayed,
        journal::Replayed {
            journals: 2,
            records: 2,
            torn_bytes: 7
        }
    );
    assert_eq!(state, b"0A23xy");
    let served = Serve::new(
        Recorder {
            state,
            ..Recorder::default()
        },
        LINE,
    )
    .persist(Some(path.clone()), "state", Duration::from_secs(3600))
    .spawn()
    .unwrap();
    // Folded into the state file at start; the old journals are gone, a new one is open.
    assert_eq!(std::fs::read(&path).unwrap(), b"0A23xy");
    assert_eq!(files_in(dir.path()), ["state.bin", "state.bin.journal.6"]);
    served.stop().unwrap();
    assert_eq!(files_in(dir.path()), ["state.bin"]);
}

#[test]
fn a_device_without_a_file_saves_nothing() {
    let served = Serve::new(Recorder::default(), LINE).spawn().unwrap();
    assert_eq!(served.save().unwrap(), None);
    served.stop().unwrap();
}

#[test]
fn a_control_socket_answers_each_line_and_goes_away_when_dropped() {
    let dir = tempfile::tempdir().unwrap();
    let sock = dir.path().join("control.sock");
    let socket = ControlSocket::bind(
        &sock,
        Arc::new(|line: &str| match line.trim() {
            "" => None,
            other => Some(format!("ok {other}")),
        }),
    )
    .unwrap();
    let stream = UnixStream::connect(&sock).unwrap();
    writeln!(&stream, "status\n\nping").unwrap();
    let mut lines = BufReader::new(&stream).lines();
    assert_eq!(lines.next().unwrap().unwrap(), "ok status");
    assert_eq!(lines.next().unwrap().unwrap(), "ok ping");
    // A plain file at the path is never replaced.
    let file = dir.path().join("plain");
    std::fs::write(&file, b"keep").unwrap();
    assert!(ControlSocket::bind(&file, Arc::new(|_: &str| None)).is_err());
    assert_eq!(std::fs::read(&file).unwrap(), b"keep");
    drop(socket);
    assert!(
        std::fs::symlink_metadata(&sock).is_err(),
        "the socket file stayed"
    );
}
