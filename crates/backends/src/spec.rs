//! candump's interface arguments: a bus name with receive filters,
//! `can0,123:7FF,~0x200:0x700,#FFFFFFFF`.
//!
//! | item | meaning (as candump) |
//! |---|---|
//! | `ID:MASK` | pass a frame when `frame_id & MASK == ID & MASK` |
//! | `ID~MASK` or `~ID:MASK` | pass a frame when it does **not** match |
//! | `#ERRMASK` | pass error frames whose class has a bit of ERRMASK (`#FFFFFFFF`: all) |
//! | `j` or `J` | a frame must pass every filter instead of one |
//!
//! Values are hex, `0x` allowed. As in SocketCAN the frame's ID carries the flags: `0x80000000`
//! extended, `0x40000000` remote. An ID written with 8 digits is an extended ID (the flag is
//! set), so `12345678:1FFFFFFF` passes only extended frames; a mask without the flag bit
//! ignores the format (`123:7FF` passes standard 0x123 and any extended ID ending in 0x123).
//! Without ID filters every frame passes; without `#` (or `-e`) no error frame does.

use std::fmt;
use std::str::FromStr;

use buslab_bus::ErrorFrame;
use buslab_can::{FdFrame, Frame};

use crate::registry::resolve;
use crate::url::{BusUrl, UrlError};

/// SocketCAN's flags in a frame's ID, as candump filters see them.
pub const EFF_FLAG: u32 = 0x8000_0000;
pub const RTR_FLAG: u32 = 0x4000_0000;
pub const ERR_FLAG: u32 = 0x2000_0000;

/// One ID filter with SocketCAN semantics.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct IdFilter {
    /// The ID with its flags (`EFF_FLAG`, `RTR_FLAG`).
    pub id: u32,
    pub mask: u32,
    /// Pass the frames that do not match.
    pub inverted: bool,
}

impl IdFilter {
    pub fn matches(&self, frame: &Frame) -> bool {
        self.matches_can_id(socketcan_id(frame))
    }

    /// Whether a frame with this SocketCAN ID (ID and flags) passes.
    pub fn matches_can_id(&self, can_id: u32) -> bool {
        ((can_id & self.mask) == (self.id & self.mask)) != self.inverted
    }
}

/// An FD frame's ID as SocketCAN gives it to filters (FD has no remote frames).
pub fn fd_socketcan_id(frame: &FdFrame) -> u32 {
    let id = frame.id().as_raw();
    if frame.is_extended() {
        id | EFF_FLAG
    } else {
        id
    }
}

/// A frame's ID as SocketCAN gives it to filters: the ID with the extended and remote flags.
pub fn socketcan_id(frame: &Frame) -> u32 {
    let mut id = frame.id().as_raw();
    if frame.is_extended() {
        id |= EFF_FLAG;
    }
    if frame.is_remote() {
        id |= RTR_FLAG;
    }
    id
}

/// The filters of one interface argument.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub struct FilterSet {
    pub ids: Vec<IdFilter>,
    /// Error classes to pass (`#ERRMASK`); `None`: none asked for here.
    pub error_mask: Option<u32>,
    /// `j`: every filter must pass (instead of any).
    pub join: bool,
}

impl FilterSet {
    /// Whether `frame` passes (every frame does without ID filters).
    pub fn passes(&self, frame: &Frame) -> bool {
        self.passes_can_id(socketcan_id(frame))
    }

    /// Whether an FD frame passes.
    pub fn passes_fd(&self, frame: &FdFrame) -> bool {
        self.passes_can_id(fd_socketcan_id(frame))
    }

    fn passes_can_id(&self, can_id: u32) -> bool {
        if self.ids.is_empty() {
            return true;
        }
        if self.join {
            self.ids.iter().all(|f| f.matches_can_id(can_id))
        } else {
            self.ids.iter().any(|f| f.matches_can_id(can_id))
        }
    }

    /// Whether an error frame passes the error mask (`#ERRMASK`, else `default_mask`).
    pub fn passes_error(&self, error: &ErrorFrame, default_mask: u32) -> bool {
        self.error_mask.unwrap_or(default_mask) & error.class() != 0
    }
}

/// One item after the interface name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FilterItem {
    Id(IdFilter),
    ErrorMask(u32),
    Join,
}

/// A filter item that cannot be read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "filter {text:?}: expected ID:MASK, ID~MASK, ~ID:MASK, #ERRORMASK or j (hex, e.g. 123:7FF, 12345678:1FFFFFFF, #FFFFFFFF)"
)]
pub struct FilterError {
    pub text: String,
}

impl FromStr for FilterItem {
    type Err = FilterError;

    fn from_str(text: &str) -> Result<Self, FilterError> {
        let bad = || FilterError {
            text: text.to_string(),
        };
        if text == "j" || text == "J" {
            return Ok(FilterItem::Join);
        }
        if let Some(mask) = text.strip_prefix('#') {
            return hex(mask).map(FilterItem::ErrorMask).ok_or_else(bad);
        }
        let (body, prefixed) = match text.strip_prefix('~') {
            Some(rest) => (rest, true),
            None => (text, false),
        };
        let (id_text, mask_text, inverted) = if let Some((i, m)) = body.split_once(':') {
            (i, m, prefixed)
        } else if let Some((i, m)) = body.split_once('~') {
            if prefixed {
                return Err(bad());
            }
            (i, m, true)
        } else {
            return Err(bad());
        };
        let mut id = hex(id_text).ok_or_else(bad)?;
        // candump: an ID written with 8 digits is extended.
        if digits(id_text).len() == 8 {
            id |= EFF_FLAG;
        }
        // Error frames are chosen by `#`, never by an ID filter (candump clears the flag).
        let mask = hex(mask_text).ok_or_else(bad)? & !ERR_FLAG;
        Ok(FilterItem::Id(IdFilter { id, mask, inverted }))
    }
}

fn digits(text: &str) -> &str {
    text.strip_prefix("0x")
        .or_else(|| text.strip_prefix("0X"))
        .unwrap_or(text)
}

fn hex(text: &str) -> Option<u32> {
    let d = digits(text);
    // Hex digits only: `from_str_radix` would take a sign (`+7FF`).
    if d.is_empty() || d.len() > 8 || !d.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    u32::from_str_radix(d, 16).ok()
}

/// Filter items as one set.
pub fn filter_set(items: impl IntoIterator<Item = FilterItem>) -> FilterSet {
    let mut set = FilterSet::default();
    for item in items {
        match item {
            FilterItem::Id(f) => set.ids.push(f),
            FilterItem::ErrorMask(m) => set.error_mask = Some(set.error_mask.unwrap_or(0) | m),
            FilterItem::Join => set.join = true,
        }
    }
    set
}

/// An interface argument: a bus (as [`resolve`] reads names) and its filters.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct BusSpec {
    pub url: BusUrl,
    pub filters: FilterSet,
}

/// Why an interface argument cannot be read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SpecError {
    #[error(transparent)]
    Bus(#[from] UrlError),
    #[error(transparent)]
    Filter(#[from] FilterError),
    /// A filter where the bus should be (`123:7FF` alone, or after `--bus URL`).
    #[error(
        "{text:?} is a filter, not a bus: as with candump, a filter follows its bus after a comma: vcan0,{text}, or URL,{text} for a bus given by its URL (--bus takes no filters)"
    )]
    FilterWithoutBus { text: String },
}

impl FromStr for BusSpec {
    type Err = SpecError;

    /// `NAME[,FILTER…]`.
    fn from_str(text: &str) -> Result<Self, SpecError> {
        let mut parts = text.split(',');
        let name = parts.next().unwrap_or_default();
        let url = resolve(name).map_err(|e| {
            // `dump --bus URL 123:7FF`: the filter was given without its bus.
            if name.parse::<FilterItem>().is_ok() {
                SpecError::FilterWithoutBus {
                    text: text.to_string(),
                }
            } else {
                SpecError::Bus(e)
            }
        })?;
        let items = parts
            .map(str::parse)
            .collect::<Result<Vec<FilterItem>, _>>()?;
        Ok(Self {
            url,
            filters: filter_set(items),
        })
    }
}

impl fmt::Display for IdFilter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sep = if self.inverted { '~' } else { ':' };
        write!(f, "{:03X}{sep}{:X}", self.id, self.mask)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(text: &str) -> Frame {
        text.parse().unwrap()
    }

    fn spec(text: &str) -> BusSpec {
        text.parse().unwrap_or_else(|e| panic!("{text}: {e}"))
    }

    #[test]
    fn candump_arguments_parse() {
        let s = spec("can0,123:7FF,~0x200:0x700,#FFFFFFFF");
        assert_eq!(s.url.to_string(), "socketcan:can0");
        assert_eq!(
            s.filters.ids,
            [
                IdFilter {
                    id: 0x123,
                    mask: 0x7FF,
                    inverted: false
                },
                IdFilter {
                    id: 0x200,
                    mask: 0x700,
                    inverted: true
                }
            ]
        );
        assert_eq!(s.filters.error_mask, Some(0xFFFF_FFFF));
        assert_eq!(spec("vcan0").filters, FilterSet::default());
        assert_eq!(
            spec("vcan0,12345678:1FFFFFFF").filters.ids[0].id,
            0x9234_5678,
            "8 digits: extended"
        );
        assert!(spec("vcan0,200~700").filters.ids[0].inverted);
        assert!(spec("vcan0,j,1:1").filters.join);
    }

    #[test]
    fn filters_pass_as_candumps() {
        let one = spec("vcan0,123:7FF").filters;
        assert!(one.passes(&frame("123#")));
        assert!(
            one.passes(&frame("00000123#")),
            "the mask ignores the format"
        );
        assert!(!one.passes(&frame("124#")));
        let sff_only = spec("vcan0,123:C00007FF").filters;
        assert!(sff_only.passes(&frame("123#")));
        assert!(!sff_only.passes(&frame("00000123#")));
        assert!(!sff_only.passes(&frame("123#R")), "RTR flag in the mask");
        let not_2xx = spec("vcan0,~200:700").filters;
        assert!(not_2xx.passes(&frame("123#")));
        assert!(!not_2xx.passes(&frame("2AB#")));
        let either = spec("vcan0,100:7FF,200:7FF").filters;
        assert!(either.passes(&frame("200#")) && !either.passes(&frame("300#")));
        let both = spec("vcan0,100:700,~1FF:7FF,j").filters;
        assert!(both.passes(&frame("100#")) && !both.passes(&frame("1FF#")));
        assert!(spec("vcan0").filters.passes(&frame("7FF#")));
    }

    #[test]
    fn error_masks_choose_classes() {
        let set = spec("vcan0,#8").filters;
        let protocol = ErrorFrame::decode(0x088, &[0; 8]).unwrap();
        let busoff = ErrorFrame::decode(0x040, &[0; 8]).unwrap();
        assert!(set.passes_error(&protocol, 0));
        assert!(!set.passes_error(&busoff, 0));
        assert!(!spec("vcan0").filters.passes_error(&busoff, 0));
        assert!(spec("vcan0").filters.passes_error(&busoff, u32::MAX), "-e");
    }

    #[test]
    fn bad_items_are_named() {
        for bad in [
            "vcan0,123",
            "vcan0,xyz:7FF",
            "vcan0,#",
            "vcan0,~1~2",
            "vcan0,123:123456789",
            "vcan0,+123:7FF",
            "vcan0,123:+7FF",
        ] {
            let err = bad.parse::<BusSpec>().unwrap_err().to_string();
            assert!(err.starts_with("filter \""), "{bad}: {err}");
            assert!(err.contains("expected ID:MASK"), "{bad}: {err}");
        }
        let err = "tcp://x,1:1".parse::<BusSpec>().unwrap_err().to_string();
        assert!(err.contains("unknown backend"), "{err}");
    }

    #[test]
    fn a_filter_given_without_its_bus_suggests_the_bus_first() {
        // `buslab dump --bus URL 123:7FF` said `unknown backend "123"`.
        for (bad, suggested) in [
            ("123:7FF", "vcan0,123:7FF"),
            ("~200:700", "vcan0,~200:700"),
            (
                "12345678:1FFFFFFF,#FFFFFFFF",
                "vcan0,12345678:1FFFFFFF,#FFFFFFFF",
            ),
        ] {
            let err = bad.parse::<BusSpec>().unwrap_err();
            assert!(
                matches!(err, SpecError::FilterWithoutBus { .. }),
                "{bad}: {err:?}"
            );
            let text = err.to_string();
            assert!(text.contains("is a filter, not a bus"), "{bad}: {text}");
            assert!(text.contains(suggested), "{bad}: {text}");
            assert!(text.contains(&format!("URL,{bad}")), "{bad}: {text}");
        }
        // A bus that is wrong for another reason keeps its own error.
        let err = "tcp://x:1".parse::<BusSpec>().unwrap_err();
        assert!(matches!(err, SpecError::Bus(_)), "{err:?}");
    }
}
