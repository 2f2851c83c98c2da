//! A mail as MoniCAN shows it: `From:`, `Subject:`, a blank line and the text, within a limit.

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

/// The text of a mail of `size` bytes (RFC822.SIZE) from its first bytes, `message` (all of
/// it, or the part fetched with `BODY.PEEK[]<0.N>`): `From:`, `Subject:`, a blank line and the
/// body with LF line ends, at most `limit` bytes. A longer mail is cut and ends with
/// `[... N more bytes not sent]`, N counting the body's bytes as the server stores them.
pub fn mail_text(message: &[u8], size: u64, limit: usize) -> Vec<u8> {
    let size = size.max(message.len() as u64);
    let (head_end, body_start) = split_header(message);
    let headers = String::from_utf8_lossy(&message[..head_end]).replace("\r\n", "\n");
    let head = format!(
        "From: {}\nSubject: {}\n\n",
        header(&headers, "From").unwrap_or_else(|| "(unknown)".into()),
        header(&headers, "Subject").unwrap_or_else(|| "(no subject)".into()),
    )
    .into_bytes();
    // The body's bytes on the server; without a header end in the part fetched, all that was
    // not fetched.
    let body = &message[body_start.unwrap_or(message.len())..];
    let body_size = match body_start {
        Some(start) => size - start as u64,
        None => size - message.len() as u64,
    };
    let note = |n: u64| format!("\n[... {n} more bytes not sent]").into_bytes();
    let reserve = note(size).len();
    // Whole if it fits: the body's trailing blank lines dropped.
    if body_size == body.len() as u64 {
        let mut text = head.clone();
        text.extend(lossy(&lf_line_ends(body)).trim_end().as_bytes());
        if text.len() <= limit {
            return text;
        }
    }
    let budget = limit.saturating_sub(reserve);
    let (kept, used) = take_lf(body, budget.saturating_sub(head.len()));
    let mut text = head;
    text.extend(lossy(&kept).as_bytes());
    let mut left_out = body_size - used as u64;
    if text.len() > budget {
        left_out += (text.len() - budget) as u64;
        text.truncate(budget);
    }
    text.extend(note(left_out));
    text.truncate(limit);
    text
}

/// Where the header ends (before the blank line) and the body starts, if the blank line is in
/// `message`.
fn split_header(message: &[u8]) -> (usize, Option<usize>) {
    let crlf = message.windows(4).position(|w| w == b"\r\n\r\n");
    let lf = message.windows(2).position(|w| w == b"\n\n");
    match (crlf, lf) {
        (Some(c), Some(l)) if l < c => (l, Some(l + 2)),
        (Some(c), _) => (c, Some(c + 4)),
        (None, Some(l)) => (l, Some(l + 2)),
        (None, None) => (message.len(), None),
    }
}

fn lf_line_ends(bytes: &[u8]) -> Vec<u8> {
    take_lf(bytes, usize::MAX).0
}

/// At most `budget` bytes of `bytes` with CRLF as LF, and how many bytes of `bytes` they are.
fn take_lf(bytes: &[u8], budget: usize) -> (Vec<u8>, usize) {
    let mut out = Vec::with_capacity(budget.min(bytes.len()));
    let mut i = 0;
    while i < bytes.len() && out.len() < budget {
        if bytes[i] == b'\r' && bytes.get(i + 1) == Some(&b'\n') {
            i += 1;
        }
        out.push(bytes[i]);
        i += 1;
    }
    (out, i)
}

fn lossy(bytes: &[u8]) -> std::borrow::Cow<'_, str> {
    String::from_utf8_lossy(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn whole(message: &[u8], limit: usize) -> String {
        String::from_utf8(mail_text(message, message.len() as u64, limit)).unwrap()
    }

    #[test]
    fn mails_become_texts_within_the_limit() {
        let raw = b"Return-Path: <x@y>\r\nFrom: Alice <alice@example.org>\r\nSubject: hello\r\n there\r\n\r\nline 1\r\nline 2\r\n";
        assert_eq!(
            whole(raw, 2048),
            "From: Alice <alice@example.org>\nSubject: hello there\n\nline 1\nline 2"
        );
        let long = [b"Subject: s\r\n\r\n".as_slice(), &[b'x'; 5000]].concat();
        let text = whole(&long, 200);
        assert_eq!(text.len(), 200);
        // 200 bytes: 28 of head, 31 of note, so 141 x's sent of 5000.
        assert!(text.ends_with("\n[... 4859 more bytes not sent]"), "{text}");
        assert!(whole(b"garbage", 64).contains("(no subject)"));
    }

    #[test]
    fn a_mail_fetched_in_part_counts_what_the_server_kept() {
        // 1 MB on the server; 2000 bytes fetched.
        let mut message = b"From: a@b\r\nSubject: big\r\n\r\n".to_vec();
        let head = message.len();
        message.extend(b"line\r\n".repeat(329));
        message.truncate(2000);
        let size = 1_000_000;
        let text = String::from_utf8(mail_text(&message, size, 200)).unwrap();
        assert!(text.len() <= 200);
        let shown = text.split("\n\n").nth(1).unwrap();
        let shown = shown.split("\n[...").next().unwrap();
        // Each shown line of 5 bytes was 6 on the server.
        let used = shown.len() + shown.matches('\n').count();
        let left = size - head as u64 - used as u64;
        assert!(
            text.ends_with(&format!("[... {left} more bytes not sent]")),
            "{text}"
        );
        // A part that ends in the header: its fields still show.
        let text = mail_text(b"From: a@b\r\nSubject: s\r\nReceived: x", 50_000, 2048);
        assert!(text.starts_with(b"From: a@b\nSubject: s\n\n"));
        assert!(text.ends_with(b"[... 49966 more bytes not sent]"));
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
            b"\xff\xff\xff\xff\xff\xff\xff\xff\n\n\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff",
            &folded_forever,
        ] {
            for limit in [64, 65, 100, 2048, 65536] {
                for size in [0, message.len() as u64, 1 << 40] {
                    let text = mail_text(message, size, limit);
                    assert!(text.len() <= limit, "{} > {limit}", text.len());
                    assert!(text.starts_with(b"From: "));
                }
            }
        }
    }
}
