//! Helpers shared by the fuzz targets: the checks every target makes the same way.

use std::fmt::Debug;

use buslab_device::Nanos;

/// The inside of an element as a `Display` impl writes it (`< open can0 >` → `open can0`).
pub fn element_inside(text: &str) -> &str {
    text.trim()
        .strip_prefix('<')
        .and_then(|t| t.strip_suffix('>'))
        .unwrap_or_else(|| panic!("not an element: {text:?}"))
}

/// `parse(print(x)) == x`: what a parser accepted and printed back reads the same again.
pub fn assert_reparses<T, E>(value: &T, printed: &str, parse: impl Fn(&str) -> Result<T, E>)
where
    T: PartialEq + Debug,
    E: Debug,
{
    match parse(printed) {
        Ok(again) => assert_eq!(&again, value, "printed as {printed:?}"),
        Err(e) => panic!("{value:?} printed as {printed:?} does not parse again: {e:?}"),
    }
}

/// The input as text, if it is UTF-8 (text parsers get text: their callers check UTF-8).
pub fn text(data: &[u8]) -> Option<&str> {
    std::str::from_utf8(data).ok()
}

/// The escape byte of the stream targets: input bytes are data, except `ESCAPE` followed by an
/// op byte (`ESCAPE ESCAPE` is the data byte FFh). Seeds are then plain protocol bytes.
pub const ESCAPE: u8 = 0xFF;

/// A stream target's input: data bytes, or an op.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Item {
    Data(u8),
    Op(u8),
}

/// Splits input into [`Item`]s.
pub fn items(data: &[u8]) -> impl Iterator<Item = Item> + '_ {
    let mut bytes = data.iter().copied();
    std::iter::from_fn(move || {
        let b = bytes.next()?;
        if b != ESCAPE {
            return Some(Item::Data(b));
        }
        Some(match bytes.next() {
            None | Some(ESCAPE) => Item::Data(ESCAPE),
            Some(op) => Item::Op(op),
        })
    })
}

/// Drives a byte device (a served model) the way the PTY adapter does: data bytes arrive one
/// after the other as fast as the line carries them; ops (see [`items`]) let time pass
/// (`00..3F`: a pause of op² ms), jump to the device's next deadlines (`40..7F`: op−3Fh times),
/// or go to the device's other inputs (`80..FE`: `extra(device, now, op & 3Fh)`: keys, power).
/// After the input, time runs on through the device's deadlines for a few seconds.
///
/// Checks that the device never sends faster than its line (every byte it hands out took a
/// byte time) and does not keep asking to be woken in the past (an adapter would spin).
pub fn drive_byte_device<D: buslab_device::ByteDevice>(
    device: &mut D,
    byte_ns: Nanos,
    data: &[u8],
    mut extra: impl FnMut(&mut D, Nanos, u8),
) {
    const MS: Nanos = Nanos::from_millis(1);
    let mut now = Nanos::ZERO;
    let mut rx_free_at = Nanos::ZERO;
    let mut sent = 0u64;
    let mut out = Vec::new();
    // A device may catch up on a long pause one step per poll (a watchdog a poll), as long as
    // a few polls at the same time bring its deadline past it.
    const CATCH_UP_POLLS: usize = 1_000;
    // Polls at `now` and gives the device's next deadline, which is then after `now`.
    let mut check = |device: &mut D, now: Nanos| {
        for _ in 0..CATCH_UP_POLLS {
            device.poll(now, &mut out);
            sent += out.len() as u64;
            out.clear();
            assert!(
                sent <= now / byte_ns + 1,
                "{sent} bytes sent by {now} ns, faster than the line ({byte_ns} ns a byte)"
            );
            match device.next_deadline() {
                Some(t) if t <= now => {}
                later => return later,
            }
        }
        panic!(
            "after {CATCH_UP_POLLS} polls at {now} the device still asks for {:?}",
            device.next_deadline()
        );
    };
    let mut upcoming = device.next_deadline().filter(|&t| t > now);
    for item in items(data) {
        match item {
            Item::Data(byte) => {
                now = now.max(rx_free_at);
                rx_free_at = now + byte_ns;
                device.receive(now, byte);
            }
            Item::Op(op @ 0x00..=0x3F) => now += u64::from(op) * u64::from(op) * MS,
            Item::Op(op @ 0x40..=0x7F) => {
                for _ in 0..op - 0x3F {
                    match check(device, now) {
                        Some(t) => now = t,
                        None => break,
                    }
                }
            }
            Item::Op(op) => extra(device, now, op & 0x3F),
        }
        upcoming = check(device, now);
    }
    let end = now + 3_000 * MS;
    for _ in 0..10_000 {
        match upcoming {
            Some(t) if t <= end => now = t,
            _ => break,
        }
        upcoming = check(device, now);
    }
}

/// Checks shared by the log-reader targets (`logs_*`).
pub mod logs {
    use std::io::Cursor;

    use buslab_logs::{LogReader, Message};

    /// Reads every entry the way `buslab play`/`dump` do (going on after an error that is not
    /// fatal, stopping after a fatal one) and gives the entries read. Fails if the reader does
    /// not move on: more calls than `max_calls` (a bound derived from the input's size) means
    /// it hands out the same error or entry forever.
    pub fn read_all(mut reader: impl LogReader, max_calls: usize) -> Vec<Message> {
        let mut entries = Vec::new();
        let mut errors = 0usize;
        for _ in 0..max_calls {
            let mut entry = Message::default();
            match reader.read_into(&mut entry) {
                Ok(true) => entries.push(entry),
                Ok(false) => {
                    // A bit rate the log gives is one CAN has: 1 kbit/s..1 Mbit/s.
                    for entry in &entries {
                        if let Some(rate) = reader.bit_rate(&entry.channel) {
                            assert!(
                                (1_000..=1_000_000).contains(&rate.bits_per_s),
                                "{rate:?} for {}",
                                entry.channel
                            );
                        }
                    }
                    return entries;
                }
                Err(e) if e.is_fatal() => {
                    // A fatal error ends the log: the next read says so.
                    let mut after = Message::default();
                    assert!(
                        matches!(reader.read_into(&mut after), Ok(false)),
                        "the reader went on after the fatal error {e}"
                    );
                    return entries;
                }
                Err(_) => errors += 1,
            }
        }
        panic!(
            "the reader does not end: {max_calls} calls gave {} entries and {errors} errors",
            entries.len()
        );
    }

    /// What a format's writer makes of entries, read back by the same format's reader, then
    /// written again, is the same file: the writer writes what its reader reads, without an
    /// error, and nothing drifts (after the first pass, which may round the timestamps or map
    /// the interface names to the format's channels).
    pub fn assert_writes_back<R: LogReader>(
        entries: &[Message],
        write: impl Fn(&[Message]) -> Vec<u8>,
        read: impl Fn(Cursor<Vec<u8>>) -> R,
    ) {
        if entries.is_empty() {
            // An empty log's header carries the time it was written: nothing to compare.
            return;
        }
        let first = write(entries);
        let again = read_strict(read(Cursor::new(first.clone())), first.len());
        let second = write(&again);
        assert!(
            first == second,
            "{entries:?}\nwritten as {:?}\nread back as {again:?}\nwritten again as {:?}",
            String::from_utf8_lossy(&first),
            String::from_utf8_lossy(&second),
        );
    }

    /// Every entry of a file a writer made: any error is a failure.
    fn read_strict(mut reader: impl LogReader, len: usize) -> Vec<Message> {
        let mut entries = Vec::new();
        for _ in 0..len + 2 {
            let mut entry = Message::default();
            match reader.read_into(&mut entry) {
                Ok(true) => entries.push(entry),
                Ok(false) => {
                    // A bit rate the log gives is one CAN has: 1 kbit/s..1 Mbit/s.
                    for entry in &entries {
                        if let Some(rate) = reader.bit_rate(&entry.channel) {
                            assert!(
                                (1_000..=1_000_000).contains(&rate.bits_per_s),
                                "{rate:?} for {}",
                                entry.channel
                            );
                        }
                    }
                    return entries;
                }
                Err(e) => panic!("the writer's own output does not read back: {e}"),
            }
        }
        panic!("the writer's own output of {len} bytes does not end");
    }
}
