//! Motorola S-records, every kind (S0–S9): one record per line, `S`, the type digit, the byte
//! count, the address (2, 3 or 4 bytes), the data, and a checksum (the ones' complement of the
//! low byte of the sum of the count, address and data bytes).
//!
//! | type | address | meaning |
//! |---|---|---|
//! | S0 | 2 bytes | header (its data is free text, usually a name) |
//! | S1, S2, S3 | 2, 3, 4 bytes | data at that address |
//! | S4 | — | reserved: refused |
//! | S5, S6 | 2, 3 bytes | count of the S1/S2/S3 records before it |
//! | S7, S8, S9 | 4, 3, 2 bytes | start address (entry point); ends the file |
//!
//! [`parse`] reads a whole file and checks every record; [`write()`] makes one (the PowerPC
//! node keeps its memory image in this format). Lines end with LF or CR LF; blank lines are
//! allowed; anything else that is not a record is an error naming its line.

use std::fmt;

/// The longest line a record can make: `S`, type, count, then 255 bytes in hex.
pub const MAX_RECORD_CHARS: usize = 4 + 2 * 255;
/// Errors kept from one file; beyond, they are counted (a file of garbage has one per line).
pub const MAX_ERRORS: usize = 20;
/// Data bytes per record in files [`write()`] makes.
pub const WRITE_CHUNK: usize = 32;

/// How many address bytes a record type has.
fn address_bytes(kind: u8) -> Option<usize> {
    match kind {
        b'0' | b'1' | b'5' | b'9' => Some(2),
        b'2' | b'6' | b'8' => Some(3),
        b'3' | b'7' => Some(4),
        _ => None,
    }
}

/// One record, decoded.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Record {
    /// S0: free text (a module name, a version).
    Header(Vec<u8>),
    /// S1, S2, S3: `data` goes at `address`.
    Data { address: u32, data: Vec<u8> },
    /// S5, S6: the number of data records before it.
    Count(u32),
    /// S7, S8, S9: the entry point; the last record.
    Start(u32),
}

/// What is wrong with one line.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Problem {
    #[error("starts with {0:?}, not 'S' (a record is S, a type digit 0..9, then hex digits)")]
    NotARecord(char),
    #[error("record type {0:?} is not a digit 0..9")]
    BadType(char),
    #[error("S4 is a reserved record type (S0..S3 and S5..S9 are records)")]
    Reserved,
    #[error("{len} characters: too short for a record (S, type, count, address, checksum)")]
    TooShort { len: usize },
    #[error("{len} characters: longer than any record ({MAX_RECORD_CHARS} at most)")]
    TooLong { len: usize },
    #[error("character {found:?} at column {column} is not a hex digit")]
    NotHex { found: char, column: usize },
    #[error("an odd number of hex digits ({0}): records are whole bytes")]
    OddDigits(usize),
    #[error("the byte count says {count} bytes follow, but the line has {actual}")]
    CountMismatch { count: usize, actual: usize },
    #[error(
        "the byte count {count} is too small for an S{kind} record ({needed} at least: address and checksum)"
    )]
    CountTooSmall {
        kind: char,
        count: usize,
        needed: usize,
    },
    #[error("checksum 0x{stated:02X}, but the record's bytes give 0x{computed:02X}")]
    Checksum { stated: u8, computed: u8 },
    #[error("an S{0} record carries no data, but this one has {1} bytes")]
    UnexpectedData(char, usize),
    #[error(
        "data at 0x{address:X} ({len} bytes) runs past the end of the {bits}-bit address space"
    )]
    Wraps { address: u32, len: usize, bits: u32 },
    #[error("a header record (S0) must come first")]
    LateHeader,
    #[error("the count record says {stated} data records, but {actual} came before it")]
    WrongCount { stated: u32, actual: usize },
    #[error("a record after the start record of line {0} (S7/S8/S9 ends the file)")]
    AfterStart(usize),
    #[error("0x{start:08X}..=0x{end:08X} is {what}")]
    Address { start: u32, end: u32, what: String },
    #[error("0x{start:08X}..=0x{end:08X} overlaps the data of line {other}")]
    Overlap { start: u32, end: u32, other: usize },
}

/// A bad line: its number (from 1) and what is wrong.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("line {line}: {problem}")]
pub struct SrecError {
    pub line: usize,
    pub problem: Problem,
}

/// Every bad line of a file (the first [`MAX_ERRORS`], and how many more).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SrecErrors {
    pub errors: Vec<SrecError>,
    /// Errors beyond [`MAX_ERRORS`], counted only.
    pub more: usize,
}

impl SrecErrors {
    pub fn push(&mut self, line: usize, problem: Problem) {
        if self.errors.len() < MAX_ERRORS {
            self.errors.push(SrecError { line, problem });
        } else {
            self.more += 1;
        }
    }

    pub fn is_empty(&self) -> bool {
        self.errors.is_empty()
    }

    /// All of them, counted.
    pub fn count(&self) -> usize {
        self.errors.len() + self.more
    }

    /// The first bad line.
    pub fn first(&self) -> Option<&SrecError> {
        self.errors.first()
    }
}

impl fmt::Display for SrecErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, e) in self.errors.iter().enumerate() {
            if i > 0 {
                f.write_str("\n")?;
            }
            write!(f, "{e}")?;
        }
        if self.more > 0 {
            write!(f, "\n… and {} more bad lines", self.more)?;
        }
        Ok(())
    }
}

impl std::error::Error for SrecErrors {}

/// A run of data bytes from one data record.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Segment {
    pub address: u32,
    pub data: Vec<u8>,
    /// The line it came from.
    pub line: usize,
}

impl Segment {
    /// The last address it writes (`None` for an empty record).
    pub fn end(&self) -> Option<u32> {
        let len = u32::try_from(self.data.len()).ok()?;
        len.checked_sub(1).map(|l| self.address.wrapping_add(l))
    }
}

/// A whole S-record file, every record checked.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Program {
    /// The S0 record's text, if any.
    pub header: Option<Vec<u8>>,
    /// The data records in file order.
    pub segments: Vec<Segment>,
    /// The entry point of the S7/S8/S9 record, if any.
    pub start: Option<u32>,
    /// Records in the file (blank lines not counted).
    pub records: usize,
}

impl Program {
    /// Data bytes in all.
    pub fn data_bytes(&self) -> usize {
        self.segments.iter().map(|s| s.data.len()).sum()
    }

    /// The header as text (non-printable bytes as `?`).
    pub fn header_text(&self) -> Option<String> {
        self.header.as_ref().map(|h| printable(h))
    }

    /// The address ranges written, merged where they touch, in address order (inclusive).
    pub fn ranges(&self) -> Vec<(u32, u32)> {
        let mut spans: Vec<(u32, u32)> = self
            .segments
            .iter()
            .filter_map(|s| s.end().map(|e| (s.address, e)))
            .collect();
        spans.sort_unstable();
        let mut merged: Vec<(u32, u32)> = Vec::new();
        for (start, end) in spans {
            match merged.last_mut() {
                Some(last) if u64::from(start) <= u64::from(last.1) + 1 => {
                    last.1 = last.1.max(end);
                }
                _ => merged.push((start, end)),
            }
        }
        merged
    }

    /// Records that write the same address twice: the later line is named, with the earlier.
    pub fn overlaps(&self) -> SrecErrors {
        let mut spans: Vec<(u32, u32, usize)> = self
            .segments
            .iter()
            .filter_map(|s| s.end().map(|e| (s.address, e, s.line)))
            .collect();
        spans.sort_unstable();
        let mut errors = SrecErrors::default();
        let mut reach: Option<(u32, usize)> = None;
        let mut found = Vec::new();
        for (start, end, line) in spans {
            if let Some((last_end, last_line)) = reach
                && start <= last_end
            {
                let (later, earlier) = if line > last_line {
                    (line, last_line)
                } else {
                    (last_line, line)
                };
                found.push((later, start, end.min(last_end), earlier));
            }
            if reach.is_none_or(|(e, _)| end > e) {
                reach = Some((end, line));
            }
        }
        found.sort_unstable();
        for (line, start, end, other) in found {
            errors.push(line, Problem::Overlap { start, end, other });
        }
        errors
    }
}

/// Bytes as text, anything but printable ASCII as `?`.
pub fn printable(bytes: &[u8]) -> String {
    bytes
        .iter()
        .map(|&b| {
            if b.is_ascii_graphic() || b == b' ' {
                b as char
            } else {
                '?'
            }
        })
        .collect()
}

fn hex_value(b: u8) -> Option<u8> {
    match b {
        b'0'..=b'9' => Some(b - b'0'),
        b'a'..=b'f' => Some(b - b'a' + 10),
        b'A'..=b'F' => Some(b - b'A' + 10),
        _ => None,
    }
}

/// One line (without its line ending) as a record.
pub fn parse_record(line: &[u8]) -> Result<Record, Problem> {
    let len = line.len();
    if len > MAX_RECORD_CHARS {
        return Err(Problem::TooLong { len });
    }
    let Some(&first) = line.first() else {
        return Err(Problem::TooShort { len });
    };
    if first != b'S' && first != b's' {
        return Err(Problem::NotARecord(first as char));
    }
    let Some(&kind) = line.get(1) else {
        return Err(Problem::TooShort { len });
    };
    if kind == b'4' {
        return Err(Problem::Reserved);
    }
    let Some(width) = address_bytes(kind) else {
        return Err(Problem::BadType(kind as char));
    };
    let digits = &line[2..];
    for (i, &b) in digits.iter().enumerate() {
        if hex_value(b).is_none() {
            return Err(Problem::NotHex {
                found: b as char,
                column: i + 3,
            });
        }
    }
    if digits.len() < 2 {
        return Err(Problem::TooShort { len });
    }
    if !digits.len().is_multiple_of(2) {
        return Err(Problem::OddDigits(digits.len()));
    }
    let bytes: Vec<u8> = digits
        .chunks_exact(2)
        .map(|p| hex_value(p[0]).unwrap_or(0) << 4 | hex_value(p[1]).unwrap_or(0))
        .collect();
    let count = usize::from(bytes[0]);
    let actual = bytes.len() - 1;
    if count != actual {
        return Err(Problem::CountMismatch { count, actual });
    }
    if count < width + 1 {
        return Err(Problem::CountTooSmall {
            kind: kind as char,
            count,
            needed: width + 1,
        });
    }
    let (body, checksum) = bytes.split_at(bytes.len() - 1);
    let sum = body.iter().fold(0u8, |s, &b| s.wrapping_add(b));
    let computed = !sum;
    if computed != checksum[0] {
        return Err(Problem::Checksum {
            stated: checksum[0],
            computed,
        });
    }
    let address = body[1..=width]
        .iter()
        .fold(0u32, |a, &b| a << 8 | u32::from(b));
    let data = &body[1 + width..];
    let no_data = |k: u8| -> Result<(), Problem> {
        if data.is_empty() {
            Ok(())
        } else {
            Err(Problem::UnexpectedData(k as char, data.len()))
        }
    };
    Ok(match kind {
        b'0' => Record::Header(data.to_vec()),
        b'1' | b'2' | b'3' => {
            let bits = 8 * width as u32;
            let last = u64::from(address) + data.len() as u64;
            if !data.is_empty() && last - 1 > (1u64 << bits) - 1 {
                return Err(Problem::Wraps {
                    address,
                    len: data.len(),
                    bits,
                });
            }
            Record::Data {
                address,
                data: data.to_vec(),
            }
        }
        b'5' | b'6' => {
            no_data(kind)?;
            Record::Count(address)
        }
        _ => {
            no_data(kind)?;
            Record::Start(address)
        }
    })
}

/// The lines of `text` (LF or CR LF; a DOS end-of-file Ctrl Z at the very end is ignored),
/// numbered from 1, blank ones left out.
fn lines(text: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    let text = text.strip_suffix(b"\x1a").unwrap_or(text);
    text.split(|&b| b == b'\n')
        .enumerate()
        .map(|(i, l)| {
            let l = l.strip_suffix(b"\r").unwrap_or(l);
            // Trailing blanks (an editor's) are not part of the record.
            let end = l
                .iter()
                .rposition(|b| !matches!(b, b' ' | b'\t'))
                .map_or(0, |p| p + 1);
            (i + 1, &l[..end])
        })
        .filter(|(_, l)| !l.is_empty())
}

/// Reads a whole S-record file, checking every record and the file's structure: the header
/// first, count records that agree, nothing after the start record. Every bad line is
/// reported (up to [`MAX_ERRORS`]).
pub fn parse(text: &[u8]) -> Result<Program, SrecErrors> {
    let mut program = Program::default();
    let mut errors = SrecErrors::default();
    let mut data_records = 0usize;
    let mut start_line: Option<usize> = None;
    for (number, line) in lines(text) {
        program.records += 1;
        let record = match parse_record(line) {
            Ok(r) => r,
            Err(problem) => {
                errors.push(number, problem);
                continue;
            }
        };
        if let Some(at) = start_line {
            errors.push(number, Problem::AfterStart(at));
            continue;
        }
        match record {
            Record::Header(text) => {
                if program.records > 1 || program.header.is_some() {
                    errors.push(number, Problem::LateHeader);
                } else {
                    program.header = Some(text);
                }
            }
            Record::Data { address, data } => {
                data_records += 1;
                program.segments.push(Segment {
                    address,
                    data,
                    line: number,
                });
            }
            Record::Count(stated) => {
                if u64::from(stated) != data_records as u64 {
                    errors.push(
                        number,
                        Problem::WrongCount {
                            stated,
                            actual: data_records,
                        },
                    );
                }
            }
            Record::Start(address) => {
                program.start = Some(address);
                start_line = Some(number);
            }
        }
    }
    if errors.is_empty() {
        Ok(program)
    } else {
        Err(errors)
    }
}

fn push_record(out: &mut Vec<u8>, kind: u8, address: u32, data: &[u8]) {
    let width = address_bytes(kind).unwrap_or(4);
    let mut bytes = Vec::with_capacity(1 + width + data.len());
    bytes.push((width + data.len() + 1) as u8);
    bytes.extend_from_slice(&address.to_be_bytes()[4 - width..]);
    bytes.extend_from_slice(data);
    let sum = bytes.iter().fold(0u8, |s, &b| s.wrapping_add(b));
    bytes.push(!sum);
    out.push(b'S');
    out.push(kind);
    for b in bytes {
        out.extend_from_slice(format!("{b:02X}").as_bytes());
    }
    out.push(b'\n');
}

/// An S-record file with 32-bit addresses: the header (S0, at most 250 bytes of it), the
/// data as S3 records of [`WRITE_CHUNK`] bytes, a count record (S5 or S6) when the count fits,
/// and the start record (S7) if there is an entry point.
pub fn write<'a>(
    header: &[u8],
    data: impl IntoIterator<Item = (u32, &'a [u8])>,
    start: Option<u32>,
) -> Vec<u8> {
    let mut out = Vec::new();
    push_record(&mut out, b'0', 0, &header[..header.len().min(250)]);
    let mut count = 0u64;
    for (address, bytes) in data {
        for (i, chunk) in bytes.chunks(WRITE_CHUNK).enumerate() {
            let at = address.wrapping_add((i * WRITE_CHUNK) as u32);
            push_record(&mut out, b'3', at, chunk);
            count += 1;
        }
    }
    if count <= 0xFFFF {
        push_record(&mut out, b'5', count as u32, &[]);
    } else if count <= 0xFF_FFFF {
        push_record(&mut out, b'6', count as u32, &[]);
    }
    if let Some(start) = start {
        push_record(&mut out, b'7', start, &[]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_of_record_is_read() {
        assert_eq!(
            parse_record(b"S00F000068656C6C6F202020202000003C"),
            Ok(Record::Header(b"hello     \0\0".to_vec()))
        );
        assert_eq!(
            parse_record(b"S1137AF00A0A0D0000000000000000000000000061"),
            Ok(Record::Data {
                address: 0x7AF0,
                data: vec![0x0A, 0x0A, 0x0D, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]
            })
        );
        assert_eq!(parse_record(b"S5030003F9"), Ok(Record::Count(3)));
        assert_eq!(parse_record(b"S9030000FC"), Ok(Record::Start(0)));
        assert_eq!(parse_record(b"S8041234565F"), Ok(Record::Start(0x123456)));
    }

    #[test]
    fn bad_records_say_what_is_wrong() {
        let problem = |l: &[u8]| parse_record(l).unwrap_err().to_string();
        assert_eq!(
            problem(b"S9030000FD"),
            "checksum 0xFD, but the record's bytes give 0xFC"
        );
        assert_eq!(
            problem(b"X9030000FC"),
            "starts with 'X', not 'S' (a record is S, a type digit 0..9, then hex digits)"
        );
        assert_eq!(
            problem(b"S4030000FC"),
            "S4 is a reserved record type (S0..S3 and S5..S9 are records)"
        );
        assert_eq!(
            problem(b"S9040000FC"),
            "the byte count says 4 bytes follow, but the line has 3"
        );
        assert_eq!(
            problem(b"S90300G0FC"),
            "character 'G' at column 7 is not a hex digit"
        );
        assert_eq!(
            problem(b"S3030000FC"),
            "the byte count 3 is too small for an S3 record (5 at least: address and checksum)"
        );
        assert!(problem(b"S903000").contains("odd number"));
        assert!(problem(b"S1").contains("too short"));
        assert!(problem(&[b'S'; 600]).contains("longer than any record"));
        // S1 at 0xFFFF with two bytes would wrap around the 16-bit space.
        let mut wrap = Vec::new();
        push_record(&mut wrap, b'1', 0xFFFF, &[1, 2]);
        assert!(problem(wrap.trim_ascii_end()).contains("runs past the end of the 16-bit"));
    }

    #[test]
    fn the_file_structure_is_checked_with_line_numbers() {
        let mut good = Vec::new();
        push_record(&mut good, b'0', 0, b"prog");
        push_record(&mut good, b'2', 0x30000, &[1, 2, 3, 4]);
        push_record(&mut good, b'2', 0x32000, &[5; 16]);
        push_record(&mut good, b'5', 2, &[]);
        push_record(&mut good, b'8', 0x32000, &[]);
        let program = parse(&good).unwrap();
        assert_eq!(program.header_text().as_deref(), Some("prog"));
        assert_eq!(program.start, Some(0x32000));
        assert_eq!(program.records, 5);
        assert_eq!(program.ranges(), [(0x30000, 0x30003), (0x32000, 0x3200F)]);
        // CR LF, blank lines and trailing blanks are fine; the line numbers count them.
        let crlf = String::from_utf8(good.clone())
            .unwrap()
            .replace('\n', "  \r\n\r\n");
        let spaced = parse(crlf.as_bytes()).unwrap();
        assert_eq!(spaced.ranges(), program.ranges());
        assert_eq!(spaced.segments[1].line, 5, "blank lines count");

        let mut bad = good.clone();
        push_record(&mut bad, b'1', 0x10, &[1]);
        let text = String::from_utf8(bad)
            .unwrap()
            .replace("S5030002FA", "S5030003F9");
        let errors = parse(text.as_bytes()).unwrap_err();
        let lines: Vec<String> = errors.errors.iter().map(ToString::to_string).collect();
        assert_eq!(
            lines,
            [
                "line 4: the count record says 3 data records, but 2 came before it",
                "line 6: a record after the start record of line 5 (S7/S8/S9 ends the file)"
            ]
        );
        let late = [&good[..], b"S00600004844521B\n"].concat();
        assert!(parse(&late).unwrap_err().to_string().starts_with("line 6:"));
    }

    #[test]
    fn overlapping_records_name_both_lines() {
        let mut text = Vec::new();
        push_record(&mut text, b'3', 0x1000, &[0; 16]);
        push_record(&mut text, b'3', 0x2000, &[0; 4]);
        push_record(&mut text, b'3', 0x100F, &[0; 2]);
        let program = parse(&text).unwrap();
        let overlaps = program.overlaps();
        assert_eq!(
            overlaps.to_string(),
            "line 3: 0x0000100F..=0x0000100F overlaps the data of line 1"
        );
        assert_eq!(program.ranges(), [(0x1000, 0x1010), (0x2000, 0x2003)]);
    }

    #[test]
    fn written_files_read_back() {
        let data = [7u8; 100];
        let text = write(
            b"image",
            [(0x20000, &data[..]), (0x40000, &[1u8, 2][..])],
            Some(0x20000),
        );
        let program = parse(&text).unwrap();
        assert_eq!(program.header.as_deref(), Some(&b"image"[..]));
        assert_eq!(program.start, Some(0x20000));
        assert_eq!(program.data_bytes(), 102);
        assert_eq!(program.ranges(), [(0x20000, 0x20063), (0x40000, 0x40001)]);
        let empty = write(b"", [], None);
        assert_eq!(parse(&empty).unwrap().segments, []);
    }
}
