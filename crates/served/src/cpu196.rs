//! The CPU196 board served on a pseudo-terminal with its image file, and the file service the
//! monitor offers a board.

use std::collections::HashMap;
use std::fs::File;
use std::io::{self, Read, Write};
use std::path::{Component, Path, PathBuf};
use std::time::Duration;

use buslab_cpu196::codes::MsgCode;
use buslab_cpu196::host::FileRequests;
use buslab_cpu196::message::{FileMode, Message, Thread};
use buslab_cpu196::pic::Peer;
use buslab_cpu196::program::Registry;
use buslab_cpu196::source::Inputs;
use buslab_cpu196::{Board, Image};
use buslab_cpu196_wasm::WasmRuntime;
use buslab_device::Nanos;
use buslab_link::fs::{open_regular, read_text_limited};
use buslab_link::{Serve, Served};

use crate::ServeError;

/// How often the image is looked at (and written if the board changed it).
pub const SAVE_EVERY: Duration = Duration::from_millis(200);

/// The largest image file read (eight full flash banks as hex are 1 MiB).
const MAX_IMAGE_FILE: u64 = 16 << 20;

/// What to serve.
#[derive(Clone, Debug)]
pub struct BoardOptions {
    /// The board's image: loaded if it exists (else the default image), written back at once,
    /// whenever the board changes it, and at stop.
    pub image: Option<PathBuf>,
    /// A symlink to the PTY.
    pub link: Option<PathBuf>,
    /// The line rate (8N1); it overrides the image's boot configuration.
    pub baud: u32,
    pub inputs: Inputs,
    /// The device on the PIC's SCI and SPI/I2C bridges.
    pub peer: Peer,
}

/// Loads the image at `path`, or the default image if there is none, and serves the board on
/// a new PTY.
pub fn spawn_board(options: BoardOptions) -> Result<Served<Board>, ServeError> {
    let image = match &options.image {
        Some(path) => {
            let mut image = load_image(path)?.unwrap_or_default();
            crate::replay_journals::<Board>(path, &mut image)?;
            image
        }
        None => Image::default(),
    };
    // Modules a user flashed run (also from the boot START).
    let mut programs = Registry::default();
    programs.set_module_runtime(Box::new(WasmRuntime::new()));
    let mut board = Board::with_registry(image, options.inputs, programs, Nanos::ZERO);
    board.set_peer(options.peer);
    if board.line().baud != options.baud {
        board.set_baud(options.baud);
    }
    let line = board.line();
    Ok(Serve::new(board, line)
        .name("cpu196")
        .link(options.link)
        .persist(options.image, "image", SAVE_EVERY)
        .spawn()?)
}

/// The image in `path`; `None` if there is no file.
pub fn load_image(path: &Path) -> Result<Option<Image>, ServeError> {
    let text = match read_text_limited(path, MAX_IMAGE_FILE) {
        Ok(text) => text,
        Err(e) if e.is_not_found() => return Ok(None),
        Err(e) => return Err(e.into()),
    };
    Image::from_toml(&text)
        .map(Some)
        .map_err(|detail| ServeError::Image {
            path: path.to_path_buf(),
            detail,
        })
}

/// Serves the board's file requests (THREAD `40/41/18/10/20`) from one folder, never outside
/// it.
pub struct FileService {
    root: PathBuf,
    files: HashMap<u8, File>,
}

/// Why a file name was refused.
#[derive(Debug, thiserror::Error)]
pub enum FileNameError {
    #[error("file name {0:?} is not UTF-8 text")]
    NotText(Vec<u8>),
    #[error(
        "file name `{0}` must be relative and stay inside the served folder (no `..`, no absolute path)"
    )]
    Escapes(String),
    #[error("file name `{0}` leads outside the served folder through a symbolic link")]
    Symlink(String),
}

impl FileService {
    /// Serves the folder `root`.
    pub fn new(root: &Path) -> io::Result<Self> {
        Ok(Self {
            root: root.canonicalize()?,
            files: HashMap::new(),
        })
    }

    /// Where `name` lives under the root, if it is allowed.
    pub fn resolve(&self, name: &[u8]) -> Result<PathBuf, FileNameError> {
        let text = std::str::from_utf8(name).map_err(|_| FileNameError::NotText(name.to_vec()))?;
        let rel = Path::new(text);
        // Names in messages are shown with their control characters written out.
        let shown = || buslab_cpu196::message::printable(name);
        if text.is_empty() || !rel.components().all(|c| matches!(c, Component::Normal(_))) {
            return Err(FileNameError::Escapes(shown()));
        }
        let path = self.root.join(rel);
        // Follow symlinks as far as the path exists: it must stay under the root. A link counts
        // as existing even when it dangles (opening would follow it); one that cannot be
        // resolved cannot be shown to stay inside.
        let mut probe = path.clone();
        while probe.symlink_metadata().is_err() {
            match probe.parent() {
                Some(p) => probe = p.to_path_buf(),
                None => break,
            }
        }
        match probe.canonicalize() {
            Ok(real) if real.starts_with(&self.root) => Ok(path),
            _ => Err(FileNameError::Symlink(shown())),
        }
    }
}

impl FileRequests for FileService {
    /// Handles a THREAD file message; returns the messages to send back and a log line.
    fn handle(&mut self, t: &Thread) -> (Vec<Message>, Option<String>) {
        match t {
            Thread::Open { mode, name, file } => {
                let shown = buslab_cpu196::message::printable(name);
                let opened = self
                    .resolve(name)
                    .map_err(|e| e.to_string())
                    .and_then(|path| {
                        // A FIFO or a device in the folder is refused without blocking: the
                        // monitor must keep sending its watchdogs.
                        if *mode == FileMode::Write
                            && let Some(dir) = path.parent()
                        {
                            std::fs::create_dir_all(dir).ok();
                        }
                        open_regular(&path, *mode == FileMode::Write).map_err(|e| {
                            if e.kind() == io::ErrorKind::InvalidInput {
                                e.to_string()
                            } else {
                                format!("{}: {e}", path.display())
                            }
                        })
                    });
                match opened {
                    Ok(f) => {
                        self.files.insert(*file, f);
                        (
                            vec![Message::Msg(MsgCode::NO_ERROR)],
                            Some(format!("file {file}: opened `{shown}` ({mode:?})")),
                        )
                    }
                    Err(e) => (
                        vec![Message::Msg(MsgCode::FILE_ERROR)],
                        Some(format!("file {file}: refused: {e}")),
                    ),
                }
            }
            Thread::Close { file } => {
                let closed = self.files.remove(file).map(|f| f.sync_all());
                (
                    Vec::new(),
                    Some(format!(
                        "file {file}: closed{}",
                        if closed.is_none() {
                            " (was not open)"
                        } else {
                            ""
                        }
                    )),
                )
            }
            Thread::Write { data, file } => {
                match self.files.get_mut(file).map(|f| f.write_all(data)) {
                    Some(Ok(())) => (Vec::new(), None),
                    Some(Err(e)) => (
                        vec![Message::Msg(MsgCode::FILE_ERROR)],
                        Some(format!("file {file}: write failed: {e}")),
                    ),
                    None => (
                        vec![Message::Msg(MsgCode::FILE_ERROR)],
                        Some(format!("file {file}: write to a file that is not open")),
                    ),
                }
            }
            Thread::ReadRequest { len, file } => {
                let mut buf = vec![0u8; *len as usize];
                match self.files.get_mut(file).map(|f| f.read(&mut buf)) {
                    Some(Ok(n)) => {
                        buf.truncate(n);
                        (
                            vec![Message::Thread(Thread::ReadData {
                                data: buf,
                                file: *file,
                            })],
                            None,
                        )
                    }
                    _ => (
                        vec![Message::Msg(MsgCode::FILE_ERROR)],
                        Some(format!("file {file}: read failed")),
                    ),
                }
            }
            _ => (Vec::new(), None),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use buslab_cpu196::message::FileMode;

    #[test]
    fn file_service_stays_inside_its_folder() {
        let dir = tempfile::tempdir().unwrap();
        let outside = tempfile::tempdir().unwrap();
        std::os::unix::fs::symlink(outside.path(), dir.path().join("out")).unwrap();
        let fs = FileService::new(dir.path()).unwrap();
        assert!(fs.resolve(b"log.txt").is_ok());
        assert!(fs.resolve(b"sub/log.txt").is_ok());
        for bad in [
            &b"../x"[..],
            b"/etc/passwd",
            b"a/../../x",
            b"",
            b"./x/../..",
        ] {
            assert!(
                matches!(fs.resolve(bad), Err(FileNameError::Escapes(_))),
                "{bad:?}"
            );
        }
        assert!(matches!(
            fs.resolve(b"out/x"),
            Err(FileNameError::Symlink(_))
        ));
        // A dangling link: File::create would follow it and make the file outside.
        std::os::unix::fs::symlink(outside.path().join("new"), dir.path().join("dangling"))
            .unwrap();
        for bad in [&b"dangling"[..], b"dangling/x"] {
            assert!(
                matches!(fs.resolve(bad), Err(FileNameError::Symlink(_))),
                "{bad:?}"
            );
        }
        assert!(matches!(
            fs.resolve(&[0xFF, 0xFE]),
            Err(FileNameError::NotText(_))
        ));
    }

    #[test]
    fn file_service_writes_and_reads() {
        let dir = tempfile::tempdir().unwrap();
        let mut fs = FileService::new(dir.path()).unwrap();
        let (r, _) = fs.handle(&Thread::Open {
            mode: FileMode::Write,
            name: b"a.txt".to_vec(),
            file: 1,
        });
        assert_eq!(r, vec![Message::Msg(MsgCode::NO_ERROR)]);
        fs.handle(&Thread::Write {
            data: b"hello".to_vec(),
            file: 1,
        });
        fs.handle(&Thread::Close { file: 1 });
        assert_eq!(std::fs::read(dir.path().join("a.txt")).unwrap(), b"hello");
        fs.handle(&Thread::Open {
            mode: FileMode::Read,
            name: b"a.txt".to_vec(),
            file: 2,
        });
        let (r, _) = fs.handle(&Thread::ReadRequest { len: 3, file: 2 });
        assert_eq!(
            r,
            vec![Message::Thread(Thread::ReadData {
                data: b"hel".to_vec(),
                file: 2
            })]
        );
        let (r, _) = fs.handle(&Thread::Open {
            mode: FileMode::Write,
            name: b"../evil".to_vec(),
            file: 3,
        });
        assert_eq!(r, vec![Message::Msg(MsgCode::FILE_ERROR)]);
        assert!(!dir.path().parent().unwrap().join("evil").exists());
    }

    #[test]
    fn file_service_refuses_a_fifo_at_once_for_reading_and_writing() {
        // A FIFO in the served folder blocked the monitor, which stopped sending watchdogs.
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        assert!(
            std::process::Command::new("mkfifo")
                .arg(&fifo)
                .status()
                .unwrap()
                .success()
        );
        let mut fs = FileService::new(dir.path()).unwrap();
        for mode in [FileMode::Read, FileMode::Write] {
            let (r, log) = fs.handle(&Thread::Open {
                mode,
                name: b"pipe".to_vec(),
                file: 1,
            });
            assert_eq!(r, vec![Message::Msg(MsgCode::FILE_ERROR)]);
            let log = log.unwrap();
            assert!(log.contains("is a FIFO, not a regular file"), "{log}");
        }
    }
}
