//! Hex digits as socketcand's elements carry them (IDs, data bytes), read without
//! allocating: shared by the command and message parsers.

use buslab_can::Id;

/// Each byte's value as a hex digit; `NOT_HEX` for the others.
pub(crate) static HEX: [u8; 256] = {
    let mut table = [NOT_HEX; 256];
    let mut i = 0;
    while i < 10 {
        table[b'0' as usize + i] = i as u8;
        i += 1;
    }
    let mut i = 0;
    while i < 6 {
        table[b'a' as usize + i] = 10 + i as u8;
        table[b'A' as usize + i] = 10 + i as u8;
        i += 1;
    }
    table
};
pub(crate) const NOT_HEX: u8 = 0x10;

/// 1..8 hex digits as an ID, as `Command::parse` reads one (8: extended, fewer: standard).
pub(crate) fn fast_id(text: &[u8]) -> Option<Id> {
    if text.is_empty() || text.len() > 8 {
        return None;
    }
    let (raw, bad) = text.iter().fold((0u32, 0u8), |(raw, bad), &b| {
        let digit = HEX[usize::from(b)];
        ((raw << 4) | u32::from(digit & 15), bad | digit)
    });
    if bad & NOT_HEX != 0 {
        return None;
    }
    if text.len() == 8 {
        Id::extended(raw).ok()
    } else {
        Id::standard(u16::try_from(raw).ok()?).ok()
    }
}

/// One or two hex digits as a byte (a `send` element's data byte); `None` for anything else.
pub(crate) fn fast_byte(text: &[u8]) -> Option<u8> {
    if text.is_empty() || text.len() > 2 {
        return None;
    }
    text.iter().try_fold(0u8, |value, &b| {
        let digit = HEX[usize::from(b)];
        (digit != NOT_HEX).then_some(value << 4 | digit)
    })
}

/// The value of a hex digit (checked by the caller).
pub(crate) fn hex_digit(b: u8) -> u8 {
    match b {
        b'0'..=b'9' => b - b'0',
        b'a'..=b'f' => b - b'a' + 10,
        b'A'..=b'F' => b - b'A' + 10,
        _ => 0,
    }
}
