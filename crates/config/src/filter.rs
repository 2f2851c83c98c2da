//! The acceptance filter in words: which IDs an ACR/AMR pair lets through ([`explain`]), and
//! the ACR/AMR that let through the IDs someone wants ([`derive()`]), for the SJA1000's three
//! filters (BasicCAN's 8 bits, PeliCAN's single and dual filter). The rules are the
//! datasheet's, as the model applies them (`buslab_sja1000::filter`); the tests hold the two
//! together frame by frame.

use std::fmt;

use buslab_canbus::AcceptanceFilter;

/// IDs whose bits equal `value` wherever `care` has a 1 (the other bits: any).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IdPattern {
    pub value: u32,
    pub care: u32,
    /// 11 (standard) or 29 (extended).
    pub bits: u32,
}

impl IdPattern {
    fn all(bits: u32) -> u32 {
        (1u32 << bits) - 1
    }

    pub fn new(value: u32, care: u32, bits: u32) -> Self {
        let all = Self::all(bits);
        Self {
            value: value & care & all,
            care: care & all,
            bits,
        }
    }

    /// Exactly one ID.
    pub fn exact(id: u32, bits: u32) -> Self {
        Self::new(id, u32::MAX, bits)
    }

    /// The smallest pattern holding `low..=high`: their common leading bits.
    pub fn covering(low: u32, high: u32, bits: u32) -> Self {
        let differ = low ^ high;
        let free = if differ == 0 {
            0
        } else {
            u32::MAX >> differ.leading_zeros()
        };
        Self::new(low, !free, bits)
    }

    pub fn matches(&self, id: u32) -> bool {
        (id ^ self.value) & self.care == 0
    }

    /// How many IDs it holds.
    pub fn count(&self) -> u64 {
        1u64 << (self.bits - (self.care & Self::all(self.bits)).count_ones())
    }

    /// The smallest pattern holding both.
    pub fn merge(&self, other: &Self) -> Self {
        Self::new(
            self.value,
            self.care & other.care & !(self.value ^ other.value),
            self.bits,
        )
    }

    /// IDs both hold.
    fn overlap(&self, other: &Self) -> u64 {
        let both = self.care & other.care;
        if (self.value ^ other.value) & both != 0 {
            return 0;
        }
        1u64 << (self.bits - (self.care | other.care).count_ones())
    }

    /// Its IDs as ranges, at most `max` of them (`None` when there are more).
    pub fn ranges(&self, max: usize) -> Option<Vec<(u32, u32)>> {
        let all = Self::all(self.bits);
        let free = !self.care & all;
        // The don't-care bits below the lowest cared-for one make each range.
        let low = if self.care & all == 0 {
            self.bits
        } else {
            (self.care & all).trailing_zeros()
        };
        let run = (1u32 << low) - 1;
        let scattered = free & !run;
        if scattered.count_ones() as usize > max.max(1).ilog2() as usize {
            return None;
        }
        // Every combination of the scattered bits, in increasing order.
        let mut out = Vec::new();
        let mut sub = 0u32;
        loop {
            let start = self.value | sub;
            out.push((start, start | run));
            if sub == scattered {
                break;
            }
            sub = (sub.wrapping_sub(scattered)) & scattered;
        }
        out.sort_unstable();
        Some(out)
    }
}

/// `0x123`, `0x100..=0x1FF (256 IDs)`, `0x101, 0x103 (2 IDs)`, or the bits:
/// `0b001_0010_xx11 (4 IDs)`.
impl fmt::Display for IdPattern {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let width = if self.bits == 11 { 3 } else { 8 };
        let count = self.count();
        let ranges = self.ranges(8);
        match ranges.as_deref() {
            Some([(a, b)]) if a == b => write!(f, "0x{a:0width$X}"),
            Some(list) => {
                let text: Vec<String> = list
                    .iter()
                    .map(|(a, b)| {
                        if a == b {
                            format!("0x{a:0width$X}")
                        } else {
                            format!("0x{a:0width$X}..=0x{b:0width$X}")
                        }
                    })
                    .collect();
                write!(f, "{} ({count} IDs)", text.join(", "))
            }
            None => {
                f.write_str("0b")?;
                for bit in (0..self.bits).rev() {
                    let c = if self.care >> bit & 1 == 0 {
                        'x'
                    } else if self.value >> bit & 1 == 1 {
                        '1'
                    } else {
                        '0'
                    };
                    write!(f, "{c}")?;
                    if bit > 0 && bit % 4 == 0 {
                        f.write_str("_")?;
                    }
                }
                write!(f, " ({count} IDs, x = any bit)")
            }
        }
    }
}

/// A data byte's condition: the bits in `care` must equal `value`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ByteCondition {
    /// 0 for data byte 1.
    pub index: usize,
    pub value: u8,
    pub care: u8,
}

impl fmt::Display for ByteCondition {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "data byte {} = ", self.index + 1)?;
        let nibble = |shift: u8| -> String {
            let care = self.care >> shift & 0xF;
            let value = self.value >> shift & 0xF;
            match care {
                0xF => format!("{value:X}"),
                0 => "?".into(),
                _ => format!(
                    "[{}]",
                    (0..4)
                        .rev()
                        .map(|b| if care >> b & 1 == 0 {
                            'x'
                        } else if value >> b & 1 == 1 {
                            '1'
                        } else {
                            '0'
                        })
                        .collect::<String>()
                ),
            }
        };
        write!(f, "0x{}{}", nibble(4), nibble(0))
    }
}

/// One way through the filter: frames of one format whose ID fits `ids`, with a condition on
/// RTR and on data bytes (checked only when the frame has the byte).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Clause {
    pub extended: bool,
    pub ids: IdPattern,
    /// `Some(true)`: remote frames only; `Some(false)`: data frames only; `None`: both.
    pub remote: Option<bool>,
    pub data: Vec<ByteCondition>,
}

impl Clause {
    /// Whether a frame passes this clause (the datasheet's rules: a data byte the frame does
    /// not have is not compared).
    pub fn matches(&self, frame: &buslab_can::Frame) -> bool {
        let id = frame.id();
        id.is_extended() == self.extended
            && self.ids.matches(id.as_raw())
            && self.remote.is_none_or(|r| r == frame.is_remote())
            && self.data.iter().all(|c| {
                frame
                    .payload()
                    .get(c.index)
                    .is_none_or(|b| (b ^ c.value) & c.care == 0)
            })
    }
}

impl fmt::Display for Clause {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = if self.extended {
            "extended"
        } else {
            "standard"
        };
        write!(f, "{kind} {}", self.ids)?;
        f.write_str(match self.remote {
            None => ", data and remote frames",
            Some(true) => ", remote frames only",
            Some(false) => ", data frames only",
        })?;
        if !self.data.is_empty() {
            let conditions: Vec<String> = self.data.iter().map(|c| c.to_string()).collect();
            write!(
                f,
                ", with {} (when the frame has it)",
                conditions.join(" and ")
            )?;
        }
        Ok(())
    }
}

/// The ways through a filter: a frame passes if it fits any clause. Empty for a filter that
/// lets everything through ([`AcceptanceFilter::AcceptAll`], or a mask of all ones).
pub fn clauses(filter: &AcceptanceFilter) -> Vec<Clause> {
    let (c, m) = filter.registers();
    if m == [0xFF; 4] {
        return Vec::new();
    }
    let care = m.map(|b| !b);
    let rtr =
        |byte: usize, bit: u8| (care[byte] >> bit & 1 == 1).then_some(c[byte] >> bit & 1 == 1);
    let sff = |hi: usize, lo: usize| {
        IdPattern::new(
            u32::from(c[hi]) << 3 | u32::from(c[lo] >> 5),
            u32::from(care[hi]) << 3 | u32::from(care[lo] >> 5),
            11,
        )
    };
    let byte = |index: usize, value: u8, care: u8| {
        (care != 0).then_some(ByteCondition { index, value, care })
    };
    let clause = |extended, ids, remote, data: Vec<Option<ByteCondition>>| Clause {
        extended,
        ids,
        remote,
        data: data.into_iter().flatten().collect(),
    };
    match filter {
        AcceptanceFilter::AcceptAll => Vec::new(),
        AcceptanceFilter::Basic { code, mask } => vec![clause(
            false,
            IdPattern::new(u32::from(*code) << 3, u32::from(!*mask) << 3, 11),
            None,
            Vec::new(),
        )],
        AcceptanceFilter::Single { .. } => vec![
            clause(
                false,
                sff(0, 1),
                rtr(1, 4),
                vec![byte(0, c[2], care[2]), byte(1, c[3], care[3])],
            ),
            clause(
                true,
                IdPattern::new(
                    u32::from_be_bytes(c) >> 3,
                    u32::from_be_bytes(care) >> 3,
                    29,
                ),
                rtr(3, 2),
                Vec::new(),
            ),
        ],
        AcceptanceFilter::Dual { .. } => {
            let eff16 = |hi: usize, lo: usize| {
                IdPattern::new(
                    u32::from(c[hi]) << 21 | u32::from(c[lo]) << 13,
                    u32::from(care[hi]) << 21 | u32::from(care[lo]) << 13,
                    29,
                )
            };
            let data1 = byte(
                0,
                (c[1] & 0x0F) << 4 | (c[3] & 0x0F),
                (care[1] & 0x0F) << 4 | (care[3] & 0x0F),
            );
            vec![
                clause(false, sff(0, 1), rtr(1, 4), vec![data1]),
                clause(false, sff(2, 3), rtr(3, 4), Vec::new()),
                clause(true, eff16(0, 1), None, Vec::new()),
                clause(true, eff16(2, 3), None, Vec::new()),
            ]
        }
    }
}

/// Several lines: what the filter lets through, one line per way through it.
pub fn explain(filter: &AcceptanceFilter) -> String {
    let ways = clauses(filter);
    if ways.is_empty() {
        return "This filter lets every frame through.".into();
    }
    let mut out = String::from("This filter lets through:");
    for (i, way) in ways.iter().enumerate() {
        let label = match (filter, i) {
            (AcceptanceFilter::Dual { .. }, 0 | 2) => "filter 1: ",
            (AcceptanceFilter::Dual { .. }, _) => "filter 2: ",
            _ => "",
        };
        out.push_str(&format!("\n  {label}{way}"));
    }
    match filter {
        AcceptanceFilter::Basic { .. } => {
            out.push_str("\n  (BasicCAN compares ID.10..3 only and receives no extended frame)")
        }
        AcceptanceFilter::Dual { .. } => {
            out.push_str("\n  (a frame passes if either filter lets it; the dual filter compares the 16 top bits of an extended ID)")
        }
        _ => {}
    }
    out
}

/// An ID or a range of IDs someone wants.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Wanted {
    pub extended: bool,
    pub low: u32,
    pub high: u32,
}

/// The largest list of IDs read.
pub const MAX_WANTED: usize = 64;

/// Reads `123, 100-1FF, 18FEF100`: IDs in hex as candump writes them (`0x` allowed), ranges
/// with `-` or `..`, 8 digits for an extended ID (or any ID above 0x7FF).
pub fn parse_wanted(text: &str) -> Result<Vec<Wanted>, String> {
    const HELP: &str = "IDs in hex as candump writes them, separated by commas or spaces: 123, 100-1FF, 18FEF100 (8 digits or above 7FF: extended)";
    let items: Vec<&str> = text
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .collect();
    if items.is_empty() {
        return Err(format!("give at least one ID: {HELP}"));
    }
    if items.len() > MAX_WANTED {
        return Err(format!("at most {MAX_WANTED} IDs or ranges"));
    }
    let id = |t: &str| -> Result<(u32, bool), String> {
        let digits = t
            .strip_prefix("0x")
            .or_else(|| t.strip_prefix("0X"))
            .unwrap_or(t);
        let bad = || format!("{t:?} is not an ID: {HELP}");
        if digits.is_empty() || digits.len() > 8 || !digits.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(bad());
        }
        let n = u32::from_str_radix(digits, 16).map_err(|_| bad())?;
        if n > 0x1FFF_FFFF {
            return Err(format!("{t:?} is above 1FFFFFFF, the largest extended ID"));
        }
        Ok((n, digits.len() == 8 || n > 0x7FF))
    };
    let mut out = Vec::new();
    for item in items {
        let (a, b) = match item.split_once("..").or_else(|| item.split_once('-')) {
            Some((a, b)) => (a, b.trim_start_matches('=')),
            None => (item, item),
        };
        let ((low, ext_a), (high, ext_b)) = (id(a)?, id(b)?);
        if low > high {
            return Err(format!("{item:?}: the range goes down"));
        }
        out.push(Wanted {
            extended: ext_a || ext_b,
            low,
            high,
        });
    }
    Ok(out)
}

/// A filter derived from wanted IDs, with what it lets through beyond them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Derived {
    pub filter: AcceptanceFilter,
    /// IDs wanted (ranges merged).
    pub wanted: u64,
    /// IDs it lets through that were not asked for (data and remote frames alike).
    pub extra: u64,
}

/// Which filter to derive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Basic,
    Single,
    Dual,
}

/// The ACR/AMR of `kind` that let through every wanted ID (data and remote frames, any data)
/// and as few others as the filter can: one pattern for the single and BasicCAN filters, the
/// best split of the IDs in two for the dual filter. IDs of one format only (a filter's bits
/// mean ID bits of either format at once).
pub fn derive(kind: Kind, wanted: &[Wanted]) -> Result<Derived, String> {
    let extended = wanted.first().is_some_and(|w| w.extended);
    if wanted.iter().any(|w| w.extended != extended) {
        return Err(
            "give standard or extended IDs, not both: the filter's bits stand for ID bits of either format at once".into(),
        );
    }
    if extended && kind == Kind::Basic {
        return Err("BasicCAN receives no extended frame: give standard IDs (000..7FF)".into());
    }
    let bits = if extended { 29 } else { 11 };
    let mut ranges: Vec<(u32, u32)> = wanted.iter().map(|w| (w.low, w.high)).collect();
    ranges.sort_unstable();
    let mut merged: Vec<(u32, u32)> = Vec::new();
    for (a, b) in ranges {
        match merged.last_mut() {
            Some((_, end)) if a <= end.saturating_add(1) => *end = (*end).max(b),
            _ => merged.push((a, b)),
        }
    }
    let count: u64 = merged.iter().map(|(a, b)| u64::from(b - a) + 1).sum();
    // What each filter can compare: BasicCAN the 8 top bits, the dual filter's extended
    // frames the 16 top bits.
    let comparable = match (kind, extended) {
        (Kind::Basic, _) => 0x7F8,
        (Kind::Dual, true) => 0x1FFF_E000,
        _ => IdPattern::all(bits),
    };
    let cover = |list: &[(u32, u32)]| -> IdPattern {
        let mut p = IdPattern::covering(list[0].0, list[0].1, bits);
        for &(a, b) in &list[1..] {
            p = p.merge(&IdPattern::covering(a, b, bits));
        }
        IdPattern::new(p.value, p.care & comparable, bits)
    };
    let (first, second) = match kind {
        Kind::Dual => {
            let whole = cover(&merged);
            let mut best = (whole, whole, whole.count());
            for k in 1..merged.len() {
                let (a, b) = (cover(&merged[..k]), cover(&merged[k..]));
                let total = a.count() + b.count() - a.overlap(&b);
                if total < best.2 {
                    best = (a, b, total);
                }
            }
            (best.0, best.1)
        }
        _ => {
            let p = cover(&merged);
            (p, p)
        }
    };
    let filter = registers(kind, extended, &first, &second);
    let passed = if first == second {
        first.count()
    } else {
        first.count() + second.count() - first.overlap(&second)
    };
    Ok(Derived {
        filter,
        wanted: count,
        extra: passed.saturating_sub(count),
    })
}

/// ACR/AMR for one pattern (or two, dual) of one format; RTR and data bytes: any.
fn registers(
    kind: Kind,
    extended: bool,
    first: &IdPattern,
    second: &IdPattern,
) -> AcceptanceFilter {
    let dc = |p: &IdPattern| !p.care;
    match (kind, extended) {
        (Kind::Basic, _) => AcceptanceFilter::Basic {
            code: (first.value >> 3) as u8,
            mask: (dc(first) >> 3) as u8,
        },
        (Kind::Single, false) => {
            let code = first.value << 21;
            let mask = dc(first) << 21 | 0x001F_FFFF;
            AcceptanceFilter::Single {
                code: code.to_be_bytes(),
                mask: mask.to_be_bytes(),
            }
        }
        (Kind::Single, true) => AcceptanceFilter::Single {
            code: (first.value << 3).to_be_bytes(),
            mask: (dc(first) << 3 | 0x7).to_be_bytes(),
        },
        (Kind::Dual, false) => {
            let half = |p: &IdPattern| ((p.value << 5) as u16, ((dc(p) << 5) as u16) | 0x1F);
            let (c1, m1) = half(first);
            let (c2, m2) = half(second);
            AcceptanceFilter::Dual {
                code: [(c1 >> 8) as u8, c1 as u8, (c2 >> 8) as u8, c2 as u8],
                mask: [(m1 >> 8) as u8, m1 as u8, (m2 >> 8) as u8, m2 as u8],
            }
        }
        (Kind::Dual, true) => {
            let half = |p: &IdPattern| ((p.value >> 13) as u16, (dc(p) >> 13) as u16);
            let (c1, m1) = half(first);
            let (c2, m2) = half(second);
            AcceptanceFilter::Dual {
                code: [(c1 >> 8) as u8, c1 as u8, (c2 >> 8) as u8, c2 as u8],
                mask: [(m1 >> 8) as u8, m1 as u8, (m2 >> 8) as u8, m2 as u8],
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use buslab_can::Frame;

    fn frame(text: &str) -> Frame {
        text.parse().unwrap()
    }

    /// Standard frames of every ID, as data (no byte, two bytes) and remote frames.
    fn standard_frames() -> impl Iterator<Item = Frame> {
        (0..0x800u32).flat_map(|id| {
            [
                frame(&format!("{id:03X}#")),
                frame(&format!("{id:03X}#5A3C")),
                frame(&format!("{id:03X}#A5")),
                frame(&format!("{id:03X}#R")),
            ]
        })
    }

    fn extended_frames() -> impl Iterator<Item = Frame> {
        let mut x = 0x2545_F491u32;
        (0..4000).flat_map(move |i| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            let id = if i % 2 == 0 {
                x & 0x1FFF_FFFF
            } else {
                (x & 0x1FFF) | 0x0246_0000
            };
            [
                frame(&format!("{id:08X}#11")),
                frame(&format!("{id:08X}#R")),
            ]
        })
    }

    /// The explanation and the model agree on every frame.
    fn agrees(filter: AcceptanceFilter) {
        let ways = clauses(&filter);
        for f in standard_frames().chain(extended_frames()) {
            let explained = ways.is_empty() || ways.iter().any(|w| w.matches(&f));
            assert_eq!(
                explained,
                filter.accepts(&f),
                "{filter:?} on {f}: the explanation says {explained}\n{}",
                explain(&filter)
            );
        }
    }

    #[test]
    fn the_explanation_is_the_model_s_filter_frame_by_frame() {
        let mut x = 0x1234_5678u32;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x
        };
        for _ in 0..24 {
            let (code, mask) = (next().to_be_bytes(), (next() | next()).to_be_bytes());
            agrees(AcceptanceFilter::Single { code, mask });
            agrees(AcceptanceFilter::Dual { code, mask });
            agrees(AcceptanceFilter::Basic {
                code: code[0],
                mask: mask[0] & 0x3C,
            });
        }
        agrees(AcceptanceFilter::AcceptAll);
        agrees(AcceptanceFilter::standard_id(0x123));
        agrees(AcceptanceFilter::extended_id(0x18FE_F100));
    }

    /// The issue's example: ACR 0x123, AMR 0x001FFFFF (single) lets only ID 0x000 of the
    /// standard ones through, which the raw registers did not say.
    #[test]
    fn the_issue_s_registers_are_explained_as_the_ids_they_let_through() {
        let filter = AcceptanceFilter::Single {
            code: 0x0000_0123u32.to_be_bytes(),
            mask: 0x001F_FFFFu32.to_be_bytes(),
        };
        let text = explain(&filter);
        assert!(
            text.contains("standard 0x000, data and remote frames"),
            "{text}"
        );
        assert!(
            text.contains("extended 0x00000000..=0x0003FFFF (262144 IDs)"),
            "{text}"
        );
        let basic = explain(&AcceptanceFilter::Basic {
            code: 0xE0,
            mask: 0x0F,
        });
        assert!(
            basic.contains("standard 0x700..=0x77F (128 IDs)"),
            "{basic}"
        );
        let dual = explain(&AcceptanceFilter::Dual {
            code: [0x20, 0x05, 0x40, 0x00],
            mask: [0x00, 0x00, 0x00, 0x1F],
        });
        assert!(
            dual.contains("filter 1: standard 0x100, data frames only, with data byte 1 = 0x5? (when the frame has it)"),
            "{dual}"
        );
        assert!(
            dual.contains("filter 2: standard 0x200, data and remote frames"),
            "{dual}"
        );
    }

    #[test]
    fn wanted_ids_are_read_as_candump_writes_them() {
        assert_eq!(
            parse_wanted("123, 100-1FF 0x7FF..0x7FF 18FEF100"),
            Ok(vec![
                Wanted {
                    extended: false,
                    low: 0x123,
                    high: 0x123
                },
                Wanted {
                    extended: false,
                    low: 0x100,
                    high: 0x1FF
                },
                Wanted {
                    extended: false,
                    low: 0x7FF,
                    high: 0x7FF
                },
                Wanted {
                    extended: true,
                    low: 0x18FE_F100,
                    high: 0x18FE_F100
                },
            ])
        );
        for bad in ["", "xyz", "200-100", "123456789", "2FFFFFFF", "-", "1-2-3"] {
            assert!(parse_wanted(bad).is_err(), "{bad:?}");
        }
        let many = vec!["1"; MAX_WANTED + 1].join(",");
        assert!(parse_wanted(&many).unwrap_err().contains("at most"));
    }

    /// What a derived filter lets through holds every ID asked for, and the count of the
    /// others is right.
    fn check_derived(kind: Kind, text: &str, extra: u64) {
        let wanted = parse_wanted(text).unwrap();
        let d = derive(kind, &wanted).unwrap();
        assert_eq!(
            d.extra,
            extra,
            "{kind:?} {text}: {d:?}\n{}",
            explain(&d.filter)
        );
        if wanted[0].extended {
            for w in &wanted {
                for id in [w.low, w.high] {
                    assert!(d.filter.accepts(&frame(&format!("{id:08X}#01"))), "{id:X}");
                }
            }
            return;
        }
        let mut passed = 0;
        for id in 0..0x800u32 {
            let asked = wanted.iter().any(|w| (w.low..=w.high).contains(&id));
            let data = d.filter.accepts(&frame(&format!("{id:03X}#5A3C")));
            let remote = d.filter.accepts(&frame(&format!("{id:03X}#R")));
            assert_eq!(data, remote, "{id:X}: data and remote alike");
            if asked {
                assert!(data, "{kind:?} {text}: {id:X} asked for and refused");
            }
            passed += u64::from(data);
        }
        assert_eq!(passed, d.wanted + d.extra, "{kind:?} {text}");
    }

    #[test]
    fn filters_derived_from_the_ids_wanted_let_them_through() {
        check_derived(Kind::Single, "100-1FF", 0);
        check_derived(Kind::Single, "123", 0);
        check_derived(Kind::Single, "120-12F, 7FF", 512 - 17);
        check_derived(Kind::Dual, "120-12F, 7FF", 0);
        check_derived(Kind::Dual, "100, 101, 300, 301", 0);
        check_derived(Kind::Dual, "100-102", 1);
        check_derived(Kind::Basic, "700-77F", 0);
        check_derived(Kind::Basic, "123", 7);
        check_derived(Kind::Single, "18FEF100", 0);
        check_derived(Kind::Dual, "18FEF100", 8191);
        assert!(derive(Kind::Basic, &parse_wanted("18FEF100").unwrap()).is_err());
        assert!(derive(Kind::Single, &parse_wanted("123 18FEF100").unwrap()).is_err());
    }
}
