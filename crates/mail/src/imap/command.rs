//! The few commands the notifier sends, as bytes: a tag, words, and strings quoted or sent
//! as literals. A command with a literal is cut into parts: each part but the last ends with
//! `{N}` and CRLF, and the next is sent only when the server asks for it with `+`.

use thiserror::Error;

/// A user name, password or mailbox name that no IMAP string can carry.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[error("{what} cannot be sent to an IMAP server: it contains a NUL byte")]
pub struct Unsendable {
    pub what: &'static str,
}

/// A command being written.
#[derive(Debug)]
pub struct Command {
    parts: Vec<Vec<u8>>,
}

impl Command {
    pub fn new(tag: &str, words: &str) -> Self {
        Self {
            parts: vec![format!("{tag} {words}").into_bytes()],
        }
    }

    fn current(&mut self) -> &mut Vec<u8> {
        self.parts.last_mut().expect("a command has a part")
    }

    /// A space, then `value` as an atom, a quoted string or a literal, whichever IMAP needs.
    pub fn string(mut self, value: &str, what: &'static str) -> Result<Self, Unsendable> {
        let bytes = value.as_bytes();
        self.current().push(b' ');
        if bytes.contains(&0) {
            return Err(Unsendable { what });
        }
        let atom = |b: &u8| b.is_ascii_alphanumeric() || b"-._@".contains(b);
        let quotable = |b: &u8| b.is_ascii() && !b.is_ascii_control();
        if !bytes.is_empty() && bytes.iter().all(atom) {
            self.current().extend_from_slice(bytes);
        } else if bytes.iter().all(quotable) {
            let part = self.current();
            part.push(b'"');
            for &b in bytes {
                if b == b'"' || b == b'\\' {
                    part.push(b'\\');
                }
                part.push(b);
            }
            part.push(b'"');
        } else {
            let announce = format!("{{{}}}\r\n", bytes.len());
            self.current().extend_from_slice(announce.as_bytes());
            self.parts.push(bytes.to_vec());
        }
        Ok(self)
    }

    /// The parts to send, CRLF ending the last one.
    pub fn finish(mut self) -> Vec<Vec<u8>> {
        self.current().extend_from_slice(b"\r\n");
        self.parts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(parts: Vec<Vec<u8>>) -> Vec<String> {
        parts
            .into_iter()
            .map(|p| String::from_utf8(p).unwrap())
            .collect()
    }

    #[test]
    fn strings_are_atoms_quoted_or_literals() {
        let login = |user: &str, password: &str| {
            Command::new("b1", "LOGIN")
                .string(user, "the user name")
                .and_then(|c| c.string(password, "the password"))
                .map(|c| text(c.finish()))
        };
        assert_eq!(
            login("alice", "s3cret").unwrap(),
            ["b1 LOGIN alice s3cret\r\n"]
        );
        assert_eq!(
            login("a b", r#"q"u\o"#).unwrap(),
            ["b1 LOGIN \"a b\" \"q\\\"u\\\\o\"\r\n"]
        );
        assert_eq!(login("", "x").unwrap(), ["b1 LOGIN \"\" x\r\n"]);
        assert_eq!(
            login("bob", "pässword").unwrap(),
            ["b1 LOGIN bob {9}\r\n", "pässword\r\n"]
        );
        assert_eq!(
            login("bob", "line\r\nbreak").unwrap(),
            ["b1 LOGIN bob {11}\r\n", "line\r\nbreak\r\n"]
        );
        assert_eq!(
            login("bob", "nul\0"),
            Err(Unsendable {
                what: "the password"
            })
        );
    }
}
