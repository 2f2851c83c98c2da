//! Analog sources as the serving tools take them: a spec, with its CSV replay file read here
//! (the device models do no I/O).

use std::ops::RangeInclusive;

use buslab_analog::{Source, SourceSpec};
use buslab_link::fs::read_text_limited;

use crate::ServeError;

/// The largest CSV replay file read.
const MAX_REPLAY_FILE: u64 = 64 << 20;

/// The source a spec names, reading a CSV replay file if it names one.
pub fn load_source(spec: SourceSpec) -> Result<Source, ServeError> {
    match spec {
        SourceSpec::Ready(s) => Ok(s),
        SourceSpec::CsvFile(path) => {
            let text = read_text_limited(&path, MAX_REPLAY_FILE)?;
            Ok(Source::replay_from_csv(&text)?)
        }
    }
}

/// `CH=SOURCE` with a channel within `channels`, its CSV replay file read.
pub fn channel_input(arg: &str, channels: RangeInclusive<u8>) -> Result<(u8, Source), ServeError> {
    let (channel, spec) = buslab_analog::parse_channel_source(arg, channels)?;
    Ok((channel, load_source(spec)?))
}
