//! Analog source specs (`--analog CH=SPEC`, `--input CH=SPEC`, the control line `analog CH
//! SPEC`) and CSV replay files: no panic parsing them, and a source gives a voltage and both
//! devices' codes at any time.
#![no_main]

use buslab_analog::{Nanos, Source, SourceSpec, parse_channel_source};
use buslab_fuzz::text;
use libfuzzer_sys::fuzz_target;

fn sample(source: &Source) {
    for t in [0, 1, 999_999_999, 1 << 40, u64::MAX / 2, u64::MAX] {
        let at = Nanos::new(t);
        let _ = buslab_zelle::analog::reading(source, at);
        let _ = buslab_cpu196::source::reading10(source, at);
        let _ = source.to_string();
    }
}

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    if let Ok(SourceSpec::Ready(source)) = SourceSpec::parse(text) {
        sample(&source);
    }
    let _ = parse_channel_source(text, 0..=7);
    let _ = buslab_zelle::analog::parse_channel_source(text);
    if let Ok(source) = Source::replay_from_csv(text) {
        sample(&source);
    }
});
