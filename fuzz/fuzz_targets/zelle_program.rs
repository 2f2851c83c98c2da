//! ZELLE program files (`program::image_from_file`, what `zelle load/upload` read: Intel HEX or
//! raw): no panic, and an image never exceeds the program area.
#![no_main]

use buslab_zelle::program::image_from_file;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(image) = image_from_file(data) {
        assert!(image.len() <= 0x400, "image of {} bytes", image.len());
    }
});
