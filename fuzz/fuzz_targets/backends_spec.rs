//! Bus names and candump-style interface arguments (`buslab_backends::resolve`, `BusUrl`,
//! `BusSpec`, `FilterItem`: what `--bus`, `dump`, `play`, `bridge` take on the command line).
//! No panic; an accepted URL prints as a URL that parses to the same; an accepted ID filter
//! prints as a filter that parses to the same; a filter set decides on any frame.
#![no_main]

use buslab_backends::{BusSpec, BusUrl, FilterItem, resolve};
use buslab_can::{Frame, Id};
use buslab_fuzz::{assert_reparses, text};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    if let Ok(url) = text.parse::<BusUrl>() {
        assert_reparses(&url, &url.to_string(), str::parse::<BusUrl>);
    }
    if let Ok(url) = resolve(text) {
        assert_reparses(&url, &url.to_string(), str::parse::<BusUrl>);
    }
    if let Ok(FilterItem::Id(filter)) = text.parse::<FilterItem>() {
        let printed = filter.to_string();
        assert_reparses(&FilterItem::Id(filter), &printed, str::parse::<FilterItem>);
    }
    if let Ok(spec) = text.parse::<BusSpec>() {
        let frames = [
            Frame::data(Id::standard(0x123).unwrap(), &[1, 2]).unwrap(),
            Frame::remote(Id::extended(0x1234_5678).unwrap(), 3).unwrap(),
            Frame::data(Id::standard(0).unwrap(), &[]).unwrap(),
        ];
        for frame in &frames {
            let _ = spec.filters.passes(frame);
        }
    }
});
