//! The CPU196 image file (`Image::from_toml`, what `cpu196 serve --image` loads): no panic, and
//! an accepted image saves as text that loads to the same image.
#![no_main]

use buslab_cpu196::Image;
use buslab_fuzz::text;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    if let Ok(image) = Image::from_toml(text) {
        let saved = image.to_toml();
        match Image::from_toml(&saved) {
            Ok(again) => assert!(again == image, "the saved image loads differently"),
            Err(e) => panic!("a saved image does not load: {e}"),
        }
    }
});
