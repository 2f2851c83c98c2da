//! What the text formats share: bounded lines out of a `BufRead` (no copy when a line lies in
//! the buffer), hex and decimal digits both ways without allocating.

use std::io::{self, BufRead};
use std::time::Duration;

use buslab_can::Nanos;

/// The longest line a text reader takes (a classic CAN line is under 100 characters; TRC and
/// ASC headers are longer, but not this long).
pub const MAX_LINE: usize = 4096;

/// A line that is longer than [`MAX_LINE`] (its bytes are skipped).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TooLong;

/// Lines of a `BufRead`, numbered from 1, without the `\n` or `\r\n`.
pub struct Lines<R> {
    input: R,
    line: u64,
    buf: Vec<u8>,
}

impl<R: BufRead> Lines<R> {
    pub fn new(input: R) -> Self {
        Self {
            input,
            line: 0,
            buf: Vec::new(),
        }
    }

    /// Hands the next line to `f` (with its number), `Ok(None)` at the end of the input.
    pub fn next<T>(
        &mut self,
        f: impl FnOnce(u64, Result<&[u8], TooLong>) -> T,
    ) -> io::Result<Option<T>> {
        self.buf.clear();
        let mut too_long = false;
        loop {
            let chunk = match self.input.fill_buf() {
                Ok(chunk) => chunk,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            if chunk.is_empty() {
                if self.buf.is_empty() && !too_long {
                    return Ok(None);
                }
                self.line += 1;
                let line = if too_long {
                    Err(TooLong)
                } else {
                    Ok(strip_cr(&self.buf))
                };
                return Ok(Some(f(self.line, line)));
            }
            match memchr::memchr(b'\n', chunk) {
                Some(i) if self.buf.is_empty() && !too_long => {
                    self.line += 1;
                    let line = if i <= MAX_LINE {
                        Ok(strip_cr(&chunk[..i]))
                    } else {
                        Err(TooLong)
                    };
                    let out = f(self.line, line);
                    self.input.consume(i + 1);
                    return Ok(Some(out));
                }
                Some(i) => {
                    if !too_long && self.buf.len() + i <= MAX_LINE {
                        self.buf.extend_from_slice(&chunk[..i]);
                    } else {
                        too_long = true;
                    }
                    self.input.consume(i + 1);
                    self.line += 1;
                    let line = if too_long {
                        Err(TooLong)
                    } else {
                        Ok(strip_cr(&self.buf))
                    };
                    return Ok(Some(f(self.line, line)));
                }
                None => {
                    let n = chunk.len();
                    if !too_long && self.buf.len() + n <= MAX_LINE {
                        self.buf.extend_from_slice(chunk);
                    } else {
                        too_long = true;
                        self.buf.clear();
                    }
                    self.input.consume(n);
                }
            }
        }
    }
}

fn strip_cr(line: &[u8]) -> &[u8] {
    line.strip_suffix(b"\r").unwrap_or(line)
}

/// Splits off the next field separated by spaces or tabs: (field, rest).
pub fn field(text: &[u8]) -> (&[u8], &[u8]) {
    let start = text
        .iter()
        .position(|&b| b != b' ' && b != b'\t')
        .unwrap_or(text.len());
    let text = &text[start..];
    let end = text
        .iter()
        .position(|&b| b == b' ' || b == b'\t')
        .unwrap_or(text.len());
    (&text[..end], &text[end..])
}

/// `text` without spaces or tabs at either end.
pub fn trim(text: &[u8]) -> &[u8] {
    let start = text
        .iter()
        .position(|&b| b != b' ' && b != b'\t')
        .unwrap_or(text.len());
    let end = text
        .iter()
        .rposition(|&b| b != b' ' && b != b'\t')
        .map_or(start, |i| i + 1);
    &text[start..end.max(start)]
}

/// Each byte's value as a hex digit, or 0xFF.
static HEX_VALUE: [u8; 256] = {
    let mut t = [0xFFu8; 256];
    let mut i = 0;
    while i < 10 {
        t[b'0' as usize + i] = i as u8;
        i += 1;
    }
    let mut i = 0;
    while i < 6 {
        t[b'a' as usize + i] = 10 + i as u8;
        t[b'A' as usize + i] = 10 + i as u8;
        i += 1;
    }
    t
};

/// The value of one hex digit, or 0xFF.
#[inline]
pub fn hex_digit(b: u8) -> u8 {
    HEX_VALUE[usize::from(b)]
}

/// 1..=8 hex digits as a number.
#[inline]
pub fn hex_u32(text: &[u8]) -> Option<u32> {
    if text.is_empty() || text.len() > 8 {
        return None;
    }
    let mut v = 0u32;
    let mut bad = 0u8;
    for &b in text {
        let d = hex_digit(b);
        bad |= d;
        v = (v << 4) | u32::from(d & 15);
    }
    (bad <= 15).then_some(v)
}

/// 1..=20 decimal digits as a number, `None` beyond `u64::MAX` (the writers print any u64).
pub fn dec_u64(text: &[u8]) -> Option<u64> {
    if text.is_empty() || text.len() > 20 {
        return None;
    }
    let mut v = 0u64;
    for &b in text {
        if !b.is_ascii_digit() {
            return None;
        }
        v = v.checked_mul(10)?.checked_add(u64::from(b - b'0'))?;
    }
    Some(v)
}

/// `UNITS[.FRACTION]` (any number of decimals; beyond nanoseconds they are cut) as a
/// duration: `unit` is a second for most logs, a millisecond for TRC.
pub fn decimal_duration(text: &[u8], unit: Nanos) -> Option<Duration> {
    let unit_ns = unit.get();
    let (int, frac) = match memchr::memchr(b'.', text) {
        Some(i) => (&text[..i], &text[i + 1..]),
        None => (text, &[][..]),
    };
    if int.is_empty() && frac.is_empty() {
        return None;
    }
    let whole = if int.is_empty() { 0 } else { dec_u64(int)? };
    if !frac.iter().all(u8::is_ascii_digit) {
        return None;
    }
    // The fraction in units of 1e-18 of the unit (18 digits fit a u64), then scaled.
    let mut attos: u64 = 0;
    for (i, &b) in frac.iter().take(18).enumerate() {
        attos += u64::from(b - b'0') * 10u64.pow(17 - i as u32);
    }
    let frac_ns = (u128::from(attos) * u128::from(unit_ns) / 1_000_000_000_000_000_000) as u64;
    let total = u128::from(whole) * u128::from(unit_ns) + u128::from(frac_ns);
    let secs = total / 1_000_000_000;
    if secs > u128::from(u64::MAX) {
        return None;
    }
    Some(Duration::new(secs as u64, (total % 1_000_000_000) as u32))
}

/// `00` to `99`: decimal digits two at a time.
static DEC_PAIRS: [[u8; 2]; 100] = {
    let mut t = [[0u8; 2]; 100];
    let mut i = 0;
    while i < 100 {
        t[i] = [b'0' + (i / 10) as u8, b'0' + (i % 10) as u8];
        i += 1;
    }
    t
};

/// `v`'s decimal digits at the end of `digits`; returns where they start.
#[inline]
fn decimal(digits: &mut [u8; 20], mut v: u64) -> usize {
    let mut i = digits.len();
    while v >= 100 {
        i -= 2;
        digits[i..i + 2].copy_from_slice(&DEC_PAIRS[(v % 100) as usize]);
        v /= 100;
    }
    if v >= 10 {
        i -= 2;
        digits[i..i + 2].copy_from_slice(&DEC_PAIRS[v as usize]);
    } else {
        i -= 1;
        digits[i] = b'0' + v as u8;
    }
    i
}

/// Appends `v` in decimal.
#[inline]
pub fn push_u64(out: &mut Vec<u8>, v: u64) {
    let mut digits = [0u8; 20];
    let i = decimal(&mut digits, v);
    out.extend_from_slice(&digits[i..]);
}

/// Appends `v` in decimal with at least `width` digits (leading zeros).
#[inline]
pub fn push_u64_zeros(out: &mut Vec<u8>, v: u64, width: usize) {
    // Every place not taken by a digit is already a leading zero.
    let mut digits = [b'0'; 20];
    let i = decimal(&mut digits, v);
    let mut extra = width.saturating_sub(digits.len());
    while extra > 0 {
        let n = extra.min(digits.len());
        out.extend_from_slice(&[b'0'; 20][..n]);
        extra -= n;
    }
    out.extend_from_slice(&digits[i.min(digits.len().saturating_sub(width))..]);
}

/// `v`'s low `N` decimal digits (leading zeros): a fixed-width field, such as a timestamp's
/// seconds and microseconds, formatted without a look at the output's capacity.
#[inline]
pub fn decimal_fixed<const N: usize>(mut v: u64) -> [u8; N] {
    let mut digits = [b'0'; N];
    let mut i = N;
    // A fixed count of steps (no early end at 0): unrolled, nothing to predict.
    while i >= 2 {
        i -= 2;
        digits[i..i + 2].copy_from_slice(&DEC_PAIRS[(v % 100) as usize]);
        v /= 100;
    }
    if i == 1 {
        digits[0] = b'0' + (v % 10) as u8;
    }
    digits
}

/// Appends `v` right-aligned in `width` columns (leading spaces).
#[inline]
pub fn push_u64_right(out: &mut Vec<u8>, v: u64, width: usize) {
    let mut digits = [0u8; 20];
    let i = decimal(&mut digits, v);
    let mut spaces = width.saturating_sub(digits.len() - i);
    while spaces > 0 {
        let n = spaces.min(SPACES.len());
        out.extend_from_slice(&SPACES[..n]);
        spaces -= n;
    }
    out.extend_from_slice(&digits[i..]);
}

const HEX: &[u8; 16] = b"0123456789ABCDEF";

/// Each byte as two uppercase hex digits.
static HEX_PAIRS: [[u8; 2]; 256] = {
    let mut t = [[0u8; 2]; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = [HEX[i >> 4], HEX[i & 15]];
        i += 1;
    }
    t
};

/// A byte as two uppercase hex digits.
#[inline]
pub fn hex_pair(b: u8) -> [u8; 2] {
    HEX_PAIRS[usize::from(b)]
}

/// Appends a byte as two uppercase hex digits.
#[inline]
pub fn push_hex_byte(out: &mut Vec<u8>, b: u8) {
    out.extend_from_slice(&hex_pair(b));
}

/// Appends `v` in uppercase hex with at least `width` digits.
pub fn push_hex(out: &mut Vec<u8>, v: u32, width: usize) {
    let mut digits = [0u8; 8];
    let mut i = digits.len();
    let mut v = v;
    loop {
        i -= 1;
        digits[i] = HEX[(v & 15) as usize];
        v >>= 4;
        if v == 0 {
            break;
        }
    }
    for _ in digits.len() - i..width {
        out.push(b'0');
    }
    out.extend_from_slice(&digits[i..]);
}

/// `v`'s low `N` nibbles in uppercase hex (leading zeros): an ID's fixed width.
#[inline]
pub fn hex_fixed<const N: usize>(v: u32) -> [u8; N] {
    let mut digits = [0u8; N];
    for (k, d) in digits.iter_mut().enumerate() {
        *d = HEX[((v >> (4 * (N - 1 - k))) & 15) as usize];
    }
    digits
}

const SPACES: [u8; 64] = [b' '; 64];

/// Appends spaces until the line (since `start`) is `width` long (at most 64 at once).
#[inline]
pub fn pad_to(out: &mut Vec<u8>, start: usize, width: usize) {
    let have = out.len() - start;
    if have < width {
        out.extend_from_slice(&SPACES[..(width - have).min(SPACES.len())]);
    }
}

/// Appends ` XX` for each byte (uppercase hex).
#[inline]
pub fn push_spaced_hex(out: &mut Vec<u8>, bytes: &[u8]) {
    // Eight at a time on the stack: a classic frame's in one go.
    for chunk in bytes.chunks(8) {
        let mut buf = [0u8; 24];
        for (k, &b) in chunk.iter().enumerate() {
            buf[3 * k] = b' ';
            buf[3 * k + 1..3 * k + 3].copy_from_slice(&hex_pair(b));
        }
        out.extend_from_slice(&buf[..3 * chunk.len()]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all_lines(input: &[u8], capacity: usize) -> Vec<Result<String, TooLong>> {
        let mut lines = Lines::new(io::BufReader::with_capacity(capacity, input));
        let mut out = Vec::new();
        while let Some(l) = lines
            .next(|_, l| l.map(|b| String::from_utf8_lossy(b).into_owned()))
            .unwrap()
        {
            out.push(l);
        }
        out
    }

    #[test]
    fn lines_across_buffer_edges_and_too_long() {
        let text = b"ab\r\ncdef\n\nlast";
        for cap in [1, 2, 3, 5, 64] {
            assert_eq!(
                all_lines(text, cap),
                [
                    Ok("ab".into()),
                    Ok("cdef".into()),
                    Ok("".into()),
                    Ok("last".into())
                ],
                "{cap}"
            );
        }
        let mut long = vec![b'x'; MAX_LINE + 1];
        long.extend_from_slice(b"\nok\n");
        assert_eq!(all_lines(&long, 100), [Err(TooLong), Ok("ok".into())]);
        assert_eq!(
            all_lines(&long, 3 * MAX_LINE),
            [Err(TooLong), Ok("ok".into())]
        );
        let mut long_last = b"ok\n".to_vec();
        long_last.extend(vec![b'y'; MAX_LINE + 5]);
        assert_eq!(all_lines(&long_last, 7), [Ok("ok".into()), Err(TooLong)]);
    }

    #[test]
    fn numbers_both_ways() {
        const SECOND: Nanos = Nanos::from_secs(1);
        const MS: Nanos = Nanos::from_millis(1);
        let d = |t: &str, unit| decimal_duration(t.as_bytes(), unit);
        assert_eq!(d("1.5", SECOND), Some(Duration::from_millis(1500)));
        assert_eq!(d("17535.4", MS), Some(Duration::from_micros(17_535_400)));
        assert_eq!(
            d("1700000000.123456789123", SECOND),
            Some(Duration::new(1_700_000_000, 123_456_789))
        );
        assert_eq!(d(".25", SECOND), Some(Duration::from_millis(250)));
        for bad in ["", ".", "1.2.3", "x", "-1", "1e5", "99999999999999999999"] {
            assert_eq!(d(bad, SECOND), None, "{bad}");
        }
        let mut out = Vec::new();
        push_u64_zeros(&mut out, 42, 6);
        push_hex(&mut out, 0x1F, 3);
        push_hex_byte(&mut out, 0xA5);
        push_u64_right(&mut out, 7, 3);
        assert_eq!(out, b"00004201FA5  7");
        assert_eq!(hex_fixed::<3>(0x7FF), *b"7FF");
        assert_eq!(hex_fixed::<8>(0x0ABC_DEF0), *b"0ABCDEF0");
    }

    /// The writers' digits are std's, at every length and at the edges.
    #[test]
    fn digits_as_std_formats_them() {
        let mut values = vec![0, 1, 9, 10, 99, 100, 101, 999, 1000, u64::MAX, u64::MAX - 1];
        let mut p = 1u64;
        while let Some(next) = p.checked_mul(10) {
            values.extend([p - 1, p, p + 1, next / 2]);
            p = next;
        }
        for v in values {
            for width in [0, 1, 6, 10, 20, 25, 70] {
                let mut out = Vec::new();
                push_u64(&mut out, v);
                assert_eq!(out, v.to_string().as_bytes());
                out.clear();
                push_u64_zeros(&mut out, v, width);
                assert_eq!(out, format!("{v:0width$}").as_bytes(), "{v} {width}");
                out.clear();
                push_u64_right(&mut out, v, width);
                assert_eq!(out, format!("{v:>width$}").as_bytes(), "{v} {width}");
            }
            // The low digits in a fixed field: as many as fit, zeros before.
            let low = |n: u32| format!("{:0n$}", v % 10u64.pow(n), n = n as usize);
            assert_eq!(decimal_fixed::<1>(v), low(1).as_bytes(), "{v}");
            assert_eq!(decimal_fixed::<6>(v), low(6).as_bytes(), "{v}");
            assert_eq!(decimal_fixed::<10>(v), low(10).as_bytes(), "{v}");
            assert_eq!(decimal_fixed::<19>(v), low(19).as_bytes(), "{v}");
        }
        for b in 0..=255u8 {
            let mut out = Vec::new();
            push_hex_byte(&mut out, b);
            assert_eq!(out, format!("{b:02X}").as_bytes());
        }
        assert_eq!(hex_u32(b"1fffFFFF"), Some(0x1FFF_FFFF));
        assert_eq!(hex_u32(b"123456789"), None);
        assert_eq!(field(b"  ab  cd"), (&b"ab"[..], &b"  cd"[..]));
        assert_eq!(trim(b" \tx y \t"), b"x y");
    }
}
