//! Frames in can-utils syntax (`Frame::from_str`, what `buslab send` and log readers take): no
//! panic, and an accepted frame prints as text that parses to the same frame.
#![no_main]

use buslab_can::Frame;
use buslab_fuzz::{assert_reparses, text};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    if let Ok(frame) = text.parse::<Frame>() {
        assert_reparses(&frame, &frame.to_string(), str::parse::<Frame>);
    }
});
