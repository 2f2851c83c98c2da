//! The typed vocabulary of a bus that has more to tell than frames (buslab's virtual bus):
//! its nodes, their counters and timing, the bus's summary, faults to put on its wire and the
//! limits that refuse them, a demo board's switches.
//!
//! The values are typed here; a transport carries them however it must (the socketcand
//! extension as `key=value` text) and turns them back into these types at its edge.

use std::fmt;
use std::time::Duration;

use buslab_device::Human;

/// A node on a buslab virtual bus: its number (given in joining order from 1) or its name.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum NodeRef {
    Number(u32),
    Name(String),
}

impl NodeRef {
    /// A number if `text` is all digits, else a name.
    pub fn parse(text: &str) -> Self {
        match text.parse::<u32>() {
            Ok(n) if text.bytes().all(|b| b.is_ascii_digit()) => NodeRef::Number(n),
            _ => NodeRef::Name(text.to_string()),
        }
    }
}

impl fmt::Display for NodeRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NodeRef::Number(n) => write!(f, "{n}"),
            NodeRef::Name(name) => f.write_str(name),
        }
    }
}

/// A node's number and name.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct NodeInfo {
    pub number: u32,
    pub name: String,
}

/// What a node has done since it joined.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct NodeCounters {
    /// Frames it transmitted successfully.
    pub sent: u64,
    /// Frames it received (and, for a client, its chip accepted).
    pub received: u64,
    /// Frames that were given up (aborted, single-shot failures, refused by the chip).
    pub tx_failed: u64,
    /// Bus errors it detected.
    pub bus_errors: u64,
    pub arbitration_lost: u64,
    /// Frames lost in the chip's receive FIFO.
    pub overruns: u64,
    /// Times it went bus-off.
    pub bus_off: u64,
    /// Frames its client could not take in time (dropped by the server for that client only).
    pub rx_lost: u64,
}

/// A node's bit timing and whether it lets the node follow the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct NodeTiming {
    pub btr0: u8,
    pub btr1: u8,
    /// The bit rate BTR0/BTR1 give with the node's crystal.
    pub bitrate: u32,
    /// Within the oscillator tolerance of the bus's bit rate.
    pub matches_bus: bool,
}

/// The whole bus, as seen when a node's status was taken.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BusSummary {
    pub bitrate: u32,
    /// Per cent of bit-times the bus was busy during the last complete second.
    pub load_percent: f64,
    /// Frames transmitted successfully by every node since the bus started.
    pub frames: u64,
    /// Error frames on the bus since it started (every node's detected errors).
    pub errors: u64,
}

/// What a transmit queue did with the frames handed to it (`BusAdmin::flush`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TxReport {
    /// Frames transmitted successfully since this client joined.
    pub sent: u64,
    /// Frames given up since this client joined.
    pub failed: u64,
}

/// A probability per bit, 0..=1: never NaN, so it compares like a plain number.
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd)]
pub struct Probability(f64);

impl Eq for Probability {}

/// A probability outside 0..=1.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("probability {0} is out of range 0..=1 (per bit)")]
pub struct BadProbability(pub f64);

impl Probability {
    pub fn new(p: f64) -> Result<Self, BadProbability> {
        if (0.0..=1.0).contains(&p) {
            Ok(Self(p))
        } else {
            Err(BadProbability(p))
        }
    }

    pub fn get(self) -> f64 {
        self.0
    }
}

impl fmt::Display for Probability {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// A fault to put on the wire of a buslab virtual bus (its engine's faults, nodes named as
/// the server names them).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum WireFault {
    /// The wire is cut: `far_side` is left on its own unterminated piece of wire, where each
    /// bit read is wrong with probability `error_rate` (the seed's cut-wire experiment).
    Cut {
        far_side: Vec<NodeRef>,
        error_rate: Probability,
    },
    /// A node's connector is pulled.
    Disconnect { node: NodeRef },
    /// Every bit read by `node` (every node if `None`) is inverted.
    Flip { node: Option<NodeRef> },
    /// Random bit errors at `rate` per bit: on the bus (`nodes` empty) or at each listed node.
    Noise {
        nodes: Vec<NodeRef>,
        rate: Probability,
    },
    /// The bus is held dominant.
    StuckDominant,
}

impl WireFault {
    /// The short name, as in scenario files and the socketcand extension.
    pub fn name(&self) -> &'static str {
        match self {
            WireFault::Cut { .. } => "cut",
            WireFault::Disconnect { .. } => "disconnect",
            WireFault::Flip { .. } => "flip",
            WireFault::Noise { .. } => "noise",
            WireFault::StuckDominant => "stuck",
        }
    }
}

/// A limit that refused a fault (`BusAdmin::inject_fault`), with the value allowed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FaultLimit {
    /// Faults on the bus at once (in force, or to start later); ended and repaired ones do
    /// not count.
    #[error(
        "{max} faults are on the wire already (at most {max} at once; they end when their time is up or with repair)"
    )]
    Active { max: u32 },
    /// Faults one client may put on the wire: at most `max` in any `per`.
    #[error(
        "too many faults from this client: at most {max} per {}; the next is allowed in {}",
        Human(*per),
        Human(*retry_after)
    )]
    Rate {
        max: u32,
        per: Duration,
        retry_after: Duration,
    },
}

/// One of the four input switches of a SLIO demo board: 0..=3, on P0..P3 (the seed's §3.2:
/// « P0-P3: ID / Entrées digitales (switches) »).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct BoardSwitch(u8);

/// A switch number that is not one of the board's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("switch {0}: a demo board has input switches 0..=3 (on P0..P3)")]
pub struct BadSwitch(pub u8);

impl BoardSwitch {
    pub fn new(n: u8) -> Result<Self, BadSwitch> {
        if n <= 3 {
            Ok(Self(n))
        } else {
            Err(BadSwitch(n))
        }
    }

    /// 0..=3, the pin it is on.
    pub fn number(self) -> u8 {
        self.0
    }
}

impl fmt::Display for BoardSwitch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// `0101`: the switches from 3 down to 0, as they sit on the board's P3..P0.
pub fn switch_bits(bits: u8) -> String {
    (0..4)
        .rev()
        .map(|k| if bits >> k & 1 == 1 { '1' } else { '0' })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refused_fault_names_the_limit_and_the_value_allowed() {
        let active = FaultLimit::Active { max: 1024 }.to_string();
        assert!(active.contains("at most 1024 at once"), "{active}");
        let rate = FaultLimit::Rate {
            max: 20,
            per: Duration::from_secs(1),
            retry_after: Duration::from_millis(50),
        }
        .to_string();
        assert!(rate.contains("at most 20 per 1.00 s"), "{rate}");
        assert!(rate.contains("allowed in 50.0 ms"), "{rate}");
    }
}
