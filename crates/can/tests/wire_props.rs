//! Property tests of the wire codec.

use buslab_can::wire::{DecodeError, Receiver, Step, decode, encode};
use buslab_can::{Frame, Id};
use proptest::prelude::*;

fn any_frame() -> impl Strategy<Value = Frame> {
    let id = prop_oneof![
        (0u16..=0x7FF).prop_map(|v| Id::standard(v).unwrap()),
        (0u32..=0x1FFF_FFFF).prop_map(|v| Id::extended(v).unwrap()),
    ];
    let body = prop_oneof![
        prop::collection::vec(any::<u8>(), 0..=8).prop_map(Ok),
        (0u8..=8).prop_map(Err),
    ];
    // Bias towards long runs of equal bits, where stuffing matters.
    let byte_runs = prop::collection::vec(prop_oneof![Just(0u8), Just(0xFF), any::<u8>()], 0..=8);
    (id, prop_oneof![body, byte_runs.prop_map(Ok)]).prop_map(|(id, body)| match body {
        Ok(data) => Frame::data(id, &data).unwrap(),
        Err(dlc) => Frame::remote(id, dlc).unwrap(),
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn decode_inverts_encode(f in any_frame()) {
        let enc = encode(&f);
        let decoded = decode(enc.on_bus().iter()).unwrap();
        prop_assert_eq!(decoded.frame, f);
        prop_assert_eq!(decoded.crc, enc.crc());
        prop_assert!(decoded.acked);
        // The transmitter's view decodes too, as not acknowledged.
        let sent = decode(enc.stuffed().iter()).unwrap();
        prop_assert_eq!(sent.frame, f);
        prop_assert!(!sent.acked);
    }

    #[test]
    fn never_six_equal_bits_in_the_stuffed_region(f in any_frame()) {
        let enc = encode(&f);
        let crc_delimiter = enc.ack_slot() - 1;
        let bits: Vec<bool> = enc.stuffed().iter().take(crc_delimiter).collect();
        for window in bits.windows(6) {
            prop_assert!(window.iter().any(|&b| b != window[0]), "{}", enc.stuffed());
        }
        // Stuff bits are the complement of the 5 bits before them.
        for i in 0..crc_delimiter {
            if enc.is_stuff_bit(i) {
                prop_assert!(bits[i - 5..i].iter().all(|&b| b != bits[i]));
            }
        }
    }

    #[test]
    fn every_single_bit_flip_is_detected(f in any_frame()) {
        let enc = encode(&f);
        let on_bus = enc.on_bus();
        for i in 0..on_bus.len() {
            if i == enc.ack_slot() {
                continue; // any receiver may or may not acknowledge
            }
            let mut bits = on_bus;
            bits.set(i, !bits.bit(i));
            let result = decode(bits.iter());
            prop_assert!(result.is_err(), "flip at {} of {} decoded as {:?}", i, f, result);
        }
    }

    #[test]
    fn garbage_never_panics(bits in prop::collection::vec(any::<bool>(), 0..400)) {
        let _ = decode(bits.iter().copied());
        let mut rx = Receiver::new();
        for &b in &bits {
            if let Step::Error(e) = rx.push(b) {
                prop_assert!((e.bit as usize) < bits.len());
            }
        }
    }

    #[test]
    fn frame_prefix_then_garbage_never_panics(
        f in any_frame(),
        cut in 0usize..160,
        tail in prop::collection::vec(any::<bool>(), 0..200),
    ) {
        let enc = encode(&f);
        let cut = cut.min(enc.stuffed().len());
        let bits: Vec<bool> = enc.on_bus().iter().take(cut).chain(tail).collect();
        match decode(bits.iter().copied()) {
            Ok(d) => prop_assert!(d.wire_len as usize <= bits.len()),
            Err(DecodeError::Truncated { bits: n, .. }) => prop_assert_eq!(n as usize, bits.len()),
            Err(_) => {}
        }
    }
}
