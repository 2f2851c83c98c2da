//! Analog source specs (`--analog CH=SPEC`, the control line `analog CH SPEC`) and CSV replay
//! files: no panic parsing them, and a source gives a voltage code at any time.
#![no_main]

use buslab_fuzz::text;
use buslab_zelle::analog::{Source, SourceSpec, parse_channel_source};
use libfuzzer_sys::fuzz_target;

fn sample(source: &Source) {
    for t in [0, 1, 999_999_999, 1 << 40, u64::MAX / 2, u64::MAX] {
        let _ = source.code(buslab_device::Nanos::new(t));
        let _ = source.to_string();
    }
}

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    if let Ok(SourceSpec::Ready(source)) = SourceSpec::parse(text) {
        sample(&source);
    }
    let _ = parse_channel_source(text);
    if let Ok(source) = Source::replay_from_csv(text) {
        sample(&source);
    }
});
