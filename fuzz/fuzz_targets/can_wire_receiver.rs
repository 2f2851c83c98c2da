//! The bit-by-bit receiver (`wire::Receiver::push`, inside every bus observer and controller)
//! over an arbitrary bit stream, restarted after each frame or error: no panic, and what it
//! reports agrees with its own accessors.
#![no_main]

use buslab_can::wire::{Receiver, Step};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut rx = Receiver::new();
    for &byte in data {
        let bit = byte & 1 == 1;
        // The receiver starts at SOF: idle (recessive) bits between frames are not given to it.
        if rx.position() == 0 && bit {
            continue;
        }
        let _ = rx.field();
        let before = rx.position();
        match rx.push(bit) {
            Step::Pending => assert_eq!(rx.position(), before + 1),
            Step::Frame(decoded) => {
                assert!(rx.is_finished());
                assert_eq!(rx.decoded(), Some(decoded));
                assert_eq!(decoded.wire_len, rx.position());
                rx.reset();
            }
            Step::Error(error) => {
                assert!(rx.is_finished());
                assert!(
                    error.bit <= before,
                    "error at {} after {before} bits",
                    error.bit
                );
                rx.reset();
            }
        }
        if let Some(early) = rx.decoded_before_ack() {
            assert!(rx.crc_ok());
            let _ = early.frame.to_string();
        }
    }
});
