//! A client that left, while its node sends what it handed over (sans-IO, bit-times).
//!
//! Real socketcand writes each frame to the kernel as it arrives, so frames a client sent just
//! before closing still go out. Here the node stays on the bus after its client left and sends
//! them, in order and with their retries, unless it goes bus-off or none of them is sent for
//! [`DEPARTURE_STALL`] of bus time (nobody acknowledges, the wire is broken, higher priorities
//! take the bus). Then it gives up: the chip ends the attempt on the wire (CMR.AT), the node is
//! pulled off, and everything not sent is counted as dropped, with the reason. So a departed
//! client never stays on the bus retrying for ever (issue 11's zombie), and never loses what it
//! handed over while the bus could take it (issue 25).

use std::fmt;
use std::time::Duration;

use buslab_can::{BitTime, Nanos};
use buslab_canbus::{ControllerState, NodeCounters};

use crate::node::ClientNode;

/// The longest a departed client's node keeps trying without sending any of its frames, in
/// bus time (bit-times at the bus's rate).
pub const DEPARTURE_STALL: Duration = Duration::from_secs(1);

/// Once a departed node gives up, how long the chip may take to end the attempt
/// on the wire before it is pulled off anyway: the longest frame with its worst stuffing, an
/// error frame and the intermission, rounded up.
pub const GIVE_UP: BitTime = BitTime::new(256);

/// Why frames a departed client handed over were not sent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DropReason {
    /// Its node went bus-off.
    BusOff,
    /// None of its frames was sent for this long of bus time.
    Stalled(Duration),
    /// The node was taken off the bus at once (the server stopped).
    Removed,
    /// Its chip gave them up (an abort the client asked for, a refusal), see the node's log.
    GivenUp,
}

impl fmt::Display for DropReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DropReason::BusOff => f.write_str("its node went bus-off"),
            DropReason::Stalled(d) => write!(
                f,
                "none sent for {} of bus time",
                buslab_canbus::bus::Human(*d)
            ),
            DropReason::Removed => f.write_str("taken off the bus at once"),
            DropReason::GivenUp => f.write_str("given up by its chip"),
        }
    }
}

/// Where a departure is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    /// Its frames are being sent; the last bit-time one was (or the queue was empty).
    Sending { progress_at: BitTime, sent: u64 },
    /// Given up at `since`: the chip ends the attempt on the wire, then the node is pulled.
    GivingUp { reason: DropReason, since: BitTime },
    /// Off the bus.
    Off,
}

/// What [`Departure::check`] decided.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Verdict {
    Stay,
    /// Pull the node off the bus now.
    Pull,
}

/// A departed client's node until it leaves, and what it left undone.
#[derive(Clone, Debug)]
pub(crate) struct Departure {
    pub number: u32,
    stage: Stage,
    reason: Option<DropReason>,
    /// The server may still hand over frames the client sent before it left.
    pub input_open: bool,
    failed_before: u64,
    bus_off_before: u64,
    stall: BitTime,
    /// Frames not sent: counted when the node is pulled off, and handed over after it.
    pub dropped: u64,
    /// The node's name and counters once it is off the bus.
    pub off: Option<(String, NodeCounters)>,
}

impl Departure {
    /// `node`'s client left at bit-time `now`, on a bus at `bitrate`.
    pub fn new(number: u32, node: &ClientNode, now: BitTime, bitrate: u32) -> Self {
        let stall = Nanos::from_duration(DEPARTURE_STALL)
            .bit_times_at(bitrate)
            .max(BitTime::ONE);
        Self {
            number,
            stage: Stage::Sending {
                progress_at: now,
                sent: node.counters.sent,
            },
            reason: None,
            input_open: true,
            failed_before: node.counters.tx_failed,
            bus_off_before: node.counters.bus_off,
            stall,
            dropped: 0,
            off: None,
        }
    }

    /// Whether frames handed over now still go to the node (else they are counted dropped).
    pub fn takes_frames(&self) -> bool {
        matches!(self.stage, Stage::Sending { .. })
    }

    /// Whether the node is off the bus.
    pub fn is_off(&self) -> bool {
        self.stage == Stage::Off
    }

    /// Why frames were dropped (`None`: none were, or the chip gave some up on its own).
    pub fn reason(&self) -> Option<DropReason> {
        self.reason
            .or((self.dropped > 0).then_some(DropReason::GivenUp))
    }

    /// The bit-time by which [`Self::check`] must look again, if any.
    pub fn deadline(&self) -> Option<BitTime> {
        match self.stage {
            Stage::Sending { progress_at, .. } => Some(progress_at.saturating_add(self.stall)),
            Stage::GivingUp { since, .. } => Some(since.saturating_add(GIVE_UP)),
            Stage::Off => None,
        }
    }

    /// Looks at the node once the bus has run up to `now`.
    pub fn check(&mut self, now: BitTime, node: &mut ClientNode) -> Verdict {
        // Nobody reads what it receives any more.
        node.take_deliveries();
        node.take_error_frames();
        if let Stage::Sending { progress_at, sent } = self.stage {
            let idle = node.tx_queued() == 0;
            if node.state() == ControllerState::BusOff
                || node.counters.bus_off > self.bus_off_before
            {
                self.give_up(DropReason::BusOff, now, node);
            } else if node.counters.sent > sent || idle {
                self.stage = Stage::Sending {
                    progress_at: now,
                    sent: node.counters.sent,
                };
                if idle && !self.input_open {
                    return Verdict::Pull;
                }
            } else if now >= progress_at.saturating_add(self.stall) {
                self.give_up(DropReason::Stalled(DEPARTURE_STALL), now, node);
            }
        }
        match self.stage {
            Stage::GivingUp { since, .. }
                if node.tx_queued() == 0 || now >= since.saturating_add(GIVE_UP) =>
            {
                Verdict::Pull
            }
            _ => Verdict::Stay,
        }
    }

    /// The chip ends the attempt on the wire and its queue is emptied (CMR.AT).
    fn give_up(&mut self, reason: DropReason, now: BitTime, node: &mut ClientNode) {
        self.reason = Some(reason);
        self.stage = Stage::GivingUp { reason, since: now };
        node.abort();
    }

    /// The node is no longer on the bus, nobody knows how (nothing to count).
    pub fn vanished(&mut self) {
        self.stage = Stage::Off;
    }

    /// The node was pulled off the bus (or `reason`: taken off at once): what it did not send
    /// is dropped.
    pub fn pulled(&mut self, name: String, node: &ClientNode, reason: Option<DropReason>) {
        if reason.is_some() {
            self.reason = reason;
        }
        self.dropped +=
            node.counters.tx_failed.saturating_sub(self.failed_before) + node.tx_queued() as u64;
        self.off = Some((name, node.counters));
        self.stage = Stage::Off;
    }
}
