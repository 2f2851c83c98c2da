//! One look at a mailbox (`buslab_mail::imap::Poll`) fed whatever a server sends: the bytes,
//! cut where the first byte says, after a look that was watching (so SEARCH and FETCH are
//! reached), in clear text or with STARTTLS (the second byte).
//!
//! Besides no panic: a look ends in an outcome or an error, never both; the texts of the mails
//! found are within the limit; what is sent back is IMAP commands (tagged lines) or the
//! password literal, nothing else; after STARTTLS's OK nothing is sent before the handshake.
#![no_main]

use std::time::{Duration, Instant};

use buslab_mail::imap::{Event, Limits, Poll, PollConfig, Security, Watermark};
use libfuzzer_sys::fuzz_target;

const TEXT_LIMIT: usize = 200;

fuzz_target!(|data: &[u8]| {
    let Some(([chunk, mode], stream)) = data.split_first_chunk::<2>() else {
        return;
    };
    let chunk = usize::from((*chunk).max(1));
    let security = if mode % 2 == 0 {
        Security::Plain
    } else {
        Security::StartTls
    };
    let config = PollConfig {
        user: "alice".into(),
        password: "pässword".into(),
        mailbox: "INBOX".into(),
        security,
        known: Some(Watermark {
            uid_validity: Some(1),
            last_uid: 3,
        }),
        fetch_at_most: 4,
        text_limit: TEXT_LIMIT,
        timeout: Duration::from_secs(30),
        limits: Limits {
            line: 512,
            literal: 1024,
            message: 4096,
            depth: 8,
        },
        response_limit: 8192,
    };
    let now = Instant::now();
    let mut poll = Poll::new(config, now);
    let mut handshaking = false;
    for part in stream.chunks(chunk) {
        if poll.handle_input(part, now).is_err() {
            return;
        }
        while let Some(event) = poll.poll_event() {
            match event {
                Event::StartTls => handshaking = true,
                Event::Done(outcome) => {
                    assert!(outcome.mails.len() <= 4);
                    for text in &outcome.mails {
                        assert!(text.len() <= TEXT_LIMIT && text.starts_with(b"From: "));
                    }
                }
            }
        }
        while let Some(bytes) = poll.poll_transmit() {
            assert!(!handshaking, "sent in clear text after STARTTLS's OK");
            assert!(
                bytes.starts_with(b"b") || bytes.starts_with("pässword".as_bytes()),
                "{:?}",
                String::from_utf8_lossy(&bytes)
            );
        }
        if handshaking {
            handshaking = false;
            if poll.tls_started(now).is_err() {
                return;
            }
        }
    }
    let _ = poll.handle_eof();
    let _ = poll.handle_timeout(now + Duration::from_secs(30));
});
