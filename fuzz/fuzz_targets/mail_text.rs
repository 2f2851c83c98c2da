//! The mail notifier's handling of what the IMAP server sends (`buslab_mail::mail_text`: the
//! first bytes of an RFC 822 message, any bytes, and its size, to the text MoniCAN shows) and
//! of the frames that carry it (`Announcer`). The first two bytes choose the limit (`buslab
//! mail --limit`, 64..=65536), the next one whether the message is whole or the server says it
//! is larger than what was fetched.
//!
//! Besides no panic: the text is within the limit and starts with its `From:` line; a text
//! that was cut says so; the frames sent when the reader asks carry exactly the text, 8 bytes a
//! frame, on the mail ID.
#![no_main]

use buslab_can::Id;
use buslab_mail::{Announcer, mail_text};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some(([l0, l1, whole], message)) = data.split_first_chunk::<3>() else {
        return;
    };
    let limit = 64 + usize::from(u16::from_le_bytes([*l0, *l1]));
    let size = message.len() as u64
        + if whole % 2 == 0 {
            0
        } else {
            u64::from(*whole) << 24
        };
    let text = mail_text(message, size, limit);
    assert!(
        text.len() <= limit,
        "{} bytes for a limit of {limit}",
        text.len()
    );
    assert!(
        text.starts_with(b"From: "),
        "{:?}",
        String::from_utf8_lossy(&text)
    );

    let id = Id::standard(0x700).expect("a standard ID");
    let mut announcer = Announcer::new(id);
    announcer.push_mail(text.clone());
    let announcement = announcer.poll_transmit().expect("a new mail is announced");
    assert!(announcement.is_remote() && announcement.id() == id);
    announcer.handle_frame(&announcement);
    let mut carried = Vec::new();
    while let Some(frame) = announcer.poll_transmit() {
        assert!(frame.id() == id && !frame.is_remote() && frame.payload().len() <= 8);
        carried.extend_from_slice(frame.payload());
    }
    assert!(carried == text, "the frames do not carry the text");
    assert_eq!((announcer.delivered(), announcer.waiting()), (1, 0));
});
