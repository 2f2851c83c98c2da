//! Calendar times in log headers: ASC dates (local time, as log2asc and python-can write
//! them), BLF's SYSTEMTIME (UTC, as python-can writes it), TRC's OLE day numbers.

use std::time::Duration;

use chrono::{DateTime, Datelike, Local, NaiveDate, NaiveDateTime, TimeZone, Timelike, Utc};

/// `Tue Nov 14 22:13:20.123 2023`: an ASC header date in local time, milliseconds cut.
pub fn asc_date(t: Duration) -> String {
    let secs = i64::try_from(t.as_secs()).unwrap_or(i64::MAX);
    let utc = DateTime::<Utc>::from_timestamp(secs, t.subsec_nanos())
        .unwrap_or(DateTime::<Utc>::UNIX_EPOCH);
    let local = utc.with_timezone(&Local);
    format!(
        "{}.{:03} {}",
        local.format("%a %b %d %H:%M:%S"),
        local.timestamp_subsec_millis().min(999),
        local.format("%Y")
    )
}

const MONTHS: [(&str, u32); 16] = [
    ("jan", 1),
    ("feb", 2),
    ("mar", 3),
    ("mär", 3),
    ("apr", 4),
    ("may", 5),
    ("mai", 5),
    ("jun", 6),
    ("jul", 7),
    ("aug", 8),
    ("sep", 9),
    ("oct", 10),
    ("okt", 10),
    ("nov", 11),
    ("dec", 12),
    ("dez", 12),
];

/// The time an ASC date names (`Tue Nov 14 22:13:20.123 2023`, `Sat Sep 30 10:06:13.191 PM
/// 2017`, German `Sam Sep 30 15:06:13.191 2017`), read as local time; `None` if it is none of
/// these.
pub fn parse_asc_date(text: &str) -> Option<Duration> {
    let mut words = text.split_whitespace();
    let mut first = words.next()?;
    // The weekday comes first; skip it unless it is already the month.
    if month(first).is_none() {
        first = words.next()?;
    }
    let month = month(first)?;
    let day: u32 = words.next()?.parse().ok()?;
    let time = words.next()?;
    let mut next = words.next()?;
    let mut hour_shift = None;
    if next.eq_ignore_ascii_case("am") || next.eq_ignore_ascii_case("pm") {
        hour_shift = Some(next.eq_ignore_ascii_case("pm"));
        next = words.next()?;
    }
    let year: i32 = next.parse().ok()?;
    let (hms, millis) = match time.split_once('.') {
        Some((hms, ms)) => {
            if ms.is_empty() || !ms.bytes().all(|b| b.is_ascii_digit()) {
                return None;
            }
            let digits = &ms[..ms.len().min(3)];
            let scale = 10u32.pow(3 - digits.len() as u32);
            (hms, digits.parse::<u32>().ok()? * scale)
        }
        None => (time, 0),
    };
    let mut parts = hms.split(':');
    let mut hour: u32 = parts.next()?.parse().ok()?;
    let minute: u32 = parts.next()?.parse().ok()?;
    let second: u32 = parts.next()?.parse().ok()?;
    if let Some(pm) = hour_shift {
        hour %= 12;
        if pm {
            hour += 12;
        }
    }
    let naive = NaiveDate::from_ymd_opt(year, month, day)?
        .and_hms_milli_opt(hour, minute, second, millis)?;
    let local = Local.from_local_datetime(&naive).earliest()?;
    let nanos = local.timestamp_nanos_opt()?;
    u64::try_from(nanos).ok().map(Duration::from_nanos)
}

fn month(word: &str) -> Option<u32> {
    let lower = word.to_lowercase();
    let prefix: String = lower.chars().take(3).collect();
    MONTHS
        .iter()
        .find(|(name, _)| *name == prefix)
        .map(|(_, m)| *m)
}

/// Windows SYSTEMTIME (year, month, weekday, day, hour, minute, second, milliseconds) in UTC;
/// all zero before 1990 (python-can's rule: not a wall-clock time).
pub fn systemtime(t: Duration) -> [u16; 8] {
    if t.as_secs() < 631_152_000 {
        return [0; 8];
    }
    let secs = i64::try_from(t.as_secs()).unwrap_or(i64::MAX);
    let Some(dt) = DateTime::<Utc>::from_timestamp(secs, t.subsec_nanos()) else {
        return [0; 8];
    };
    [
        dt.year().clamp(0, i32::from(u16::MAX)) as u16,
        dt.month() as u16,
        dt.weekday().num_days_from_sunday() as u16,
        dt.day() as u16,
        dt.hour() as u16,
        dt.minute() as u16,
        dt.second() as u16,
        (dt.timestamp_subsec_millis().min(999)) as u16,
    ]
}

/// Whether a SYSTEMTIME holds `t`: its year is 16 bits, so the last time it names is in
/// 65535.
pub fn fits_systemtime(t: Duration) -> bool {
    i64::try_from(t.as_secs())
        .ok()
        .and_then(|secs| DateTime::<Utc>::from_timestamp(secs, 0))
        .is_some_and(|dt| dt.year() <= i32::from(u16::MAX))
}

/// The error a log writer gives for an entry whose time its format cannot hold (rather than
/// writing another time in its place).
pub fn out_of_range(t: Duration, format: &str, holds: &str) -> std::io::Error {
    std::io::Error::new(
        std::io::ErrorKind::InvalidInput,
        format!(
            "timestamp {}.{:09} s cannot be written to {format}: it holds {holds}",
            t.as_secs(),
            t.subsec_nanos()
        ),
    )
}

/// The time a SYSTEMTIME names (UTC), or zero when it names none (all zero, or invalid).
pub fn from_systemtime(st: [u16; 8]) -> Duration {
    let naive = NaiveDate::from_ymd_opt(i32::from(st[0]), u32::from(st[1]), u32::from(st[3]))
        .and_then(|d| {
            d.and_hms_milli_opt(
                u32::from(st[4]),
                u32::from(st[5]),
                u32::from(st[6]),
                u32::from(st[7]),
            )
        });
    // Seconds and nanoseconds apart: nanoseconds in an i64 end in 2262, a SYSTEMTIME in 65535.
    naive
        .map(|n: NaiveDateTime| n.and_utc())
        .and_then(|dt| {
            Some(Duration::new(
                u64::try_from(dt.timestamp()).ok()?,
                dt.timestamp_subsec_nanos(),
            ))
        })
        .unwrap_or(Duration::ZERO)
}

/// Days from 1899-12-30 (the OLE date zero) to the Unix epoch.
const OLE_EPOCH_DAYS: u64 = 25_569;
const NANOS_PER_DAY: u128 = 86_400_000_000_000;

/// TRC's `$STARTTIME`: days since 1899-12-30 (UTC, as python-can reads and writes it) with
/// 15 decimals, enough for the time to come back to the nanosecond.
pub fn ole_days(t: Duration) -> String {
    let ns = t.as_nanos() + u128::from(OLE_EPOCH_DAYS) * NANOS_PER_DAY;
    let days = ns / NANOS_PER_DAY;
    let rest = ns % NANOS_PER_DAY;
    // rest / NANOS_PER_DAY in units of 1e-15, rounded.
    let frac = (rest * 1_000_000_000_000_000 + NANOS_PER_DAY / 2) / NANOS_PER_DAY;
    let (days, frac) = if frac >= 1_000_000_000_000_000 {
        (days + 1, frac - 1_000_000_000_000_000)
    } else {
        (days, frac)
    };
    format!("{days}.{frac:015}")
}

/// The time a `$STARTTIME` names; `None` if it is no decimal number of days after the Unix
/// epoch's.
pub fn parse_ole_days(text: &str) -> Option<Duration> {
    let (int, frac) = text.trim().split_once('.').unwrap_or((text.trim(), ""));
    let days: u64 = int.parse().ok()?;
    if !frac.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let digits = &frac[..frac.len().min(18)];
    let scale = 10u128.pow(digits.len() as u32);
    let num: u128 = if digits.is_empty() {
        0
    } else {
        digits.parse().ok()?
    };
    let frac_ns = (num * NANOS_PER_DAY + scale / 2) / scale;
    let total = u128::from(days.checked_sub(OLE_EPOCH_DAYS)?) * NANOS_PER_DAY + frac_ns;
    let secs = u64::try_from(total / 1_000_000_000).ok()?;
    Some(Duration::new(secs, (total % 1_000_000_000) as u32))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ole_days_come_back_to_the_nanosecond() {
        for ns in [
            0u64,
            1,
            1_700_000_000_123_456_789,
            1_639_837_687_062_000_000,
        ] {
            let t = Duration::from_nanos(ns);
            assert_eq!(parse_ole_days(&ole_days(t)), Some(t), "{}", ole_days(t));
        }
        // PCAN-View's 18.12.2021 14:28:07.062 (UTC as python-can reads it).
        let t = parse_ole_days("44548.6028595139").unwrap();
        assert_eq!(t.as_secs(), 1_639_837_687);
        assert_eq!(parse_ole_days("1.5"), None); // before 1970
        assert_eq!(parse_ole_days("x"), None);
    }

    #[test]
    fn systemtime_round_trip_in_milliseconds() {
        let t = Duration::new(1_700_000_000, 123_000_000);
        assert_eq!(systemtime(t), [2023, 11, 2, 14, 22, 13, 20, 123]);
        assert_eq!(from_systemtime(systemtime(t)), t);
        assert_eq!(systemtime(Duration::from_secs(5)), [0; 8]);
        assert_eq!(from_systemtime([0; 8]), Duration::ZERO);
    }

    /// Found by fuzzing (`logs_blf`): a BLF written with a start after 2262 read back with no
    /// start time at all (its times began at 0).
    #[test]
    fn systemtime_after_2262_comes_back() {
        let t = Duration::new(17_670_240_701, 815_000_000);
        assert_eq!(systemtime(t)[0], 2529);
        assert_eq!(from_systemtime(systemtime(t)), t);
    }

    #[test]
    fn asc_dates_in_local_time() {
        let t = Duration::new(1_700_000_000, 704_000_000);
        let text = asc_date(t);
        assert_eq!(parse_asc_date(&text), Some(t), "{text}");
        assert!(text.contains(".704 "), "{text}");
        for text in [
            "Sat Sep 30 10:06:13.191 PM 2017",
            "Sam Sep 30 22:06:13.191 2017",
            "Sep 30 22:06:13.191 2017",
        ] {
            let got = parse_asc_date(text).unwrap();
            assert_eq!(
                got,
                parse_asc_date("Sat Sep 30 22:06:13.191 2017").unwrap(),
                "{text}"
            );
        }
        assert_eq!(parse_asc_date("Tue Xyz 14 22:13:20 2023"), None);
    }
}
