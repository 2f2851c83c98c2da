//! Known vectors (facts sheet §1.5) and hand-made corner cases.

use alloc::string::ToString;
use alloc::vec::Vec;

use super::*;
use crate::{Frame, Id};

fn frame(s: &str) -> Frame {
    s.parse().unwrap()
}

/// (frame, CRC, stuff bits, wire bits SOF..EOF + 3 intermission bits), decoded by sigrok.
const VECTORS: [(&str, u16, usize, usize); 7] = [
    ("123#1122", 0x04B7, 2, 65),
    ("009#", 0x7C20, 5, 52),
    ("123#R", 0x1B9D, 1, 48),
    ("12345678#0102030405060708", 0x221A, 9, 140),
    ("01ABCDEF#R", 0x557F, 5, 72),
    ("000#0000000000000000", 0x145B, 16, 127),
    ("7EF#FFFFFFFFFFFFFFFF", 0x38A0, 14, 125),
];

#[test]
fn facts_sheet_vectors() {
    for (text, crc, stuff, wire_with_ifs) in VECTORS {
        let f = frame(text);
        let enc = encode(&f);
        assert_eq!(enc.crc(), crc, "{text} CRC");
        assert_eq!(enc.stuff_bits(), stuff, "{text} stuff bits");
        assert_eq!(enc.stuffed().len() + 3, wire_with_ifs, "{text} length");
        let n = f.payload().len();
        let unstuffed = if f.is_extended() { 64 } else { 44 } + 8 * n;
        assert_eq!(enc.unstuffed().len(), unstuffed, "{text} unstuffed length");
        let decoded = decode(enc.on_bus().iter()).unwrap();
        assert_eq!(decoded.frame, f);
        assert_eq!(decoded.crc, crc);
        assert_eq!(decoded.stuff_bits as usize, stuff);
        assert_eq!(decoded.wire_len as usize, enc.stuffed().len());
        assert!(decoded.acked);
    }
}

#[test]
fn sff_123_matches_the_facts_sheet_bit_for_bit() {
    let enc = encode(&frame("123#1122"));
    let raw = "00010010001100000100001000100100010000010010110111";
    let wire = "00010010001100000110000100010010001000001100101101111011111111111";
    assert_eq!(enc.unstuffed().to_string()[..50], *raw);
    // The facts sheet shows the bus with a receiver (ACK dominant) and the 3 IFS bits.
    assert_eq!(enc.on_bus().to_string() + "111", wire);
    assert!(enc.is_stuff_bit(17) && enc.is_stuff_bit(40));
    assert_eq!((0..62).filter(|&i| enc.is_stuff_bit(i)).count(), 2);
    // The transmitter sends the ACK slot recessive.
    let sent = enc.stuffed().to_string();
    assert_eq!(&sent[53..54], "1");
    assert_eq!(&wire[53..54], "0");
    assert_eq!(enc.ack_slot(), 53);
}

#[test]
fn stuff_bit_before_the_crc_delimiter() {
    let enc = encode(&frame("009#"));
    assert_eq!(enc.crc() & 0x1F, 0, "CRC ends with 00000");
    let crc = enc
        .wire_fields()
        .iter()
        .find(|s| s.field == Field::Crc)
        .copied()
        .unwrap();
    let stuff_in_crc = (crc.start as usize..crc.end())
        .filter(|&i| enc.is_stuff_bit(i))
        .count();
    assert_eq!(crc.len as usize, 15 + stuff_in_crc);
    let last = crc.end() - 1;
    assert!(enc.is_stuff_bit(last));
    assert!(enc.stuffed().bit(last), "stuff bit after 00000 is 1");
    assert!(enc.stuffed().bit(last + 1), "then the CRC delimiter");
    // A receiver that sees a 0 there instead has a stuff error at that bit.
    let mut bits = enc.on_bus();
    bits.set(last, false);
    let err = decode(bits.iter()).unwrap_err();
    assert_eq!(
        err,
        DecodeError::Wire(WireError {
            kind: WireErrorKind::Stuff,
            bit: last as u32,
            field: Field::Crc
        })
    );
}

#[test]
fn fields_cover_the_frame_in_order() {
    for (text, ..) in VECTORS {
        let enc = encode(&frame(text));
        for (spans, len) in [
            (enc.fields(), enc.unstuffed().len()),
            (enc.wire_fields(), enc.stuffed().len()),
        ] {
            let mut at = 0;
            for span in spans {
                assert_eq!(span.start as usize, at, "{text} {:?}", span.field);
                at = span.end();
            }
            assert_eq!(at, len);
        }
        let names: Vec<_> = enc.fields().iter().map(|s| s.field).collect();
        assert_eq!(names[0], Field::Sof);
        assert_eq!(*names.last().unwrap(), Field::Eof);
        assert_eq!(names.contains(&Field::Srr), frame(text).is_extended());
    }
}

#[test]
fn raw_dlc_above_8_means_8_bytes() {
    let f = frame("123#0102030405060708");
    let enc = encode_with_dlc(&f, 15).unwrap();
    let decoded = decode(enc.on_bus().iter()).unwrap();
    assert_eq!(decoded.frame, f);
    assert_eq!(decoded.dlc, 15);
    assert_ne!(
        enc.crc(),
        encode(&f).crc(),
        "the raw DLC is covered by the CRC"
    );
    assert!(encode_with_dlc(&f, 7).is_none());
    assert!(encode_with_dlc(&f, 16).is_none());
    // A remote frame with DLC 12 decodes as a remote frame requesting 8 bytes.
    let r = frame("123#R8");
    let decoded = decode(encode_with_dlc(&r, 12).unwrap().on_bus().iter()).unwrap();
    assert_eq!((decoded.frame, decoded.dlc), (r, 12));
}

#[test]
fn reserved_bits_and_srr_are_accepted_either_way() {
    // EFF: SRR at unstuffed 12, r1 at 33, r0 at 34. Rebuild the wire bits with them flipped.
    let f = frame("12345678#AA");
    let enc = encode(&f);
    for flip in [12usize, 33, 34] {
        let mut raw: Vec<bool> = enc.unstuffed().iter().collect();
        raw[flip] = !raw[flip];
        let crc_start = enc
            .fields()
            .iter()
            .find(|s| s.field == Field::Crc)
            .unwrap()
            .start as usize;
        let mut crc = Crc15::new();
        raw[..crc_start].iter().for_each(|&b| crc.push(b));
        for (k, slot) in raw[crc_start..crc_start + 15].iter_mut().enumerate() {
            *slot = crc.value() >> (14 - k) & 1 == 1;
        }
        let wire = stuff(&raw[..crc_start + 15], &raw[crc_start + 15..]);
        assert_eq!(decode(wire).unwrap().frame, f, "flip at {flip}");
    }
}

/// Independent stuffing helper for tests: stuff `region`, then append `tail` as is.
fn stuff(region: &[bool], tail: &[bool]) -> Vec<bool> {
    let mut out = Vec::new();
    let (mut last, mut run) = (true, 0);
    for &b in region {
        out.push(b);
        run = if b == last { run + 1 } else { 1 };
        last = b;
        if run == 5 {
            out.push(!b);
            (last, run) = (!b, 1);
        }
    }
    out.extend_from_slice(tail);
    out
}

#[test]
fn errors_name_position_and_field() {
    let enc = encode(&frame("123#1122"));
    let on_bus = enc.on_bus();
    let flipped = |i: usize| {
        let mut b = on_bus;
        b.set(i, !b.bit(i));
        decode(b.iter()).unwrap_err()
    };
    // SOF recessive.
    assert!(matches!(
        flipped(0),
        DecodeError::Wire(WireError {
            kind: WireErrorKind::Form,
            bit: 0,
            field: Field::Sof
        })
    ));
    // Stuff bit at wire 17 flipped: 6 zeros.
    assert!(matches!(
        flipped(17),
        DecodeError::Wire(WireError {
            kind: WireErrorKind::Stuff,
            bit: 17,
            field: Field::Dlc
        })
    ));
    // A data bit flipped: CRC error, signalled at the ACK delimiter (wire 54).
    assert_eq!(
        flipped(22),
        DecodeError::Wire(WireError {
            kind: WireErrorKind::Crc {
                received: 0x04B7,
                computed: {
                    let mut c = Crc15::new();
                    let mut raw: Vec<bool> = enc.unstuffed().iter().collect();
                    raw[21] = !raw[21]; // wire 22 comes after one stuff bit
                    raw[..35].iter().for_each(|&b| c.push(b));
                    c.value()
                }
            },
            bit: 54,
            field: Field::AckDelimiter,
        })
    );
    // Delimiters and EOF.
    for (i, field) in [
        (52, Field::CrcDelimiter),
        (54, Field::AckDelimiter),
        (55, Field::Eof),
        (61, Field::Eof),
    ] {
        assert_eq!(
            flipped(i),
            DecodeError::Wire(WireError {
                kind: WireErrorKind::Form,
                bit: i as u32,
                field
            })
        );
    }
    // The ACK slot is reported, not checked.
    let mut unacked = on_bus;
    unacked.set(53, true);
    assert!(!decode(unacked.iter()).unwrap().acked);
    let text = flipped(17).to_string();
    assert_eq!(
        text,
        "stuff error at wire bit 17 (DLC): 6 consecutive equal bits"
    );
}

#[test]
fn truncated_and_trailing_input() {
    let enc = encode(&frame("123#1122"));
    let bits: Vec<bool> = enc.on_bus().iter().collect();
    assert_eq!(decode([]), Err(DecodeError::Empty));
    assert_eq!(
        decode(bits[..20].iter().copied()),
        Err(DecodeError::Truncated {
            bits: 20,
            field: Field::Data
        })
    );
    let mut longer = bits.clone();
    longer.extend([true, true, true]);
    assert!(decode(longer.iter().copied()).is_ok());
    longer.push(false);
    assert_eq!(
        decode(longer.iter().copied()),
        Err(DecodeError::TrailingDominant { bit: 65 })
    );
}

#[test]
fn a_flipped_stuff_bit_is_a_stuff_error_in_the_field_that_caused_it() {
    let mut checked = 0;
    for (text, ..) in VECTORS {
        let enc = encode(&frame(text));
        let wire = enc.on_bus();
        for i in (0..wire.len()).filter(|&i| enc.is_stuff_bit(i)) {
            let mut bits = wire;
            bits.set(i, !bits.bit(i));
            let field = enc
                .wire_fields()
                .iter()
                .find(|s| (s.start as usize..s.end()).contains(&i))
                .unwrap()
                .field;
            // Bit 12 reads as RTR until IDE tells SRR apart.
            let field = if field == Field::Srr {
                Field::Rtr
            } else {
                field
            };
            assert_eq!(
                decode(bits.iter()),
                Err(DecodeError::Wire(WireError {
                    kind: WireErrorKind::Stuff,
                    bit: i as u32,
                    field
                })),
                "{text} stuff bit {i}"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 2 + 5 + 1 + 9 + 5 + 16 + 14);
}

/// Every frame fits [`LONGEST_FRAME_BITS`] with its intermission, and the bound is the
/// encoder's own arithmetic: an extended 8-byte frame is 128 bits unstuffed (118 of them
/// stuffable), plus at most one stuff bit per four stuffable bits after the first.
#[test]
fn no_frame_is_longer_on_the_wire_than_the_longest_frame_bits() {
    let longest = Frame::data(Id::extended(0x1234_5678).unwrap(), &[0x55; 8]).unwrap();
    let unstuffed = encode(&longest).unstuffed().len() as u64;
    assert_eq!(unstuffed, 128);
    assert_eq!(LONGEST_FRAME_BITS, unstuffed + (118 - 1) / 4 + 3);
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    for i in 0..20_000u32 {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let id = (seed as u32) & crate::EFF_MAX;
        let data = if i % 3 == 0 {
            [0; 8]
        } else {
            seed.to_le_bytes()
        };
        let frame = Frame::data(Id::extended(id).unwrap(), &data[..(i % 9) as usize]).unwrap();
        let bits = encode(&frame).stuffed().len() as u64 + 3;
        assert!(bits <= LONGEST_FRAME_BITS, "{frame}: {bits} bit-times");
    }
}

#[test]
fn frame_bits_count_stuffing_and_the_intermission() {
    // A standard data frame with no data: 44 bits, stuffing, 3 of intermission; 8 bytes of
    // 0x55 stuff nothing in the data (alternating bits).
    let empty: Frame = "7FF#".parse().unwrap();
    let bits = frame_bits(&empty);
    assert_eq!(bits, encode(&empty).stuffed().len() as u64 + 3);
    assert!((47..=60).contains(&bits), "{bits}");
    let full: Frame = "555#5555555555555555".parse().unwrap();
    assert!(
        (111..=130).contains(&frame_bits(&full)),
        "{}",
        frame_bits(&full)
    );
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(2000))]

    /// The stuff-bit mask is derived from the stuffed bits (five equal bits before a bit make
    /// it a stuff bit): it must name exactly the bits the encoder inserted, which de-stuffing
    /// removes to give the de-stuffed bits back, on frames full of long runs (bytes biased to
    /// 0x00 and 0xFF) and on random ones.
    #[test]
    fn the_stuff_mask_names_exactly_the_inserted_bits(
        extended in proptest::bool::ANY,
        raw_id in 0u32..=0x1FFF_FFFF,
        data in proptest::collection::vec(
            proptest::prop_oneof![proptest::strategy::Just(0u8), proptest::strategy::Just(0xFF), 0u8..],
            0..=8,
        ),
    ) {
        let id = if extended {
            Id::extended(raw_id).unwrap()
        } else {
            Id::standard(raw_id as u16 & 0x7FF).unwrap()
        };
        let enc = encode(&Frame::data(id, &data).unwrap());
        let mask = enc.stuff_mask();
        let wire = enc.stuffed();
        proptest::prop_assert_eq!(mask.len(), wire.len());
        let destuffed: Bits = (0..wire.len())
            .filter(|&i| !mask.bit(i))
            .map(|i| wire.bit(i))
            .collect();
        proptest::prop_assert_eq!(destuffed, enc.unstuffed(), "{}", enc.frame());
        for i in 0..wire.len() {
            proptest::prop_assert_eq!(mask.bit(i), enc.is_stuff_bit(i), "{} bit {}", enc.frame(), i);
        }
        proptest::prop_assert_eq!(mask.count_ones() as usize, enc.stuff_bits());
    }
}
