//! Output that goes to a regular file in whole, aligned blocks.
//!
//! The kernel takes a long stream of text into the page cache at about half the cost when it
//! comes in aligned blocks of 256 KiB rather than in ragged writes of a few tens of KiB: each
//! ragged write starts and ends inside a page, which is then looked up and copied into twice
//! (225 MB on ext4: 0.044 s of system time in 256 KiB blocks, 0.09–0.2 s in 37 KiB writes;
//! docs/sim.md). A terminal or a pipe wants each piece as soon as it is ready instead, so
//! this is only for regular files ([`BlockWriter::for_stdout`]).

use std::fs::File;
use std::io::{self, Seek, Write};
use std::os::fd::AsFd;

/// The size of the blocks written.
pub const BLOCK: usize = 256 * 1024;

/// Writes a regular file in whole [`BLOCK`]s aligned to the file's offsets, from a buffer the
/// caller fills: what does not fill a block waits in the buffer for the next call, or for
/// [`write_rest`](Self::write_rest) at the end.
#[derive(Debug)]
pub struct BlockWriter {
    file: File,
    /// The file offset the next write starts at (where the buffer's first byte goes).
    offset: u64,
}

impl BlockWriter {
    /// Writes to `file` from its current position (an offset that cannot be read counts as
    /// 0: the blocks may then be unaligned, which costs only speed).
    pub fn new(mut file: File) -> Self {
        let offset = file.stream_position().unwrap_or(0);
        Self { file, offset }
    }

    /// A writer to the process's standard output if it is a regular file (through its own
    /// descriptor, sharing the offset); `None` for a terminal, a pipe or a socket, which
    /// want each piece as it comes.
    pub fn for_stdout() -> io::Result<Option<Self>> {
        let file = File::from(io::stdout().as_fd().try_clone_to_owned()?);
        Ok(file
            .metadata()?
            .file_type()
            .is_file()
            .then(|| Self::new(file)))
    }

    /// Writes the longest start of `buf` that ends on a block boundary of the file and
    /// removes it from `buf`; less than a block stays.
    pub fn write_blocks(&mut self, buf: &mut Vec<u8>) -> io::Result<()> {
        let block = BLOCK as u64;
        let end = (self.offset + buf.len() as u64) / block * block;
        if end <= self.offset {
            return Ok(());
        }
        let n = (end - self.offset) as usize;
        self.file.write_all(&buf[..n])?;
        self.offset = end;
        buf.drain(..n);
        Ok(())
    }

    /// Writes all of `buf` (the end of the output) and empties it.
    pub fn write_rest(&mut self, buf: &mut Vec<u8>) -> io::Result<()> {
        self.file.write_all(buf)?;
        self.offset += buf.len() as u64;
        buf.clear();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Where each call's writes ended shows in the file's length after it.
    #[test]
    fn whole_blocks_are_written_at_aligned_offsets_and_the_rest_waits() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("trace.log");
        let mut file = File::create(&path).unwrap();
        // A file that already holds something: blocks align to the file, not to the writer.
        file.write_all(&[b'0'; 1000]).unwrap();
        let mut w = BlockWriter::new(file);
        let mut buf = vec![b'a'; BLOCK - 1000 - 1];
        w.write_blocks(&mut buf).unwrap();
        assert_eq!(buf.len(), BLOCK - 1001, "less than a block waits");
        assert_eq!(std::fs::metadata(&path).unwrap().len(), 1000);

        buf.extend_from_slice(&[b'b'; BLOCK + 10]);
        w.write_blocks(&mut buf).unwrap();
        // Up to the file's second block boundary: 2 blocks in all, the rest waits.
        assert_eq!(std::fs::metadata(&path).unwrap().len(), 2 * BLOCK as u64);
        assert_eq!(buf.len(), 1000 + BLOCK - 1001 + BLOCK + 10 - 2 * BLOCK);
        assert!(buf.iter().all(|&b| b == b'b'));

        w.write_rest(&mut buf).unwrap();
        assert!(buf.is_empty());
        let text = std::fs::read(&path).unwrap();
        assert_eq!(text.len(), 1000 + (BLOCK - 1001) + BLOCK + 10);
        assert_eq!(text.iter().filter(|&&b| b == b'0').count(), 1000);
        assert_eq!(text.iter().filter(|&&b| b == b'a').count(), BLOCK - 1001);
        assert_eq!(text.iter().filter(|&&b| b == b'b').count(), BLOCK + 10);
        assert!(text.is_sorted(), "written in order");
    }

    #[test]
    fn a_buffer_that_ends_on_a_boundary_is_written_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("trace.log");
        let mut w = BlockWriter::new(File::create(&path).unwrap());
        let mut buf = vec![b'z'; 3 * BLOCK];
        w.write_blocks(&mut buf).unwrap();
        assert!(buf.is_empty());
        assert_eq!(std::fs::metadata(&path).unwrap().len(), 3 * BLOCK as u64);
        // Nothing left: the end writes nothing more.
        w.write_rest(&mut buf).unwrap();
        assert_eq!(std::fs::metadata(&path).unwrap().len(), 3 * BLOCK as u64);
    }
}
