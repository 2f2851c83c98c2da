//! The ZELLE state file (`BatteryRam::from_state_file`, what `zelle serve --state` loads): no
//! panic, and an accepted file saves as text that loads to the same memory.
#![no_main]

use buslab_fuzz::text;
use buslab_zelle::BatteryRam;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    if let Ok(ram) = BatteryRam::from_state_file(text) {
        let again = BatteryRam::from_state_file(&ram.to_state_file()).expect("saved state loads");
        assert_eq!(again.as_bytes(), ram.as_bytes());
    }
});
