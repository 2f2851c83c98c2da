//! Elements on the byte stream: everything from a `<` to the next `>`.
//!
//! Like socketcand, text outside elements is skipped; unlike socketcand, it is reported, so a
//! client that sends garbage hears about it.

/// The longest element accepted (socketcand's buffer is about 8290 bytes; python-can drops
/// incomplete messages over 200 characters). Classic CAN needs far less.
pub const MAX_ELEMENT: usize = 8192;

/// What the stream held besides well-formed elements.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ElementError {
    #[error("text outside < >: {0:?}")]
    Outside(String),
    #[error("element longer than {MAX_ELEMENT} bytes without a closing >")]
    TooLong,
    #[error("element is not UTF-8 text")]
    NotText,
}

/// What the bytes at the front of the buffer are, once known.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Skip {
    /// Nothing to skip: an element, whitespace or junk not reported yet.
    #[default]
    Nothing,
    /// The rest of a run of junk already reported: dropped up to the next `<`.
    Junk,
    /// The rest of an element already reported as too long: dropped up to its `>`.
    Overlong,
}

/// Collects bytes and hands out complete elements (the text between `<` and `>`).
///
/// Linear in its input: every byte is looked at once (a position remembers how far the search
/// for the end of the element or junk at the front went), consumed bytes are dropped in bulk,
/// and a run of junk gives one error however long it is (a megabyte of `>` is one error).
#[derive(Debug, Default)]
pub struct Deframer {
    buf: Vec<u8>,
    /// Bytes before this are consumed.
    start: usize,
    /// Bytes from `start` up to this were searched for the end of what starts at `start`.
    scanned: usize,
    skip: Skip,
    /// The byte at `start` is known not to be whitespace.
    front_known: bool,
    /// Bytes looked at in all (the work done, for tests that it stays linear).
    examined: u64,
}

/// Junk shorter than this waits for its end (a `<`, a `>` or a newline) to be reported whole.
const JUNK_WAIT: usize = 41;

impl Deframer {
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.compact();
        self.buf.extend_from_slice(bytes);
    }

    /// Bytes buffered.
    pub fn len(&self) -> usize {
        self.buf.len() - self.start
    }

    /// Whether an unfinished element is buffered.
    pub fn is_empty(&self) -> bool {
        self.buf[self.start..]
            .iter()
            .all(|b| b.is_ascii_whitespace())
    }

    /// At the end of the stream: what is left that no more bytes will complete (an unfinished
    /// element, or junk shorter than a report waits for), as an excerpt and its length in
    /// bytes; `None` if nothing is (whitespace, or the rest of what was reported already).
    /// The deframer is empty afterwards.
    pub fn take_unfinished(&mut self) -> Option<(String, usize)> {
        let rest = &self.buf[self.start..];
        let unfinished = (self.skip == Skip::Nothing
            && !rest.iter().all(|b| b.is_ascii_whitespace()))
        .then(|| (excerpt(rest), rest.len()));
        *self = Self {
            examined: self.examined,
            ..Self::default()
        };
        unfinished
    }

    /// Bytes looked at since the start: about one per byte received, whatever the input.
    pub fn bytes_examined(&self) -> u64 {
        self.examined
    }

    /// Where `want` is in the unscanned bytes, looking at each once.
    fn find(&mut self, from: usize, want: impl Fn(u8) -> bool) -> Option<usize> {
        let found = self.buf[from..].iter().position(|&b| want(b));
        self.found(from, found)
    }

    /// [`Self::find`] for one byte (memchr: many bytes a step).
    fn find_byte(&mut self, from: usize, want: u8) -> Option<usize> {
        let found = memchr::memchr(want, &self.buf[from..]);
        self.found(from, found)
    }

    /// Counts the bytes a search from `from` looked at; where it found, in the buffer.
    fn found(&mut self, from: usize, found: Option<usize>) -> Option<usize> {
        self.examined += found.map_or(self.buf.len() - from, |p| p + 1) as u64;
        found.map(|p| from + p)
    }

    /// Drops consumed bytes when they are most of the buffer (amortised: each byte moves at
    /// most once). Done before taking bytes in, when what is left of the last read is at most
    /// the start of one element (moved, rather than half a read's elements).
    fn compact(&mut self) {
        if self.start == self.buf.len() {
            self.buf.clear();
        } else if self.start >= 4096 && self.start * 2 >= self.buf.len() {
            self.buf.drain(..self.start);
        } else {
            return;
        }
        self.scanned -= self.start;
        self.start = 0;
    }

    /// Consumes up to `end`.
    fn consume_to(&mut self, end: usize) {
        self.start = end;
        self.scanned = end;
        self.front_known = false;
    }

    /// The next complete element's inside (without `<` and `>`), an error for bytes that are
    /// not part of one, or `None` if more bytes are needed.
    pub fn next_element(&mut self) -> Option<Result<String, ElementError>> {
        Some(
            self.next_inside()?
                .and_then(|inside| element_text(inside).map(str::to_string)),
        )
    }

    /// [`Self::next_element`] without copying and before the checks of [`element_text`]: the
    /// inside as it is in the buffer, for a reader that accepts only some ASCII bytes and
    /// hands the rest to `element_text`.
    pub(crate) fn next_inside(&mut self) -> Option<Result<&[u8], ElementError>> {
        let len = self.buf.len();
        match self.skip {
            Skip::Nothing => {}
            Skip::Junk => match self.find_byte(self.start, b'<') {
                Some(p) => {
                    self.skip = Skip::Nothing;
                    self.consume_to(p);
                }
                None => {
                    self.consume_to(len);
                    return None;
                }
            },
            Skip::Overlong => match self.find_byte(self.start, b'>') {
                Some(p) => {
                    self.skip = Skip::Nothing;
                    self.consume_to(p + 1);
                }
                None => {
                    self.consume_to(len);
                    return None;
                }
            },
        }
        // Whitespace between elements (python-can and socketcand send none, telnet users a
        // newline) is fine. (Once the search at the front has begun, the front is known.)
        if !self.front_known {
            let Some(first) = self.find(self.start, |b| !b.is_ascii_whitespace()) else {
                self.consume_to(len);
                return None;
            };
            self.consume_to(first);
            self.front_known = true;
        }
        let (start, len) = (self.start, self.buf.len());
        if self.buf[start] == b'<' {
            let from = self.scanned.max(start + 1);
            let Some(end) = self.find_byte(from, b'>') else {
                self.scanned = len;
                if len - start > MAX_ELEMENT + 1 {
                    self.skip = Skip::Overlong;
                    self.consume_to(len);
                    return Some(Err(ElementError::TooLong));
                }
                return None;
            };
            self.consume_to(end + 1);
            if end - (start + 1) > MAX_ELEMENT {
                return Some(Err(ElementError::TooLong));
            }
            return Some(Ok(&self.buf[start + 1..end]));
        }
        // Junk: it runs to the next `<`. Reported once, when it ends or is clearly junk (a `>`,
        // a line end, or long); what follows up to the next `<` is dropped without more errors.
        let from = self.scanned.max(start);
        let stop = memchr::memchr3(b'<', b'>', b'\n', &self.buf[from..]);
        let stop = self.found(from, stop);
        let report_to = match stop {
            Some(p) if self.buf[p] == b'<' => Some(p),
            // Clearly junk: it runs to the next `<` if that is here already.
            Some(p) => match self.find_byte(p + 1, b'<') {
                Some(next) => Some(next),
                None => {
                    self.skip = Skip::Junk;
                    Some(len)
                }
            },
            None if len - start >= JUNK_WAIT => {
                self.skip = Skip::Junk;
                Some(len)
            }
            None => None,
        };
        let Some(to) = report_to else {
            self.scanned = len;
            return None;
        };
        let error = ElementError::Outside(excerpt(&self.buf[start..to]));
        self.consume_to(to);
        Some(Err(error))
    }
}

/// An element's inside as text: UTF-8 without `<` (a `<` inside means the earlier `<` started
/// junk).
pub(crate) fn element_text(inside: &[u8]) -> Result<&str, ElementError> {
    match std::str::from_utf8(inside) {
        Ok(_) if memchr::memchr(b'<', inside).is_some() => {
            Err(ElementError::Outside(excerpt(inside)))
        }
        Ok(text) => Ok(text),
        Err(_) => Err(ElementError::NotText),
    }
}

/// The first characters of some garbage, for an error message (never the whole flood).
fn excerpt(bytes: &[u8]) -> String {
    const KEEP: usize = 40;
    let text = String::from_utf8_lossy(bytes);
    let text = text.trim();
    if text.chars().count() > KEEP {
        format!("{}…", text.chars().take(KEEP).collect::<String>())
    } else {
        text.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drain(d: &mut Deframer) -> usize {
        std::iter::from_fn(|| d.next_element()).count()
    }

    /// Feeds `bytes` in reads of `chunk`, taking elements after each; the events and the work.
    fn work(bytes: &[u8], chunk: usize) -> (usize, u64) {
        let mut d = Deframer::new();
        let mut events = 0;
        for c in bytes.chunks(chunk) {
            d.push(c);
            events += drain(&mut d);
        }
        (events, d.bytes_examined())
    }

    #[test]
    fn a_megabyte_of_closing_brackets_is_one_error_in_linear_work() {
        // It was 32 MB of error replies and 15.5 s of CPU: one error per `>`, and the buffer
        // rescanned for every byte.
        let (events, small) = work(&vec![b'>'; 100_000], 16 * 1024);
        assert_eq!(events, 1);
        let (events, large) = work(&vec![b'>'; 1_000_000], 16 * 1024);
        assert_eq!(events, 1);
        assert!(large <= 1_000_000 + 100, "{large} bytes examined");
        // About one look per byte: ten times the input, ten times the work.
        assert!(
            small <= 100_100 && large <= 11 * small,
            "100 KB: {small}, 1 MB: {large}"
        );
    }

    #[test]
    fn an_element_arriving_byte_by_byte_is_scanned_once() {
        let mut text = b"< send 123 8 ".to_vec();
        text.extend(std::iter::repeat_n(b'a', 8000));
        text.push(b'>');
        let (events, examined) = work(&text, 1);
        assert_eq!(events, 1);
        assert!(examined <= text.len() as u64 + 2, "{examined}");
        // Many small elements, and junk between them, in big reads: linear too.
        let many = b"< echo >x< send 1 0 >\n".repeat(50_000);
        let (events, examined) = work(&many, 16 * 1024);
        assert_eq!(events, 3 * 50_000);
        assert!(
            examined <= 2 * many.len() as u64,
            "{examined} for {}",
            many.len()
        );
    }

    #[test]
    fn the_end_of_an_overlong_element_alone_in_a_read_is_dropped() {
        // The `>` that ends an overlong element as the last byte of a read: the stream goes
        // on with the next read (this once left the deframer pointing past its buffer).
        let mut d = Deframer::new();
        d.push(b"<");
        d.push(&vec![b'a'; 20_000]);
        assert_eq!(d.next_element(), Some(Err(ElementError::TooLong)));
        d.push(b"aaa>");
        assert_eq!(d.next_element(), None);
        assert_eq!(d.len(), 0);
        d.push(b"< echo >");
        assert_eq!(d.next_element(), Some(Ok(" echo ".into())));
        assert_eq!(d.next_element(), None);
    }

    #[test]
    fn what_the_end_of_the_stream_leaves_unfinished_is_told_once() {
        let mut d = Deframer::new();
        d.push(b"< send 123 1 11 >< send 123 2 11");
        assert_eq!(d.next_element(), Some(Ok(" send 123 1 11 ".into())));
        assert_eq!(d.next_element(), None);
        assert_eq!(
            d.take_unfinished(),
            Some(("< send 123 2 11".to_string(), 15))
        );
        assert_eq!(d.len(), 0);
        assert_eq!(d.take_unfinished(), None);
        // Whitespace, or the rest of junk already reported, is nothing unfinished.
        d.push(b"< echo >\n  ");
        assert_eq!(d.next_element(), Some(Ok(" echo ".into())));
        assert_eq!(d.next_element(), None);
        assert_eq!(d.take_unfinished(), None);
        d.push(b"> and then more junk without end");
        assert!(matches!(
            d.next_element(),
            Some(Err(ElementError::Outside(_)))
        ));
        d.push(b" still junk");
        assert_eq!(d.next_element(), None);
        assert_eq!(d.take_unfinished(), None);
        // Short junk waits for its end: at the end of the stream it is told.
        d.push(b"hello");
        assert_eq!(d.next_element(), None);
        assert_eq!(d.take_unfinished(), Some(("hello".to_string(), 5)));
    }

    #[test]
    fn overlong_elements_are_one_error_and_the_stream_goes_on() {
        let mut d = Deframer::new();
        d.push(b"<");
        d.push(&vec![b'a'; 20_000]);
        assert_eq!(d.next_element(), Some(Err(ElementError::TooLong)));
        d.push(&vec![b'a'; 20_000]);
        assert_eq!(d.next_element(), None);
        d.push(b"aaa>< echo >");
        assert_eq!(d.next_element(), Some(Ok(" echo ".into())));
        assert!(d.len() < 1024, "{}", d.len());
    }
}
