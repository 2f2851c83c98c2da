//! A frame's length on the wire, for estimating the bus load from frames alone.

use buslab_can::Frame;
use buslab_can::wire::encode;

/// Bits `frame` takes on the bus: SOF to EOF with its stuff bits, plus the 3-bit
/// intermission.
pub fn frame_bits(frame: &Frame) -> u64 {
    encode(frame).stuffed().len() as u64 + 3
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lengths_on_the_wire_include_stuffing_and_intermission() {
        // A standard data frame with no data: 44 bits + stuffing; 8 bytes of 0x55: no
        // stuffing in the data (alternating bits).
        let empty: Frame = "7FF#".parse().unwrap();
        assert!(
            (47..=60).contains(&frame_bits(&empty)),
            "{}",
            frame_bits(&empty)
        );
        let full: Frame = "555#5555555555555555".parse().unwrap();
        assert!(
            (111..=130).contains(&frame_bits(&full)),
            "{}",
            frame_bits(&full)
        );
    }
}
