//! candump log lines (`candump::parse_line`) and whole logs (`candump::Reader`, what `buslab
//! play` reads): no panic, an accepted line prints as a line that parses to the same entry (to
//! the microsecond, as candump logs it), the reader's fast path (`parse_line_into`) agrees with
//! the full parser, and the reader never hands out more than the input holds.
#![no_main]

use buslab_fuzz::text;
use buslab_logs::Message;
use buslab_logs::candump::{Reader, format_line, parse_line, parse_line_into};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut entries = 0usize;
    for item in Reader::new(data) {
        if item.is_ok() {
            entries += 1;
        }
        assert!(entries <= data.len());
    }
    let Some(text) = text(data) else { return };
    for line in text.lines() {
        // The reader's fast path gives what the full parser gives, on any line.
        let mut fast = Message::default();
        let fast = parse_line_into(line.as_bytes(), &mut fast).map(|()| fast);
        assert_eq!(
            fast.as_ref().ok(),
            parse_line(line).as_ref().ok(),
            "fast and full parsers disagree on {line:?}"
        );
        let Ok(entry) = parse_line(line) else {
            continue;
        };
        // candump's format keeps microseconds (a reader takes up to 9 decimals): the printed
        // line is the canonical one, and it reads back to itself.
        let printed = format_line(&entry, entry.direction.is_some());
        match parse_line(&printed) {
            Ok(again) => {
                assert_eq!(again.at.as_micros(), entry.at.as_micros());
                assert_eq!(
                    (&again.channel, &again.record),
                    (&entry.channel, &entry.record)
                );
                assert_eq!(format_line(&again, again.direction.is_some()), printed);
            }
            Err(e) => panic!("{entry:?} printed as {printed:?} does not parse: {e}"),
        }
    }
});
