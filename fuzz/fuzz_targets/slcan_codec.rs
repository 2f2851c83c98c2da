//! SLCAN lines (`buslab_slcan::codec`): bytes from a serial line cut by `LineSplitter` (bounded)
//! and parsed as a host's command (`parse_command`, what `buslab slcan serve` reads) and as an
//! adapter's reply (`parse_reply`, what the `slcan:` backend reads). No panic, and what either
//! parser accepted, formatted again, splits and parses to the same value.
#![no_main]

use buslab_slcan::codec::Line;
use buslab_slcan::{
    Command, LineSplitter, MAX_LINE, Reply, format_command, format_reply, parse_command,
    parse_reply,
};
use libfuzzer_sys::fuzz_target;

/// The one line `bytes` holds (they end with its terminator), as a splitter cuts it.
fn single_line(bytes: &[u8]) -> (Vec<u8>, bool) {
    let mut splitter = LineSplitter::new();
    let mut lines = Vec::new();
    for &b in bytes {
        match splitter.push(b) {
            Some(Line::Text(t)) => lines.push((t.to_vec(), false)),
            Some(Line::Bell(t)) => lines.push((t.to_vec(), true)),
            Some(Line::TooLong) => panic!("{bytes:?} is too long a line"),
            None => {}
        }
    }
    assert_eq!(lines.len(), 1, "{bytes:?} is not one line");
    assert_eq!(splitter.pending(), 0);
    lines.pop().unwrap()
}

fn check_command(command: &Command) {
    let mut out = Vec::new();
    format_command(command, &mut out);
    let (line, bell) = single_line(&out);
    assert!(!bell);
    match parse_command(&line) {
        Ok(again) => assert_eq!(&again, command, "formatted as {out:?}"),
        Err(e) => panic!("{command:?} formatted as {out:?} does not parse: {e}"),
    }
}

fn check_reply(reply: &Reply) {
    let mut out = Vec::new();
    format_reply(reply, &mut out);
    let (line, bell) = single_line(&out);
    match parse_reply(&line, bell) {
        Ok(again) => assert_eq!(&again, reply, "formatted as {out:?}"),
        Err(e) => panic!("{reply:?} formatted as {out:?} does not parse: {e}"),
    }
}

fuzz_target!(|data: &[u8]| {
    let mut splitter = LineSplitter::new();
    for &byte in data {
        let line = splitter.push(byte);
        if let Some(Line::Text(t) | Line::Bell(t)) = line {
            assert!(t.len() <= MAX_LINE);
        }
        match line {
            None | Some(Line::TooLong) => {}
            Some(Line::Text(text)) => {
                if let Ok(command) = parse_command(text) {
                    check_command(&command);
                }
                if let Ok(reply) = parse_reply(text, false) {
                    check_reply(&reply);
                }
            }
            Some(Line::Bell(text)) => {
                let _ = parse_command(text);
                assert_eq!(parse_reply(text, true).ok(), Some(Reply::Error));
            }
        }
        assert!(splitter.pending() <= MAX_LINE);
    }
});
