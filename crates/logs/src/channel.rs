//! Interface names ↔ channel numbers, for the formats that number channels from 1 (ASC, BLF,
//! TRC): `can0` is channel 1, `vcan1` channel 2 (the digits at the end plus one, as python-can
//! and log2asc count), and channel N reads back as `can{N-1}` (as asc2log names it).

/// Numbers interface names for a writer. A name ending in digits gets those digits plus one; a
/// name without digits, or whose number another name already has, gets the lowest free number
/// (with a warning, since a reader will not see the name).
#[derive(Clone, Debug, Default)]
pub struct ChannelMap {
    names: Vec<(String, u16)>,
    /// The last lookup, so a log on one interface costs a string comparison per entry.
    last: Option<usize>,
}

impl ChannelMap {
    pub fn new() -> Self {
        Self::default()
    }

    /// The channel number (1-based) for `interface`.
    pub fn number(&mut self, interface: &str) -> u16 {
        if let Some(i) = self.last
            && self.names[i].0 == interface
        {
            return self.names[i].1;
        }
        if let Some(i) = self.names.iter().position(|(n, _)| n == interface) {
            self.last = Some(i);
            return self.names[i].1;
        }
        let wanted = trailing_number(interface).and_then(|n| n.checked_add(1));
        let taken = |n: u16| self.names.iter().any(|(_, c)| *c == n);
        let number = match wanted {
            Some(n) if !taken(n) => n,
            _ => {
                let free = (1..=u16::MAX).find(|&n| !taken(n)).unwrap_or(u16::MAX);
                tracing::warn!(
                    "interface {interface:?} is written as channel {free} (read back as {})",
                    channel_name(free)
                );
                free
            }
        };
        self.names.push((interface.to_string(), number));
        self.last = Some(self.names.len() - 1);
        number
    }
}

/// `can0` → 0, `vcan12` → 12, `lab` → None.
fn trailing_number(name: &str) -> Option<u16> {
    let digits = name.len() - name.trim_end_matches(|c: char| c.is_ascii_digit()).len();
    if digits == 0 {
        return None;
    }
    name[name.len() - digits..].parse().ok()
}

/// The interface name a channel number reads back as: `can{N-1}` (channel 0, which no writer
/// should use, is `can0` too).
pub fn channel_name(channel: u16) -> String {
    format!("can{}", channel.saturating_sub(1))
}

/// The channel number an interface name read back from a numbered format stands for: `can0`
/// is 1 (the inverse of [`channel_name`]); `None` for a name no reader gives.
pub(crate) fn channel_of(interface: &str) -> Option<u16> {
    let digits = interface.strip_prefix("can")?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse::<u16>().ok()?.checked_add(1)
}

/// Writes [`channel_name`] into `out`, reusing its allocation.
pub(crate) fn set_channel_name(out: &mut String, channel: u16) {
    use std::fmt::Write as _;
    out.clear();
    let _ = write!(out, "can{}", channel.saturating_sub(1));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_follow_the_digits_then_the_first_free() {
        let mut map = ChannelMap::new();
        assert_eq!(map.number("can0"), 1);
        assert_eq!(map.number("vcan1"), 2);
        assert_eq!(map.number("vcan0"), 3); // 1 is can0's
        assert_eq!(map.number("lab"), 4);
        assert_eq!(map.number("can0"), 1);
        assert_eq!(map.number("vcan1"), 2);
        assert_eq!(channel_name(1), "can0");
        assert_eq!(channel_name(0), "can0");
        assert_eq!(map.number("can99999999"), 5);
    }
}
