//! A unix socket that takes control lines for a served device, one reply line each
//! (`echo status | socat - UNIX-CONNECT:/tmp/zelle.sock`).

use std::io::{self, BufRead, BufReader, Write};
use std::os::unix::fs::{FileTypeExt, MetadataExt};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Handles one control line; `None` for lines that get no reply (blank, comments).
pub type LineHandler = dyn Fn(&str) -> Option<String> + Send + Sync;

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

impl ControlSocket {
    /// Listens on `path` (replacing a stale socket file there, never another kind of file);
    /// each client gets a thread that passes its lines to `handler` and writes the replies.
    pub fn bind(path: &Path, handler: Arc<LineHandler>) -> io::Result<Self> {
        if let Ok(meta) = std::fs::symlink_metadata(path)
            && meta.file_type().is_socket()
        {
            std::fs::remove_file(path)?;
        }
        let listener = UnixListener::bind(path)?;
        let stop = Arc::new(AtomicBool::new(false));
        {
            let stop = stop.clone();
            std::thread::Builder::new()
                .name("control-socket".into())
                .spawn(move || {
                    for stream in listener.incoming() {
                        if stop.load(Ordering::SeqCst) {
                            break;
                        }
                        let Ok(stream) = stream else { continue };
                        let handler = handler.clone();
                        let _ = std::thread::Builder::new()
                            .name("control-client".into())
                            .spawn(move || serve_client(stream, &*handler));
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

fn serve_client(stream: UnixStream, handler: &LineHandler) {
    let Ok(mut writer) = stream.try_clone() else {
        return;
    };
    for line in BufReader::new(stream).lines() {
        let Ok(line) = line else { break };
        if let Some(reply) = handler(&line)
            && writeln!(writer, "{reply}").is_err()
        {
            break;
        }
    }
}
