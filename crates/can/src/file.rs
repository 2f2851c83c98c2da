//! The file protocol (SPEC N5): data longer than 8 bytes goes as data frames on one ID, every
//! frame with DLC 8 except the last, which is shorter — empty when the length is a multiple of
//! 8 — so the receiver knows where the data ends.

use crate::{Frame, Id};

/// The frames that carry `data` on `id`: `len / 8` full frames, then one with `len % 8` bytes.
pub fn frames(id: Id, data: &[u8]) -> impl Iterator<Item = Frame> + '_ {
    (0..=data.len() / 8).filter_map(move |i| frame(id, data, i))
}

/// Frame `i` of [`frames`], or `None` past the last one (for senders that keep one frame in
/// flight and remember only the index).
pub fn frame(id: Id, data: &[u8], i: usize) -> Option<Frame> {
    let start = i.checked_mul(8).filter(|&s| s <= data.len())?;
    let chunk = &data[start..data.len().min(start + 8)];
    Some(Frame::data(id, chunk).expect("chunks hold at most 8 bytes"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec::Vec;

    #[test]
    fn full_frames_then_a_shorter_last_one() {
        let id = Id::standard(0x100).unwrap();
        let lens = |n: u8| {
            let data: Vec<u8> = (0..n).collect();
            frames(id, &data).map(|f| f.dlc()).collect::<Vec<_>>()
        };
        assert_eq!(lens(0), [0]);
        assert_eq!(lens(5), [5]);
        assert_eq!(lens(8), [8, 0]);
        assert_eq!(lens(19), [8, 8, 3]);
        let data: Vec<u8> = (0..19).collect();
        let joined: Vec<u8> = frames(id, &data)
            .flat_map(|f| f.payload().to_vec())
            .collect();
        assert_eq!(joined, data);
        assert_eq!(frame(id, &data, 3), None);
        assert_eq!(frame(id, &data, usize::MAX), None);
    }
}
