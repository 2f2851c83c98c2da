//! Faults on the wire, active from `start` (included) to `end` (excluded) in bit-times.

use crate::rng::threshold;
use crate::time::BitTime;

/// A fault and when it is active.
#[derive(Clone, Debug, PartialEq)]
pub struct Fault {
    pub kind: FaultKind,
    pub start: BitTime,
    /// First bit-time the fault is gone; `BitTime::MAX` = until the end.
    pub end: BitTime,
}

/// What goes wrong. Nodes are indices as returned by [`crate::Simulation::add_node`].
#[derive(Clone, Debug, PartialEq)]
pub enum FaultKind {
    /// The node's connector is pulled: what it drives does not reach the bus and it reads only
    /// its own level. Its frames get no ACK; the others do not see it.
    Disconnect { node: usize },
    /// The wire is cut: `far_side` nodes are on their own piece of wire (wired-AND among
    /// themselves), the others stay on the main piece. The far piece is unterminated, so its
    /// nodes read each bit inverted with probability `error_rate` (reflections); 0.0 is a clean,
    /// terminated cut.
    Cut {
        far_side: Vec<usize>,
        error_rate: f64,
    },
    /// Invert the level read by `node` (or by every node when `None`) during the fault.
    Flip { node: Option<usize> },
    /// The bus is held dominant (every node still connected to it reads dominant).
    StuckDominant,
    /// Random bit errors at `rate` per bit-time: on the bus itself, read the same by everyone
    /// (`nodes` empty), or independently at each listed node.
    Noise { nodes: Vec<usize>, rate: f64 },
}

impl FaultKind {
    /// The nodes it names.
    pub fn nodes(&self) -> impl Iterator<Item = usize> + '_ {
        let (list, one): (&[usize], Option<usize>) = match self {
            FaultKind::Disconnect { node } => (&[], Some(*node)),
            FaultKind::Cut { far_side, .. } => (far_side, None),
            FaultKind::Flip { node } => (&[], *node),
            FaultKind::StuckDominant => (&[], None),
            FaultKind::Noise { nodes, .. } => (nodes, None),
        };
        list.iter().copied().chain(one)
    }

    /// Node `removed` left the bus: indices above it move down one. Returns `false` when the
    /// fault has nothing left to act on (it named that node alone).
    pub fn forget_node(&mut self, removed: usize) -> bool {
        let shift = |n: &mut usize| {
            if *n > removed {
                *n -= 1;
            }
        };
        let forget_in = |list: &mut Vec<usize>| {
            let had = !list.is_empty();
            list.retain(|&n| n != removed);
            list.iter_mut().for_each(shift);
            !had || !list.is_empty()
        };
        match self {
            FaultKind::Disconnect { node } | FaultKind::Flip { node: Some(node) } => {
                if *node == removed {
                    return false;
                }
                shift(node);
                true
            }
            FaultKind::Cut { far_side, .. } => forget_in(far_side),
            FaultKind::Noise { nodes, .. } => forget_in(nodes),
            FaultKind::Flip { node: None } | FaultKind::StuckDominant => true,
        }
    }

    /// Short name, as in scenario files.
    pub fn name(&self) -> &'static str {
        match self {
            FaultKind::Disconnect { .. } => "disconnect",
            FaultKind::Cut { .. } => "cut",
            FaultKind::Flip { .. } => "flip",
            FaultKind::StuckDominant => "stuck_dominant",
            FaultKind::Noise { .. } => "noise",
        }
    }
}

/// The wiring and read corruption in force between two fault changes, flattened for the
/// per-bit loop.
#[derive(Clone, Debug, Default)]
pub(crate) struct Wiring {
    /// Piece of wire each node is attached to; 0 is the main bus.
    pub segment: Vec<usize>,
    /// Whether a segment is bus wire (stuck-dominant and bus noise apply) or a lone
    /// disconnected node's stub.
    pub is_bus: Vec<bool>,
    pub stuck_dominant: bool,
    /// Bus-wide noise threshold (see [`crate::rng::threshold`]); 0 = none.
    pub bus_noise: u64,
    /// Per-node read corruption thresholds (noise, unterminated cut); 0 = none.
    pub node_noise: Vec<u64>,
    pub flip_all: bool,
    pub flip_node: Vec<bool>,
}

impl Wiring {
    /// The wiring with `active` faults on `nodes` nodes.
    pub fn build<'a>(nodes: usize, active: impl Iterator<Item = &'a Fault>) -> Self {
        let mut w = Wiring {
            segment: vec![0; nodes],
            is_bus: vec![true],
            node_noise: vec![0; nodes],
            flip_node: vec![false; nodes],
            ..Default::default()
        };
        let mut disconnected = Vec::new();
        for fault in active {
            match &fault.kind {
                FaultKind::Disconnect { node } => disconnected.push(*node),
                FaultKind::Cut {
                    far_side,
                    error_rate,
                } => {
                    let seg = w.is_bus.len();
                    w.is_bus.push(true);
                    for &n in far_side {
                        w.segment[n] = seg;
                        combine(&mut w.node_noise[n], *error_rate);
                    }
                }
                FaultKind::Flip { node: None } => w.flip_all = true,
                FaultKind::Flip { node: Some(n) } => w.flip_node[*n] = true,
                FaultKind::StuckDominant => w.stuck_dominant = true,
                FaultKind::Noise { nodes, rate } if nodes.is_empty() => {
                    combine(&mut w.bus_noise, *rate)
                }
                FaultKind::Noise { nodes, rate } => {
                    for &n in nodes {
                        combine(&mut w.node_noise[n], *rate);
                    }
                }
            }
        }
        // A pulled connector wins over any cut: the node is alone on its stub.
        for n in disconnected {
            w.segment[n] = w.is_bus.len();
            w.is_bus.push(false);
        }
        w
    }
}

/// Two independent error sources: p = 1 - (1 - a)(1 - b).
fn combine(acc: &mut u64, rate: f64) {
    let a = *acc as f64 / u64::MAX as f64;
    *acc = threshold(1.0 - (1.0 - a) * (1.0 - rate.clamp(0.0, 1.0)));
}

/// Forgets the faults that have ended by `now` (their end reported), keeping the three
/// lists index for index: a bus that lives for days gets faults injected all along, and only
/// those not ended yet cost anything.
pub(crate) fn forget_ended(
    now: BitTime,
    faults: &mut Vec<Fault>,
    active: &mut Vec<bool>,
    numbers: &mut Vec<usize>,
) {
    let mut keep = 0;
    for at in 0..faults.len() {
        if faults[at].end > now {
            faults.swap(keep, at);
            active.swap(keep, at);
            numbers.swap(keep, at);
            keep += 1;
        }
    }
    faults.truncate(keep);
    active.truncate(keep);
    numbers.truncate(keep);
}
