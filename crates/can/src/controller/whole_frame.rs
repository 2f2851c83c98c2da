//! A whole frame at once: what the bus engine needs to apply a clean frame to every node
//! without stepping each bit, and the controller's side of it.
//!
//! The engine asks every node whether it is lined up at a frame start ([`FrameStart`]), picks
//! the winner by comparing the frames, works out each loser's lost bit from the wire bits, and
//! then moves every node through the frame in a few ranges of wire bits
//! ([`Controller::advance_frame`]). The node ends in exactly the state the bit-by-bit path
//! leaves it in; that equivalence is what `buslab-sim`'s property tests check.

use core::ops::Range;

use super::{Controller, ErrorState, Event, Phase};
use crate::wire::{Bits, Encoded, Receiver};
use crate::{Frame, Level};

/// Bits of intermission after EOF, applied with the frame.
const INTERMISSION_BITS: u32 = 3;

/// A node's answer when the engine considers applying a whole frame at once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameStart<'a> {
    /// Not waiting for SOF on an idle bus as an error-active node, or a node kind that cannot
    /// take a frame at once: the engine steps bit by bit.
    NotReady,
    /// Waiting for SOF, error-active. `sends`: the frame it starts with SOF now, if any;
    /// `acks`: it acknowledges a correct frame it does not send (not listen-only).
    Ready {
        sends: Option<&'a Encoded>,
        acks: bool,
    },
}

/// A node's part in the frame being applied.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameRole {
    /// Sends the frame and wins arbitration.
    Transmitter,
    /// Sent SOF and lost arbitration at wire bit `wire_bit` (SOF = 0), which is bit `index`
    /// of its de-stuffed frame (what [`Event::ArbitrationLost`] reports).
    LostArbitration { wire_bit: u32, index: u32 },
    /// Receives it.
    Receiver,
}

/// What a [`Controller::bystander`] does in the frames going by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bystander {
    /// Receives them (acknowledging them unless listen-only).
    Receiver,
    /// Sends SOF with its frame (arbitration key `key`) each time and loses, then receives.
    Loser { key: u32 },
}

/// A clean, acknowledged frame on the wire, from SOF to the end of intermission, as every node
/// sees it.
#[derive(Clone, Debug)]
pub struct WireFrame {
    frame: Frame,
    bus: Bits,
    ack_slot: u32,
    /// A receiver that took SOF..ACK delimiter: where every node's receive path ends.
    receiver: Receiver,
}

impl WireFrame {
    /// The winner's frame on a bus where a receiver acknowledges. `None` if the bits do not
    /// decode to a frame (never for what [`crate::wire::encode`] makes).
    pub fn new(winner: &Encoded) -> Option<Self> {
        let bus = winner.on_bus();
        let receiver = Receiver::after_ack_delimiter(winner);
        let frame = receiver.decoded()?.frame;
        Some(Self {
            frame,
            bus,
            ack_slot: winner.ack_slot() as u32,
            receiver,
        })
    }

    /// The receive path every node ends with: a [`Receiver`] that took SOF..ACK delimiter.
    pub fn receiver(&self) -> &Receiver {
        &self.receiver
    }

    /// The frame as receivers deliver it.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// The bus levels SOF..end of EOF (ACK slot dominant).
    pub fn bus(&self) -> &Bits {
        &self.bus
    }

    /// Wire bits SOF..end of EOF.
    pub fn len(&self) -> u32 {
        self.bus.len() as u32
    }

    /// Always false: a frame has bits.
    pub fn is_empty(&self) -> bool {
        self.bus.is_empty()
    }

    /// Bit-times the frame takes with its intermission: when it has been applied every node
    /// waits for the next SOF again.
    pub fn total(&self) -> u32 {
        self.len() + INTERMISSION_BITS
    }

    /// Wire index of the ACK slot.
    pub fn ack_slot(&self) -> u32 {
        self.ack_slot
    }

    /// Wire index of EOF bit `n` (1..=7): receivers deliver at 6, the transmitter is done
    /// at 7.
    pub fn eof_bit(&self, n: u32) -> u32 {
        self.len() - 8 + n
    }

    /// The wire bits at which some node may report something, given the losers' lost bits:
    /// arbitration lost, the ACK slot (a receiver's REC goes down), EOF bits 6 and 7. The
    /// engine cuts the frame after each of them, so every event has its exact bit-time.
    pub fn event_bits(&self) -> [u32; 3] {
        [self.ack_slot, self.eof_bit(6), self.eof_bit(7)]
    }

    /// How `loser` loses arbitration to `winner` (both sent SOF together): its wire bit and
    /// de-stuffed index. `None` unless it loses on a recessive data bit of its arbitration
    /// field, as distinct arbitration fields always do.
    pub fn lost_bit(loser: &Encoded, winner: &Encoded) -> Option<FrameRole> {
        ArbitrationBits::of(loser).lost_to(ArbitrationBits::of(winner))
    }
}

/// What deciding arbitration needs of a frame on the wire: its first 64 wire bits. Any
/// arbitration field ends inside them (at most 32 de-stuffed bits and their stuff bits), so a
/// difference after them is never a lost arbitration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArbitrationBits {
    /// Wire bits 0..64, first bit lowest; zero past the frame's end.
    bits: u64,
    len: u32,
    extended: bool,
}

/// Which of the first 64 wire bits `bits` (inside the stuffed region) are stuff bits: from
/// bit 5 on, those after five equal bits (as the encoder inserts them).
#[inline]
fn stuff_bits(bits: u64) -> u64 {
    // equal[i]: bit i equals bit i - 1.
    let equal = !(bits ^ bits << 1);
    equal << 1 & equal << 2 & equal << 3 & equal << 4 & !0x1F
}

impl ArbitrationBits {
    #[inline]
    pub fn of(frame: &Encoded) -> Self {
        Self {
            bits: frame.stuffed().window(0) as u64,
            len: frame.stuffed().len() as u32,
            extended: frame.frame().is_extended(),
        }
    }

    /// [`WireFrame::lost_bit`] of a loser with these bits against `winner`.
    #[inline]
    pub fn lost_to(self, winner: Self) -> Option<FrameRole> {
        let diff = (self.bits ^ winner.bits) & !1;
        let i = diff.trailing_zeros();
        if diff == 0 || i >= self.len.min(winner.len) {
            return None;
        }
        let bit = 1u64 << i;
        // Up to bit `i` both frames have the same bits, so the same stuff bits: found here
        // from the bits, only where needed, rather than for every sender and frame.
        let stuff = stuff_bits(self.bits) & (bit << 1).wrapping_sub(1);
        let index = i - (stuff & (bit - 1)).count_ones();
        let arbitration_end = if self.extended { 32 } else { 12 };
        let ok = self.bits & bit != 0 && stuff & bit == 0 && (1..=arbitration_end).contains(&index);
        ok.then_some(FrameRole::LostArbitration { wire_bit: i, index })
    }
}

impl Controller {
    /// Whether this controller is lined up at a frame start (bus idle, waiting for SOF,
    /// error-active) and what it sends with the next SOF.
    #[inline]
    pub fn frame_start(&self) -> FrameStart<'_> {
        if self.phase != Phase::Idle || self.state() != ErrorState::Active {
            return FrameStart::NotReady;
        }
        let sends = match (self.drive, &self.tx) {
            (Level::Recessive, _) => None,
            (Level::Dominant, Some(tx)) => Some(tx),
            (Level::Dominant, None) => return FrameStart::NotReady,
        };
        FrameStart::Ready {
            sends,
            acks: !self.config.listen_only,
        }
    }

    /// The wire bits `bits` (SOF = 0, up to [`WireFrame::total`]) of `frame` have passed, this
    /// node taking part as `role`: applies what the bit-by-bit path does in them, with the
    /// same events. Call it with consecutive ranges from 0, after [`Self::frame_start`] said
    /// `Ready`. Between two calls only the queue and the counters are meant to be looked at;
    /// after the last range the controller is exactly where stepping every bit leaves it.
    ///
    /// The engine may instead call the steps it is made of at their bits, in this order:
    /// [`Self::frame_begin`] (bit 0), [`Self::frame_lost`] (a loser's lost bit),
    /// [`Self::frame_ack`] (ACK slot), [`Self::frame_received`] (EOF 6),
    /// [`Self::frame_eof7`] (EOF 7), [`Self::frame_end`] (last intermission bit).
    pub fn advance_frame(&mut self, frame: &WireFrame, role: FrameRole, bits: Range<u32>) {
        if bits.contains(&0) {
            self.frame_begin(role);
        }
        if let FrameRole::LostArbitration { wire_bit, index } = role
            && bits.contains(&wire_bit)
        {
            self.lose_arbitration(index);
        }
        if bits.contains(&frame.ack_slot) {
            self.frame_ack();
        }
        if bits.contains(&frame.eof_bit(6))
            && let Some(event) = self.frame_received(frame)
        {
            self.events.push_back(event);
        }
        if bits.contains(&frame.eof_bit(7)) {
            self.last_eof_bit_queued();
        }
        if bits.contains(&(frame.total() - 1)) {
            self.frame_end(frame);
        }
    }

    /// Wire bit 0 (SOF) of a whole frame, taking part as `role`.
    #[inline]
    pub fn frame_begin(&mut self, role: FrameRole) {
        self.phase = Phase::Frame;
        self.transmitting = role != FrameRole::Receiver;
        self.drive = Level::Recessive;
    }

    /// The lost bit (de-stuffed `index`) of a whole frame: arbitration lost there. Returns
    /// the [`Event::ArbitrationLost`] to hand on (not queued, unlike a [`Event::Dropped`]
    /// that may follow it: handle the returned event first, then poll).
    #[inline]
    pub fn frame_lost(&mut self, index: u32) -> Option<Event> {
        // `lose_arbitration`, with its first event handed back.
        self.transmitting = false;
        let frame = *self.tx.as_ref()?.frame();
        if self.config.single_shot || self.abort_in_flight {
            self.drop_tx();
        }
        Some(Event::ArbitrationLost { frame, bit: index })
    }

    /// The ACK slot of a whole frame.
    #[inline]
    pub fn frame_ack(&mut self) {
        if self.transmitting || self.config.listen_only {
            return;
        }
        // Our dominant ACK: a successful reception (rule 8). With REC at 0 it stays 0 and the
        // counters' state, already derived from them, stays the same: nothing to do.
        if self.counters.rec != 0 {
            self.counters.receive_ok();
            self.update_state();
        }
    }

    /// EOF bit 6 of a whole frame: the event a receiver delivers there, which the caller hands
    /// on (it is not queued in the controller).
    #[inline]
    pub fn frame_received(&self, frame: &WireFrame) -> Option<Event> {
        (!self.transmitting).then_some(Event::Received(frame.frame))
    }

    /// EOF bit 7 of a whole frame: the transmitter's frame is sent. Returns its
    /// [`Event::Transmitted`] to hand on (not queued, as with [`Self::frame_received`]; what
    /// may follow it, such as the frame received back with self-reception, is: handle
    /// whatever was queued before, then the returned event, then poll). `None` for a
    /// receiver.
    #[inline]
    pub fn frame_eof7(&mut self) -> Option<Event> {
        self.last_eof_bit()
    }

    /// What this controller, lined up at a frame start, does in the next whole frames as
    /// long as nobody looks at it: `None` unless it only watches them go by, with no
    /// report of its own but the frame received (and the arbitration lost, for a
    /// [`Bystander::Loser`]). Such a node's state after any number of frames is known
    /// without applying each one ([`Self::bystander_frames`]): the engine advances these
    /// nodes as a group and fills them in when something looks at them.
    ///
    /// The conditions: error-active, REC 0 (a reception leaves it 0; listen-only nodes do
    /// not count it), no event waiting, not single-shot, and either nothing to send (or
    /// listen-only) or one frame it retries after losing (no abort pending, nothing queued
    /// since it was chosen, so the frame end keeps it). Given a frame to send, such a node is
    /// a bystander again.
    #[inline]
    pub fn bystander(&self) -> Option<Bystander> {
        // Single-shot nodes never: one given a frame to send would drop it when it loses.
        if self.phase != Phase::Idle
            || self.state() != ErrorState::Active
            || (self.counters.rec != 0 && !self.config.listen_only)
            || !self.events.is_empty()
            || self.config.single_shot
        {
            return None;
        }
        match (self.drive, &self.tx) {
            (Level::Recessive, _) if self.config.listen_only => Some(Bystander::Receiver),
            (Level::Recessive, None) => Some(Bystander::Receiver),
            (Level::Dominant, Some(tx)) if self.tx_is_best && !self.abort_in_flight => {
                Some(Bystander::Loser {
                    key: tx.frame().arbitration_key(),
                })
            }
            _ => None,
        }
    }

    /// One or more whole frames, the last of them `last`, have gone by this
    /// [`Self::bystander`] (which said what it is): where they leave it. Its reports are one
    /// [`Event::Received`] per frame, and one [`Event::ArbitrationLost`] for a loser, which
    /// the caller counts itself.
    pub fn bystander_frames(&mut self, last: &WireFrame) {
        // `frame_begin` .. `frame_end` as a receiver (or a loser, a receiver from its lost
        // bit on): the counters, the queue and the level driven stay as they were.
        self.phase = Phase::Idle;
        self.transmitting = false;
        self.was_transmitter = false;
        self.rx.clone_from(&last.receiver);
        self.frame_bit = last.total();
    }

    /// The last (3rd) intermission bit of a whole frame: waiting for SOF again, or suspended.
    #[inline]
    pub fn frame_end(&mut self, frame: &WireFrame) {
        self.phase = if self.suspended() {
            Phase::Suspend { n: 1 }
        } else {
            Phase::Idle
        };
        self.rx.clone_from(&frame.receiver);
        self.frame_bit = frame.total();
        self.drive = self.next_drive();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Id;
    use crate::controller::ControllerConfig;
    use crate::wire::encode;
    use alloc::format;
    use alloc::vec::Vec;
    use proptest::prelude::*;

    /// [`WireFrame::lost_bit`] the plain way, bit by bit.
    fn lost_bit_stepwise(loser: &Encoded, winner: &Encoded) -> Option<FrameRole> {
        let (lb, wb) = (loser.stuffed(), winner.stuffed());
        let arbitration_end = if loser.frame().is_extended() { 32 } else { 12 };
        let mut stuff = 0;
        for i in 1..lb.len().min(wb.len()) {
            let is_stuff = loser.is_stuff_bit(i);
            if lb.bit(i) != wb.bit(i) {
                let index = (i - stuff) as u32;
                let ok = lb.bit(i)
                    && !is_stuff
                    && !winner.is_stuff_bit(i)
                    && (1..=arbitration_end).contains(&index);
                return ok.then_some(FrameRole::LostArbitration {
                    wire_bit: i as u32,
                    index,
                });
            }
            stuff += is_stuff as usize;
        }
        None
    }

    /// IDs close together and full of runs (stuff bits), both formats, data and remote.
    fn any_frame() -> impl Strategy<Value = Frame> {
        (
            any::<bool>(),
            prop_oneof![Just(0u32), Just(u32::MAX), any::<u32>(), 0u32..64],
            any::<bool>(),
            prop::collection::vec(prop_oneof![Just(0u8), Just(0xFF), any::<u8>()], 0..=8),
        )
            .prop_map(|(extended, raw, remote, data)| {
                let id = if extended {
                    Id::extended(raw & 0x1FFF_FFFF).unwrap()
                } else {
                    Id::standard((raw & 0x7FF) as u16).unwrap()
                };
                if remote {
                    Frame::remote(id, data.len() as u8).unwrap()
                } else {
                    Frame::data(id, &data).unwrap()
                }
            })
    }

    /// A controller lined up at a frame start: idle after integrating, `queued` waiting.
    fn lined_up(config: ControllerConfig, queued: &[Frame]) -> Controller {
        let mut c = Controller::new(config);
        for _ in 0..11 {
            c.sample(Level::Recessive);
        }
        for f in queued {
            c.enqueue(*f).unwrap();
        }
        c
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(500))]

        /// A bystander filled in at once after some frames is the controller that took each
        /// of them whole, and its reports are one `Received` (and one `ArbitrationLost`) per
        /// frame.
        #[test]
        fn a_bystander_filled_in_at_once_is_the_one_that_took_every_frame(
            frames in prop::collection::vec(any_frame(), 1..6),
            own in prop::option::of(any_frame()),
            listen_only in any::<bool>(),
        ) {
            let config = ControllerConfig { listen_only, ..Default::default() };
            let queued: Vec<Frame> = own.into_iter().collect();
            let mut stepped = lined_up(config, &queued);
            let mut lazy = stepped.clone();
            let kind = lazy.bystander();
            prop_assert!(kind.is_some());
            let mut last = None;
            let mut reports = 0;
            for f in &frames {
                let FrameStart::Ready { sends, .. } = stepped.frame_start() else {
                    return Err(TestCaseError::fail("not lined up"));
                };
                let winner = encode(f);
                let role = match sends {
                    Some(mine) => match WireFrame::lost_bit(mine, &winner) {
                        Some(role) => role,
                        // Not a loser to this frame (the same arbitration field, or it would
                        // win): not a case of the group.
                        None => return Ok(()),
                    },
                    None => FrameRole::Receiver,
                };
                let wire = WireFrame::new(&winner).unwrap();
                stepped.advance_frame(&wire, role, 0..wire.total());
                while let Some(event) = stepped.poll_event() {
                    let loser = matches!(kind, Some(Bystander::Loser { .. }));
                    let expected = matches!(event, Event::Received(_))
                        || matches!(event, Event::ArbitrationLost { .. } if loser);
                    prop_assert!(expected, "{:?}", event);
                    reports += 1;
                }
                last = Some(wire);
            }
            lazy.bystander_frames(last.as_ref().unwrap());
            prop_assert_eq!(format!("{lazy:?}"), format!("{stepped:?}"));
            let per_frame = 1 + matches!(kind, Some(Bystander::Loser { .. })) as usize;
            prop_assert_eq!(reports, per_frame * frames.len());
            prop_assert_eq!(stepped.bystander(), kind);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]

        #[test]
        fn lost_bit_is_the_first_differing_wire_bit(a in any_frame(), b in any_frame()) {
            let (a, b) = (encode(&a), encode(&b));
            prop_assert_eq!(WireFrame::lost_bit(&a, &b), lost_bit_stepwise(&a, &b));
            prop_assert_eq!(WireFrame::lost_bit(&b, &a), lost_bit_stepwise(&b, &a));
        }
    }
}
