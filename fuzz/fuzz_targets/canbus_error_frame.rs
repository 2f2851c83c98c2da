//! SocketCAN error frames (`ErrorFrame::decode` of a class and data bytes, what the socketcand
//! client and log readers get from outside): no panic, and a decoded error frame encodes to a
//! class and data that, cut to the frame's own length (a frame may have fewer than 8 bytes),
//! decode to the same error frame.
#![no_main]

use buslab_canbus::ErrorFrame;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if data.len() < 4 {
        return;
    }
    let (id, bytes) = data.split_at(4);
    let id = u32::from_le_bytes(id.try_into().unwrap());
    if let Ok(frame) = ErrorFrame::decode(id, bytes) {
        let (class, d) = frame.encode();
        let len = frame.data_len();
        assert_eq!(ErrorFrame::decode(class, &d[..len]), Ok(frame.clone()));
        let _ = frame.describe(", ");
        let _ = frame.to_string();
    }
});
