//! Device timestamps (`Z1`: milliseconds wrapping at 60000) mapped onto the host's clock, so
//! frames keep the adapter's spacing instead of the USB stack's jitter.

use std::time::Duration;

use buslab_bus::Timestamp;

use crate::codec::TIMESTAMP_WRAP_MS;

/// The device counter is trusted only while it stays this close to the host clock; beyond, the
/// mapping starts again from the host's time.
const MAX_DRIFT: Duration = Duration::from_millis(500);

/// Maps the adapter's wrapping millisecond counter to host time: the first frame anchors the
/// counter to the host time it arrived; later frames add the counter's progress. A gap longer
/// than half a wrap (30 s, when the counter's progress is ambiguous) or a drift beyond half a
/// second re-anchors.
#[derive(Clone, Debug, Default)]
pub struct DeviceClock {
    anchor: Option<Anchor>,
}

#[derive(Clone, Copy, Debug)]
struct Anchor {
    host: Timestamp,
    /// The device counter unwrapped since the anchor, at the last frame.
    device_ms: u64,
    last_raw: u16,
    last_host: Timestamp,
}

impl DeviceClock {
    pub fn new() -> Self {
        Self::default()
    }

    /// The time of a frame that arrived at `host` with the device's timestamp, if it has one.
    pub fn stamp(&mut self, host: Timestamp, device_ms: Option<u16>) -> Timestamp {
        let Some(raw) = device_ms else {
            return host;
        };
        let raw = raw % TIMESTAMP_WRAP_MS;
        let half_wrap = Duration::from_millis(u64::from(TIMESTAMP_WRAP_MS) / 2);
        if let Some(a) = &mut self.anchor
            && host.saturating_since(a.last_host) < half_wrap
            && host >= a.last_host
        {
            let progress = (u32::from(raw) + u32::from(TIMESTAMP_WRAP_MS) - u32::from(a.last_raw))
                % u32::from(TIMESTAMP_WRAP_MS);
            let device_ms = a.device_ms + u64::from(progress);
            let t = a.host.saturating_add(Duration::from_millis(device_ms));
            let drift = t.saturating_since(host).max(host.saturating_since(t));
            if drift <= MAX_DRIFT {
                a.device_ms = device_ms;
                a.last_raw = raw;
                a.last_host = host;
                return t;
            }
        }
        self.anchor = Some(Anchor {
            host,
            device_ms: 0,
            last_raw: raw,
            last_host: host,
        });
        host
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(ms: u64) -> Timestamp {
        Timestamp::from_micros(ms * 1000)
    }

    #[test]
    fn the_device_spacing_is_kept_across_a_wrap() {
        let mut c = DeviceClock::new();
        assert_eq!(c.stamp(ms(100_000), Some(59_990)), ms(100_000));
        // USB jitter: the frame arrives 7 ms late, the device says 20 ms after the first.
        assert_eq!(c.stamp(ms(100_027), Some(10)), ms(100_020));
        assert_eq!(
            c.stamp(ms(100_500), None),
            ms(100_500),
            "no device time: the host's"
        );
    }

    #[test]
    fn a_long_gap_or_drift_reanchors_to_the_host() {
        let mut c = DeviceClock::new();
        c.stamp(ms(0), Some(0));
        assert_eq!(
            c.stamp(ms(45_000), Some(5_000)),
            ms(45_000),
            "ambiguous after 30 s"
        );
        assert_eq!(
            c.stamp(ms(46_000), Some(5_000)),
            ms(46_000),
            "the counter stood still: drift"
        );
        assert_eq!(c.stamp(ms(46_100), Some(5_100)), ms(46_100));
    }
}
