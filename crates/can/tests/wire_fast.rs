//! Differential tests of the table-driven encoder, the whole-frame decoder and the encode
//! cache: against the original bit-by-bit encoder (`reference/`) and the bit-by-bit
//! `Receiver` (`wire::decode`).

mod reference;

use buslab_can::controller::WireFrame;
use buslab_can::wire::{
    Bits, EncodeCache, Encoded, Receiver, Step, decode, decode_bits, encode, encode_with_dlc,
};
use buslab_can::{Frame, Id};
use proptest::prelude::*;

/// Identifiers of every pattern: random, all zeros, all ones, alternating (no stuffing), and
/// runs that straddle field boundaries.
fn any_id() -> impl Strategy<Value = Id> {
    let standard = prop_oneof![
        0u16..=0x7FF,
        Just(0),
        Just(0x7FF),
        Just(0x555),
        Just(0x2AA),
        Just(0x00F),
        Just(0x7C0),
    ]
    .prop_map(|v| Id::standard(v).unwrap());
    let extended = prop_oneof![
        0u32..=0x1FFF_FFFF,
        Just(0),
        Just(0x1FFF_FFFF),
        Just(0x1555_5555),
        Just(0x0AAA_AAAA),
        Just(0x0003_FFFF),
        Just(0x1FFC_0000),
    ]
    .prop_map(|v| Id::extended(v).unwrap());
    prop_oneof![standard, extended]
}

/// A frame and the raw DLC it is sent with (9..15 only where it means 8 bytes).
fn any_frame_and_dlc() -> impl Strategy<Value = (Frame, u8)> {
    // Bias towards all-zero and all-one bytes, which force stuff bits.
    let byte = prop_oneof![Just(0u8), Just(0xFF), any::<u8>()];
    let data = (any_id(), prop::collection::vec(byte, 0..=8), 8u8..=15).prop_map(
        |(id, data, long_dlc)| {
            let frame = Frame::data(id, &data).unwrap();
            let dlc = if data.len() == 8 {
                long_dlc
            } else {
                frame.dlc()
            };
            (frame, dlc)
        },
    );
    let remote =
        (any_id(), 0u8..=15).prop_map(|(id, dlc)| (Frame::remote(id, dlc.min(8)).unwrap(), dlc));
    prop_oneof![3 => data, 1 => remote]
}

fn encoded(frame: &Frame, dlc: u8) -> Encoded {
    encode_with_dlc(frame, dlc).unwrap()
}

fn assert_matches_reference(frame: &Frame, dlc: u8) {
    let new = encoded(frame, dlc);
    let old = reference::encode_with_dlc(frame, dlc);
    let context = format!("{frame} DLC {dlc}");
    assert_eq!(new.crc(), old.crc, "{context}");
    assert_eq!(new.unstuffed(), old.unstuffed, "{context}");
    assert_eq!(*new.stuffed(), old.stuffed, "{context}");
    let stuff: Vec<usize> = (0..Bits::CAPACITY)
        .filter(|&i| new.is_stuff_bit(i))
        .collect();
    assert_eq!(stuff, old.stuff_bits, "{context}");
    assert_eq!(new.stuff_bits(), old.stuff_bits.len(), "{context}");
    assert_eq!(new.fields().as_slice(), old.fields.as_slice(), "{context}");
    assert_eq!(
        new.wire_fields().as_slice(),
        old.wire_fields.as_slice(),
        "{context}"
    );
    let ack = old
        .wire_fields
        .iter()
        .find(|s| s.field == buslab_can::wire::Field::AckSlot);
    assert_eq!(new.ack_slot(), ack.unwrap().start as usize, "{context}");
    assert_eq!(new.dlc(), dlc);
    assert_eq!(new.frame(), frame);
}

/// `decode_bits` and the bit-by-bit receiver give the same answer.
fn assert_decoders_agree(bits: &Bits) {
    assert_eq!(decode_bits(bits), decode(bits.iter()), "{bits}");
}

#[test]
fn every_standard_id_with_stuffing_data_matches_the_reference() {
    for id in 0..=0x7FF {
        let id = Id::standard(id).unwrap();
        for frame in [
            Frame::data(id, &[0; 8]).unwrap(),
            Frame::data(id, &[0xFF; 8]).unwrap(),
            Frame::data(id, &[]).unwrap(),
            Frame::remote(id, 0).unwrap(),
        ] {
            assert_matches_reference(&frame, frame.dlc());
            assert_decoders_agree(&encode(&frame).on_bus());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn encoder_equals_the_bit_by_bit_reference((frame, dlc) in any_frame_and_dlc()) {
        assert_matches_reference(&frame, dlc);
    }

    #[test]
    fn whole_frame_receiver_is_the_bit_by_bit_one((frame, dlc) in any_frame_and_dlc()) {
        let enc = encoded(&frame, dlc);
        let bus = enc.on_bus();
        let mut stepped = Receiver::new();
        for i in 0..=enc.ack_slot() + 1 {
            prop_assert_eq!(stepped.push(bus.bit(i)), Step::Pending);
        }
        let whole = WireFrame::new(&enc).unwrap();
        prop_assert_eq!(whole.receiver(), &stepped);
        prop_assert_eq!(whole.frame(), &frame);
    }

    #[test]
    fn whole_frame_decoder_equals_the_receiver((frame, dlc) in any_frame_and_dlc()) {
        let enc = encoded(&frame, dlc);
        for bits in [enc.on_bus(), *enc.stuffed()] {
            let decoded = decode_bits(&bits);
            prop_assert_eq!(decoded, decode(bits.iter()));
            prop_assert_eq!(decoded, Ok(enc.decoded(bits == enc.on_bus())));
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Every single bit flipped, and every prefix: same error, same bit, same field.
    #[test]
    fn decoders_agree_on_every_flip_and_cut((frame, dlc) in any_frame_and_dlc()) {
        let on_bus = encoded(&frame, dlc).on_bus();
        for i in 0..on_bus.len() {
            let mut flipped = on_bus;
            flipped.set(i, !flipped.bit(i));
            assert_decoders_agree(&flipped);
            let cut: Bits = on_bus.iter().take(i).collect();
            assert_decoders_agree(&cut);
        }
    }

    /// Idle after the frame, then possibly a dominant bit.
    #[test]
    fn decoders_agree_on_trailing_bits(
        (frame, dlc) in any_frame_and_dlc(),
        tail in prop::collection::vec(any::<bool>(), 0..30),
    ) {
        let bits: Bits = encoded(&frame, dlc).on_bus().iter().chain(tail).collect();
        assert_decoders_agree(&bits);
    }

    /// A frame's start followed by garbage (reaches every field and error kind).
    #[test]
    fn decoders_agree_on_a_frame_prefix_then_garbage(
        (frame, dlc) in any_frame_and_dlc(),
        cut in 0usize..160,
        tail in prop::collection::vec(any::<bool>(), 0..=Bits::CAPACITY),
    ) {
        let on_bus = encoded(&frame, dlc).on_bus();
        let bits: Bits = on_bus
            .iter()
            .take(cut)
            .chain(tail)
            .take(Bits::CAPACITY)
            .collect();
        assert_decoders_agree(&bits);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    /// Garbage never panics and decodes as the receiver decodes it.
    #[test]
    fn garbage_decodes_as_the_receiver_does(
        bits in prop::collection::vec(any::<bool>(), 0..=Bits::CAPACITY),
        dominant_runs in any::<bool>(),
    ) {
        // Half the cases: mostly dominant, so they get past SOF and deep into a frame.
        let bits: Bits = bits
            .into_iter()
            .enumerate()
            .map(|(i, b)| if dominant_runs && i % 3 != 0 { false } else { b })
            .collect();
        assert_decoders_agree(&bits);
    }
}

#[test]
fn the_cache_gives_the_encoders_results_and_counts() {
    let a: Frame = "123#1122".parse().unwrap();
    let b: Frame = "1ABCDEF0#0102030405060708".parse().unwrap();
    let mut cache = EncodeCache::new();
    assert_eq!(*cache.encode(&a), encode(&a));
    assert_eq!(*cache.encode(&a), encode(&a));
    assert_eq!((cache.hits(), cache.misses()), (1, 1));
    // A different raw DLC of the same frame is a different encoding.
    assert_eq!(
        cache.encode_with_dlc(&b, 8),
        encode_with_dlc(&b, 8).as_ref()
    );
    assert_eq!(
        cache.encode_with_dlc(&b, 15),
        encode_with_dlc(&b, 15).as_ref()
    );
    assert_eq!(
        cache.encode_with_dlc(&b, 15),
        encode_with_dlc(&b, 15).as_ref()
    );
    assert_eq!((cache.hits(), cache.misses()), (2, 3));
    // A DLC that does not fit leaves the kept encoding alone.
    assert_eq!(cache.encode_with_dlc(&a, 9), None);
    assert_eq!(cache.last(), encode_with_dlc(&b, 15).as_ref());
    assert_eq!(*cache.encode(&b), encode(&b));
    cache.clear();
    assert_eq!(cache.last(), None);
    assert_eq!(*cache.encode(&b), encode(&b));
    assert_eq!((cache.hits(), cache.misses()), (2, 5));
}
