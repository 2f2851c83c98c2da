//! Text from elsewhere (a board, a bus server, a file) made safe to print on a terminal.

use core::fmt::Write as _;

/// Text from a device or a server as it may be shown on a terminal: UTF-8 (invalid bytes as
/// U+FFFD), every control character written out (`\x1B`, `\x0A`, `\u{9B}`), and so are the
/// invisible marks that reorder text (bidirectional overrides and isolates, `\u{202E}`), so
/// an escape sequence in a device's text or a node's name cannot drive the user's terminal
/// or disguise what is shown.
pub fn printable(bytes: &[u8]) -> String {
    let mut out = String::with_capacity(bytes.len());
    for c in String::from_utf8_lossy(bytes).chars() {
        if (c as u32) < 0x20 || c == '\x7F' {
            let _ = write!(out, "\\x{:02X}", c as u32);
        } else if c.is_control() || reorders(c) {
            let _ = write!(out, "\\u{{{:X}}}", c as u32);
        } else {
            out.push(c);
        }
    }
    out
}

/// Unicode's bidirectional formatting characters (UAX #9): invisible, they change the order
/// in which the characters around them are shown.
fn reorders(c: char) -> bool {
    matches!(c, '\u{061C}' | '\u{200E}' | '\u{200F}' | '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escape_sequences_and_reordering_marks_are_written_out() {
        assert_eq!(printable(b"engine"), "engine");
        assert_eq!(printable(b"\x1B[2Jgone"), "\\x1B[2Jgone");
        assert_eq!(printable(b"a\r\nb\t\x7F"), "a\\x0D\\x0Ab\\x09\\x7F");
        assert_eq!(printable("\u{9B}2J".as_bytes()), "\\u{9B}2J");
        assert_eq!(printable("abc\u{202E}fed".as_bytes()), "abc\\u{202E}fed");
        assert_eq!(printable(b"\xff"), "\u{FFFD}");
        assert_eq!(printable("Zürich µs".as_bytes()), "Zürich µs");
    }
}
