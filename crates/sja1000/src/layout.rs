//! How a frame is laid out in the TX buffer and in the RX FIFO (PeliCAN and BasicCAN).

use buslab_can::{Frame, Id};

pub use buslab_chips::sja1000::CanMode;

/// Bytes of one stored message: header then data (none for remote frames).
pub fn encode(mode: CanMode, frame: &Frame, out: &mut [u8; 13]) -> usize {
    let rtr = frame.is_remote() as u8;
    let dlc = frame.dlc();
    let header = match (mode, frame.id()) {
        (CanMode::Basic, id) => {
            let id = match id {
                Id::Standard(id) => id.as_raw(),
                Id::Extended(id) => id.base(),
            };
            out[0] = (id >> 3) as u8;
            out[1] = ((id & 7) << 5) as u8 | rtr << 4 | dlc;
            2
        }
        (CanMode::Peli, Id::Standard(id)) => {
            let id = id.as_raw();
            out[0] = rtr << 6 | dlc;
            out[1] = (id >> 3) as u8;
            out[2] = ((id & 7) << 5) as u8 | rtr << 4;
            3
        }
        (CanMode::Peli, Id::Extended(id)) => {
            let id = id.as_raw();
            out[0] = 0x80 | rtr << 6 | dlc;
            out[1] = (id >> 21) as u8;
            out[2] = (id >> 13) as u8;
            out[3] = (id >> 5) as u8;
            out[4] = ((id & 0x1F) << 3) as u8 | rtr << 2;
            5
        }
    };
    let data = frame.payload();
    out[header..header + data.len()].copy_from_slice(data);
    header + data.len()
}

/// Length of the message [`encode`] makes of `frame` in `mode`.
#[inline]
pub fn message_len(mode: CanMode, frame: &Frame) -> usize {
    let header = match (mode, frame.id()) {
        (CanMode::Basic, _) => 2,
        (CanMode::Peli, Id::Standard(_)) => 3,
        (CanMode::Peli, Id::Extended(_)) => 5,
    };
    header + frame.payload().len()
}

/// Length of the message whose first bytes are `first` and `second` (enough to see the format,
/// RTR and DLC). DLC 9..15 stores 8 data bytes.
#[inline]
pub fn stored_len(mode: CanMode, first: u8, second: u8) -> usize {
    let (header, remote, dlc) = match mode {
        CanMode::Basic => (2, second & 0x10 != 0, second & 0x0F),
        CanMode::Peli => {
            let header = if first & 0x80 != 0 { 5 } else { 3 };
            (header, first & 0x40 != 0, first & 0x0F)
        }
    };
    header + if remote { 0 } else { dlc.min(8) as usize }
}

/// The DLC a program wrote into the TX buffer's frame info (descriptor), 0..15: the chip sends
/// it as coded ([`decode_tx`] gives the frame, with at most 8 bytes).
pub fn raw_dlc(mode: CanMode, buf: &[u8; 13]) -> u8 {
    match mode {
        CanMode::Basic => buf[1] & 0x0F,
        CanMode::Peli => buf[0] & 0x0F,
    }
}

/// Reads the frame a program wrote into the TX buffer. The RTR copies in the ID bytes are
/// ignored (the frame-info/descriptor bit decides); DLC 9..15 means 8 data bytes (buslab's
/// `Frame` carries DLC 0..8; the chip puts the coded DLC on the wire, see [`raw_dlc`]).
pub fn decode_tx(mode: CanMode, buf: &[u8; 13]) -> Frame {
    let (id, remote, dlc, data): (Id, bool, u8, &[u8]) = match mode {
        CanMode::Basic => {
            let raw = (buf[0] as u16) << 3 | (buf[1] >> 5) as u16;
            let id = Id::standard(raw).expect("11 bits fit");
            (id, buf[1] & 0x10 != 0, buf[1] & 0x0F, &buf[2..10])
        }
        CanMode::Peli => {
            let remote = buf[0] & 0x40 != 0;
            let dlc = buf[0] & 0x0F;
            if buf[0] & 0x80 != 0 {
                let raw = (buf[1] as u32) << 21
                    | (buf[2] as u32) << 13
                    | (buf[3] as u32) << 5
                    | (buf[4] >> 3) as u32;
                (
                    Id::extended(raw).expect("29 bits fit"),
                    remote,
                    dlc,
                    &buf[5..13],
                )
            } else {
                let raw = (buf[1] as u16) << 3 | (buf[2] >> 5) as u16;
                (
                    Id::standard(raw).expect("11 bits fit"),
                    remote,
                    dlc,
                    &buf[3..11],
                )
            }
        }
    };
    let dlc = dlc.min(8);
    if remote {
        Frame::remote(id, dlc).expect("DLC clamped to 8")
    } else {
        Frame::data(id, &data[..dlc as usize]).expect("at most 8 bytes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn f(s: &str) -> Frame {
        s.parse().unwrap()
    }

    #[test]
    fn peli_layout_matches_the_datasheet() {
        let mut buf = [0u8; 13];
        let n = encode(CanMode::Peli, &f("123#AABB"), &mut buf);
        assert_eq!(&buf[..n], &[0x02, 0x24, 0x60, 0xAA, 0xBB]);
        let n = encode(CanMode::Peli, &f("12345678#R3"), &mut buf);
        assert_eq!(&buf[..n], &[0xC3, 0x91, 0xA2, 0xB3, 0xC4]);
        assert_eq!(stored_len(CanMode::Peli, 0xC3, 0x91), 5);
        assert_eq!(stored_len(CanMode::Peli, 0x02, 0x24), 5);
        assert_eq!(
            stored_len(CanMode::Peli, 0x0F, 0x24),
            11,
            "DLC 15 stores 8 bytes"
        );
    }

    #[test]
    fn basic_layout_matches_the_datasheet() {
        let mut buf = [0u8; 13];
        let n = encode(CanMode::Basic, &f("7FF#R2"), &mut buf);
        assert_eq!(&buf[..n], &[0xFF, 0xF2]);
        assert_eq!(stored_len(CanMode::Basic, 0xFF, 0xF2), 2);
        let n = encode(CanMode::Basic, &f("001#01"), &mut buf);
        assert_eq!(&buf[..n], &[0x00, 0x21, 0x01]);
        assert_eq!(stored_len(CanMode::Basic, 0x00, 0x21), 3);
    }

    #[test]
    fn tx_buffer_round_trips_every_shape() {
        for s in [
            "000#",
            "7FF#0102030405060708",
            "123#R",
            "123#R8",
            "1FFFFFFF#11",
            "00000000#R1",
        ] {
            for mode in [CanMode::Peli, CanMode::Basic] {
                let frame = f(s);
                if mode == CanMode::Basic && frame.is_extended() {
                    continue; // BasicCAN has no extended IDs
                }
                let mut buf = [0u8; 13];
                encode(mode, &f(s), &mut buf);
                assert_eq!(decode_tx(mode, &buf), f(s), "{mode:?} {s}");
            }
        }
    }

    #[test]
    fn dlc_above_8_sends_8_bytes() {
        let mut buf = [0u8; 13];
        buf[0] = 0x0C; // SFF data, DLC 12
        buf[3..11].copy_from_slice(&[1, 2, 3, 4, 5, 6, 7, 8]);
        assert_eq!(decode_tx(CanMode::Peli, &buf).dlc(), 8);
    }
}
