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

/// Collects bytes and hands out complete elements (the text between `<` and `>`).
#[derive(Debug, Default)]
pub struct Deframer {
    buf: Vec<u8>,
}

impl Deframer {
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// Bytes buffered.
    pub fn len(&self) -> usize {
        self.buf.len()
    }

    /// Whether an unfinished element is buffered.
    pub fn is_empty(&self) -> bool {
        self.buf.iter().all(|b| b.is_ascii_whitespace())
    }

    /// The next complete element's inside (without `<` and `>`), an error for bytes that are
    /// not part of one, or `None` if more bytes are needed.
    pub fn next_element(&mut self) -> Option<Result<String, ElementError>> {
        let start = self.buf.iter().position(|&b| b == b'<');
        let junk_end = start.unwrap_or(self.buf.len());
        // Whitespace between elements (python-can and socketcand send none, telnet users a
        // newline) is fine; anything else before a `<` is garbage.
        if self.buf[..junk_end]
            .iter()
            .any(|b| !b.is_ascii_whitespace())
        {
            // Wait for the `<` that ends the junk, unless it is already long.
            if start.is_none() && self.buf.len() < MAX_ELEMENT && !self.buf.contains(&b'>') {
                return None;
            }
            let end = start.unwrap_or_else(|| {
                self.buf
                    .iter()
                    .position(|&b| b == b'>')
                    .map_or(self.buf.len(), |p| p + 1)
            });
            let junk: Vec<u8> = self.buf.drain(..end).collect();
            return Some(Err(ElementError::Outside(excerpt(&junk))));
        }
        let start = match start {
            Some(s) => s,
            None => {
                self.buf.clear();
                return None;
            }
        };
        self.buf.drain(..start);
        let Some(end) = self.buf.iter().position(|&b| b == b'>') else {
            if self.buf.len() > MAX_ELEMENT {
                self.buf.clear();
                return Some(Err(ElementError::TooLong));
            }
            return None;
        };
        let element: Vec<u8> = self.buf.drain(..=end).collect();
        let inner = &element[1..element.len() - 1];
        if inner.len() > MAX_ELEMENT {
            return Some(Err(ElementError::TooLong));
        }
        Some(
            String::from_utf8(inner.to_vec())
                .map_err(|_| ElementError::NotText)
                .and_then(|s| {
                    if s.contains('<') {
                        // `<` inside an element: the earlier `<` started garbage.
                        Err(ElementError::Outside(excerpt(s.as_bytes())))
                    } else {
                        Ok(s)
                    }
                }),
        )
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
