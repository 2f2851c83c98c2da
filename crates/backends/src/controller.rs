//! A host's controller configuration (`buslab.toml`'s `[controller]`, the seed's configuration
//! assistant) applied where the bus has the setting: on buslab's bus each client's own SJA1000
//! takes every part (`< buslab_controller … >`); an SLCAN adapter takes the bit rate (`S`/`s`),
//! listen-only (`L`) and the acceptance code and mask (`M`/`m`, Lawicel's); a SocketCAN
//! interface takes the acceptance filter as kernel filters. What a transport cannot apply is
//! said in the [`ControllerReport`], never dropped in silence.
//!
//! Where the filter is not the client's own chip's, [`Accepting`] checks each received frame
//! as the configured SJA1000 would ([`AcceptanceFilter::accepts`], the model's logic), so the
//! frames a command shows are the ones the configured filter lets through, whatever the
//! transport filtered before.

use std::fmt;
use std::time::{Duration, Instant};

use buslab_bus::{
    AcceptanceFilter, BusAdmin, BusError, CanBus, ControllerPart, ControllerSettings, ErrorState,
    Filter, Message, Record,
};
use buslab_can::Frame;

use crate::DynBus;

/// What became of one part of the controller settings.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Applied: where and how.
    Applied(String),
    /// Not applied, and why (what to do instead when there is something).
    NotApplied(String),
}

/// What became of each part asked for, in [`ControllerPart::ALL`]'s order.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ControllerReport {
    pub parts: Vec<(ControllerPart, Outcome)>,
}

impl ControllerReport {
    /// Every part of `settings` with the outcome `decide` gives it.
    pub fn each(settings: &ControllerSettings, decide: impl Fn(ControllerPart) -> Outcome) -> Self {
        Self {
            parts: settings
                .parts()
                .into_iter()
                .map(|p| (p, decide(p)))
                .collect(),
        }
    }

    /// The parts that were not applied, with why.
    pub fn not_applied(&self) -> impl Iterator<Item = (ControllerPart, &str)> {
        self.parts.iter().filter_map(|(p, o)| match o {
            Outcome::NotApplied(why) => Some((*p, why.as_str())),
            Outcome::Applied(_) => None,
        })
    }

    pub fn is_empty(&self) -> bool {
        self.parts.is_empty()
    }
}

/// One line per part: `the bit timing (controller.bitrate/btr0/btr1): applied: …`.
impl fmt::Display for ControllerReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, (part, outcome)) in self.parts.iter().enumerate() {
            if i > 0 {
                f.write_str("\n")?;
            }
            match outcome {
                Outcome::Applied(how) => write!(f, "{}: applied: {how}", part.describe())?,
                Outcome::NotApplied(why) => write!(f, "{}: not applied: {why}", part.describe())?,
            }
        }
        Ok(())
    }
}

/// Frames refused after the time is up that one call still looks through.
const LATE_FRAMES: usize = 4096;

/// A bus whose received frames are those `filter` lets through, checked as the configured
/// SJA1000 checks them.
pub struct Accepting {
    inner: DynBus,
    filter: AcceptanceFilter,
}

impl Accepting {
    pub fn new(inner: DynBus, filter: AcceptanceFilter) -> Self {
        Self { inner, filter }
    }

    /// The inner bus's events until one passes or `timeout` is over.
    fn next(
        &mut self,
        timeout: Option<Duration>,
        mut read: impl FnMut(&mut DynBus, Option<Duration>) -> Result<Option<Message>, BusError>,
    ) -> Result<Option<Message>, BusError> {
        let deadline = timeout.map(|t| Instant::now() + t);
        // Once the time is up, the frames already there are still looked through, up to a
        // bound (a bus that never stops must not hold the caller).
        let mut late = 0;
        loop {
            let left = deadline.map(|d| d.saturating_duration_since(Instant::now()));
            match read(&mut self.inner, left)? {
                Some(Message {
                    record: Record::Frame(frame),
                    ..
                }) if !self.filter.accepts(&frame) => {
                    if left.is_some_and(|l| l.is_zero()) {
                        late += 1;
                        if late > LATE_FRAMES {
                            return Ok(None);
                        }
                    }
                }
                other => return Ok(other),
            }
        }
    }
}

impl CanBus for Accepting {
    fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
        self.inner.send(frame)
    }

    fn send_all(&mut self, frames: &[Frame]) -> Result<(), BusError> {
        self.inner.send_all(frames)
    }

    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
        let event = self.next(timeout, |bus, left| {
            Ok(bus.recv(left)?.map(Message::into_record))
        })?;
        Ok(event.and_then(Message::into_frame))
    }

    fn recv_event(&mut self, timeout: Option<Duration>) -> Result<Option<Message>, BusError> {
        self.next(timeout, |bus, left| bus.recv_event(left))
    }

    fn set_error_frames(&mut self, on: bool) -> Result<(), BusError> {
        self.inner.set_error_frames(on)
    }

    fn set_filters(&mut self, filters: &[Filter]) -> Result<(), BusError> {
        self.inner.set_filters(filters)
    }

    fn state(&mut self) -> Result<ErrorState, BusError> {
        self.inner.state()
    }

    fn channel_info(&self) -> String {
        self.inner.channel_info()
    }

    fn admin(&mut self) -> Option<&mut dyn BusAdmin> {
        self.inner.admin()
    }

    /// The inner bus's: a wake ends the inner wait, which ends this one (`None`).
    fn recv_waker(&mut self) -> Option<std::sync::Arc<dyn buslab_bus::RecvWaker>> {
        self.inner.recv_waker()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::VecDeque;

    /// A bus that hands out frames from a list.
    struct Scripted(VecDeque<Frame>);

    impl CanBus for Scripted {
        fn send(&mut self, _: &Frame) -> Result<(), BusError> {
            Ok(())
        }
        fn recv(&mut self, _: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
            Ok(self
                .0
                .pop_front()
                .map(|f| Message::rx(buslab_bus::Timestamp::EPOCH, "test", f)))
        }
        fn set_filters(&mut self, _: &[Filter]) -> Result<(), BusError> {
            Ok(())
        }
        fn state(&mut self) -> Result<ErrorState, BusError> {
            Ok(ErrorState::Active)
        }
        fn channel_info(&self) -> String {
            "scripted".into()
        }
    }

    #[test]
    fn only_the_frames_the_filter_lets_through_come_out() {
        let frames = ["100#", "123#11", "124#", "00000123#", "123#R"];
        let inner = Scripted(frames.iter().map(|t| t.parse().unwrap()).collect());
        let mut bus = Accepting::new(Box::new(inner), AcceptanceFilter::standard_id(0x123));
        let mut got = Vec::new();
        while let Some(m) = bus.recv(Some(Duration::ZERO)).unwrap() {
            got.push(m.record.to_string());
        }
        // standard_id passes data and remote frames of 0x123, nothing else.
        assert_eq!(got, ["123#11", "123#R"]);
    }

    #[test]
    fn a_report_names_each_part_and_what_became_of_it() {
        let settings = ControllerSettings {
            filter: Some(AcceptanceFilter::AcceptAll),
            output_control: Some(0x1A),
            ..ControllerSettings::default()
        };
        let report = ControllerReport::each(&settings, |p| match p {
            ControllerPart::Filter => Outcome::Applied("by the chip".into()),
            _ => Outcome::NotApplied("no such setting".into()),
        });
        assert_eq!(
            report.to_string(),
            "the acceptance filter (controller.filter/acceptance_code/acceptance_mask): applied: by the chip\n\
             the output control (controller.output_control): not applied: no such setting"
        );
        assert_eq!(report.not_applied().count(), 1);
    }
}
