//! A unix socket that takes control lines for a served device, one reply line each
//! (`echo status | socat - UNIX-CONNECT:/tmp/zelle.sock`).
//!
//! Bounded like every input ([`ControlLimits`]): a line longer than the limit is answered with
//! an error and its connection closed (it is never held whole in memory); a client that sends
//! no complete line for the idle time, or does not read its replies, is closed; at most so
//! many clients are served at once (a thread each), further ones are told so and closed.

use std::io::{self, BufRead, BufReader, Write};
use std::os::unix::fs::{FileTypeExt, MetadataExt};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Handles one control line; `None` for lines that get no reply (blank, comments).
pub type LineHandler = dyn Fn(&str) -> Option<String> + Send + Sync;

/// What one control socket's clients may hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ControlLimits {
    /// The longest line taken, in bytes without its newline (a command with a file path
    /// fits).
    pub max_line: usize,
    /// Clients served at once.
    pub max_clients: usize,
    /// How long a client may take to send its next line, or to read a reply.
    pub idle: Duration,
}

impl Default for ControlLimits {
    fn default() -> Self {
        Self {
            max_line: 16 * 1024,
            max_clients: 16,
            idle: Duration::from_secs(300),
        }
    }
}

/// A listening control socket. Dropping it stops listening and removes the socket file,
/// unless another server has bound the same path since.
pub struct ControlSocket {
    path: PathBuf,
    /// Device and inode of our socket file.
    id: Option<(u64, u64)>,
    stop: Arc<AtomicBool>,
}

fn file_id(path: &Path) -> Option<(u64, u64)> {
    std::fs::symlink_metadata(path)
        .ok()
        .map(|m| (m.dev(), m.ino()))
}

/// Counts a client as served until dropped.
struct Place(Arc<AtomicUsize>);

impl Drop for Place {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

impl ControlSocket {
    /// Listens on `path` (replacing a stale socket file there, never another kind of file)
    /// with the default [`ControlLimits`]; each client gets a thread that passes its lines
    /// to `handler` and writes the replies.
    pub fn bind(path: &Path, handler: Arc<LineHandler>) -> io::Result<Self> {
        Self::bind_with(path, handler, ControlLimits::default())
    }

    /// [`bind`](Self::bind) with the given limits.
    pub fn bind_with(
        path: &Path,
        handler: Arc<LineHandler>,
        limits: ControlLimits,
    ) -> io::Result<Self> {
        if let Ok(meta) = std::fs::symlink_metadata(path)
            && meta.file_type().is_socket()
        {
            std::fs::remove_file(path)?;
        }
        let listener = UnixListener::bind(path)?;
        let stop = Arc::new(AtomicBool::new(false));
        {
            let stop = stop.clone();
            let served = Arc::new(AtomicUsize::new(0));
            std::thread::Builder::new()
                .name("control-socket".into())
                .spawn(move || {
                    for stream in listener.incoming() {
                        if stop.load(Ordering::SeqCst) {
                            break;
                        }
                        let Ok(stream) = stream else { continue };
                        if served.fetch_add(1, Ordering::SeqCst) >= limits.max_clients {
                            let _place = Place(served.clone());
                            refuse(stream, limits.max_clients);
                            continue;
                        }
                        let place = Place(served.clone());
                        let handler = handler.clone();
                        let spawned = std::thread::Builder::new()
                            .name("control-client".into())
                            .spawn(move || {
                                serve_client(stream, &*handler, limits);
                                drop(place);
                            });
                        if let Err(e) = spawned {
                            tracing::warn!("control socket: cannot serve a client: {e}");
                        }
                    }
                })?;
        }
        Ok(Self {
            path: path.to_path_buf(),
            id: file_id(path),
            stop,
        })
    }

    /// The socket's path.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for ControlSocket {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if self.id.is_some() && file_id(&self.path) == self.id {
            // Wakes the accepting thread so it sees `stop`.
            let _ = UnixStream::connect(&self.path);
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// Tells a client over the limit why it is closed, without ever waiting for it.
fn refuse(mut stream: UnixStream, max: usize) {
    let _ = stream.set_nonblocking(true);
    let _ = writeln!(
        stream,
        "error: too many control connections (at most {max} at once); try again later"
    );
}

/// Why a client's connection ends.
#[derive(Debug, PartialEq, Eq)]
enum LineError {
    /// The line grew past the limit before its newline.
    TooLong,
    /// No complete line within the idle time.
    Idle,
    /// The connection failed.
    Broken,
}

/// Reads one line (without its newline), taking at most `max` bytes of it into memory and
/// giving up at `deadline`; `Ok(None)` at the end of the stream.
fn read_line(
    reader: &mut BufReader<UnixStream>,
    max: usize,
    deadline: Instant,
) -> Result<Option<Vec<u8>>, LineError> {
    let mut line = Vec::new();
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(LineError::Idle);
        }
        reader
            .get_ref()
            .set_read_timeout(Some(left))
            .map_err(|_| LineError::Broken)?;
        let buf = match reader.fill_buf() {
            Ok(buf) => buf,
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) =>
            {
                return Err(LineError::Idle);
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(_) => return Err(LineError::Broken),
        };
        if buf.is_empty() {
            // The last line may lack its newline.
            return Ok((!line.is_empty()).then_some(line));
        }
        let (taken, end) = match buf.iter().position(|&b| b == b'\n') {
            Some(i) => (i, true),
            None => (buf.len(), false),
        };
        if line.len() + taken > max {
            return Err(LineError::TooLong);
        }
        line.extend_from_slice(&buf[..taken]);
        reader.consume(taken + usize::from(end));
        if end {
            return Ok(Some(line));
        }
    }
}

fn serve_client(stream: UnixStream, handler: &LineHandler, limits: ControlLimits) {
    let Ok(mut writer) = stream.try_clone() else {
        return;
    };
    // A client that does not read its replies is closed too.
    let _ = writer.set_write_timeout(Some(limits.idle));
    let mut reader = BufReader::new(stream);
    loop {
        let deadline = Instant::now() + limits.idle;
        let reply = match read_line(&mut reader, limits.max_line, deadline) {
            Ok(None) | Err(LineError::Broken) => return,
            Err(LineError::TooLong) => {
                let _ = writeln!(
                    writer,
                    "error: a control line is at most {} bytes: connection closed",
                    limits.max_line
                );
                return;
            }
            Err(LineError::Idle) => {
                let _ = writeln!(
                    writer,
                    "error: no command for {} s: connection closed",
                    limits.idle.as_secs_f64()
                );
                return;
            }
            Ok(Some(bytes)) => match std::str::from_utf8(&bytes) {
                Ok(line) => handler(line.trim_end_matches('\r')),
                Err(_) => Some("error: a control line must be UTF-8 text".to_string()),
            },
        };
        if let Some(reply) = reply
            && writeln!(writer, "{reply}").is_err()
        {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;
    use std::sync::Mutex;

    /// Only a guard against a hung server: every wait ends on an event first.
    const HANG: Duration = Duration::from_secs(120);

    struct Bench {
        _dir: tempfile::TempDir,
        path: PathBuf,
        _socket: ControlSocket,
        /// The lines the handler saw (their lengths).
        seen: Arc<Mutex<Vec<usize>>>,
    }

    fn bench(limits: ControlLimits) -> Bench {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("control.sock");
        let seen = Arc::new(Mutex::new(Vec::new()));
        let log = seen.clone();
        let socket = ControlSocket::bind_with(
            &path,
            Arc::new(move |line: &str| {
                log.lock().unwrap().push(line.len());
                (!line.is_empty()).then(|| format!("ok {}", line.len()))
            }),
            limits,
        )
        .unwrap();
        Bench {
            _dir: dir,
            path,
            _socket: socket,
            seen,
        }
    }

    fn connect(path: &Path) -> UnixStream {
        let s = UnixStream::connect(path).unwrap();
        s.set_read_timeout(Some(HANG)).unwrap();
        s
    }

    /// Everything the server says until it closes the connection.
    fn rest(s: &UnixStream) -> String {
        let mut text = String::new();
        // A reset after the server's last words counts as closed.
        let _ = (&*s).read_to_string(&mut text);
        text
    }

    #[test]
    fn a_line_longer_than_the_limit_is_refused_and_never_held_whole() {
        // Regression: a 400 MiB line was read into memory before anything looked at it.
        let limits = ControlLimits {
            max_line: 4096,
            ..ControlLimits::default()
        };
        let b = bench(limits);
        let s = connect(&b.path);
        writeln!(&s, "{}", "s".repeat(4096)).unwrap();
        let mut reply = String::new();
        BufReader::new(&s).read_line(&mut reply).unwrap();
        assert_eq!(reply, "ok 4096\n", "a line of the limit is taken");
        // 64 MiB without a newline: the server stops reading after the limit, says why,
        // closes; the writer then finds the connection closed.
        let writer = {
            let s = s.try_clone().unwrap();
            std::thread::spawn(move || {
                let chunk = vec![b'x'; 1 << 20];
                let mut written = 0usize;
                for _ in 0..64 {
                    match (&s).write(&chunk) {
                        Ok(n) => written += n,
                        Err(_) => break,
                    }
                }
                written
            })
        };
        let said = rest(&s);
        assert_eq!(
            said,
            "error: a control line is at most 4096 bytes: connection closed\n"
        );
        let written = writer.join().unwrap();
        assert!(written < 64 << 20, "the server took all {written} bytes");
        assert_eq!(
            *b.seen.lock().unwrap(),
            [4096],
            "the long line reached nobody"
        );
    }

    #[test]
    fn clients_beyond_the_limit_are_told_so_and_a_freed_place_serves_again() {
        // Regression: each idle connection held a thread of its own (2000 connections:
        // 2000 threads).
        let b = bench(ControlLimits {
            max_clients: 3,
            ..ControlLimits::default()
        });
        // Three clients that each got an answer hold the three places.
        let held: Vec<UnixStream> = (0..3)
            .map(|_| {
                let s = connect(&b.path);
                writeln!(&s, "ping").unwrap();
                let mut reply = String::new();
                BufReader::new(&s).read_line(&mut reply).unwrap();
                assert_eq!(reply, "ok 4\n");
                s
            })
            .collect();
        for _ in 0..50 {
            let s = connect(&b.path);
            let _ = writeln!(&s, "ping");
            assert_eq!(
                rest(&s),
                "error: too many control connections (at most 3 at once); try again later\n"
            );
        }
        drop(held);
        // The places are freed as their threads see the ends.
        let deadline = Instant::now() + HANG;
        loop {
            let s = connect(&b.path);
            // A refused client may find its connection closed before it writes (EPIPE).
            let _ = writeln!(&s, "ping");
            let mut reply = String::new();
            let _ = BufReader::new(&s).read_line(&mut reply);
            if reply == "ok 4\n" {
                break;
            }
            assert!(reply.starts_with("error: too many"), "{reply}");
            assert!(Instant::now() < deadline, "no place was freed");
        }
    }

    #[test]
    fn an_idle_client_is_closed_after_the_idle_time_and_not_before() {
        let idle = Duration::from_millis(500);
        let b = bench(ControlLimits {
            idle,
            ..ControlLimits::default()
        });
        let s = connect(&b.path);
        let started = Instant::now();
        // Half a line, then nothing.
        write!(&s, "sta").unwrap();
        let said = rest(&s);
        assert!(started.elapsed() >= idle);
        assert_eq!(said, "error: no command for 0.5 s: connection closed\n");
        assert!(b.seen.lock().unwrap().is_empty());
    }

    #[test]
    fn garbage_lines_get_an_error_and_the_connection_goes_on() {
        let b = bench(ControlLimits::default());
        let s = connect(&b.path);
        (&s).write_all(b"\xff\xfe\r\nabc\r\n\nlast").unwrap();
        s.shutdown(std::net::Shutdown::Write).unwrap();
        assert_eq!(
            rest(&s),
            "error: a control line must be UTF-8 text\nok 3\nok 4\n"
        );
    }
}
