//! Device timestamps (`Z1`: milliseconds wrapping at 60000) mapped onto the host's clock, so
//! frames keep the adapter's spacing instead of the USB stack's jitter.

use crate::codec::TIMESTAMP_WRAP_MS;

/// The device counter is trusted only while it stays this close to the host clock (seconds);
/// beyond, the mapping starts again from the host's time.
const MAX_DRIFT_S: f64 = 0.5;

/// Maps the adapter's wrapping millisecond counter to host seconds: the first frame anchors
/// the counter to the host time it arrived; later frames add the counter's progress. A gap
/// longer than half a wrap (30 s, when the counter's progress is ambiguous) or a drift beyond
/// half a second re-anchors.
#[derive(Clone, Debug, Default)]
pub struct DeviceClock {
    anchor: Option<Anchor>,
}

#[derive(Clone, Copy, Debug)]
struct Anchor {
    host_s: f64,
    /// The device counter unwrapped, at the anchor and at the last frame.
    device_ms_at_anchor: u64,
    device_ms: u64,
    last_raw: u16,
    last_host_s: f64,
}

impl DeviceClock {
    pub fn new() -> Self {
        Self::default()
    }

    /// The time of a frame that arrived at `host_s` with the device's timestamp, if it has one.
    pub fn stamp(&mut self, host_s: f64, device_ms: Option<u16>) -> f64 {
        let Some(raw) = device_ms else {
            return host_s;
        };
        let raw = raw % TIMESTAMP_WRAP_MS;
        if let Some(a) = &mut self.anchor
            && host_s - a.last_host_s < f64::from(TIMESTAMP_WRAP_MS) / 2000.0
        {
            let progress = (u32::from(raw) + u32::from(TIMESTAMP_WRAP_MS) - u32::from(a.last_raw))
                % u32::from(TIMESTAMP_WRAP_MS);
            let device_ms = a.device_ms + u64::from(progress);
            let t = a.host_s + (device_ms - a.device_ms_at_anchor) as f64 / 1000.0;
            if (t - host_s).abs() <= MAX_DRIFT_S {
                a.device_ms = device_ms;
                a.last_raw = raw;
                a.last_host_s = host_s;
                return t;
            }
        }
        self.anchor = Some(Anchor {
            host_s,
            device_ms_at_anchor: 0,
            device_ms: 0,
            last_raw: raw,
            last_host_s: host_s,
        });
        host_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_device_spacing_is_kept_across_a_wrap() {
        let mut c = DeviceClock::new();
        assert_eq!(c.stamp(100.0, Some(59_990)), 100.0);
        // USB jitter: the frame arrives 7 ms late, the device says 20 ms after the first.
        let t = c.stamp(100.027, Some(10));
        assert!((t - 100.020).abs() < 1e-9, "{t}");
        assert_eq!(c.stamp(100.5, None), 100.5, "no device time: the host's");
    }

    #[test]
    fn a_long_gap_or_drift_reanchors_to_the_host() {
        let mut c = DeviceClock::new();
        c.stamp(0.0, Some(0));
        assert_eq!(c.stamp(45.0, Some(5_000)), 45.0, "ambiguous after 30 s");
        assert_eq!(
            c.stamp(46.0, Some(5_000)),
            46.0,
            "the counter stood still: drift"
        );
        let t = c.stamp(46.1, Some(5_100));
        assert!((t - 46.1).abs() < 1e-9, "{t}");
    }
}
