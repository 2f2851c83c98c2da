//! Following a growing log (`open_source` with `follow_until`): a file truncated, rewritten
//! past the reader's position, or replaced (rotated) is read again from the start of its new
//! content, never from the old position in the middle of it.

use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use buslab_logs::{Format, Message, OpenOptions, open_source};

/// How long a test waits for an event that normally comes within a second.
const EVENT: Duration = Duration::from_secs(60);

/// `n` candump lines on `iface`, IDs from `from`.
fn lines(iface: &str, from: u32, n: u32) -> String {
    (from..from + n)
        .map(|i| format!("(1700000000.{i:06}) {iface} {i:03X}#{:02X}\n", i % 256))
        .collect()
}

fn write(path: &Path, text: &str) {
    std::fs::write(path, text).unwrap();
}

/// What the reader read, as candump lines without times.
fn shown(entries: &[Message]) -> Vec<String> {
    entries
        .iter()
        .map(|e| format!("{} {}", e.channel, e.frame().unwrap()))
        .collect()
}

fn expect(text: &str) -> Vec<String> {
    text.lines()
        .map(|l| l.split_once(' ').unwrap().1.to_string())
        .collect()
}

/// A reader following `path` in a thread; each time it catches up with the file it waits in
/// `on_wait` until the test says go (so the test changes the file while it is not looking).
struct Follower {
    caught_up: Receiver<()>,
    go: mpsc::Sender<()>,
    stop: Arc<AtomicBool>,
    entries: Receiver<Message>,
    thread: std::thread::JoinHandle<()>,
}

impl Follower {
    fn start(path: &Path) -> Self {
        let (caught_tx, caught_up) = mpsc::channel();
        let (go, go_rx) = mpsc::channel::<()>();
        let go_rx = Mutex::new(go_rx);
        let stop = Arc::new(AtomicBool::new(false));
        let options = OpenOptions {
            follow_until: Some(stop.clone()),
            on_wait: Some(Arc::new(move || {
                let _ = caught_tx.send(());
                let _ = go_rx.lock().unwrap().recv();
            })),
        };
        let path = path.to_path_buf();
        let (entry_tx, entries) = mpsc::channel();
        let thread = std::thread::spawn(move || {
            let mut source = open_source(&path, Format::Candump, &options).unwrap();
            let mut entry = Message::default();
            while source.reader.read_into(&mut entry).unwrap() {
                entry_tx.send(entry.clone()).unwrap();
            }
        });
        Self {
            caught_up,
            go,
            stop,
            entries,
            thread,
        }
    }

    /// Waits until the reader is at the end of the file.
    fn wait_caught_up(&self) {
        self.caught_up
            .recv_timeout(EVENT)
            .expect("the follower never caught up");
    }

    fn go(&self) {
        self.go.send(()).unwrap();
    }

    fn finish(self) -> Vec<Message> {
        self.stop.store(true, Ordering::SeqCst);
        drop(self.go);
        self.thread.join().unwrap();
        self.entries.try_iter().collect()
    }
}

/// The bug: `log convert --follow` kept its byte position when the input was truncated and
/// written again, so it read the new content from the middle (49 of 170 lines skipped).
#[test]
fn a_followed_log_truncated_rewritten_or_replaced_is_read_again_from_its_start() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("live.log");
    let a = lines("can0", 0, 10);
    write(&path, &a);
    let follower = Follower::start(&path);
    follower.wait_caught_up();

    // Truncated and written again, longer than before, while the reader did not look: only
    // the bytes before its position tell.
    let b = lines("can1", 0x100, 40);
    write(&path, &b);
    follower.go();
    follower.wait_caught_up();

    // Truncated to less than was read.
    let c = lines("can2", 0x200, 3);
    write(&path, &c);
    follower.go();
    follower.wait_caught_up();

    // Rotated: renamed away, a new file in its place.
    std::fs::rename(&path, dir.path().join("live.log.1")).unwrap();
    let d = lines("can3", 0x300, 5);
    write(&path, &d);
    follower.go();
    follower.wait_caught_up();

    // Appended: read on from where it was.
    let e = lines("can3", 0x305, 2);
    std::fs::OpenOptions::new()
        .append(true)
        .open(&path)
        .unwrap()
        .write_all(e.as_bytes())
        .unwrap();
    follower.go();
    follower.wait_caught_up();

    let got = follower.finish();
    let want: Vec<String> = [a, b, c, d, e].iter().flat_map(|t| expect(t)).collect();
    assert_eq!(shown(&got), want);
}
