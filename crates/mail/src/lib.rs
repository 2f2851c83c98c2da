//! The mail notifier's core (seed 002 §5.4.5, JerryCAN's `MailWatcher`), sans-IO: a mail as
//! the IMAP server hands it over becomes the text MoniCAN shows ([`mail_text`]), and the
//! [`Announcer`] turns the waiting texts into CAN frames: a remote frame announces mail, the
//! reader's remote frame on the same ID asks for it, the file protocol carries it. `buslab
//! mail` owns the IMAP connection, the bus and the clock.

use std::collections::VecDeque;

use buslab_can::{Frame, Id};

/// The bus side of the notifier, sans-IO: mails in, frames out.
#[derive(Debug)]
pub struct Announcer {
    id: Id,
    mails: VecDeque<Vec<u8>>,
    /// The first mail was announced and not yet asked for.
    announced: bool,
    outbox: VecDeque<Frame>,
    delivered: usize,
}

impl Announcer {
    pub fn new(id: Id) -> Self {
        Self {
            id,
            mails: VecDeque::new(),
            announced: false,
            outbox: VecDeque::new(),
            delivered: 0,
        }
    }

    fn announcement(&self) -> Frame {
        Frame::remote(self.id, 0).expect("DLC 0")
    }

    /// A new mail: announced at once unless another one waits for its reader.
    pub fn push_mail(&mut self, text: Vec<u8>) {
        self.mails.push_back(text);
        if !self.announced {
            self.announced = true;
            self.outbox.push_back(self.announcement());
        }
    }

    /// Announces the waiting mail again (a MoniCAN started since has no notice).
    pub fn remind(&mut self) {
        if self.announced {
            self.outbox.push_back(self.announcement());
        }
    }

    /// A frame from the bus: MoniCAN's remote frame on the mail ID asks for the mail.
    pub fn handle_frame(&mut self, frame: &Frame) {
        if !(self.announced && frame.is_remote() && frame.id() == self.id && frame.dlc() == 0) {
            return;
        }
        let Some(text) = self.mails.pop_front() else {
            return;
        };
        self.outbox.extend(buslab_can::file::frames(self.id, &text));
        self.delivered += 1;
        self.announced = !self.mails.is_empty();
        if self.announced {
            self.outbox.push_back(self.announcement());
        }
    }

    pub fn poll_transmit(&mut self) -> Option<Frame> {
        self.outbox.pop_front()
    }

    /// Mails sent to a reader so far.
    pub fn delivered(&self) -> usize {
        self.delivered
    }

    /// Mails not yet asked for.
    pub fn waiting(&self) -> usize {
        self.mails.len()
    }
}

/// A header's value (unfolded), if the header block has it.
pub fn header(headers: &str, name: &str) -> Option<String> {
    let mut value: Option<String> = None;
    for line in headers.lines() {
        if let Some(v) = &mut value {
            if line.starts_with([' ', '\t']) {
                v.push(' ');
                v.push_str(line.trim());
                continue;
            }
            break;
        }
        if let Some((key, rest)) = line.split_once(':')
            && key.trim().eq_ignore_ascii_case(name)
        {
            value = Some(rest.trim().to_string());
        }
    }
    value
}

/// A mail as MoniCAN shows it: `From:`, `Subject:`, a blank line and the text, at most
/// `limit` bytes; a longer one is cut and says how many bytes were left out.
pub fn mail_text(message: &[u8], limit: usize) -> Vec<u8> {
    let message = String::from_utf8_lossy(message).replace("\r\n", "\n");
    let (headers, body) = message.split_once("\n\n").unwrap_or((&message, ""));
    let mut text = format!(
        "From: {}\nSubject: {}\n\n{}",
        header(headers, "From").unwrap_or_else(|| "(unknown)".into()),
        header(headers, "Subject").unwrap_or_else(|| "(no subject)".into()),
        body.trim_end()
    )
    .into_bytes();
    if text.len() > limit {
        let note = |n: usize| format!("\n[... {n} more bytes not sent]").into_bytes();
        let keep = limit.saturating_sub(note(text.len()).len());
        let left_out = text.len() - keep;
        text.truncate(keep);
        text.extend(note(left_out));
        text.truncate(limit);
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    fn id() -> Id {
        Id::standard(0x700).unwrap()
    }

    #[test]
    fn a_mail_is_announced_and_sent_when_asked_for() {
        let mut a = Announcer::new(id());
        a.push_mail(b"0123456789".to_vec());
        a.push_mail(b"second".to_vec());
        let announce = a.poll_transmit().unwrap();
        assert!(announce.is_remote() && announce.id() == id() && announce.dlc() == 0);
        assert_eq!(a.poll_transmit(), None, "one announcement for two mails");
        a.handle_frame(&"700#00".parse().unwrap());
        a.handle_frame(&"701#R".parse().unwrap());
        assert_eq!(
            a.poll_transmit(),
            None,
            "only a remote frame on the ID asks"
        );
        a.handle_frame(&"700#R".parse().unwrap());
        let sent: Vec<Frame> = std::iter::from_fn(|| a.poll_transmit()).collect();
        assert_eq!(
            sent.len(),
            3,
            "8 bytes, 2 bytes, then the next announcement"
        );
        assert_eq!(sent[0].payload(), b"01234567");
        assert_eq!(sent[1].payload(), b"89");
        assert!(sent[2].is_remote());
        assert_eq!((a.delivered(), a.waiting()), (1, 1));
    }

    #[test]
    fn mails_become_texts_within_the_limit() {
        let raw = b"Return-Path: <x@y>\r\nFrom: Alice <alice@example.org>\r\nSubject: hello\r\n there\r\n\r\nline 1\r\nline 2\r\n";
        assert_eq!(
            String::from_utf8(mail_text(raw, 2048)).unwrap(),
            "From: Alice <alice@example.org>\nSubject: hello there\n\nline 1\nline 2"
        );
        let long = [b"Subject: s\r\n\r\n".as_slice(), &[b'x'; 5000]].concat();
        let text = String::from_utf8(mail_text(&long, 200)).unwrap();
        assert_eq!(text.len(), 200);
        assert!(text.ends_with("more bytes not sent]"), "{text}");
        assert!(
            String::from_utf8(mail_text(b"garbage", 64))
                .unwrap()
                .contains("(no subject)")
        );
    }

    #[test]
    fn garbage_from_the_server_still_gives_a_text_within_the_limit() {
        let folded_forever = [b"Subject: a".as_slice(), &b"\r\n x".repeat(10_000)].concat();
        for message in [
            &b""[..],
            b"\xff\xfe\x00\x01\r\n\r\n\xc3",
            b"\r\n\r\n\r\n",
            b"From:\r\nSubject:\r\n",
            b": no name\n\n",
            b"From: \xc3\xa4\xc3\xa4\xc3\xa4\n\nbody",
            &folded_forever,
        ] {
            for limit in [64, 65, 100, 2048, 65536] {
                let text = mail_text(message, limit);
                assert!(text.len() <= limit, "{} > {limit}", text.len());
                assert!(text.starts_with(b"From: "));
            }
        }
    }
}
