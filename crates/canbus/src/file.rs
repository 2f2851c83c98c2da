//! The file protocol (SPEC N5): data longer than 8 bytes goes as data frames on one ID, every
//! frame with DLC 8 except the last, which is shorter — empty when the length is a multiple of
//! 8 — so the receiver knows where the data ends.
//!
//! Both ends stream: [`FileFrames`] reads the frames' bytes from a reader as they are sent,
//! [`FileReceiver`] checks the frames as they come and hands each one's bytes on, so a
//! file's size never has to fit in memory ([`FileAssembler`] keeps them, for small data).

use std::io::{self, Read};

use buslab_can::{Frame, Id};

pub use buslab_can::file::frames;

/// Bad input to a [`FileReceiver`] or a [`FileAssembler`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FileError {
    #[error("frame {frame} has ID {got}, but this file arrives on ID {expected}")]
    WrongId { expected: Id, got: Id, frame: Frame },
    #[error("frame {frame} is a remote frame; the file protocol uses data frames only")]
    RemoteFrame { frame: Frame },
    #[error("frame {frame} arrived after the file had ended (its last frame was shorter than 8)")]
    AfterEnd { frame: Frame },
    #[error("the file exceeds the limit of {limit} bytes")]
    TooLarge { limit: usize },
}

/// What one accepted frame adds to the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Received<'f> {
    /// The frame's bytes: the next ones of the file.
    pub bytes: &'f [u8],
    /// This frame ended the file (fewer than 8 bytes).
    pub complete: bool,
}

/// Checks the frames of one file as they come, keeping only a count: push each frame on the
/// file's ID; the frame with fewer than 8 bytes completes it. The caller puts each frame's
/// bytes where they go (`buslab recvfile` writes them to its output file as they come).
#[derive(Clone, Debug)]
pub struct FileReceiver {
    id: Id,
    len: usize,
    limit: usize,
    done: bool,
}

impl FileReceiver {
    /// No size limit; see [`with_limit`](Self::with_limit) for untrusted senders.
    pub fn new(id: Id) -> Self {
        Self::with_limit(id, usize::MAX)
    }

    /// Refuses files longer than `limit` bytes.
    pub fn with_limit(id: Id, limit: usize) -> Self {
        Self {
            id,
            len: 0,
            limit,
            done: false,
        }
    }

    pub fn id(&self) -> Id {
        self.id
    }

    /// Bytes received so far.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no byte arrived yet.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    pub fn is_complete(&self) -> bool {
        self.done
    }

    /// Checks one frame; its bytes are the file's next ones. A rejected frame leaves the
    /// receiver unchanged.
    pub fn push<'f>(&mut self, frame: &'f Frame) -> Result<Received<'f>, FileError> {
        if frame.id() != self.id {
            return Err(FileError::WrongId {
                expected: self.id,
                got: frame.id(),
                frame: *frame,
            });
        }
        if frame.is_remote() {
            return Err(FileError::RemoteFrame { frame: *frame });
        }
        if self.done {
            return Err(FileError::AfterEnd { frame: *frame });
        }
        let bytes = frame.payload();
        if self.len.saturating_add(bytes.len()) > self.limit {
            return Err(FileError::TooLarge { limit: self.limit });
        }
        self.len += bytes.len();
        self.done = bytes.len() < 8;
        Ok(Received {
            bytes,
            complete: self.done,
        })
    }

    /// Starts over for the next file on the same ID.
    pub fn reset(&mut self) {
        self.len = 0;
        self.done = false;
    }
}

/// Rebuilds data sent with [`frames`] in memory: push each frame on the file's ID; the frame
/// with fewer than 8 bytes completes it.
#[derive(Clone, Debug)]
pub struct FileAssembler {
    receiver: FileReceiver,
    data: Vec<u8>,
}

impl FileAssembler {
    /// No size limit beyond memory; see [`with_limit`](Self::with_limit) for untrusted senders.
    pub fn new(id: Id) -> Self {
        Self::with_limit(id, usize::MAX)
    }

    /// Refuses files longer than `limit` bytes.
    pub fn with_limit(id: Id, limit: usize) -> Self {
        Self {
            receiver: FileReceiver::with_limit(id, limit),
            data: Vec::new(),
        }
    }

    pub fn id(&self) -> Id {
        self.receiver.id()
    }

    /// The bytes received so far.
    pub fn received(&self) -> &[u8] {
        &self.data
    }

    pub fn is_complete(&self) -> bool {
        self.receiver.is_complete()
    }

    /// Adds one frame. Returns the whole data when this frame ends the file. A rejected frame
    /// leaves the assembler unchanged.
    pub fn push(&mut self, frame: &Frame) -> Result<Option<Vec<u8>>, FileError> {
        let received = self.receiver.push(frame)?;
        self.data.extend_from_slice(received.bytes);
        Ok(received.complete.then(|| self.data.clone()))
    }

    /// Starts over for the next file on the same ID.
    pub fn reset(&mut self) {
        self.receiver.reset();
        self.data.clear();
    }
}

/// Why [`FileFrames`] could not make the next frame.
#[derive(Debug, thiserror::Error)]
pub enum FileReadError {
    #[error(transparent)]
    Io(#[from] io::Error),
    #[error("the data ended after {read} of its {len} bytes (the file shrank while it was sent)")]
    Short { read: u64, len: u64 },
}

/// The frames that carry the next `len` bytes of `reader` on `id`, read as they are taken
/// ([`frames`] for a stream): `len / 8` full frames, then one with `len % 8` bytes. Bytes
/// beyond `len` are not read; a reader that ends before `len` is an error, never a shorter
/// last frame (the receiver would take it for the end of a shorter file).
pub struct FileFrames<R> {
    id: Id,
    reader: io::Take<R>,
    len: u64,
    done: bool,
}

impl<R: Read> FileFrames<R> {
    pub fn new(id: Id, reader: R, len: u64) -> Self {
        Self {
            id,
            reader: reader.take(len),
            len,
            done: false,
        }
    }

    /// Fills `buf` unless the reader ends first; the bytes read.
    fn fill(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let mut got = 0;
        while got < buf.len() {
            match self.reader.read(&mut buf[got..]) {
                Ok(0) => break,
                Ok(n) => got += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(got)
    }
}

impl<R: Read> Iterator for FileFrames<R> {
    type Item = Result<Frame, FileReadError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let mut chunk = [0u8; 8];
        let got = match self.fill(&mut chunk) {
            Ok(got) => got,
            Err(e) => {
                self.done = true;
                return Some(Err(e.into()));
            }
        };
        if got < 8 {
            self.done = true;
            let read = self.len - self.reader.limit();
            if read < self.len {
                return Some(Err(FileReadError::Short {
                    read,
                    len: self.len,
                }));
            }
        }
        Some(Ok(
            Frame::data(self.id, &chunk[..got]).expect("chunks hold at most 8 bytes")
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn id() -> Id {
        Id::standard(0x321).unwrap()
    }

    #[test]
    fn lengths_of_the_frames() {
        let lens = |n: usize| -> Vec<u8> { frames(id(), &vec![0; n]).map(|f| f.dlc()).collect() };
        assert_eq!(lens(0), [0]);
        assert_eq!(lens(5), [5]);
        assert_eq!(lens(8), [8, 0]);
        assert_eq!(lens(17), [8, 8, 1]);
    }

    #[test]
    fn garbage_is_refused_with_reasons() {
        let mut asm = FileAssembler::with_limit(id(), 10);
        let other: Frame = "322#01".parse().unwrap();
        assert_eq!(
            asm.push(&other).unwrap_err().to_string(),
            "frame 322#01 has ID 322, but this file arrives on ID 321"
        );
        let remote: Frame = "321#R".parse().unwrap();
        assert!(matches!(
            asm.push(&remote),
            Err(FileError::RemoteFrame { .. })
        ));
        let full: Frame = "321#0102030405060708".parse().unwrap();
        assert_eq!(asm.push(&full), Ok(None));
        assert_eq!(
            asm.push(&full).unwrap_err().to_string(),
            "the file exceeds the limit of 10 bytes"
        );
        assert_eq!(asm.received().len(), 8, "a refused frame changes nothing");
        let end: Frame = "321#0909".parse().unwrap();
        assert_eq!(asm.push(&end), Ok(Some(vec![1, 2, 3, 4, 5, 6, 7, 8, 9, 9])));
        assert!(matches!(asm.push(&end), Err(FileError::AfterEnd { .. })));
        asm.reset();
        assert_eq!(asm.push(&"321#".parse().unwrap()), Ok(Some(vec![])));
    }

    #[test]
    fn a_file_read_as_it_is_sent_gives_the_same_frames_and_never_a_short_end() {
        for n in [0usize, 5, 8, 17, 4096] {
            let data: Vec<u8> = (0..n).map(|i| i as u8).collect();
            let streamed: Vec<Frame> = FileFrames::new(id(), &data[..], n as u64)
                .map(Result::unwrap)
                .collect();
            assert_eq!(streamed, frames(id(), &data).collect::<Vec<_>>(), "{n}");
        }
        // A file that grew is sent as long as it was; one that shrank is an error, not a
        // shorter file.
        let data = [7u8; 20];
        assert_eq!(FileFrames::new(id(), &data[..], 16).count(), 3);
        let mut shrunk = FileFrames::new(id(), &data[..], 24);
        assert!(shrunk.next().unwrap().is_ok());
        assert!(shrunk.next().unwrap().is_ok());
        let e = shrunk.next().unwrap().unwrap_err();
        assert_eq!(
            e.to_string(),
            "the data ended after 20 of its 24 bytes (the file shrank while it was sent)"
        );
        assert!(shrunk.next().is_none());
    }

    #[test]
    fn a_receiver_hands_on_each_frames_bytes_and_keeps_none() {
        let mut rx = FileReceiver::with_limit(id(), 12);
        let full: Frame = "321#0102030405060708".parse().unwrap();
        let got = rx.push(&full).unwrap();
        assert_eq!(got.bytes, &[1, 2, 3, 4, 5, 6, 7, 8]);
        assert!(!got.complete);
        assert_eq!(rx.push(&full), Err(FileError::TooLarge { limit: 12 }));
        assert_eq!(rx.len(), 8);
        let end: Frame = "321#0909".parse().unwrap();
        assert_eq!(
            rx.push(&end),
            Ok(Received {
                bytes: &[9, 9],
                complete: true
            })
        );
        assert!(matches!(rx.push(&end), Err(FileError::AfterEnd { .. })));
    }

    proptest! {
        #[test]
        fn round_trip(data in proptest::collection::vec(any::<u8>(), 0..100), ext in any::<bool>()) {
            let id = if ext { Id::extended(0x1234567).unwrap() } else { id() };
            let sent: Vec<Frame> = frames(id, &data).collect();
            prop_assert_eq!(sent.len(), data.len() / 8 + 1);
            let mut asm = FileAssembler::new(id);
            let (last, body) = sent.split_last().unwrap();
            for frame in body {
                prop_assert_eq!(frame.dlc(), 8);
                prop_assert_eq!(asm.push(frame), Ok(None));
            }
            prop_assert!(last.dlc() < 8);
            prop_assert_eq!(asm.push(last), Ok(Some(data)));
        }
    }
}
