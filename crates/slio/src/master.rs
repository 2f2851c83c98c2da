//! The host side of SLIOs, sans-IO: what the seed's `slio.s` does on the PowerPC node and
//! CANAPI's unfinished `SlIo` class meant to do on the PC.
//!
//! A [`Master`] decides which frames to send and when, and makes sense of what SLIOs send
//! back; an adapter moves the frames (a `CanBus`, or an SJA1000 driven through its
//! registers) and gives it the time on the host's clock ([`Nanos`]). Its rhythms are the
//! SLIOs' and so counted in bit-times ([`BitTime`] consts); [`Master::new`] turns them into
//! nanoseconds at the bus's bit rate, once:
//! - calibration at start: 48 calibration frames, each tried once
//!   ([`Transmit::single_shot`]): before they are calibrated the SLIOs do not acknowledge,
//!   and a frame nobody acknowledges would be retried forever (the seed aborts it);
//! - periodic calibration: a calibration frame every 5000 bit-times (inside the 3000..8000 the
//!   seed asks for, well before the 8192 of the SLIO's watchdog), retried like any frame: one
//!   that lost arbitration to other traffic must still go out in time;
//! - the inventory, from sign-ons and every frame a SLIO sends;
//! - register writes and reads that complete only when the SLIO confirms them: every request is
//!   a 3-byte data frame, as the seed's `make_slio_ffi` builds them (DLC = 3), and only the
//!   read-only registers have a read ([`Request`]); a request's wait for its answer starts when
//!   its frame is handed to the adapter, not when it is queued behind others;
//! - a host that was not running (a PC under load, a process stopped) for nearly the SLIOs'
//!   watchdog may have let them lose their calibration: the master then calibrates them again
//!   as at start and sends the unanswered requests again ([`MasterEvent::CalibrationLost`]).

use std::collections::VecDeque;

use buslab_can::{BitTime, Frame, Nanos};

use crate::ids::{Direction, SlioId, calibration_frame};
use crate::registers::{NotReadable, Register, Reply, Request};
use crate::slio::{LONGEST_FRAME, WATCHDOG};

/// Calibration frames sent at start (the seed's `calibration_slio` loops 48 times).
pub const START_CALIBRATIONS: u32 = 48;
/// Between two periodic calibration frames.
pub const CALIBRATION_EVERY: BitTime = BitTime::new(5000);
/// How long a request waits for the SLIO's answer: a few frames' worth on a busy bus.
pub const ANSWER_WITHIN: BitTime = BitTime::new(4000);
/// The time between two calibration frames handed over after which the SLIOs may have lost
/// their calibration: the watchdog's 8192, less the time the later frame may wait on the wire
/// behind eight of the longest frames. (The rhythm of [`CALIBRATION_EVERY`] keeps the
/// gaps well below this while the host runs.)
pub const CALIBRATION_LOST_AFTER: BitTime = BitTime::new(WATCHDOG.get() - 8 * LONGEST_FRAME.get());

/// A frame for the adapter to send.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transmit {
    pub frame: Frame,
    /// Try once, give up if not acknowledged (CMR.AT after TR on an SJA1000).
    pub single_shot: bool,
}

/// What the master learned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MasterEvent {
    /// A SLIO signed on (or answered for the first time): its number and its inputs.
    Present { slio: SlioId, inputs: u16 },
    /// A SLIO sent a register's content (the answer to a request, a conversion result, an
    /// input report).
    Register {
        slio: SlioId,
        register: Register,
        value: u16,
    },
    /// A request was answered: what the SLIO confirmed.
    Confirmed {
        request: RequestId,
        slio: SlioId,
        register: Register,
        value: u16,
    },
    /// A request got no answer in time.
    NoAnswer { request: RequestId, slio: SlioId },
    /// No calibration frame went out for `silent` (the host did not run), so the SLIOs may
    /// have lost their calibration and ignored or left unanswered what was sent meanwhile.
    /// The start-up calibration goes out again (tried once each: the adapter's abort after the
    /// first also gives up a frame nobody acknowledges), then the requests still unanswered.
    CalibrationLost { silent: Nanos },
}

/// Identifies a request in [`MasterEvent::Confirmed`] and [`MasterEvent::NoAnswer`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RequestId(pub u64);

/// What the master knows of one SLIO.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Known {
    /// The last content each register was seen with (confirmed by the SLIO), by number.
    pub registers: [Option<u16>; 9],
    /// When it last sent anything.
    pub last_heard: Nanos,
}

#[derive(Clone, Copy, Debug)]
struct Pending {
    id: RequestId,
    slio: SlioId,
    register: Register,
    /// Its frame, to send again after a lost calibration.
    frame: Frame,
    /// When the answer is given up: set when the frame is handed to the adapter.
    deadline: Option<Nanos>,
}

/// The host side of SLIOs on one bus.
#[derive(Debug)]
pub struct Master {
    /// [`CALIBRATION_EVERY`] on the host's clock.
    calibration_period: Nanos,
    /// [`CALIBRATION_LOST_AFTER`] on the host's clock.
    calibration_lost_after: Nanos,
    answer_within: Nanos,
    /// Frames to send, with the request each one carries.
    outbox: VecDeque<(Transmit, Option<RequestId>)>,
    events: VecDeque<MasterEvent>,
    known: [Option<Known>; 16],
    pending: Vec<Pending>,
    /// The earliest of `pending`'s deadlines: [`Self::next_deadline`] is asked at every bit by
    /// a node stepped bit by bit, so it is kept rather than searched for.
    first_answer_deadline: Option<Nanos>,
    next_request: u64,
    next_calibration: Option<Nanos>,
    /// When the last calibration frame was handed over (the SLIOs' watchdog restarts about
    /// then); `keeping` counts from its creation.
    last_calibration_sent: Nanos,
}

impl Master {
    /// A master for a bus at `bitrate`, calibrating from `now` on: the 48 start-up
    /// calibration frames are queued, then one every [`CALIBRATION_EVERY`].
    pub fn new(bitrate: u32, now: Nanos) -> Self {
        let mut m = Self {
            calibration_period: CALIBRATION_EVERY.at_bitrate(bitrate),
            calibration_lost_after: CALIBRATION_LOST_AFTER.at_bitrate(bitrate),
            answer_within: ANSWER_WITHIN.at_bitrate(bitrate),
            outbox: VecDeque::new(),
            events: VecDeque::new(),
            known: [None; 16],
            pending: Vec::new(),
            first_answer_deadline: None,
            next_request: 0,
            next_calibration: None,
            last_calibration_sent: now,
        };
        m.calibrate(now);
        m
    }

    /// A master that keeps SLIOs calibrated but does not run the start-up calibration (they
    /// are already calibrated by another host).
    pub fn keeping(bitrate: u32, now: Nanos) -> Self {
        let mut m = Self::new(bitrate, now);
        m.outbox.clear();
        m
    }

    /// Queues the start-up calibration (48 frames, each tried once) and restarts the period.
    pub fn calibrate(&mut self, now: Nanos) {
        for _ in 0..START_CALIBRATIONS {
            self.outbox.push_back(Self::start_up_frame());
        }
        self.next_calibration = Some(now + self.calibration_period());
    }

    fn start_up_frame() -> (Transmit, Option<RequestId>) {
        (
            Transmit {
                frame: calibration_frame(),
                single_shot: true,
            },
            None,
        )
    }

    /// One calibration period ([`CALIBRATION_EVERY`]) on the host's clock.
    pub fn calibration_period(&self) -> Nanos {
        self.calibration_period
    }

    /// The last start-up calibration frame went out at `now` (an adapter that waits for each
    /// one may take long over the 48): the periodic ones follow one period after it, not
    /// after the start. Nothing changes while the periodic calibration is stopped.
    pub fn start_up_sent(&mut self, now: Nanos) {
        if self.next_calibration.is_some() {
            self.next_calibration = Some(now + self.calibration_period());
        }
    }

    /// When the next periodic calibration frame is due, unless it is stopped.
    pub fn next_calibration(&self) -> Option<Nanos> {
        self.next_calibration
    }

    /// How long requests wait for their answer before [`MasterEvent::NoAnswer`] (default
    /// [`ANSWER_WITHIN`]; a host on a loaded machine may want more).
    pub fn set_answer_within(&mut self, wait: Nanos) {
        self.answer_within = wait.max(Nanos::new(1));
    }

    /// Stops the periodic calibration (the SLIOs will lose it after 8192 bit-times).
    pub fn stop_calibrating(&mut self) {
        self.next_calibration = None;
    }

    /// What is known of a SLIO, if it was heard from.
    pub fn known(&self, slio: SlioId) -> Option<&Known> {
        self.known[slio.number() as usize].as_ref()
    }

    /// Every SLIO heard from, in number order.
    pub fn present(&self) -> impl Iterator<Item = (SlioId, &Known)> {
        SlioId::all().filter_map(|s| self.known(s).map(|k| (s, k)))
    }

    /// Writes `value` into a SLIO register; confirmed (or not) by a later event.
    pub fn write(&mut self, slio: SlioId, register: Register, value: u16) -> RequestId {
        self.request(slio, Request::Write { register, value })
            .expect("a write always has its 3-byte frame")
    }

    /// Asks a SLIO for a read-only register's content (DATA_INPUT; ADC: a conversion). A
    /// writable register has no read ([`NotReadable`]): its content is known from the SLIO's
    /// answer to a write ([`Known::registers`]).
    pub fn read(&mut self, slio: SlioId, register: Register) -> Result<RequestId, NotReadable> {
        self.request(slio, Request::read(register)?)
    }

    fn request(&mut self, slio: SlioId, request: Request) -> Result<RequestId, NotReadable> {
        let frame = request.frame(slio)?;
        let id = RequestId(self.next_request);
        self.next_request += 1;
        self.outbox.push_back((
            Transmit {
                frame,
                single_shot: false,
            },
            Some(id),
        ));
        // A conversion request is answered with the ADC register.
        let register = match request {
            Request::Write {
                register: Register::AnalogConfig,
                value,
            } if value & crate::registers::CONVERT != 0 => Register::Adc,
            other => other.register(),
        };
        self.pending.push(Pending {
            id,
            slio,
            register,
            frame,
            deadline: None,
        });
        Ok(id)
    }

    /// A frame from the bus. Returns whether it was a SLIO's.
    pub fn handle_frame(&mut self, now: Nanos, frame: &Frame) -> bool {
        let Some((slio, Direction::FromSlio)) = SlioId::from_id(frame.id()) else {
            return false;
        };
        if frame.is_remote() {
            return true;
        }
        let Ok(reply) = Reply::parse(frame.payload()) else {
            return true;
        };
        let entry = &mut self.known[slio.number() as usize];
        let first = entry.is_none();
        let known = entry.get_or_insert_with(Known::default);
        known.registers[reply.register.index()] = Some(reply.value);
        known.last_heard = now;
        if first || reply.status.reset_detected {
            let inputs = if reply.register == Register::DataInput {
                reply.value
            } else {
                0
            };
            self.events.push_back(MasterEvent::Present { slio, inputs });
        }
        self.events.push_back(MasterEvent::Register {
            slio,
            register: reply.register,
            value: reply.value,
        });
        if let Some(i) = self
            .pending
            .iter()
            .position(|p| p.slio == slio && p.register == reply.register)
        {
            let p = self.pending.remove(i);
            self.pending_changed();
            self.events.push_back(MasterEvent::Confirmed {
                request: p.id,
                slio,
                register: reply.register,
                value: reply.value,
            });
        }
        true
    }

    /// Time passes: a calibration perhaps lost while the host did not run, the periodic
    /// calibration, requests that got no answer.
    pub fn handle_timeout(&mut self, now: Nanos) {
        self.check_calibration_gap(now);
        if let Some(t) = self.next_calibration
            && now >= t
        {
            // Retried like any frame (the seed's `send_calibration` sends it plainly): calibrated
            // SLIOs acknowledge it, and one that lost arbitration must still go out before the
            // SLIOs' watchdog runs out.
            self.outbox.push_back((
                Transmit {
                    frame: calibration_frame(),
                    single_shot: false,
                },
                None,
            ));
            // Keep the rhythm, but never queue a burst after a long pause.
            let period = self.calibration_period;
            self.next_calibration = Some((t + period).max(now + period / 2));
        }
        let mut late = Vec::new();
        self.pending.retain(|p| {
            let expired = p.deadline.is_some_and(|d| now >= d);
            if expired {
                late.push((p.id, p.slio));
            }
            !expired
        });
        self.pending_changed();
        for (request, slio) in late {
            self.events
                .push_back(MasterEvent::NoAnswer { request, slio });
        }
    }

    /// Whether the SLIOs may have lost their calibration since the last calibration frame went
    /// out (asked before anything is handed over: a frame handed over after a pause must not
    /// hide it).
    fn check_calibration_gap(&mut self, now: Nanos) {
        let silent = now.saturating_sub(self.last_calibration_sent);
        if self.next_calibration.is_some() && silent >= self.calibration_lost_after {
            self.recalibrate(now, silent);
        }
    }

    /// The SLIOs may have lost their calibration: the start-up calibration goes first again,
    /// then the requests handed over and not answered (their wait restarts when they go out
    /// again), then what was queued.
    fn recalibrate(&mut self, now: Nanos, silent: Nanos) {
        // The start-up frames go first: while some still wait, this is the same lost
        // calibration (an adapter that does not take frames must not pile up 48 more per
        // look at the clock), and nothing was handed over since.
        if self
            .outbox
            .front()
            .is_some_and(|(t, _)| t.single_shot && t.frame == calibration_frame())
        {
            return;
        }
        let mut again: VecDeque<_> = (0..START_CALIBRATIONS)
            .map(|_| Self::start_up_frame())
            .collect();
        for p in self.pending.iter_mut().filter(|p| p.deadline.is_some()) {
            p.deadline = None;
            again.push_back((
                Transmit {
                    frame: p.frame,
                    single_shot: false,
                },
                Some(p.id),
            ));
        }
        self.pending_changed();
        again.append(&mut self.outbox);
        self.outbox = again;
        // Counted from now until the adapter reports the start-up frames sent.
        self.last_calibration_sent = now;
        self.next_calibration = Some(now + self.calibration_period());
        self.events
            .push_back(MasterEvent::CalibrationLost { silent });
    }

    /// When [`Self::handle_timeout`] must be called.
    pub fn next_deadline(&self) -> Option<Nanos> {
        match (self.next_calibration, self.first_answer_deadline) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    fn pending_changed(&mut self) {
        self.first_answer_deadline = self.pending.iter().filter_map(|p| p.deadline).min();
    }

    /// The next frame to send, handed to the adapter at `now`: a request's answer is awaited
    /// from then on.
    pub fn poll_transmit(&mut self, now: Nanos) -> Option<Transmit> {
        if !self.outbox.is_empty() {
            self.check_calibration_gap(now);
        }
        let (transmit, request) = self.outbox.pop_front()?;
        if transmit.frame == calibration_frame() {
            self.last_calibration_sent = now;
        }
        if let Some(request) = request
            && let Some(p) = self.pending.iter_mut().find(|p| p.id == request)
        {
            p.deadline = Some(now + self.answer_within);
            self.pending_changed();
        }
        Some(transmit)
    }

    /// Frames waiting to be sent.
    pub fn queued(&self) -> usize {
        self.outbox.len()
    }

    /// The next thing learned.
    pub fn poll_event(&mut self) -> Option<MasterEvent> {
        self.events.pop_front()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slio(n: u8) -> SlioId {
        SlioId::new(n).unwrap()
    }

    #[test]
    fn start_up_calibration_then_every_5000_bit_times() {
        let mut m = Master::new(125_000, Nanos::ZERO);
        let mut start = 0;
        while let Some(t) = m.poll_transmit(Nanos::ZERO) {
            assert!(t.single_shot);
            assert_eq!(t.frame, calibration_frame());
            start += 1;
        }
        assert_eq!(start, 48);
        // 5000 bit-times at 125 kbit/s = 40 ms.
        assert_eq!(m.next_deadline(), Some(Nanos::new(40_000_000)));
        m.handle_timeout(Nanos::new(39_999_999));
        assert!(m.poll_transmit(Nanos::new(39_999_999)).is_none());
        m.handle_timeout(Nanos::new(40_000_000));
        assert_eq!(
            m.poll_transmit(Nanos::new(40_000_000)).map(|t| t.frame),
            Some(calibration_frame())
        );
        assert_eq!(m.next_deadline(), Some(Nanos::new(80_000_000)));
    }

    #[test]
    fn the_period_restarts_from_the_last_start_up_frame() {
        // An adapter that waited 100 ms for the 48 start-up frames: the next one is due one
        // period after the last of them, not 60 ms before it went out.
        let mut m = Master::new(125_000, Nanos::ZERO);
        while m.poll_transmit(Nanos::ZERO).is_some() {}
        m.start_up_sent(Nanos::new(100_000_000));
        assert_eq!(m.next_deadline(), Some(Nanos::new(140_000_000)));
        m.stop_calibrating();
        m.start_up_sent(Nanos::new(200_000_000));
        assert_eq!(m.next_deadline(), None);
    }

    #[test]
    fn a_sign_on_makes_a_slio_present_and_writes_complete_on_confirmation() {
        let mut m = Master::keeping(125_000, Nanos::ZERO);
        let sign_on = Frame::data(slio(3).reply_id(), &[0x30, 0x00, 0x03]).unwrap();
        assert!(m.handle_frame(Nanos::new(10), &sign_on));
        assert_eq!(
            m.poll_event(),
            Some(MasterEvent::Present {
                slio: slio(3),
                inputs: 3
            })
        );
        m.poll_event();
        let r = m.write(slio(3), Register::DataOutput, 0x2000);
        let sent = m.poll_transmit(Nanos::new(20)).unwrap();
        assert!(!sent.single_shot);
        assert_eq!(sent.frame.to_string(), "29C#032000");
        // Another SLIO's frame does not confirm it.
        m.handle_frame(
            Nanos::new(30),
            &Frame::data(slio(4).reply_id(), &[0x23, 0x20, 0x00]).unwrap(),
        );
        let confirmed = |m: &mut Master| {
            std::iter::from_fn(|| m.poll_event())
                .any(|e| matches!(e, MasterEvent::Confirmed { request, .. } if request == r))
        };
        assert!(!confirmed(&mut m));
        m.handle_frame(
            Nanos::new(40),
            &Frame::data(slio(3).reply_id(), &[0x23, 0x20, 0x00]).unwrap(),
        );
        assert!(confirmed(&mut m));
        assert_eq!(
            m.known(slio(3)).unwrap().registers[Register::DataOutput.index()],
            Some(0x2000)
        );
    }

    #[test]
    fn reads_are_three_byte_frames_and_writable_registers_have_none() {
        let mut m = Master::keeping(125_000, Nanos::ZERO);
        m.read(slio(3), Register::DataInput).unwrap();
        m.read(slio(3), Register::Adc).unwrap();
        let sent: Vec<String> = std::iter::from_fn(|| m.poll_transmit(Nanos::ZERO))
            .map(|t| t.frame.to_string())
            .collect();
        // Seed 002 §2.1.2.1 and `make_slio_ffi` (DLC = 3): never `29C#00`.
        assert_eq!(sent, ["29C#000000", "29C#080000"]);
        for register in [
            Register::DataOutput,
            Register::OutputEnable,
            Register::Dpm1,
            Register::AnalogConfig,
        ] {
            assert_eq!(
                m.read(slio(3), register),
                Err(NotReadable(register)),
                "{register}"
            );
        }
        assert!(
            m.poll_transmit(Nanos::ZERO).is_none(),
            "a refused read sends nothing"
        );
    }

    #[test]
    fn an_unanswered_request_times_out_and_garbage_is_ignored() {
        let mut m = Master::keeping(125_000, Nanos::ZERO);
        let r = m.read(slio(5), Register::Adc).unwrap();
        m.poll_transmit(Nanos::ZERO).unwrap();
        m.handle_frame(
            Nanos::new(1),
            &Frame::data(slio(5).reply_id(), &[0x20]).unwrap(),
        );
        m.handle_frame(
            Nanos::new(1),
            &Frame::remote(slio(5).reply_id(), 3).unwrap(),
        );
        assert!(!m.handle_frame(Nanos::new(1), &"123#112233".parse().unwrap()));
        let deadline = ANSWER_WITHIN.get() * 8000;
        m.handle_timeout(Nanos::new(deadline));
        let events: Vec<_> = std::iter::from_fn(|| m.poll_event()).collect();
        assert!(events.contains(&MasterEvent::NoAnswer {
            request: r,
            slio: slio(5)
        }));
    }

    /// CI, 2026-11-28: `buslab slio --calibrate write` on a loaded machine stopped running for
    /// longer than the SLIOs' watchdog after the census; they lost their calibration, executed
    /// the write without answering (a roughly calibrated SLIO does not transmit), signed on
    /// again after the next calibration frames, and the write was never answered. Now a gap
    /// near the watchdog between calibration frames queues the start-up calibration again,
    /// then the unanswered request.
    #[test]
    fn a_host_that_did_not_run_for_the_watchdog_calibrates_again_and_repeats_its_request() {
        let bit = 8000; // 125 kbit/s
        let mut m = Master::new(125_000, Nanos::ZERO);
        // A user's generous wait (`buslab slio --timeout 30s`).
        let within = 30_000_000_000;
        m.set_answer_within(Nanos::new(within));
        while m.poll_transmit(Nanos::ZERO).is_some() {}
        m.start_up_sent(Nanos::ZERO);
        let r = m.write(slio(3), Register::DataOutput, 0x2080);
        assert_eq!(
            m.poll_transmit(Nanos::ZERO).unwrap().frame.to_string(),
            "29C#032080"
        );
        // A late wake-up that keeps within the watchdog: only the periodic frame.
        let late = 6000 * bit;
        m.handle_timeout(Nanos::new(late));
        assert_eq!(m.poll_event(), None);
        let t = m.poll_transmit(Nanos::new(late)).unwrap();
        assert!(!t.single_shot && t.frame == calibration_frame());
        assert!(m.poll_transmit(Nanos::new(late)).is_none());
        // Then nothing for CALIBRATION_LOST_AFTER.
        let back = late + CALIBRATION_LOST_AFTER.get() * bit;
        m.handle_timeout(Nanos::new(back));
        assert_eq!(
            m.poll_event(),
            Some(MasterEvent::CalibrationLost {
                silent: Nanos::new(CALIBRATION_LOST_AFTER.get() * bit)
            })
        );
        let sent: Vec<Transmit> =
            std::iter::from_fn(|| m.poll_transmit(Nanos::new(back))).collect();
        assert_eq!(sent.len(), 49);
        assert!(
            sent[..48]
                .iter()
                .all(|t| t.single_shot && t.frame == calibration_frame())
        );
        assert_eq!(sent[48].frame.to_string(), "29C#032080");
        // The request's wait restarted when it went out again; its answer completes it.
        assert_eq!(m.next_deadline(), Some(Nanos::new(back + 5000 * bit)));
        m.stop_calibrating();
        assert_eq!(m.next_deadline(), Some(Nanos::new(back + within)));
        m.handle_frame(
            Nanos::new(back + 1),
            &Frame::data(slio(3).reply_id(), &[0x23, 0x20, 0x80]).unwrap(),
        );
        let events: Vec<_> = std::iter::from_fn(|| m.poll_event()).collect();
        assert!(
            events
                .iter()
                .any(|e| matches!(e, MasterEvent::Confirmed { request, value: 0x2080, .. } if *request == r)),
            "{events:?}"
        );
    }

    /// The fuzzer (monican_app): an adapter that takes no frames while the clock jumps again
    /// and again got 48 more start-up frames per jump. One lost calibration queues them once.
    #[test]
    fn an_adapter_that_takes_no_frames_does_not_pile_up_start_up_frames() {
        let bit = 8000;
        let mut m = Master::new(125_000, Nanos::ZERO);
        assert_eq!(m.queued(), 48);
        for step in 1..=10 {
            m.handle_timeout(Nanos::new(step * CALIBRATION_LOST_AFTER.get() * bit));
        }
        // The first 48 were never taken: still the one start-up burst, and the periodic
        // frames behind it (at most one per look).
        assert!(m.queued() <= 48 + 10, "{} queued", m.queued());
    }

    /// A master that stopped calibrating leaves the SLIOs alone, however long it was away.
    #[test]
    fn a_master_that_stopped_calibrating_does_not_calibrate_again() {
        let mut m = Master::keeping(125_000, Nanos::ZERO);
        m.stop_calibrating();
        m.handle_timeout(Nanos::new(u64::MAX / 2));
        assert_eq!(m.poll_event(), None);
        assert!(m.poll_transmit(Nanos::new(u64::MAX / 2)).is_none());
    }

    /// The wait for an answer opened when the request was queued, so a request queued behind
    /// the 48 start-up calibration frames (which an adapter confirms one by one, slowly on a
    /// loaded machine) was given up before it was even sent.
    #[test]
    fn the_answer_is_awaited_from_the_hand_over_not_from_the_queueing() {
        let mut m = Master::new(125_000, Nanos::ZERO);
        let r = m.read(slio(3), Register::DataInput).unwrap();
        let within = ANSWER_WITHIN.get() * 8000;
        // Not handed over yet: no answer deadline, however late it is.
        assert_eq!(
            m.next_deadline(),
            Some(Nanos::new(CALIBRATION_EVERY.get() * 8000))
        );
        m.stop_calibrating();
        assert_eq!(m.next_deadline(), None);
        m.handle_timeout(Nanos::new(10 * within));
        assert!(std::iter::from_fn(|| m.poll_event()).next().is_none());
        // The 48 calibration frames, then the read, handed over at 10 × within.
        let mut sent = 0;
        while let Some(t) = m.poll_transmit(Nanos::new(10 * within)) {
            sent += 1;
            if !t.single_shot {
                assert_eq!(t.frame.to_string(), "29C#000000");
            }
        }
        assert_eq!(sent, 49);
        assert_eq!(m.next_deadline(), Some(Nanos::new(11 * within)));
        m.handle_timeout(Nanos::new(11 * within - 1));
        assert!(std::iter::from_fn(|| m.poll_event()).next().is_none());
        m.handle_timeout(Nanos::new(11 * within));
        assert_eq!(
            m.poll_event(),
            Some(MasterEvent::NoAnswer {
                request: r,
                slio: slio(3)
            })
        );
    }
}
