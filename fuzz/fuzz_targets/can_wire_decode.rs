//! The wire decoder (`wire::decode`, what `buslab wire decode` runs) over arbitrary bit
//! strings, one input byte per bit (its low bit: the text `0110…` is a bit string): no panic,
//! and a frame it rebuilds encodes to bits that decode to the same frame.
#![no_main]

use buslab_can::wire::{decode, encode_with_dlc};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let bits = data.iter().map(|b| b & 1 == 1);
    let Ok(decoded) = decode(bits) else { return };
    assert!(decoded.wire_len as usize <= data.len());
    let encoded = encode_with_dlc(&decoded.frame, decoded.dlc).expect("decoded DLC encodes");
    let again = decode(encoded.on_bus().iter()).expect("encoded frame decodes");
    assert_eq!(again.frame, decoded.frame);
    assert_eq!(again.dlc, decoded.dlc);
});
