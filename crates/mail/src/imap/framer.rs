//! Cuts the bytes an IMAP server sends into whole responses before anything parses them, and
//! refuses, as soon as a cap is crossed, what no honest server sends: a line that never ends,
//! a literal larger than anything asked for, parentheses nested deeper than any response has,
//! a response larger than a bound. Memory held is at most [`Limits::message`] bytes whatever
//! arrives, and the parser behind it never sees a nesting it could overflow its stack on.
//!
//! It tracks only what framing needs (RFC 3501 §4.3, §7): quoted strings (a `(` or `{` inside
//! one does not count; a quoted string ends at its line), literals `{N}` / `~{N}` at the end of
//! a line (the next N bytes are data, whatever they hold), and the parenthesis depth outside
//! both. A line ends at LF (CRLF or a bare LF).

use std::collections::VecDeque;

use thiserror::Error;

/// The caps, in bytes (depth in parentheses).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// One line outside literals (a response line, or what follows a literal up to the next
    /// line end).
    pub line: usize,
    /// One literal's announced size.
    pub literal: u64,
    /// One whole response: its lines and literals.
    pub message: usize,
    /// Parentheses open at once outside quoted strings and literals.
    pub depth: u32,
}

impl Limits {
    /// What `buslab mail` uses. A `UID SEARCH` answer listing 100 000 new UIDs fits in a line;
    /// the largest literal it asks for (`BODY.PEEK[]<0.N>`) is [`crate::imap::FETCH_MAX`]; a
    /// `BODYSTRUCTURE` of a mail nested 8 deep (imap-codec's own limit) opens about 24.
    pub const DEFAULT: Self = Self {
        line: 1 << 20,
        literal: 1 << 20,
        message: 4 << 20,
        depth: 32,
    };
}

impl Default for Limits {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// What the framer refused; the connection cannot be trusted past it.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum FrameError {
    #[error("a line longer than {limit} bytes without a line end")]
    LineTooLong { limit: usize },
    #[error("a literal announced as {announced} bytes (at most {limit} accepted)")]
    LiteralTooLarge { announced: u64, limit: u64 },
    #[error("a literal announced with {digits} digits (at most {limit} bytes accepted)")]
    LiteralSizeUnreadable { digits: usize, limit: u64 },
    #[error("parentheses nested deeper than {limit}")]
    TooDeep { limit: u32 },
    #[error("a response longer than {limit} bytes")]
    MessageTooLarge { limit: usize },
}

/// Where the scanner is within the current response.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// On a line, outside a literal.
    Line {
        quoted: bool,
        /// The last byte was a backslash inside a quoted string.
        escaped: bool,
        literal: LiteralScan,
    },
    /// Inside a literal's data: this many bytes still to come.
    Literal(u64),
}

/// A literal's size being read at the end of a line: `{`, digits, an optional `+`, `}`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LiteralScan {
    None,
    /// After `{`: the size so far (saturating) and how many digits.
    Digits(u64, usize),
    /// After `+` (LITERAL+ syntax, tolerated).
    Plus(u64, usize),
    /// After `}`: a literal if the line ends here.
    Closed(u64, usize),
    /// After `}` and CR.
    ClosedCr(u64, usize),
}

const LINE_START: State = State::Line {
    quoted: false,
    escaped: false,
    literal: LiteralScan::None,
};

/// The scanner, sans-IO: bytes in ([`Framer::push`]), whole responses out
/// ([`Framer::next_message`]).
#[derive(Debug)]
pub struct Framer {
    limits: Limits,
    state: State,
    /// The response being read.
    current: Vec<u8>,
    /// Bytes of the current line outside literals.
    line: usize,
    depth: u32,
    ready: VecDeque<Vec<u8>>,
    failed: Option<FrameError>,
}

impl Framer {
    pub fn new(limits: Limits) -> Self {
        Self {
            limits,
            state: LINE_START,
            current: Vec::new(),
            line: 0,
            depth: 0,
            ready: VecDeque::new(),
            failed: None,
        }
    }

    /// Bytes from the server. Once it failed, it keeps failing: the stream past a refused
    /// byte has no frame to resynchronise on.
    pub fn push(&mut self, mut data: &[u8]) -> Result<(), FrameError> {
        if let Some(e) = &self.failed {
            return Err(e.clone());
        }
        while !data.is_empty() {
            let used = match self.scan(data) {
                Ok(used) => used,
                Err(e) => {
                    self.current = Vec::new();
                    self.failed = Some(e.clone());
                    return Err(e);
                }
            };
            data = &data[used..];
        }
        Ok(())
    }

    /// The next whole response (with its line end), if one is complete.
    pub fn next_message(&mut self) -> Option<Vec<u8>> {
        self.ready.pop_front()
    }

    /// No byte is held: neither a whole response nor part of one (checked before the TLS
    /// handshake of STARTTLS, so nothing sent in clear text is taken as sent under TLS).
    pub fn is_empty(&self) -> bool {
        self.ready.is_empty() && self.current.is_empty()
    }

    /// Takes what `data` starts with; returns how many bytes were used.
    fn scan(&mut self, data: &[u8]) -> Result<usize, FrameError> {
        if let State::Literal(left) = self.state {
            let take = usize::try_from(left).unwrap_or(usize::MAX).min(data.len());
            self.grow(&data[..take])?;
            let left = left - take as u64;
            self.state = if left == 0 {
                self.line = 0;
                LINE_START
            } else {
                State::Literal(left)
            };
            return Ok(take);
        }
        // On a line: byte by byte up to its end.
        for (i, &byte) in data.iter().enumerate() {
            self.line += 1;
            if self.line > self.limits.line {
                return Err(FrameError::LineTooLong {
                    limit: self.limits.line,
                });
            }
            if byte == b'\n' {
                self.grow(&data[..=i])?;
                self.end_of_line()?;
                return Ok(i + 1);
            }
            self.state = self.step(byte)?;
        }
        self.grow(data)?;
        Ok(data.len())
    }

    fn grow(&mut self, bytes: &[u8]) -> Result<(), FrameError> {
        if self.current.len() + bytes.len() > self.limits.message {
            return Err(FrameError::MessageTooLarge {
                limit: self.limits.message,
            });
        }
        self.current.extend_from_slice(bytes);
        Ok(())
    }

    /// The state after one byte of a line (not LF).
    fn step(&mut self, byte: u8) -> Result<State, FrameError> {
        let State::Line {
            quoted,
            escaped,
            literal,
        } = self.state
        else {
            unreachable!("called on lines only");
        };
        if quoted {
            return Ok(State::Line {
                quoted: escaped || byte != b'"',
                escaped: !escaped && byte == b'\\',
                literal: LiteralScan::None,
            });
        }
        let literal = match (literal, byte) {
            (_, b'{') => LiteralScan::Digits(0, 0),
            (LiteralScan::Digits(n, d), b'0'..=b'9') => LiteralScan::Digits(
                n.saturating_mul(10).saturating_add(u64::from(byte - b'0')),
                d + 1,
            ),
            (LiteralScan::Digits(n, d), b'+') if d > 0 => LiteralScan::Plus(n, d),
            (LiteralScan::Digits(n, d) | LiteralScan::Plus(n, d), b'}') if d > 0 => {
                LiteralScan::Closed(n, d)
            }
            (LiteralScan::Closed(n, d), b'\r') => LiteralScan::ClosedCr(n, d),
            _ => LiteralScan::None,
        };
        match byte {
            b'(' => {
                self.depth += 1;
                if self.depth > self.limits.depth {
                    return Err(FrameError::TooDeep {
                        limit: self.limits.depth,
                    });
                }
            }
            b')' => self.depth = self.depth.saturating_sub(1),
            _ => {}
        }
        Ok(State::Line {
            quoted: byte == b'"',
            escaped: false,
            literal,
        })
    }

    /// LF: a literal follows, or the response is whole.
    fn end_of_line(&mut self) -> Result<(), FrameError> {
        let State::Line { literal, .. } = self.state else {
            unreachable!("called on lines only");
        };
        self.line = 0;
        match literal {
            LiteralScan::Closed(size, digits) | LiteralScan::ClosedCr(size, digits) => {
                let limit = self.limits.literal;
                if digits > 20 {
                    return Err(FrameError::LiteralSizeUnreadable { digits, limit });
                }
                if size > limit {
                    return Err(FrameError::LiteralTooLarge {
                        announced: size,
                        limit,
                    });
                }
                self.state = if size == 0 {
                    LINE_START
                } else {
                    State::Literal(size)
                };
            }
            _ => {
                self.state = LINE_START;
                self.depth = 0;
                self.ready.push_back(std::mem::take(&mut self.current));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> Limits {
        Limits {
            line: 64,
            literal: 100,
            message: 256,
            depth: 4,
        }
    }

    fn messages(framer: &mut Framer) -> Vec<Vec<u8>> {
        std::iter::from_fn(|| framer.next_message()).collect()
    }

    #[test]
    fn responses_are_cut_at_line_ends_outside_literals() {
        let stream = b"* OK [CAPABILITY IMAP4rev1] ready\r\n* 1 FETCH (BODY[] {12}\r\nline1\r\n(((\r\n UID 4)\r\na1 OK done\r\n";
        // Whatever way the bytes arrive, the same responses come out.
        for chunk in [1, 2, 3, 7, stream.len()] {
            let mut framer = Framer::new(Limits::DEFAULT);
            for part in stream.chunks(chunk) {
                framer.push(part).unwrap();
            }
            assert_eq!(
                messages(&mut framer),
                [
                    b"* OK [CAPABILITY IMAP4rev1] ready\r\n".to_vec(),
                    b"* 1 FETCH (BODY[] {12}\r\nline1\r\n(((\r\n UID 4)\r\n".to_vec(),
                    b"a1 OK done\r\n".to_vec(),
                ],
                "chunks of {chunk}"
            );
            assert!(framer.is_empty());
        }
    }

    #[test]
    fn quoted_strings_hide_parentheses_and_braces() {
        let mut framer = Framer::new(small());
        framer
            .push(b"* LIST () \"((((((\\\"{5}\" x\r\n* 2 FETCH (X \"{3}\")\r\n")
            .unwrap();
        assert_eq!(messages(&mut framer).len(), 2);
        // A quoted string ends with its line.
        framer.push(b"* OK \"unclosed\r\n* OK next\r\n").unwrap();
        assert_eq!(messages(&mut framer).len(), 2);
    }

    #[test]
    fn a_line_without_lf_is_refused_at_the_line_cap() {
        let mut framer = Framer::new(small());
        assert_eq!(
            framer.push(&[b'x'; 100]),
            Err(FrameError::LineTooLong { limit: 64 })
        );
        assert_eq!(
            framer.push(b"\r\n"),
            Err(FrameError::LineTooLong { limit: 64 }),
            "no resynchronisation"
        );
        assert!(framer.current.capacity() <= 256);
    }

    #[test]
    fn a_huge_literal_is_refused_when_announced() {
        let mut framer = Framer::new(small());
        assert_eq!(
            framer.push(b"* 1 FETCH (BODY[] {2147483648}\r\n"),
            Err(FrameError::LiteralTooLarge {
                announced: 2_147_483_648,
                limit: 100
            })
        );
        let mut framer = Framer::new(small());
        assert_eq!(
            framer.push(b"* 1 FETCH (BODY[] {99999999999999999999999999}\r\n"),
            Err(FrameError::LiteralSizeUnreadable {
                digits: 26,
                limit: 100
            })
        );
        let mut framer = Framer::new(small());
        framer.push(b"* 1 FETCH (BODY[] {100}\r\n").unwrap();
        framer.push(&[b'\n'; 100]).unwrap();
        framer.push(b")\r\n").unwrap();
        assert_eq!(messages(&mut framer).len(), 1, "a literal at the cap");
    }

    #[test]
    fn deep_nesting_is_refused_before_any_parser_sees_it() {
        let mut framer = Framer::new(small());
        framer.push(b"* 1 FETCH ((((x))))\r\n").unwrap();
        assert_eq!(
            framer.push(b"* 1 FETCH (BODYSTRUCTURE (((((\r\n"),
            Err(FrameError::TooDeep { limit: 4 })
        );
        // Depth counts across a literal within one response, and restarts with the next.
        let mut framer = Framer::new(small());
        framer.push(b"* 1 FETCH (((x {2}\r\n((").unwrap();
        assert_eq!(
            framer.push(b" ((\r\n"),
            Err(FrameError::TooDeep { limit: 4 })
        );
    }

    #[test]
    fn many_lines_of_a_response_are_capped_by_the_message_cap() {
        let mut framer = Framer::new(small());
        framer.push(b"* 1 FETCH (A {50}\r\n").unwrap();
        framer.push(&[b'a'; 50]).unwrap();
        let mut refused = None;
        for _ in 0..10 {
            if let Err(e) = framer
                .push(b" B {50}\r\n")
                .and_then(|_| framer.push(&[b'b'; 50]))
            {
                refused = Some(e);
                break;
            }
        }
        assert_eq!(refused, Some(FrameError::MessageTooLarge { limit: 256 }));
    }

    #[test]
    fn a_brace_not_at_the_end_of_a_line_is_no_literal() {
        let mut framer = Framer::new(small());
        framer
            .push(b"* OK {5} text\r\n* OK {x}\r\n* OK {}\r\n* OK {7+}\r\n1234567\r\n")
            .unwrap();
        assert_eq!(messages(&mut framer).len(), 4);
        framer.push(b"* OK ~{0}\r\n\r\n").unwrap();
        assert_eq!(messages(&mut framer), [b"* OK ~{0}\r\n\r\n".to_vec()]);
    }
}
