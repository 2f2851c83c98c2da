//! The file protocol (SPEC N5): data longer than 8 bytes goes as data frames on one ID, every
//! frame with DLC 8 except the last, which is shorter — empty when the length is a multiple of
//! 8 — so the receiver knows where the data ends.

use buslab_can::{Frame, Id};

pub use buslab_can::file::frames;

/// Bad input to a [`FileAssembler`].
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

/// Rebuilds data sent with [`frames`]: push each frame on the file's ID; the frame with fewer
/// than 8 bytes completes it.
#[derive(Clone, Debug)]
pub struct FileAssembler {
    id: Id,
    data: Vec<u8>,
    limit: usize,
    done: bool,
}

impl FileAssembler {
    /// No size limit beyond memory; see [`with_limit`](Self::with_limit) for untrusted senders.
    pub fn new(id: Id) -> Self {
        Self::with_limit(id, usize::MAX)
    }

    /// Refuses files longer than `limit` bytes.
    pub fn with_limit(id: Id, limit: usize) -> Self {
        Self {
            id,
            data: Vec::new(),
            limit,
            done: false,
        }
    }

    pub fn id(&self) -> Id {
        self.id
    }

    /// The bytes received so far.
    pub fn received(&self) -> &[u8] {
        &self.data
    }

    pub fn is_complete(&self) -> bool {
        self.done
    }

    /// Adds one frame. Returns the whole data when this frame ends the file. A rejected frame
    /// leaves the assembler unchanged.
    pub fn push(&mut self, frame: &Frame) -> Result<Option<Vec<u8>>, FileError> {
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
        let payload = frame.payload();
        if self.data.len().saturating_add(payload.len()) > self.limit {
            return Err(FileError::TooLarge { limit: self.limit });
        }
        self.data.extend_from_slice(payload);
        if payload.len() < 8 {
            self.done = true;
            return Ok(Some(self.data.clone()));
        }
        Ok(None)
    }

    /// Starts over for the next file on the same ID.
    pub fn reset(&mut self) {
        self.data.clear();
        self.done = false;
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
