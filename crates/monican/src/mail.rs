//! A supervisor's message (seed §4.3.3.2): a frame on the mail identifier announces it; once
//! the user presses Ctrl R, MoniCAN answers with a remote frame on the same identifier and
//! the text arrives with the file protocol (8 bytes a frame, the last one shorter, possibly
//! empty). It is shown on a page of its own; any key goes back to the SLIO screen.

use crate::screen::{COLS, Screen};

/// The first and last rows of the message text on its page.
const FIRST_TEXT_ROW: u8 = 3;
const LAST_TEXT_ROW: u8 = 22;
const STATUS_ROW: u8 = 23;
const HINT_ROW: u8 = 24;
const TAB: usize = 8;

pub const PAGE_TITLE: &str = "*** MoniCAN: message from the supervisor ***";
pub const WAITING: &str = "(waiting for the message...)";
pub const END: &str = "--- end of message ---";
pub const HINT: &str = "press any key to return to the SLIO screen";

/// A message being received.
#[derive(Clone, Debug)]
pub struct MailReader {
    text: Vec<u8>,
    limit: usize,
    /// Bytes that arrived beyond `limit` (counted, not kept).
    dropped: usize,
    complete: bool,
}

impl MailReader {
    /// Keeps at most `limit` bytes of the message.
    pub fn new(limit: usize) -> Self {
        Self {
            text: Vec::new(),
            limit,
            dropped: 0,
            complete: false,
        }
    }

    /// The data of one frame on the mail identifier; a frame shorter than 8 bytes ends the
    /// message. Returns whether this frame ended it. Frames after the end are ignored.
    pub fn push(&mut self, data: &[u8]) -> bool {
        if self.complete {
            return false;
        }
        let room = self.limit.saturating_sub(self.text.len());
        let kept = data.len().min(room);
        self.text.extend_from_slice(&data[..kept]);
        self.dropped = self.dropped.saturating_add(data.len() - kept);
        self.complete = data.len() < 8;
        self.complete
    }

    pub fn is_complete(&self) -> bool {
        self.complete
    }

    /// The bytes kept so far.
    pub fn text(&self) -> &[u8] {
        &self.text
    }

    /// Bytes beyond the limit, not kept.
    pub fn dropped(&self) -> usize {
        self.dropped
    }

    /// Draws the page: title, the text from row 3 (wrapped at 80 columns; newline, tab; any
    /// other control or non-ASCII byte as `?`), the state on row 23, the hint on row 24.
    pub fn draw(&self, screen: &mut Screen) {
        screen.blank();
        screen.put_line(1, PAGE_TITLE);
        let (mut row, mut col) = (FIRST_TEXT_ROW, 0usize);
        let mut overflow = false;
        for &byte in &self.text {
            match byte {
                b'\r' => continue,
                b'\n' => {
                    row += 1;
                    col = 0;
                }
                b'\t' => col = (col / TAB + 1) * TAB,
                _ => {
                    if col >= COLS {
                        row += 1;
                        col = 0;
                    }
                    if row > LAST_TEXT_ROW {
                        overflow = true;
                        break;
                    }
                    screen.put_byte(row, col as u8 + 1, byte);
                    col += 1;
                }
            }
        }
        let mut status = if self.complete {
            END.to_string()
        } else {
            WAITING.to_string()
        };
        if overflow {
            status = format!("{status} (longer than the page: the rest is not shown)");
        }
        if self.dropped > 0 {
            status = format!(
                "{status} ({} bytes beyond the {}-byte limit not kept)",
                self.dropped, self.limit
            );
        }
        screen.put_line(STATUS_ROW, &status);
        screen.put_line(HINT_ROW, HINT);
        screen.set_cursor(HINT_ROW, HINT.len() as u8 + 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shorter_frame_ends_the_message_and_the_limit_is_kept() {
        let mut m = MailReader::new(10);
        assert!(!m.push(b"Hello, w"));
        assert!(m.push(b"orld"));
        assert!(m.is_complete());
        assert_eq!(m.text(), b"Hello, wor");
        assert_eq!(m.dropped(), 2);
        assert!(!m.push(b"late"));
        assert_eq!(m.dropped(), 2);
        // A length that is a multiple of 8 ends with an empty frame.
        let mut m = MailReader::new(100);
        assert!(!m.push(b"12345678"));
        assert!(m.push(b""));
        assert_eq!(m.text(), b"12345678");
    }

    #[test]
    fn the_page_wraps_and_says_what_it_could_not_show() {
        let mut m = MailReader::new(4096);
        m.push(&[b'a'; 8]);
        let mut s = Screen::new();
        m.draw(&mut s);
        assert_eq!(s.line(3), "aaaaaaaa");
        assert_eq!(s.line(23), WAITING);
        let mut long = Vec::new();
        long.extend_from_slice(b"line\r\n\tx\x01\xff\n");
        long.extend(std::iter::repeat_n(b'b', 85));
        long.extend(std::iter::repeat_n(b'\n', 30));
        long.push(b'c');
        for chunk in long.chunks(8) {
            m.push(chunk);
        }
        m.push(&[]);
        m.draw(&mut s);
        assert_eq!(s.line(3), "aaaaaaaaline");
        assert_eq!(s.line(4), "        x??");
        assert_eq!(s.line(5), "b".repeat(80));
        assert_eq!(s.line(6), "bbbbb");
        assert!(s.line(23).starts_with(END));
        assert!(s.line(23).contains("longer than the page"));
        assert_eq!(s.line(24), HINT);
    }
}
