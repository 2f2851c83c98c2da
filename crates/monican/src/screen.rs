//! A VT100 screen of 24 rows by 80 columns, kept as the text it should show; rendering sends
//! only the cells that differ from what the terminal already shows, with cursor addressing.
//!
//! Rendering is pulled ([`Screen::render`]): whoever owns the line asks when it has room, so a
//! burst of changes (a busy bus rewriting "Last frame received") costs one update of the final
//! text rather than a queue of stale ones that a 19200-baud line could not carry.

/// Rows of a VT100 screen.
pub const ROWS: usize = 24;
/// Columns of a VT100 screen.
pub const COLS: usize = 80;

/// ASCII BEL: the terminal beeps.
pub const BELL: u8 = 0x07;
/// Bells sent by one render at most (a key held down must not flood the line with beeps).
const MAX_BELLS: u32 = 4;
/// Up to this many unchanged cells between two changes are rewritten rather than skipped with
/// a cursor move (a move costs more bytes).
const BRIDGE: usize = 4;

/// What the terminal should show, and what it shows.
#[derive(Clone, Debug)]
pub struct Screen {
    want: [[u8; COLS]; ROWS],
    shown: [[u8; COLS]; ROWS],
    /// Clear the terminal before the next render (start-up, Ctrl L, a new page).
    clear: bool,
    bells: u32,
    /// Where the cursor should rest (row, column), 1-based.
    cursor: (u8, u8),
    /// Where the terminal's cursor is, when known.
    shown_cursor: Option<(u8, u8)>,
}

impl Default for Screen {
    fn default() -> Self {
        Self::new()
    }
}

impl Screen {
    /// A blank screen that clears the terminal at its first render.
    pub fn new() -> Self {
        Self {
            want: [[b' '; COLS]; ROWS],
            shown: [[b' '; COLS]; ROWS],
            clear: true,
            bells: 0,
            cursor: (1, 1),
            shown_cursor: None,
        }
    }

    /// Blanks the wanted text (the terminal is updated cell by cell, not cleared).
    pub fn blank(&mut self) {
        self.want = [[b' '; COLS]; ROWS];
    }

    /// The next render clears the terminal and draws everything (what the terminal shows is
    /// no longer trusted: Ctrl L, a terminal opened late, lost bytes).
    pub fn redraw(&mut self) {
        self.clear = true;
    }

    /// Writes `text` from (`row`, `col`), 1-based; what falls beyond column 80 is clipped, and
    /// bytes a VT100 cannot show as one cell (controls, non-ASCII) become `?`.
    pub fn put(&mut self, row: u8, col: u8, text: &str) {
        let Some(line) = self.want.get_mut(usize::from(row).wrapping_sub(1)) else {
            return;
        };
        let start = usize::from(col.max(1)) - 1;
        for (cell, byte) in line.iter_mut().skip(start).zip(text.bytes()) {
            *cell = printable(byte);
        }
    }

    /// Replaces a whole row with `text` from column 1.
    pub fn put_line(&mut self, row: u8, text: &str) {
        if let Some(line) = self.want.get_mut(usize::from(row).wrapping_sub(1)) {
            *line = [b' '; COLS];
        }
        self.put(row, 1, text);
    }

    /// One byte at (`row`, `col`).
    pub fn put_byte(&mut self, row: u8, col: u8, byte: u8) {
        let (r, c) = (
            usize::from(row).wrapping_sub(1),
            usize::from(col).wrapping_sub(1),
        );
        if let Some(cell) = self.want.get_mut(r).and_then(|line| line.get_mut(c)) {
            *cell = printable(byte);
        }
    }

    /// The wanted text of a row (1-based), trailing blanks removed.
    pub fn line(&self, row: u8) -> String {
        self.want
            .get(usize::from(row).wrapping_sub(1))
            .map(|l| String::from_utf8_lossy(l).trim_end().to_string())
            .unwrap_or_default()
    }

    /// Every wanted row, trailing blanks removed, joined with newlines.
    pub fn text(&self) -> String {
        (1..=ROWS as u8)
            .map(|r| self.line(r))
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// Rings the terminal's bell at the next render.
    pub fn bell(&mut self) {
        self.bells = self.bells.saturating_add(1);
    }

    /// Where the cursor rests after a render (1-based).
    pub fn set_cursor(&mut self, row: u8, col: u8) {
        self.cursor = (row.clamp(1, ROWS as u8), col.clamp(1, COLS as u8));
    }

    /// Whether a render would send anything.
    pub fn is_dirty(&self) -> bool {
        self.clear
            || self.bells > 0
            || self.want != self.shown
            || Some(self.cursor) != self.shown_cursor
    }

    /// Appends the VT100 bytes that bring the terminal to the wanted text: a clear if asked
    /// for, then runs of changed cells each after a cursor move, the bells, the cursor.
    pub fn render(&mut self, out: &mut Vec<u8>) {
        if self.clear {
            self.clear = false;
            // Home, erase the whole screen; attributes back to normal.
            out.extend_from_slice(b"\x1b[0m\x1b[H\x1b[2J");
            self.shown = [[b' '; COLS]; ROWS];
            self.shown_cursor = Some((1, 1));
        }
        for r in 0..ROWS {
            // Most renders change a row or two: whole rows compare at once.
            if self.want[r] == self.shown[r] {
                continue;
            }
            let mut c = 0;
            while c < COLS {
                if self.want[r][c] == self.shown[r][c] {
                    c += 1;
                    continue;
                }
                // A run of changes, bridging short stretches of unchanged cells.
                let start = c;
                let mut end = c + 1;
                let mut same = 0;
                let mut k = c + 1;
                while k < COLS && same <= BRIDGE {
                    if self.want[r][k] == self.shown[r][k] {
                        same += 1;
                    } else {
                        same = 0;
                        end = k + 1;
                    }
                    k += 1;
                }
                let at = (r as u8 + 1, start as u8 + 1);
                if self.shown_cursor != Some(at) {
                    move_to(out, at);
                }
                out.extend_from_slice(&self.want[r][start..end]);
                self.shown[r][start..end].copy_from_slice(&self.want[r][start..end]);
                // After the last column a VT100 waits to wrap: where it is then is not worth
                // guessing.
                self.shown_cursor = (end < COLS).then_some((r as u8 + 1, end as u8 + 1));
                c = end;
            }
        }
        for _ in 0..self.bells.min(MAX_BELLS) {
            out.push(BELL);
        }
        self.bells = 0;
        if self.shown_cursor != Some(self.cursor) {
            move_to(out, self.cursor);
            self.shown_cursor = Some(self.cursor);
        }
    }
}

/// CUP: `ESC [ row ; col H`.
fn move_to(out: &mut Vec<u8>, (row, col): (u8, u8)) {
    out.extend_from_slice(format!("\x1b[{row};{col}H").as_bytes());
}

fn printable(byte: u8) -> u8 {
    if (0x20..0x7F).contains(&byte) {
        byte
    } else {
        b'?'
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn render(s: &mut Screen) -> String {
        let mut out = Vec::new();
        s.render(&mut out);
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn the_first_render_clears_then_only_changes_are_sent() {
        let mut s = Screen::new();
        s.put(2, 3, "abc");
        s.set_cursor(24, 1);
        assert_eq!(render(&mut s), "\x1b[0m\x1b[H\x1b[2J\x1b[2;3Habc\x1b[24;1H");
        assert!(!s.is_dirty());
        assert_eq!(render(&mut s), "");
        s.put(2, 4, "X");
        assert_eq!(render(&mut s), "\x1b[2;4HX\x1b[24;1H");
        // Two changes close together are one run; far apart, two.
        s.put(5, 1, "1..2");
        s.put(5, 40, "3");
        assert_eq!(render(&mut s), "\x1b[5;1H1..2\x1b[5;40H3\x1b[24;1H");
    }

    #[test]
    fn text_is_clipped_and_controls_are_not_sent() {
        let mut s = Screen::new();
        s.put(1, 78, "abcdef");
        s.put(3, 1, "a\x1b[2Jb\u{e9}");
        s.put(0, 1, "nowhere");
        s.put(25, 1, "nowhere");
        assert_eq!(s.line(1), format!("{}abc", " ".repeat(77)));
        assert_eq!(s.line(3), "a?[2Jb??");
        let out = render(&mut s);
        assert!(!out.contains("\x1b[2Jb"));
    }

    #[test]
    fn bells_are_bounded_per_render() {
        let mut s = Screen::new();
        render(&mut s);
        for _ in 0..100 {
            s.bell();
        }
        assert_eq!(render(&mut s).matches('\x07').count(), MAX_BELLS as usize);
        assert_eq!(render(&mut s), "");
    }
}
