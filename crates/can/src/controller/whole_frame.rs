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
use crate::wire::{Bits, Encoded, Receiver, Step};
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
        let ack_slot = winner.ack_slot() as u32;
        let mut receiver = Receiver::new();
        for i in 0..=ack_slot as usize + 1 {
            if let Step::Error(_) = receiver.push(bus.bit(i)) {
                return None;
            }
        }
        let frame = receiver.decoded()?.frame;
        Some(Self {
            frame,
            bus,
            ack_slot,
            receiver,
        })
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
}

impl Controller {
    /// Whether this controller is lined up at a frame start (bus idle, waiting for SOF,
    /// error-active) and what it sends with the next SOF.
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
    pub fn advance_frame(&mut self, frame: &WireFrame, role: FrameRole, bits: Range<u32>) {
        if bits.contains(&0) {
            self.phase = Phase::Frame;
            self.transmitting = role != FrameRole::Receiver;
            self.drive = Level::Recessive;
        }
        if let FrameRole::LostArbitration { wire_bit, index } = role
            && bits.contains(&wire_bit)
        {
            self.lose_arbitration(index);
        }
        if bits.contains(&frame.ack_slot) && !self.transmitting && !self.config.listen_only {
            // Our dominant ACK: a successful reception (rule 8).
            self.counters.receive_ok();
            self.update_state();
        }
        if bits.contains(&frame.eof_bit(6)) && !self.transmitting {
            self.events.push_back(Event::Received(frame.frame));
        }
        if bits.contains(&frame.eof_bit(7)) {
            self.last_eof_bit();
        }
        let last = frame.total() - 1;
        if bits.contains(&last) {
            // The 3rd intermission bit, as `intermission_bit` ends it.
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
}
