//! The wizard's text questions: a one-line editor with the keys a shell user expects
//! (readline's: Ctrl-U erases to the start of the line, Ctrl-K to its end, Ctrl-W the word
//! before the cursor, Ctrl-A/Ctrl-E/Home/End and the arrows move), which `inquire` 0.9's text
//! prompt does not have (its Ctrl-U types `u`).
//!
//! [`LineEditor`] is sans-IO: the terminal's bytes go in, the line and what to do come out;
//! [`ask`] runs it on the terminal in raw mode, drawn as `inquire` draws its questions.

use std::io::{Read, Write};

/// The longest answer taken (a path, a host name, a list of IDs).
pub const MAX_CHARS: usize = 512;

/// What a key did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// The line changed or the cursor moved (or nothing happened).
    Editing,
    /// Enter: the line is the answer.
    Submit,
    /// Escape or Ctrl-C.
    Cancel,
}

/// The line being typed and the cursor in it, fed the terminal's bytes.
#[derive(Clone, Debug, Default)]
pub struct LineEditor {
    text: Vec<char>,
    cursor: usize,
    /// Bytes of a UTF-8 character or an escape sequence not complete yet.
    pending: Vec<u8>,
}

impl LineEditor {
    /// Starts with `text`, the cursor at its end.
    pub fn with_text(text: &str) -> Self {
        let text: Vec<char> = text.chars().take(MAX_CHARS).collect();
        Self {
            cursor: text.len(),
            text,
            pending: Vec::new(),
        }
    }

    pub fn text(&self) -> String {
        self.text.iter().collect()
    }

    /// The cursor, in characters from the start.
    pub fn cursor(&self) -> usize {
        self.cursor
    }

    /// Bytes from the terminal (one key's, as [`ask`] reads them); stops at the first Enter
    /// or cancel, the bytes after it not looked at.
    pub fn feed(&mut self, bytes: &[u8]) -> Outcome {
        let mut i = 0;
        while i < bytes.len() {
            let b = bytes[i];
            i += 1;
            if !self.pending.is_empty() || b == 0x1B || b >= 0x80 {
                self.pending.push(b);
                match self.take_pending(i == bytes.len()) {
                    Some(Outcome::Editing) | None => continue,
                    Some(done) => return done,
                }
            }
            match b {
                b'\r' | b'\n' => return Outcome::Submit,
                0x03 => return Outcome::Cancel,
                0x7F | 0x08 => self.backspace(),
                0x15 => {
                    self.text.drain(..self.cursor);
                    self.cursor = 0;
                }
                0x0B => self.text.truncate(self.cursor),
                0x17 => self.delete_word_back(),
                0x01 => self.cursor = 0,
                0x05 => self.cursor = self.text.len(),
                0x02 => self.cursor = self.cursor.saturating_sub(1),
                0x06 => self.cursor = (self.cursor + 1).min(self.text.len()),
                0x04 => self.delete(),
                b if b >= 0x20 => self.insert(b as char),
                // Other control keys type nothing.
                _ => {}
            }
        }
        Outcome::Editing
    }

    /// Acts on `pending` when it is complete: an escape sequence, or a UTF-8 character.
    /// `at_end`: nothing more came in this read (a lone Escape is the key itself).
    fn take_pending(&mut self, at_end: bool) -> Option<Outcome> {
        let p = &self.pending;
        if p[0] == 0x1B {
            let done = match p.as_slice() {
                [0x1B] if at_end => Some(Outcome::Cancel),
                [0x1B] => None,
                [0x1B, b'[' | b'O'] => None,
                [0x1B, b'[', rest @ ..] | [0x1B, b'O', rest @ ..] => {
                    let last = *rest.last().unwrap_or(&0);
                    if !(0x40..=0x7E).contains(&last) {
                        // Parameters still coming (`ESC [ 3 ~`), up to a bound.
                        if p.len() > 16 {
                            self.pending.clear();
                        }
                        return None;
                    }
                    match rest {
                        [b'D'] => self.cursor = self.cursor.saturating_sub(1),
                        [b'C'] => self.cursor = (self.cursor + 1).min(self.text.len()),
                        [b'H'] | [b'1', b'~'] | [b'7', b'~'] => self.cursor = 0,
                        [b'F'] | [b'4', b'~'] | [b'8', b'~'] => self.cursor = self.text.len(),
                        [b'3', b'~'] => self.delete(),
                        _ => {}
                    }
                    Some(Outcome::Editing)
                }
                // Alt+key and the like: nothing.
                _ => Some(Outcome::Editing),
            };
            if done.is_some() {
                self.pending.clear();
            }
            return done;
        }
        let need = match p[0] {
            0xC0..=0xDF => 2,
            0xE0..=0xEF => 3,
            0xF0..=0xF7 => 4,
            _ => {
                self.pending.clear();
                return Some(Outcome::Editing);
            }
        };
        if p.len() < need {
            return None;
        }
        if let Some(c) = std::str::from_utf8(p).ok().and_then(|s| s.chars().next()) {
            self.insert(c);
        }
        self.pending.clear();
        Some(Outcome::Editing)
    }

    fn insert(&mut self, c: char) {
        if self.text.len() < MAX_CHARS && !c.is_control() {
            self.text.insert(self.cursor, c);
            self.cursor += 1;
        }
    }

    fn backspace(&mut self) {
        if self.cursor > 0 {
            self.cursor -= 1;
            self.text.remove(self.cursor);
        }
    }

    fn delete(&mut self) {
        if self.cursor < self.text.len() {
            self.text.remove(self.cursor);
        }
    }

    /// Readline's Ctrl-W: the spaces before the cursor, then the word before them.
    fn delete_word_back(&mut self) {
        let mut start = self.cursor;
        while start > 0 && self.text[start - 1].is_whitespace() {
            start -= 1;
        }
        while start > 0 && !self.text[start - 1].is_whitespace() {
            start -= 1;
        }
        self.text.drain(start..self.cursor);
        self.cursor = start;
    }
}

/// Raw mode until dropped.
struct Raw;

impl Raw {
    fn enter() -> std::io::Result<Self> {
        crossterm::terminal::enable_raw_mode()?;
        Ok(Raw)
    }
}

impl Drop for Raw {
    fn drop(&mut self) {
        let _ = crossterm::terminal::disable_raw_mode();
    }
}

/// Why a question got no answer.
#[derive(Debug, thiserror::Error)]
pub enum AskError {
    #[error("cancelled")]
    Cancelled,
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

/// Asks `question` on the terminal: `? question (default) …` with `help` below; Enter on an
/// empty line answers `default`. An answer `check` refuses stays on the line with the reason
/// below, to be corrected. The question ends as `> question answer`.
pub fn ask(
    question: &str,
    default: &str,
    help: &str,
    check: &dyn Fn(&str) -> Result<(), String>,
) -> Result<String, AskError> {
    let _raw = Raw::enter()?;
    let mut out = std::io::stdout();
    let mut stdin = std::io::stdin();
    let mut editor = LineEditor::default();
    let mut screen = Screen::default();
    let mut note = format!("[{help}]");
    let prefix = if default.is_empty() {
        format!("? {question} ")
    } else {
        format!("? {question} ({default}) ")
    };
    loop {
        screen.draw(&mut out, &prefix, &editor, &note)?;
        let Some(key) = read_key(&mut stdin)? else {
            return Err(AskError::Cancelled);
        };
        match editor.feed(&key) {
            Outcome::Editing => {}
            Outcome::Cancel => {
                screen.finish(&mut out, &format!("> {question} (cancelled)"))?;
                return Err(AskError::Cancelled);
            }
            Outcome::Submit => {
                let typed = editor.text();
                let answer = if typed.trim().is_empty() {
                    default.to_string()
                } else {
                    typed
                };
                match check(&answer) {
                    Ok(()) => {
                        screen.finish(&mut out, &format!("> {question} {answer}"))?;
                        return Ok(answer);
                    }
                    Err(why) => {
                        note = format!("# {why}");
                        editor = LineEditor::with_text(&answer);
                    }
                }
            }
        }
    }
}

/// How long the rest of an escape sequence may take to follow its Escape (a terminal sends
/// them at once; a lone Escape is the key).
const ESCAPE_WAIT_MS: u16 = 50;

/// One key's bytes, read a byte at a time: nothing typed after it is taken from the terminal
/// (the next question, an `inquire` one, reads it). `None` at the end of the input.
fn read_key(stdin: &mut std::io::Stdin) -> std::io::Result<Option<Vec<u8>>> {
    use nix::poll::{PollFd, PollFlags, PollTimeout, poll};
    use std::os::fd::AsFd;
    let mut byte = [0u8; 1];
    if stdin.read(&mut byte)? == 0 {
        return Ok(None);
    }
    let mut key = vec![byte[0]];
    if byte[0] != 0x1B {
        return Ok(Some(key));
    }
    let complete = |k: &[u8]| match k {
        [_, b'[' | b'O'] => false,
        [_, _] => true,
        [_, _, .., last] => (0x40..=0x7E).contains(last),
        _ => false,
    };
    while key.len() < 16 && !complete(&key) {
        let mut fds = [PollFd::new(stdin.as_fd(), PollFlags::POLLIN)];
        if poll(&mut fds, PollTimeout::from(ESCAPE_WAIT_MS)).map_err(std::io::Error::from)? == 0 {
            break;
        }
        if stdin.read(&mut byte)? == 0 {
            break;
        }
        key.push(byte[0]);
    }
    Ok(Some(key))
}

/// Where the question is drawn: the cursor is `up` rows below the question's first row (a
/// long line or note wraps over several rows of the terminal).
#[derive(Default)]
struct Screen {
    up: u16,
}

impl Screen {
    /// The question's line and the note below it, the cursor where the editor has it.
    fn draw(
        &mut self,
        out: &mut impl Write,
        prefix: &str,
        editor: &LineEditor,
        note: &str,
    ) -> std::io::Result<()> {
        use crossterm::{cursor, queue};
        let width = crossterm::terminal::size().map_or(80, |(w, _)| w).max(1) as usize;
        let rows = |chars: usize| chars.max(1).div_ceil(width);
        self.top(out)?;
        let line = format!("{prefix}{}", editor.text());
        write!(out, "{line}\r\n{note}")?;
        let last = rows(line.chars().count()) + rows(note.chars().count()) - 1;
        let at = prefix.chars().count() + editor.cursor();
        let row = (at / width).min(last);
        if last > row {
            queue!(
                out,
                cursor::MoveUp((last - row).min(u16::MAX as usize) as u16)
            )?;
        }
        queue!(out, cursor::MoveToColumn((at % width) as u16))?;
        self.up = row.min(u16::MAX as usize) as u16;
        out.flush()
    }

    /// Replaces the question and its note by `line`.
    fn finish(&mut self, out: &mut impl Write, line: &str) -> std::io::Result<()> {
        self.top(out)?;
        write!(out, "{line}\r\n")?;
        self.up = 0;
        out.flush()
    }

    /// To the question's first row, everything from there down cleared.
    fn top(&self, out: &mut impl Write) -> std::io::Result<()> {
        use crossterm::{cursor, queue, terminal};
        if self.up > 0 {
            queue!(out, cursor::MoveUp(self.up))?;
        }
        queue!(
            out,
            cursor::MoveToColumn(0),
            terminal::Clear(terminal::ClearType::FromCursorDown)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn typed(bytes: &[u8]) -> (LineEditor, Outcome) {
        let mut e = LineEditor::default();
        let outcome = e.feed(bytes);
        (e, outcome)
    }

    /// The issue's bug: Ctrl-U typed `u` (inquire 0.9's text prompt has no such key).
    #[test]
    fn ctrl_u_erases_the_line_instead_of_typing_u() {
        let (e, outcome) = typed(b"0x1E0\x15");
        assert_eq!((e.text(), outcome), (String::new(), Outcome::Editing));
        let (e, _) = typed(b"125000\x15125k");
        assert_eq!(e.text(), "125k");
        // From the cursor to the start, as readline: after two steps left, "ab" stays.
        let (e, _) = typed(b"xyzab\x1b[D\x1b[D\x15");
        assert_eq!((e.text(), e.cursor()), ("ab".to_string(), 0));
    }

    #[test]
    fn the_other_editing_keys_do_what_a_shell_does() {
        assert_eq!(typed(b"can0 vcan0\x17").0.text(), "can0 ");
        assert_eq!(typed(b"abc\x01X").0.text(), "Xabc");
        assert_eq!(typed(b"abc\x01\x05X").0.text(), "abcX");
        assert_eq!(typed(b"abcd\x02\x02\x0B").0.text(), "ab");
        assert_eq!(typed(b"abc\x7f").0.text(), "ab");
        assert_eq!(typed(b"abc\x1b[H\x1b[3~").0.text(), "bc");
        assert_eq!(typed(b"abc\x1bOH!").0.text(), "!abc");
        assert_eq!(typed("µs".as_bytes()).0.text(), "µs");
        // Control keys without a meaning type nothing.
        assert_eq!(typed(b"a\x07\x0e\x10b").0.text(), "ab");
    }

    #[test]
    fn enter_submits_and_escape_or_ctrl_c_cancel() {
        assert_eq!(typed(b"125k\r").1, Outcome::Submit);
        assert_eq!(typed(b"125k\x03").1, Outcome::Cancel);
        assert_eq!(typed(b"\x1b").1, Outcome::Cancel);
        // An arrow key's sequence is not an Escape.
        assert_eq!(typed(b"\x1b[D").1, Outcome::Editing);
        // A sequence split between two reads still is one key.
        let mut e = LineEditor::with_text("ab");
        assert_eq!(e.feed(b"\x1b["), Outcome::Editing);
        assert_eq!(e.feed(b"D"), Outcome::Editing);
        assert_eq!(e.cursor(), 1);
    }

    #[test]
    fn an_endless_line_is_bounded() {
        let (e, _) = typed(&[b'7'; MAX_CHARS + 100]);
        assert_eq!(e.text().len(), MAX_CHARS);
        let mut e = LineEditor::default();
        e.feed(b"\x1b[");
        e.feed(&[b'1'; 40]);
        e.feed(b"xy");
        assert!(e.text().ends_with("xy"), "{:?}", e.text());
    }
}
