//! The virtual bus, sans-IO: the one bus engine ([`Simulation`]) with a client's SJA1000
//! ([`ClientNode`]) for every client that joins, beside whatever simulated nodes a scenario put
//! on the same wire. Faults, counters, traces and bus load see every node alike.
//!
//! The network side ([`crate::server`]) moves frames between clients and [`ClientNode`]
//! queues and decides how far to run; everything here is plain state in virtual time.

use std::fmt;

use buslab_can::node::BusNode;
use buslab_can::wire::encode;
use buslab_can::{BitTime, Frame, Nanos};
use buslab_canbus::WireFault;
use buslab_canbus::admin::FaultLimit;
use buslab_canbus::admin::{BoardInput, BoardState};
use buslab_canbus::{
    BusOffRecovery, BusSummary, ControllerSettings, ErrorRegisters, NodeCounters, NodeInfo,
    NodeRef, NodeRegisters, NodeStatus, NodeTiming, Sja1000Config,
};
use buslab_sim::{BusStats, Fault, FaultKind, RecordedEvents, Simulation};
use buslab_sja1000::BitTiming;

use buslab_slio::{Calibration, ModeChangeCause, SlioId, SlioNotice};

use crate::departure::{Departure, DropReason, Verdict};
use crate::device::{Board, DeviceNode, DeviceNotice};
use crate::node::{ClientNode, NodeNotice, node_config};

/// Why a bus could not be set up or a request failed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum VbusError {
    /// The bus bit rate and why a client chip cannot run at it (the reason names the rate).
    #[error("{1}")]
    Bitrate(u32, String),
    #[error("no node {0} (see buslab_nodes)")]
    NoNode(String),
    #[error("node {0} is a simulated protocol controller: it has no registers")]
    NoRegisters(String),
    #[error("node {0} is not this client's")]
    NotAClient(String),
    #[error("the bus is full ({0} nodes)")]
    Full(usize),
    #[error("name {0:?} is taken by node {1}")]
    NameTaken(String, u32),
    #[error("name {0:?} must be 1..=64 of A-Z a-z 0-9 _ - . (not only digits)")]
    BadName(String),
    #[error("the chip refused the configuration: {0}")]
    Driver(String),
    /// A limit refused a fault (the socketcand extension answers `< buslab_refused … >`).
    #[error("{0}")]
    FaultRefused(FaultLimit),
    /// No demo board with that SLIO number; the ones there are.
    #[error("no SLIO demo board {slio} on this bus ({})", boards_text(.boards))]
    NoBoard { slio: SlioId, boards: Vec<SlioId> },
    #[error("switches {0:#X}: a demo board has four input switches (0x0..0xF, bit 0 on P0)")]
    Switches(u8),
}

fn boards_text(boards: &[SlioId]) -> String {
    if boards.is_empty() {
        return "it has none".into();
    }
    let list: Vec<String> = boards.iter().map(ToString::to_string).collect();
    format!("boards: {}", list.join(", "))
}

/// Most faults on one bus at once (scenario and injected, in force or to start later); ended
/// and repaired ones are forgotten and do not count.
pub const MAX_FAULTS: usize = 1024;

/// Most nodes on one bus (an ISO 11898 segment allows far fewer real ones).
pub const MAX_NODES: usize = 64;

/// Something that happened on the bus that its operator may want to read, with words.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BusEvent {
    Joined {
        number: u32,
        name: String,
        btr0: u8,
        btr1: u8,
    },
    /// A node left the bus: at once, or once its departed client's frames were sent or
    /// given up (`dropped` of them, for `reason`; see [`crate::departure`]).
    Left {
        number: u32,
        name: String,
        counters: NodeCounters,
        dropped: u64,
        reason: Option<DropReason>,
    },
    Renamed {
        number: u32,
        old: String,
        new: String,
    },
    /// A client reprogrammed its bit timing.
    Timing {
        number: u32,
        name: String,
        btr0: u8,
        btr1: u8,
        bitrate: u32,
        bus_bitrate: u32,
    },
    /// What a client node's driver noticed.
    Node {
        number: u32,
        name: String,
        notice: NodeNotice,
    },
    /// A client put a fault on the wire.
    Fault {
        description: String,
        lasting: Option<std::time::Duration>,
    },
    /// A client ended the faults on the wire.
    Repaired { faults: usize },
    /// A client reprogrammed its controller (buslab.toml's `[controller]`): what it set.
    Configured {
        number: u32,
        name: String,
        settings: ControllerSettings,
        /// Whether its bit rate now lets it follow the bus.
        matches_bus: bool,
    },
    /// A client changed a SLIO demo board's inputs (a switch, the potentiometer).
    Board {
        number: u32,
        name: String,
        input: BoardInput,
    },
    /// What a bench's device reported (a SLIO board's calibration changed, or it changed its
    /// bus mode).
    Device {
        number: u32,
        name: String,
        notice: DeviceNotice,
    },
}

impl BusEvent {
    /// Whether the operator should be warned (rather than informed).
    pub fn is_warning(&self) -> bool {
        match self {
            BusEvent::Timing {
                bitrate,
                bus_bitrate,
                ..
            } => !within_tolerance(*bitrate, *bus_bitrate),
            BusEvent::Node { notice, .. } => {
                matches!(
                    notice,
                    NodeNotice::Overrun
                        | NodeNotice::Restarted(Err(_))
                        | NodeNotice::Recovering(Err(_))
                )
            }
            BusEvent::Device { notice, .. } => notice.is_warning(),
            BusEvent::Fault { .. } => true,
            BusEvent::Configured { matches_bus, .. } => !matches_bus,
            BusEvent::Left { dropped, .. } => *dropped > 0,
            _ => false,
        }
    }
}

impl fmt::Display for BusEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BusEvent::Joined {
                number,
                name,
                btr0,
                btr1,
            } => write!(
                f,
                "node {number} ({name}) joined (PeliCAN, accept all, BTR0={btr0:02X} BTR1={btr1:02X})"
            ),
            BusEvent::Left {
                number,
                name,
                counters: c,
                dropped,
                reason,
            } => {
                write!(
                    f,
                    "node {number} ({name}) left: sent {}, dropped {dropped}",
                    c.sent
                )?;
                if let Some(reason) = reason.filter(|_| *dropped > 0) {
                    write!(f, " ({reason})")?;
                }
                write!(f, ", received {}, lost {}", c.received, c.rx_lost)
            }
            BusEvent::Fault {
                description,
                lasting,
            } => {
                write!(f, "fault injected: {description}")?;
                match lasting {
                    Some(d) => write!(f, " for {}", buslab_canbus::bus::Human(*d)),
                    None => f.write_str(" until repaired"),
                }
            }
            BusEvent::Repaired { faults } => write!(f, "wire repaired: {faults} fault(s) ended"),
            BusEvent::Configured {
                number,
                name,
                settings,
                matches_bus,
            } => {
                write!(f, "node {number} ({name}) set its controller: {settings}")?;
                if !matches_bus {
                    f.write_str(": its bit rate is not the bus's, it cannot communicate")?;
                }
                Ok(())
            }
            BusEvent::Board {
                number,
                name,
                input,
            } => write!(f, "node {number} ({name}): demo board's {input}"),
            BusEvent::Renamed { number, old, new } => {
                write!(f, "node {number} ({old}) is now called {new}")
            }
            BusEvent::Timing {
                number,
                name,
                btr0,
                btr1,
                bitrate,
                bus_bitrate,
            } => {
                write!(
                    f,
                    "node {number} ({name}): BTR0={btr0:02X} BTR1={btr1:02X} give {bitrate} bit/s"
                )?;
                if within_tolerance(*bitrate, *bus_bitrate) {
                    write!(f, " (bus {bus_bitrate} bit/s)")
                } else {
                    write!(
                        f,
                        ", the bus runs at {bus_bitrate} bit/s: this node cannot communicate"
                    )
                }
            }
            BusEvent::Device {
                number,
                name,
                notice: DeviceNotice::Slio(notice),
            } => {
                write!(f, "node {number} ({name}): SLIO ")?;
                match notice {
                    SlioNotice::Calibration(c) => f.write_str(match c {
                        Calibration::Asleep => "asleep (bus mode 3)",
                        Calibration::Unsynced => "awake, waiting for edges to measure a bit",
                        Calibration::Rough => "roughly calibrated (executes, does not acknowledge)",
                        Calibration::Calibrated => "calibrated: signs on, acknowledges, answers",
                    }),
                    SlioNotice::BusModeChange(ModeChangeCause::Watchdog) => f.write_str(
                        "lost its calibration: no calibration frame for 8192 bit-times (bus-mode change, registers cleared)",
                    ),
                    SlioNotice::BusModeChange(ModeChangeCause::BusOff) => {
                        f.write_str("went bus-off (bus-mode change, registers cleared)")
                    }
                    SlioNotice::Register { register, value } => {
                        write!(f, "{register} = 0x{value:04X}")
                    }
                }
            }
            BusEvent::Node {
                number,
                name,
                notice,
            } => {
                write!(f, "node {number} ({name}): ")?;
                match notice {
                    NodeNotice::NotSent { frame, reason } => {
                        write!(f, "frame {frame} not sent: {reason}")
                    }
                    NodeNotice::Refused { frame } => {
                        write!(
                            f,
                            "frame {frame} refused by the chip (bus-off or reset mode)"
                        )
                    }
                    NodeNotice::Overrun => f.write_str("RX FIFO overrun, frames lost in the chip"),
                    NodeNotice::StateChanged {
                        from,
                        to,
                        txerr,
                        rxerr,
                    } => write!(f, "{from} -> {to} (TXERR {txerr}, RXERR {rxerr})"),
                    NodeNotice::Restarted(Ok(())) => f.write_str("restarted after bus-off"),
                    NodeNotice::Restarted(Err(e)) => write!(f, "restart failed: {e}"),
                    NodeNotice::Recovering(Ok(())) => f.write_str(
                        "bus-off: reset mode cleared, the chip counts 128 × 11 recessive bits \
                         (TXERR falling) before it is back",
                    ),
                    NodeNotice::Recovering(Err(e)) => {
                        write!(f, "bus-off: reset mode could not be cleared: {e}")
                    }
                }
            }
        }
    }
}

/// `cut, far side [engine], error rate 0.05`, naming nodes by their names.
fn describe_fault(kind: &FaultKind, nodes: &[NodeInfo]) -> String {
    let name = |i: usize| nodes.get(i).map_or("?", |n| n.name.as_str());
    let names = |list: &[usize]| list.iter().map(|&i| name(i)).collect::<Vec<_>>().join(", ");
    match kind {
        FaultKind::Disconnect { node } => format!("disconnect {}", name(*node)),
        FaultKind::Cut {
            far_side,
            error_rate,
        } => format!(
            "cut, far side [{}], error rate {error_rate}",
            names(far_side)
        ),
        FaultKind::Flip { node: Some(n) } => format!("flip at {}", name(*n)),
        FaultKind::Flip { node: None } => "flip at every node".into(),
        FaultKind::StuckDominant => "stuck dominant".into(),
        FaultKind::Noise { nodes, rate } if nodes.is_empty() => {
            format!("noise on the bus, rate {rate}")
        }
        FaultKind::Noise { nodes, rate } => format!("noise at [{}], rate {rate}", names(nodes)),
    }
}

fn within_tolerance(rate: u32, bus: u32) -> bool {
    let diff = (rate as i64 - bus as i64).unsigned_abs();
    diff * 1000 <= bus as u64 * crate::node::TOLERANCE_PERMILLE
}

/// The bus and its nodes.
#[derive(Debug)]
pub struct VirtualBus {
    sim: Simulation,
    /// The number of each node of `sim`, index for index.
    numbers: Vec<u32>,
    next_number: u32,
    /// Bus statistics at the start of the current second, and over the last complete one.
    window_start: BusStats,
    last_second: BusStats,
    next_window: BitTime,
    error_frames: bool,
    /// How client chips come back after bus-off (the seed's counted recovery by default).
    bus_off_recovery: BusOffRecovery,
    events: Vec<(BitTime, BusEvent)>,
    /// The bit-time by which a client's frame put on an idle bus has reached every node (see
    /// [`VirtualBus::frame_end`]).
    frame_end: Option<BitTime>,
    /// Nodes whose clients left, until they have left too.
    departures: Vec<Departure>,
}

impl VirtualBus {
    /// An empty bus at `bitrate`; fails if a client chip cannot be programmed for it.
    pub fn new(bitrate: u32) -> Result<Self, VbusError> {
        let config = node_config(bitrate);
        config
            .bit_timing()
            .map_err(|e| VbusError::Bitrate(bitrate, e.to_string()))?;
        config
            .validate()
            .map_err(|e| VbusError::Bitrate(bitrate, format!("bit rate {bitrate} bit/s: {e}")))?;
        let mut sim = Simulation::new(bitrate, 1);
        sim.set_record_events(RecordedEvents::empty());
        Ok(Self::around(sim))
    }

    fn around(sim: Simulation) -> Self {
        let second = Nanos::from_secs(1).bit_times_at(sim.bitrate());
        let now = sim.now();
        let stats = *sim.bus_stats();
        let count = sim.nodes().len() as u32;
        Self {
            numbers: (1..=count).collect(),
            next_number: count + 1,
            window_start: stats,
            last_second: BusStats::default(),
            next_window: now + second,
            sim,
            error_frames: false,
            bus_off_recovery: BusOffRecovery::default(),
            events: Vec::new(),
            frame_end: None,
            departures: Vec::new(),
        }
    }

    /// The bus is the scenario's simulation: its nodes, traffic and faults are on the wire,
    /// numbered 1.. in the scenario's order, and clients join beside them. The scenario's bit
    /// rate must be the bus's (`bitrate`).
    pub fn with_scenario(self, mut sim: Simulation) -> Self {
        assert_eq!(
            sim.bitrate(),
            self.bitrate(),
            "a scenario at another bit rate"
        );
        sim.set_record_events(RecordedEvents::empty());
        Self {
            error_frames: self.error_frames,
            bus_off_recovery: self.bus_off_recovery,
            ..Self::around(sim)
        }
    }

    /// Whether nodes that join from now on collect error frames for their clients.
    pub fn set_error_frames(&mut self, on: bool) {
        self.error_frames = on;
    }

    /// How the chips of clients that join from now on come back after bus-off.
    pub fn set_bus_off_recovery(&mut self, recovery: BusOffRecovery) {
        self.bus_off_recovery = recovery;
    }

    pub fn bitrate(&self) -> u32 {
        self.sim.bitrate()
    }
    /// Bit-times simulated so far.
    pub fn now(&self) -> BitTime {
        self.sim.now()
    }
    /// The bus engine (every node, faults, statistics).
    pub fn sim(&self) -> &Simulation {
        &self.sim
    }
    pub fn sim_mut(&mut self) -> &mut Simulation {
        &mut self.sim
    }
    /// Statistics since the bus started.
    pub fn stats(&self) -> &BusStats {
        self.sim.bus_stats()
    }
    /// Statistics of the last complete second (or of the first one so far).
    pub fn last_second(&self) -> BusStats {
        if self.last_second.bits == 0 {
            self.sim.bus_stats().since(&self.window_start)
        } else {
            self.last_second
        }
    }

    /// What happened since the last call, with the bit-time.
    pub fn take_events(&mut self) -> Vec<(BitTime, BusEvent)> {
        self.collect_notices();
        std::mem::take(&mut self.events)
    }

    /// Every node: number and name.
    pub fn nodes(&self) -> Vec<NodeInfo> {
        self.numbers
            .iter()
            .zip(self.sim.nodes())
            .map(|(&number, n)| NodeInfo {
                number,
                name: n.name().to_string(),
            })
            .collect()
    }

    /// The index in the engine of a node.
    pub fn index(&self, node: &NodeRef) -> Option<usize> {
        match node {
            NodeRef::Number(k) => self.numbers.iter().position(|n| n == k),
            NodeRef::Name(name) => self.sim.find_node(name),
        }
    }

    fn index_of(&self, node: &NodeRef) -> Result<usize, VbusError> {
        self.index(node)
            .ok_or_else(|| VbusError::NoNode(node.to_string()))
    }

    /// A client's node.
    pub fn client(&self, number: u32) -> Result<&ClientNode, VbusError> {
        let i = self.index_of(&NodeRef::Number(number))?;
        self.sim
            .node(i)
            .get::<ClientNode>()
            .ok_or_else(|| VbusError::NotAClient(number.to_string()))
    }

    /// A client's node, to change.
    pub fn client_mut(&mut self, number: u32) -> Result<&mut ClientNode, VbusError> {
        let i = self.index_of(&NodeRef::Number(number))?;
        self.sim
            .node_mut(i)
            .get_mut::<ClientNode>()
            .ok_or_else(|| VbusError::NotAClient(number.to_string()))
    }

    /// Hands a client's frame to its node (`Ok(Err(frame))`: the node's queue is full, the
    /// client waits). A frame put on an idle bus goes out at once and alone, so the bus knows
    /// when it will have reached every node: [`Self::frame_end`].
    ///
    /// A departed client's frames go to its node while it sends them; once it has given up
    /// (see [`Self::depart`]) they are counted as dropped.
    pub fn submit(&mut self, number: u32, frame: Frame) -> Result<Result<(), Frame>, VbusError> {
        if let Some(d) = self.departure_mut(number)
            && !d.takes_frames()
        {
            d.dropped += 1;
            return Ok(Ok(()));
        }
        let now = self.now();
        // A node with frames queued is not quiet, so the bus is not idle: no need to ask
        // every node (a sender kept busy at `--speed max` always has some queued).
        let idle = self.client(number)?.tx_queued() == 0 && self.sim.is_idle();
        let submitted = self.client_mut(number)?.submit(frame);
        if submitted.is_ok() && idle {
            // Its start of frame is the next bit; receivers have it at the last but one bit
            // of its end of frame, the sender at the last.
            let end = now + BitTime::new(encode(&frame).stuffed().len() as u64);
            // Several at once: they contend, and the first to end is the shortest at best.
            self.frame_end = Some(match self.frame_end {
                Some(known) if known > now => known.min(end),
                _ => end,
            });
        }
        Ok(submitted)
    }

    /// While a client's frame put on an idle bus is on the wire: the bit-time at which it will
    /// have reached every node and its sender (once the bus has run up to it, the deliveries
    /// are there). `None` when the bus cannot tell: no such frame, or it has passed (traffic
    /// of simulated nodes, frames queued behind others, errors).
    pub fn frame_end(&self) -> Option<BitTime> {
        self.frame_end.filter(|&end| end > self.now())
    }

    /// Every client node with its number.
    pub fn clients_mut(&mut self) -> impl Iterator<Item = (u32, &mut ClientNode)> {
        self.numbers
            .iter()
            .zip(self.sim.nodes_mut())
            .filter_map(|(&number, n)| n.get_mut::<ClientNode>().map(|c| (number, c)))
    }

    /// A new client node: a fresh SJA1000 initialised by the driver (PeliCAN, accept all, the
    /// bus's bit rate), called `node<number>`. Returns its number.
    pub fn join(&mut self) -> Result<u32, VbusError> {
        if self.sim.nodes().len() >= MAX_NODES {
            return Err(VbusError::Full(MAX_NODES));
        }
        let config = Sja1000Config {
            bus_off_recovery: self.bus_off_recovery,
            ..node_config(self.bitrate())
        };
        let node = ClientNode::with_config(config, self.bitrate(), self.error_frames)
            .map_err(VbusError::Driver)?;
        let (btr0, btr1) = node.btr();
        let number = self.next_number;
        let mut name = format!("node{number}");
        // A scenario node may already have that name.
        while self.sim.find_node(&name).is_some() {
            name.push('_');
        }
        self.next_number += 1;
        self.sim.add_device(name.clone(), Box::new(node));
        self.numbers.push(number);
        self.say(BusEvent::Joined {
            number,
            name,
            btr0,
            btr1,
        });
        Ok(number)
    }

    /// Puts a simulated node on the bus (a SLIO board, the PowerPC node): numbered like the
    /// others, reported by `status`, served by nobody's socket. Returns its number.
    pub fn add_node(&mut self, name: &str, node: Box<dyn BusNode>) -> Result<u32, VbusError> {
        if self.sim.nodes().len() >= MAX_NODES {
            return Err(VbusError::Full(MAX_NODES));
        }
        if let Some(i) = self.sim.find_node(name) {
            return Err(VbusError::NameTaken(name.to_string(), self.numbers[i]));
        }
        let number = self.next_number;
        self.next_number += 1;
        self.sim.add_device(name, node);
        self.numbers.push(number);
        Ok(number)
    }

    /// A node of type `T` by its name, for whoever put it there (the PowerPC node's
    /// terminal), as itself or as a [`DeviceNode`]'s node.
    pub fn device_mut<T: BusNode>(&mut self, name: &str) -> Option<&mut T> {
        let i = self.sim.find_node(name)?;
        let node = self.sim.node_mut(i);
        if node.get::<DeviceNode>().is_some() {
            return node.get_mut::<DeviceNode>()?.get_mut();
        }
        node.get_mut()
    }

    /// Removes a node at once (its connector is pulled, even in the middle of a frame; its
    /// queued frames are dropped and counted, as are those of a departed client not handed
    /// over yet).
    pub fn leave(&mut self, number: u32) {
        let known = self.departure_mut(number).is_some();
        let Some(i) = self.index(&NodeRef::Number(number)).filter(|_| !known) else {
            if known {
                self.take_off(number);
            }
            return;
        };
        if self.depart(number).is_err() {
            // Not a client's node: nothing of anybody's is queued in it.
            self.collect_notices();
            let node = self.sim.remove_node(i);
            self.numbers.remove(i);
            self.say(BusEvent::Left {
                number,
                name: node.name().to_string(),
                counters: NodeCounters::default(),
                dropped: 0,
                reason: None,
            });
            return;
        }
        self.take_off(number);
    }

    /// A departure ends now: its node (if still on the bus) is pulled off, and nothing more
    /// of its client's is handed over.
    fn take_off(&mut self, number: u32) {
        if let Some(k) = self.departures.iter().position(|d| d.number == number) {
            self.departures[k].input_open = false;
            if !self.departures[k].is_off() {
                self.pull(k, Some(DropReason::Removed));
            }
        }
        self.check_departures();
    }

    /// The client of node `number` left: its node stays on the bus and sends the frames the
    /// client handed over, in order and with their retries, then leaves. It gives up if it goes
    /// bus-off or sends none of them for [`crate::DEPARTURE_STALL`] of bus time: the attempt on
    /// the wire ends, the node is pulled off and what it did not send is counted as dropped,
    /// with the reason ([`BusEvent::Left`]). Meanwhile the server goes on handing over what the
    /// client sent before it left ([`Self::submit`]) until it says there is no more
    /// ([`Self::input_ended`]). Its name is given up to a client that asks for it.
    pub fn depart(&mut self, number: u32) -> Result<(), VbusError> {
        if self.departure_mut(number).is_some() {
            return Ok(());
        }
        let (now, bitrate) = (self.now(), self.bitrate());
        let departure = Departure::new(number, self.client(number)?, now, bitrate);
        self.departures.push(departure);
        Ok(())
    }

    /// Everything the departed client of node `number` sent has been handed over.
    pub fn input_ended(&mut self, number: u32) {
        // Its client left without the server noticing first (a closed session).
        let _ = self.depart(number);
        if let Some(d) = self.departure_mut(number) {
            d.input_open = false;
        }
        self.check_departures();
    }

    /// Whether node `number`'s client left and the node is still on the bus.
    pub fn is_departing(&self, number: u32) -> bool {
        self.departures
            .iter()
            .any(|d| d.number == number && !d.is_off())
    }

    /// Departed clients' nodes still on the bus, or whose client's last frames are still
    /// being handed over.
    pub fn departing(&self) -> Vec<u32> {
        self.departures.iter().map(|d| d.number).collect()
    }

    /// Whether [`Self::submit`] would take a frame for node `number` now: its queue has room,
    /// or (a departed client's node that gave up) the frame is counted as dropped.
    pub fn takes_frame(&self, number: u32) -> bool {
        if self
            .departures
            .iter()
            .any(|d| d.number == number && !d.takes_frames())
        {
            return true;
        }
        self.client(number).is_ok_and(|node| node.tx_room() > 0)
    }

    fn departure_mut(&mut self, number: u32) -> Option<&mut Departure> {
        self.departures.iter_mut().find(|d| d.number == number)
    }

    /// The earliest bit-time at which a departure must be looked at.
    fn next_departure_check(&self) -> Option<BitTime> {
        self.departures.iter().filter_map(Departure::deadline).min()
    }

    /// Looks at every departed client's node: pulls off those that are done or gave up, and
    /// says which have left.
    fn check_departures(&mut self) {
        let now = self.now();
        let mut k = 0;
        while k < self.departures.len() {
            if !self.departures[k].is_off() {
                let number = self.departures[k].number;
                let verdict = match self
                    .index(&NodeRef::Number(number))
                    .and_then(|i| self.sim.node_mut(i).get_mut::<ClientNode>())
                {
                    Some(node) => self.departures[k].check(now, node),
                    None => Verdict::Stay,
                };
                if verdict == Verdict::Pull {
                    self.pull(k, None);
                }
            }
            let d = &self.departures[k];
            if d.is_off() && !d.input_open {
                let d = self.departures.remove(k);
                let (name, counters) = d.off.clone().unwrap_or_default();
                self.say(BusEvent::Left {
                    number: d.number,
                    name,
                    counters,
                    dropped: d.dropped,
                    reason: d.reason(),
                });
                continue;
            }
            k += 1;
        }
    }

    /// Takes departure `k`'s node off the wire (its connector is pulled).
    fn pull(&mut self, k: usize, reason: Option<DropReason>) {
        let number = self.departures[k].number;
        let Some(i) = self.index(&NodeRef::Number(number)) else {
            // Not on the bus any more (never happens: only departures pull client nodes).
            self.departures[k].vanished();
            return;
        };
        self.collect_notices();
        let mut node = self.sim.remove_node(i);
        self.numbers.remove(i);
        let name = node.name().to_string();
        match node.get_mut::<ClientNode>() {
            Some(client) => self.departures[k].pulled(name, client, reason),
            None => self.departures[k].vanished(),
        }
    }

    /// Renames node `number`.
    pub fn rename(&mut self, number: u32, name: &str) -> Result<(), VbusError> {
        let valid = (1..=64).contains(&name.len())
            && name
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'))
            && !name.bytes().all(|b| b.is_ascii_digit());
        if !valid {
            return Err(VbusError::BadName(name.to_string()));
        }
        let i = self.index_of(&NodeRef::Number(number))?;
        if let Some(other) = self.sim.find_node(name).filter(|&j| j != i) {
            let holder = self.numbers[other];
            if !self.is_departing(holder) {
                return Err(VbusError::NameTaken(name.to_string(), holder));
            }
            // A departed client's node gives its name up (python-can scripts run back to back
            // under one name): it goes back to its number's.
            let mut default = format!("node{holder}");
            while self.sim.find_node(&default).is_some() {
                default.push('_');
            }
            self.sim.node_mut(other).set_name(default.clone());
            self.say(BusEvent::Renamed {
                number: holder,
                old: name.to_string(),
                new: default,
            });
        }
        let node = self.sim.node_mut(i);
        let old = node.name().to_string();
        node.set_name(name);
        self.say(BusEvent::Renamed {
            number,
            old,
            new: name.to_string(),
        });
        Ok(())
    }

    /// Reprograms a client's bit timing through its driver (see [`ClientNode::set_btr`]).
    pub fn set_btr(&mut self, number: u32, btr0: u8, btr1: u8) -> Result<(), VbusError> {
        let bus_bitrate = self.bitrate();
        let i = self.index_of(&NodeRef::Number(number))?;
        let node = self.sim.node_mut(i);
        let name = node.name().to_string();
        let client = node
            .get_mut::<ClientNode>()
            .ok_or_else(|| VbusError::NotAClient(number.to_string()))?;
        client.set_btr(btr0, btr1).map_err(VbusError::Driver)?;
        let bitrate = client.bitrate();
        self.say(BusEvent::Timing {
            number,
            name,
            btr0,
            btr1,
            bitrate,
            bus_bitrate,
        });
        Ok(())
    }

    /// Reprograms a client's controller with the parts `settings` gives (see
    /// [`ClientNode::configure`]): as the seed's configuration assistant set up the card
    /// JerryCAN then used.
    pub fn configure(
        &mut self,
        number: u32,
        settings: &ControllerSettings,
    ) -> Result<(), VbusError> {
        let bus_bitrate = self.bitrate();
        let i = self.index_of(&NodeRef::Number(number))?;
        let node = self.sim.node_mut(i);
        let name = node.name().to_string();
        let client = node
            .get_mut::<ClientNode>()
            .ok_or_else(|| VbusError::NotAClient(number.to_string()))?;
        client.configure(settings).map_err(VbusError::Driver)?;
        let matches_bus =
            client.mismatch().is_none() && within_tolerance(client.bitrate(), bus_bitrate);
        self.say(BusEvent::Configured {
            number,
            name,
            settings: *settings,
            matches_bus,
        });
        Ok(())
    }

    /// Puts a fault on the wire from now on, for `lasting` (until [`Self::repair`] if `None`).
    pub fn inject_fault(
        &mut self,
        fault: &WireFault,
        lasting: Option<std::time::Duration>,
    ) -> Result<(), VbusError> {
        let now = self.now();
        // Those ended but not forgotten yet (the bus has not run since) do not count either.
        let on_wire = self.sim.faults().iter().filter(|f| f.end > now).count();
        if on_wire >= MAX_FAULTS {
            return Err(VbusError::FaultRefused(FaultLimit::Active {
                max: MAX_FAULTS as u32,
            }));
        }
        let indices = |bus: &Self, nodes: &[NodeRef]| -> Result<Vec<usize>, VbusError> {
            nodes.iter().map(|n| bus.index_of(n)).collect()
        };
        let kind = match fault {
            WireFault::Cut {
                far_side,
                error_rate,
            } => FaultKind::Cut {
                far_side: indices(self, far_side)?,
                error_rate: error_rate.get(),
            },
            WireFault::Disconnect { node } => FaultKind::Disconnect {
                node: self.index_of(node)?,
            },
            WireFault::Flip { node } => FaultKind::Flip {
                node: node.as_ref().map(|n| self.index_of(n)).transpose()?,
            },
            WireFault::Noise { nodes, rate } => FaultKind::Noise {
                nodes: indices(self, nodes)?,
                rate: rate.get(),
            },
            WireFault::StuckDominant => FaultKind::StuckDominant,
        };
        let start = self.now();
        let end = lasting.map_or(BitTime::MAX, |d| {
            let bits = Nanos::from_duration(d).bit_times_at(self.bitrate());
            start.saturating_add(bits.max(BitTime::ONE))
        });
        self.say(BusEvent::Fault {
            description: describe_fault(&kind, &self.nodes()),
            lasting,
        });
        self.sim.add_fault(Fault { kind, start, end });
        Ok(())
    }

    /// A SLIO demo board (by its SLIO number), after `change` to its inputs at the bus's
    /// time: the SLIO sees the new levels on its pins (reporting the edges its edge registers
    /// ask for, while P13 selects the switches) and converts the new potentiometer level.
    pub fn demo_board(
        &mut self,
        slio: SlioId,
        change: Option<BoardInput>,
    ) -> Result<BoardState, VbusError> {
        if let Some(BoardInput::Switches(bits)) = change
            && bits > 0xF
        {
            return Err(VbusError::Switches(bits));
        }
        let now = self.now();
        let found = self
            .sim
            .nodes_mut()
            .iter_mut()
            .position(|n| board_of(n).is_some_and(|b| b.slio() == slio));
        let Some(i) = found else {
            let boards = self
                .sim
                .nodes_mut()
                .iter_mut()
                .filter_map(|n| board_of(n).map(|b| b.slio()))
                .collect();
            return Err(VbusError::NoBoard { slio, boards });
        };
        let number = self.numbers[i];
        let node = self.sim.node_mut(i);
        let name = node.name().to_string();
        let board = board_of(node).expect("found above");
        if let Some(input) = change {
            board.change(now, input);
        }
        let state = board.state(
            now,
            NodeInfo {
                number,
                name: name.clone(),
            },
        );
        if let Some(input) = change {
            self.say(BusEvent::Board {
                number,
                name,
                input,
            });
        }
        Ok(state)
    }

    /// Ends every fault on the wire now; returns how many were ended.
    pub fn repair(&mut self) -> usize {
        let ended = self.sim.end_faults();
        if ended > 0 {
            self.say(BusEvent::Repaired { faults: ended });
        }
        ended
    }

    /// Simulates up to (not including) bit-time `end`.
    pub fn run_until(&mut self, end: BitTime) {
        while self.now() < end {
            let mut stop = end.min(self.next_window);
            if let Some(check) = self.next_departure_check() {
                stop = stop.min(check.max(self.now() + BitTime::ONE));
            }
            self.sim.run_until(stop);
            if self.now() >= self.next_window {
                let stats = *self.sim.bus_stats();
                self.last_second = stats.since(&self.window_start);
                self.window_start = stats;
                self.next_window += Nanos::from_secs(1).bit_times_at(self.bitrate());
            }
            if !self.departures.is_empty() {
                self.check_departures();
            }
        }
    }

    /// Whether the bus would only let time pass until [`Self::next_activity`]: no fault, and
    /// every node idle with nothing to send.
    pub fn is_idle(&self) -> bool {
        self.sim.is_idle()
    }

    /// The next bit-time at which scenario traffic, a fault change or a sample is due.
    pub fn next_activity(&self) -> BitTime {
        self.sim.next_activity()
    }

    /// A node's status (typed; the socketcand extension carries it as text).
    pub fn status(&mut self, node: &NodeRef) -> Result<NodeStatus, VbusError> {
        let i = self.index_of(node)?;
        let number = self.numbers[i];
        let bus = BusSummary {
            bitrate: self.bitrate(),
            load_percent: 100.0 * self.last_second().load(),
            frames: self.stats().frames,
            errors: self.stats().errors,
        };
        let bus_bitrate = self.bitrate();
        let node = self.sim.node_mut(i);
        let name = node.name().to_string();
        let stats = *node.stats();
        let (tec, rec, state) = (node.tec(), node.rec(), node.state());
        if let Some(client) = node.get_mut::<ClientNode>() {
            let (btr0, btr1) = client.btr();
            let bitrate = client.bitrate();
            let timing = Some(NodeTiming {
                btr0,
                btr1,
                bitrate,
                matches_bus: client.mismatch().is_none() && within_tolerance(bitrate, bus_bitrate),
            });
            let tx_queued = client.tx_queued() as u64;
            let counters = client.counters;
            let state = client.state().error_state();
            let driver = client.driver();
            let sr = Some(driver.status());
            // BasicCAN cannot read its counters: none then, as the chip shows.
            let errors = driver.error_registers();
            return Ok(NodeStatus {
                number,
                name,
                state,
                errors,
                sr,
                timing,
                counters,
                tx_queued,
                bus,
            });
        }
        Ok(NodeStatus {
            number,
            name,
            state,
            errors: Some(ErrorRegisters {
                alc: None,
                ecc: None,
                rxerr: rec.min(255) as u8,
                txerr: tec.min(255) as u8,
            }),
            sr: None,
            timing: None,
            counters: NodeCounters {
                sent: stats.sent,
                received: stats.received,
                tx_failed: stats.dropped,
                bus_errors: stats.errors,
                arbitration_lost: stats.arbitration_lost,
                bus_off: stats.bus_off,
                ..NodeCounters::default()
            },
            tx_queued: node.device().pending() as u64,
            bus,
        })
    }

    /// A client node's register dump.
    pub fn regs(&mut self, node: &NodeRef) -> Result<NodeRegisters, VbusError> {
        let i = self.index_of(node)?;
        let number = self.numbers[i];
        let n = self.sim.node_mut(i);
        let name = n.name().to_string();
        let client = n
            .get_mut::<ClientNode>()
            .ok_or_else(|| VbusError::NoRegisters(name.clone()))?;
        Ok(NodeRegisters {
            number,
            name,
            dump: client.driver().register_dump(),
        })
    }

    fn say(&mut self, event: BusEvent) {
        self.events.push((self.now(), event));
    }

    /// Moves what the client nodes' drivers and the bench's devices noticed into the bus's
    /// events.
    fn collect_notices(&mut self) {
        let Self {
            sim,
            numbers,
            events,
            ..
        } = self;
        for (&number, node) in numbers.iter().zip(sim.nodes_mut()) {
            if let Some(device) = node.get_mut::<DeviceNode>() {
                for (time, notice) in device.device_mut().take_notices() {
                    events.push((
                        time,
                        BusEvent::Device {
                            number,
                            name: node.name().to_string(),
                            notice,
                        },
                    ));
                }
                continue;
            }
            let Some(notices) = node
                .get_mut::<ClientNode>()
                .map(ClientNode::take_notices)
                .filter(|n| !n.is_empty())
            else {
                continue;
            };
            for (time, notice) in notices {
                let name = node.name().to_string();
                events.push((
                    time,
                    BusEvent::Node {
                        number,
                        name,
                        notice,
                    },
                ));
            }
        }
    }
}

/// A node's SLIO demo board, if it is a device that has one.
fn board_of(node: &mut buslab_sim::Node) -> Option<&mut dyn Board> {
    node.get_mut::<DeviceNode>()?.device_mut().board()
}

/// The bit timing a node gets for `bitrate` (for the log and docs).
pub fn timing_for(bitrate: u32) -> Option<BitTiming> {
    node_config(bitrate).bit_timing().ok()
}
