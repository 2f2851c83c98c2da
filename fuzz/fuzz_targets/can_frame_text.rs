//! Frames in can-utils syntax (`Frame::from_str`, what `buslab send` and log readers take): no
//! panic, and an accepted frame prints as text that parses to the same frame. The same text as
//! a protocol identifier (`StandardId::parse_protocol_id`, `--mail-id`, `--id`): no panic, and
//! an accepted one is in CAN 2.0A's range and reads back from its hex and decimal forms.
#![no_main]

use buslab_can::{Frame, SFF_MAX_CAN20A, StandardId};
use buslab_fuzz::{assert_reparses, text};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    if let Ok(frame) = text.parse::<Frame>() {
        assert_reparses(&frame, &frame.to_string(), str::parse::<Frame>);
    }
    if let Ok(id) = StandardId::parse_protocol_id(text) {
        assert!(id.as_raw() <= SFF_MAX_CAN20A);
        for form in [format!("0x{:X}", id.as_raw()), id.as_raw().to_string()] {
            assert_eq!(StandardId::parse_protocol_id(&form), Ok(id), "{form}");
        }
    }
});
