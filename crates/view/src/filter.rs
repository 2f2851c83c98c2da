//! Which frames a log shows: candump's `ID:MASK` (and `ID~MASK`, inverted) filters, and its
//! `#MASK` for error frames.

use std::fmt;
use std::str::FromStr;

use buslab_bus::ErrorFrame;
use buslab_can::{Frame, Id};

/// One or more filters, comma-separated, any of which lets a frame through; empty: every
/// frame and every error frame.
///
/// `123` (exactly that ID), `120:7F0` (candump's ID and mask), `300~700` (every frame that
/// does NOT match). An ID of more than three hex digits is extended. `#MASK` lets the error
/// frames through that have a class bit in MASK (`#FFFFFFFF`: all, `#080`: bus errors), as
/// candump's error filter; a filter without one shows no error frames.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LogFilter {
    rules: Vec<Rule>,
    /// The class bits of error frames let through (0: none, unless there are no rules).
    error_mask: u32,
    text: String,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Rule {
    id: u32,
    mask: u32,
    extended: bool,
    invert: bool,
}

/// A filter that cannot be read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FilterError {
    #[error(
        "filter {0:?}: expected ID, ID:MASK or ID~MASK in hex (e.g. 123, 120:7F0, 18FF0010:1FFFFFFF)"
    )]
    Syntax(String),
    #[error("filter {text:?}: ID {id:X} is above {max:X}")]
    Range { text: String, id: u32, max: u32 },
    #[error("filter {0:?} is longer than 256 characters")]
    TooLong(String),
    #[error(
        "filter {0:?}: expected #MASK, the error classes in hex (e.g. #FFFFFFFF for every error frame, #080 for bus errors)"
    )]
    ErrorMask(String),
}

impl LogFilter {
    /// Lets every frame through.
    pub fn all() -> Self {
        Self::default()
    }

    pub fn is_all(&self) -> bool {
        self.rules.is_empty() && self.error_mask == 0
    }

    pub fn matches(&self, frame: &Frame) -> bool {
        self.matches_id(frame.id())
    }

    /// Whether a frame with this ID (classic or CAN FD) passes.
    pub fn matches_id(&self, id: Id) -> bool {
        if self.is_all() {
            return true;
        }
        let (raw, extended) = (id.as_raw(), id.is_extended());
        self.rules.iter().any(|r| {
            let hit = r.extended == extended && (raw ^ r.id) & r.mask == 0;
            hit != r.invert
        })
    }

    /// Whether an error frame passes: every one with no filter at all, else those with a
    /// class in the filter's `#MASK`.
    pub fn matches_error(&self, error: &ErrorFrame) -> bool {
        self.is_all() || error.class() & self.error_mask != 0
    }
}

impl FromStr for LogFilter {
    type Err = FilterError;

    fn from_str(text: &str) -> Result<Self, FilterError> {
        let text = text.trim();
        if text.len() > 256 {
            return Err(FilterError::TooLong(text.chars().take(40).collect()));
        }
        let mut rules = Vec::new();
        let mut error_mask = 0;
        for part in text.split([',', ' ']).filter(|p| !p.is_empty()) {
            if let Some(mask) = part.strip_prefix('#') {
                let bad = || FilterError::ErrorMask(part.to_string());
                if mask.is_empty() || mask.len() > 8 || !mask.bytes().all(|b| b.is_ascii_hexdigit())
                {
                    return Err(bad());
                }
                error_mask |= u32::from_str_radix(mask, 16).map_err(|_| bad())?;
                continue;
            }
            let syntax = || FilterError::Syntax(part.to_string());
            let (id_text, mask_text, invert) = match part.split_once([':', '~']) {
                Some((id, mask)) => (id, Some(mask), part.contains('~')),
                None => (part, None, false),
            };
            let hex = |t: &str| {
                if t.is_empty() || t.len() > 8 || !t.bytes().all(|b| b.is_ascii_hexdigit()) {
                    Err(syntax())
                } else {
                    u32::from_str_radix(t, 16).map_err(|_| syntax())
                }
            };
            let id = hex(id_text)?;
            let extended = id_text.len() > 3;
            let max = if extended { 0x1FFF_FFFF } else { 0x7FF };
            if id > max {
                return Err(FilterError::Range {
                    text: part.to_string(),
                    id,
                    max,
                });
            }
            let mask = match mask_text {
                Some(m) => hex(m)? & max,
                None => max,
            };
            rules.push(Rule {
                id,
                mask,
                extended,
                invert,
            });
        }
        Ok(Self {
            rules,
            error_mask,
            text: text.to_string(),
        })
    }
}

impl fmt::Display for LogFilter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn f(s: &str) -> Frame {
        s.parse().unwrap()
    }

    #[test]
    fn candump_filters_select_frames() {
        let all: LogFilter = "".parse().unwrap();
        assert!(all.is_all() && all.matches(&f("7FF#")));
        let one: LogFilter = "123".parse().unwrap();
        assert!(one.matches(&f("123#11")) && !one.matches(&f("124#11")));
        assert!(!one.matches(&f("00000123#")), "a 3-digit ID is standard");
        let range: LogFilter = "120:7F0, 18FF0010".parse().unwrap();
        assert!(range.matches(&f("12F#")) && range.matches(&f("18FF0010#A5")));
        assert!(!range.matches(&f("130#")));
        let not: LogFilter = "200~7FF".parse().unwrap();
        assert!(!not.matches(&f("200#00")) && not.matches(&f("080#01")));
    }

    #[test]
    fn error_frames_pass_no_filter_or_a_filter_naming_their_class() {
        let bus_error = ErrorFrame::decode(0x088, &[]).unwrap();
        let bus_off = ErrorFrame::decode(0x040, &[]).unwrap();
        assert!(LogFilter::all().matches_error(&bus_error));
        let ids: LogFilter = "123".parse().unwrap();
        assert!(
            !ids.matches_error(&bus_error),
            "as candump: IDs alone show no errors"
        );
        let both: LogFilter = "123, #080".parse().unwrap();
        assert!(both.matches_error(&bus_error) && !both.matches_error(&bus_off));
        assert!(both.matches(&f("123#")) && !both.matches(&f("124#")));
        let errors_only: LogFilter = "#FFFFFFFF".parse().unwrap();
        assert!(errors_only.matches_error(&bus_off));
        assert!(
            !errors_only.matches(&f("123#")),
            "an error mask alone shows no frames"
        );
        for bad in ["#", "#XYZ", "#123456789"] {
            let e = bad.parse::<LogFilter>().unwrap_err().to_string();
            assert!(e.contains("#MASK") && e.contains(bad), "{e}");
        }
    }

    #[test]
    fn bad_filters_name_the_part_and_the_rule() {
        for (text, want) in [
            ("12G", "filter \"12G\": expected ID"),
            ("800", "ID 800 is above 7FF"),
            ("123:", "filter \"123:\""),
            ("123456789", "filter \"123456789\""),
        ] {
            let err = text.parse::<LogFilter>().unwrap_err().to_string();
            assert!(err.contains(want), "{text}: {err}");
        }
        assert!(matches!(
            "1,".repeat(200).parse::<LogFilter>(),
            Err(FilterError::TooLong(_))
        ));
    }
}
