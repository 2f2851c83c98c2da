//! The framer in front of the IMAP parser (`buslab_mail::imap::Framer`): any bytes a server
//! sends, cut anywhere (the first byte chooses the chunk size).
//!
//! Besides no panic: what comes out is exactly what went in, in order, up to the first
//! refusal; no response is longer than the response cap; a refused stream stays refused.
#![no_main]

use buslab_mail::imap::{Framer, Limits};
use libfuzzer_sys::fuzz_target;

const LIMITS: Limits = Limits {
    line: 256,
    literal: 300,
    message: 1024,
    depth: 6,
};

fuzz_target!(|data: &[u8]| {
    let Some((&chunk, stream)) = data.split_first() else {
        return;
    };
    let chunk = usize::from(chunk.max(1));
    let mut framer = Framer::new(LIMITS);
    let mut out = Vec::new();
    let mut taken = 0;
    let mut refused = None;
    for part in stream.chunks(chunk) {
        match framer.push(part) {
            Ok(()) => taken += part.len(),
            Err(e) => {
                refused = Some(e);
                break;
            }
        }
        while let Some(message) = framer.next_message() {
            assert!(message.len() <= LIMITS.message, "{} bytes", message.len());
            assert!(message.ends_with(b"\n"), "a response ends with its line");
            out.extend(message);
        }
    }
    assert!(
        stream[..taken].starts_with(&out),
        "the responses are not the bytes received"
    );
    if let Some(e) = refused {
        assert_eq!(
            framer.push(b"\r\n"),
            Err(e),
            "a refused stream stays refused"
        );
    }
});
