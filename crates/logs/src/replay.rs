//! When each frame of a log goes out when it is replayed, as canplayer times it, sans-IO: the
//! caller gives its own clock's time (a [`Duration`] since an epoch it chose) and sleeps until
//! the time given back.

use std::time::Duration;

use crate::Timestamp;

/// How a replay is timed (canplayer's options).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReplayTiming {
    /// Play this many times faster than logged (canplayer has none: 1.0).
    pub speed: f64,
    /// `-s`: a gap in the log longer than this restarts the timing at the frame after it
    /// (sent at once).
    pub skip_gaps: Option<Duration>,
    /// `-g`: at least this long between two frames sent.
    pub min_gap: Option<Duration>,
    /// `-t`: the log's times are ignored (frames go as fast as `min_gap` lets them).
    pub ignore_timestamps: bool,
}

impl Default for ReplayTiming {
    fn default() -> Self {
        Self {
            speed: 1.0,
            skip_gaps: None,
            min_gap: None,
            ignore_timestamps: false,
        }
    }
}

/// The due times of a log's frames, one pass over the log at a time.
#[derive(Clone, Debug)]
pub struct ReplaySchedule {
    timing: ReplayTiming,
    /// The log time the timing counts from, and when (caller's clock) it was due.
    zero: Option<(Timestamp, Duration)>,
    previous: Option<Timestamp>,
    last_sent: Option<Duration>,
}

impl ReplaySchedule {
    pub fn new(timing: ReplayTiming) -> Self {
        Self {
            timing,
            zero: None,
            previous: None,
            last_sent: None,
        }
    }

    /// A new pass over the log (`-l`): its first frame is due at once, the later ones from it.
    /// The gap to the last frame sent still holds.
    pub fn restart(&mut self) {
        self.zero = None;
        self.previous = None;
    }

    /// When the frame logged at `at` is due, asked at `now`: its time since the first frame of
    /// the pass, divided by the speed, after the time the first was due; never sooner than
    /// `min_gap` after the last frame sent. Saturates at the end of the caller's clock.
    pub fn due(&mut self, at: Timestamp, now: Duration) -> Duration {
        let mut due = now;
        if !self.timing.ignore_timestamps {
            if let (Some(limit), Some(before)) = (self.timing.skip_gaps, self.previous)
                && at.saturating_since(before) > limit
            {
                self.zero = Some((at, now));
            }
            self.previous = Some(at);
            let (t0, start) = *self.zero.get_or_insert((at, now));
            let offset = at.saturating_since(t0).as_secs_f64() / self.timing.speed;
            let offset = Duration::try_from_secs_f64(offset).unwrap_or(Duration::MAX);
            due = start.saturating_add(offset);
        }
        if let (Some(gap), Some(last)) = (self.timing.min_gap, self.last_sent) {
            due = due.max(last.saturating_add(gap));
        }
        due
    }

    /// The frame went out at `now`.
    pub fn sent(&mut self, now: Duration) {
        self.last_sent = Some(now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    fn at(ms: u64) -> Timestamp {
        Timestamp::from_micros(1_700_000_000_000_000 + ms * 1000)
    }

    /// Plays the log times `log` (ms), each frame sent when due; the send times.
    fn play(timing: ReplayTiming, log: &[u64], start: Duration) -> Vec<Duration> {
        let mut s = ReplaySchedule::new(timing);
        let mut now = start;
        log.iter()
            .map(|&t| {
                now = now.max(s.due(at(t), now));
                s.sent(now);
                now
            })
            .collect()
    }

    #[test]
    fn frames_keep_their_spacing_from_the_first_scaled_by_the_speed() {
        let log = [0, 10, 10, 250];
        assert_eq!(
            play(ReplayTiming::default(), &log, ms(5)),
            [ms(5), ms(15), ms(15), ms(255)]
        );
        let twice = ReplayTiming {
            speed: 2.0,
            ..ReplayTiming::default()
        };
        assert_eq!(play(twice, &log, ms(0)), [ms(0), ms(5), ms(5), ms(125)]);
    }

    #[test]
    fn a_long_gap_restarts_the_timing_and_a_minimum_gap_spaces_the_frames() {
        let skip = ReplayTiming {
            skip_gaps: Some(ms(100)),
            ..ReplayTiming::default()
        };
        // The 5 s gap is skipped: 5000 goes at once after 20, 5010 10 ms later.
        assert_eq!(
            play(skip, &[0, 20, 5000, 5010], ms(0)),
            [ms(0), ms(20), ms(20), ms(30)]
        );
        let spaced = ReplayTiming {
            min_gap: Some(ms(7)),
            ..ReplayTiming::default()
        };
        assert_eq!(
            play(spaced, &[0, 1, 2, 50], ms(0)),
            [ms(0), ms(7), ms(14), ms(50)]
        );
        let untimed = ReplayTiming {
            ignore_timestamps: true,
            min_gap: Some(ms(3)),
            ..ReplayTiming::default()
        };
        assert_eq!(play(untimed, &[0, 900, 9000], ms(1)), [ms(1), ms(4), ms(7)]);
    }

    #[test]
    fn a_new_pass_starts_from_its_first_frame_and_garbage_times_saturate() {
        let mut s = ReplaySchedule::new(ReplayTiming::default());
        assert_eq!(s.due(at(100), ms(0)), ms(0));
        assert_eq!(s.due(at(200), ms(0)), ms(100));
        s.restart();
        assert_eq!(s.due(at(100), ms(500)), ms(500));
        // A log time far after the first: far in the future, no panic.
        let far = s.due(Timestamp::since_epoch(Duration::MAX), ms(500));
        assert!(far > Duration::from_secs(1 << 60), "{far:?}");
        // A log going backwards: due at once.
        s.restart();
        assert_eq!(s.due(at(100), ms(0)), ms(0));
        assert_eq!(s.due(at(50), ms(1)), ms(0));
    }
}
