//! The virtual bus, sans-IO: SJA1000 chips on one wired-AND wire, stepped once per bit-time in
//! virtual time, each operated through the host library's driver as a client's computer would.
//!
//! The network side ([`crate::server`]) moves frames between clients and [`Node`] queues and
//! decides how far to run; everything here is plain state.

use std::collections::VecDeque;

use buslab_can::{Frame, Level};
use buslab_canbus::{
    ControllerState, DriverEvent, Sja1000Config, Sja1000Driver, Timing, TxFailure,
};
use buslab_sim::Simulation;
use buslab_sja1000::{BitTiming, Sja1000};
use buslab_socketcand::NodeRef;

/// Crystal of every client's SJA1000 (the seed's boards: 16 MHz, CAN clock 8 MHz).
pub const CRYSTAL_HZ: u32 = 16_000_000;
/// A node whose bit rate differs from the bus by more than this (per mille) cannot follow it.
/// CAN's oscillator tolerance is at most 1.58 %; 1 % is a round figure inside it.
pub const TOLERANCE_PERMILLE: u64 = 10;
/// How long a bus-off node waits before its driver restarts it (Linux's `restart-ms` idea).
pub const RESTART_AFTER_MS: u64 = 100;

/// Why a bus could not be set up or a request failed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum VbusError {
    /// The bus bit rate and why a client chip cannot run at it (the reason names the rate).
    #[error("{1}")]
    Bitrate(u32, String),
    #[error("no node {0} (see buslab_nodes)")]
    NoNode(String),
    #[error("the bus is full ({0} nodes)")]
    Full(usize),
    #[error("name {0:?} is taken by node {1}")]
    NameTaken(String, u32),
    #[error("the chip refused the configuration: {0}")]
    Driver(String),
}

/// A frame for a client and the bit-time at which its chip had it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Delivery {
    pub frame: Frame,
    pub time: u64,
}

/// SocketCAN error classes (`linux/can/error.h`) for the error frames sent to clients.
pub mod error_class {
    pub const LOST_ARBITRATION: u32 = 0x002;
    pub const CONTROLLER: u32 = 0x004;
    pub const PROTOCOL: u32 = 0x008;
    pub const BUS_OFF: u32 = 0x040;
    pub const BUS_ERROR: u32 = 0x080;
    pub const RESTARTED: u32 = 0x100;
}

/// An error frame for a client: its SocketCAN class and the bit-time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ErrorFrame {
    pub class: u32,
    pub time: u64,
}

/// Counters a client and the log can see.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NodeCounters {
    pub sent: u64,
    pub received: u64,
    pub tx_failed: u64,
    pub bus_errors: u64,
    pub arbitration_lost: u64,
    pub overruns: u64,
    pub bus_off: u64,
    /// Frames the client could not take in time (counted by the network side).
    pub rx_lost: u64,
}

/// One client's SJA1000 with its driver.
#[derive(Debug)]
pub struct Node {
    pub number: u32,
    pub name: String,
    driver: Sja1000Driver<Sja1000>,
    config: Sja1000Config,
    /// The node's own bit rate when it differs from the bus's.
    mismatch: Option<u32>,
    /// Frames the client sent, not yet handed to the chip.
    pub tx: VecDeque<Frame>,
    /// Frames for the client.
    pub rx: Vec<Delivery>,
    /// Also deliver the node's own frames once sent.
    pub receive_own: bool,
    /// Error frames for the client (collected only when `error_frames` is on).
    pub errors: Vec<ErrorFrame>,
    pub error_frames: bool,
    pub counters: NodeCounters,
    bus_off_at: Option<u64>,
}

impl Node {
    /// The node's bit rate from its BTR0/BTR1 and crystal.
    pub fn bitrate(&mut self) -> u32 {
        self.driver.registers().bit_timing().bitrate(CRYSTAL_HZ / 2)
    }

    pub fn mismatch(&self) -> Option<u32> {
        self.mismatch
    }

    pub fn state(&self) -> ControllerState {
        self.driver.state()
    }
}

/// Bus load over the whole run and over the last virtual second.
#[derive(Clone, Copy, Debug, Default)]
pub struct Load {
    pub frames: u64,
    pub errors: u64,
    busy_total: u64,
    bits_total: u64,
    window_busy: u64,
    window_bits: u64,
    last_percent: f64,
    last_frames: u64,
    window_frames: u64,
    recessive_run: u64,
}

impl Load {
    /// Per cent of bit-times that were busy (not the 12th or later recessive bit in a row).
    pub fn total_percent(&self) -> f64 {
        percent(self.busy_total, self.bits_total)
    }
    /// Load over the last complete second (or so far, in the first).
    pub fn last_second_percent(&self) -> f64 {
        if self.last_percent == 0.0 && self.window_bits > 0 {
            percent(self.window_busy, self.window_bits)
        } else {
            self.last_percent
        }
    }
    pub fn frames_last_second(&self) -> u64 {
        self.last_frames
    }

    #[inline]
    fn bit(&mut self, level: Level) {
        if level == Level::Recessive {
            self.recessive_run += 1;
        } else {
            self.recessive_run = 0;
        }
        let busy = (self.recessive_run < 12) as u64;
        self.busy_total += busy;
        self.window_busy += busy;
        self.bits_total += 1;
        self.window_bits += 1;
    }

    fn idle(&mut self, bits: u64) {
        let busy = 11u64.saturating_sub(self.recessive_run).min(bits);
        self.recessive_run += bits;
        self.busy_total += busy;
        self.window_busy += busy;
        self.bits_total += bits;
        self.window_bits += bits;
    }

    fn close_window(&mut self) {
        self.last_percent = percent(self.window_busy, self.window_bits);
        self.last_frames = self.window_frames;
        self.window_busy = 0;
        self.window_bits = 0;
        self.window_frames = 0;
    }
}

fn percent(part: u64, whole: u64) -> f64 {
    if whole == 0 {
        0.0
    } else {
        100.0 * part as f64 / whole as f64
    }
}

/// `key=value` pairs of a status report, in order.
pub type Fields = Vec<(String, String)>;

/// Per-node transmit queue length (frames waiting for the chip's single TX buffer).
pub const TX_QUEUE: usize = 64;
/// Most nodes on one bus (an ISO 11898 segment allows far fewer real ones).
pub const MAX_NODES: usize = 64;

/// The bus and its nodes.
#[derive(Debug)]
pub struct VirtualBus {
    bitrate: u32,
    now: u64,
    nodes: Vec<Node>,
    next_number: u32,
    load: Load,
    rng: u64,
    log: Vec<String>,
    scenario: Option<Simulation>,
    next_window: u64,
    error_frames: bool,
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
        Ok(Self {
            bitrate,
            now: 0,
            nodes: Vec::new(),
            next_number: 1,
            load: Load::default(),
            rng: 0x9E37_79B9_7F4A_7C15,
            log: Vec::new(),
            scenario: None,
            next_window: bitrate as u64,
            error_frames: false,
        })
    }

    /// Puts a scenario's simulated nodes on the same wire (their traffic and faults run in
    /// the same virtual time; bus-wide faults reach the chips, node faults only the
    /// scenario's nodes).
    pub fn with_scenario(mut self, sim: Simulation) -> Self {
        self.scenario = Some(sim);
        self
    }

    /// Whether nodes that join from now on collect error frames for their clients.
    pub fn set_error_frames(&mut self, on: bool) {
        self.error_frames = on;
    }

    pub fn bitrate(&self) -> u32 {
        self.bitrate
    }
    /// Bit-times simulated so far.
    pub fn now(&self) -> u64 {
        self.now
    }
    pub fn load(&self) -> &Load {
        &self.load
    }
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }
    pub fn nodes_mut(&mut self) -> &mut [Node] {
        &mut self.nodes
    }
    pub fn scenario(&self) -> Option<&Simulation> {
        self.scenario.as_ref()
    }

    /// Log lines (in words, with the virtual time) since the last call.
    pub fn take_log(&mut self) -> Vec<String> {
        std::mem::take(&mut self.log)
    }

    fn say(&mut self, line: String) {
        let t = self.now as f64 / self.bitrate as f64;
        self.log.push(format!("({t:.6}) {line}"));
    }

    /// A new node: a fresh SJA1000 initialised by the driver (PeliCAN, accept all, the bus's
    /// bit rate). Returns its number.
    pub fn join(&mut self) -> Result<u32, VbusError> {
        if self.nodes.len() >= MAX_NODES {
            return Err(VbusError::Full(MAX_NODES));
        }
        let number = self.next_number;
        let config = node_config(self.bitrate);
        let mut driver = Sja1000Driver::new(Sja1000::new());
        driver
            .init(&config)
            .map_err(|e| VbusError::Driver(e.to_string()))?;
        self.next_number += 1;
        self.nodes.push(Node {
            number,
            name: format!("node{number}"),
            driver,
            config,
            mismatch: None,
            tx: VecDeque::new(),
            rx: Vec::new(),
            receive_own: false,
            errors: Vec::new(),
            error_frames: self.error_frames,
            counters: NodeCounters::default(),
            bus_off_at: None,
        });
        let (btr0, btr1) = self
            .nodes
            .last_mut()
            .map_or((0, 0), |n| n.driver.registers().bit_timing().registers());
        self.say(format!(
            "node {number} joined (PeliCAN, accept all, BTR0={btr0:02X} BTR1={btr1:02X})"
        ));
        Ok(number)
    }

    /// Removes a node (its connector is pulled, even in the middle of a frame).
    pub fn leave(&mut self, number: u32) {
        if let Some(i) = self.index(&NodeRef::Number(number)) {
            let n = self.nodes.remove(i);
            self.say(format!(
                "node {} ({}) left: sent {}, received {}, lost {}",
                n.number, n.name, n.counters.sent, n.counters.received, n.counters.rx_lost
            ));
        }
    }

    pub fn index(&self, node: &NodeRef) -> Option<usize> {
        self.nodes.iter().position(|n| match node {
            NodeRef::Number(k) => n.number == *k,
            NodeRef::Name(name) => &n.name == name,
        })
    }

    pub fn node_mut(&mut self, node: &NodeRef) -> Result<&mut Node, VbusError> {
        let i = self
            .index(node)
            .ok_or_else(|| VbusError::NoNode(node.to_string()))?;
        Ok(&mut self.nodes[i])
    }

    pub fn rename(&mut self, number: u32, name: &str) -> Result<(), VbusError> {
        if let Some(other) = self
            .nodes
            .iter()
            .find(|n| n.name == name && n.number != number)
        {
            return Err(VbusError::NameTaken(name.to_string(), other.number));
        }
        let node = self.node_mut(&NodeRef::Number(number))?;
        let old = std::mem::replace(&mut node.name, name.to_string());
        self.say(format!("node {number} ({old}) is now called {name}"));
        Ok(())
    }

    /// Reprograms a node's bit timing through the driver. A timing that does not give the
    /// bus's bit rate (within [`TOLERANCE_PERMILLE`]) leaves the node unable to communicate:
    /// it samples the bus at the wrong instants and reads noise (see docs/bus.md).
    pub fn set_btr(&mut self, number: u32, btr0: u8, btr1: u8) -> Result<(), VbusError> {
        let bus = self.bitrate;
        let node = self.node_mut(&NodeRef::Number(number))?;
        let mut config = node.config.clone();
        config.timing = Timing::Registers { btr0, btr1 };
        node.driver
            .init(&config)
            .map_err(|e| VbusError::Driver(e.to_string()))?;
        node.config = config;
        node.bus_off_at = None;
        let rate = node.bitrate();
        let diff = (rate as i64 - bus as i64).unsigned_abs();
        node.mismatch = (diff * 1000 > bus as u64 * TOLERANCE_PERMILLE).then_some(rate);
        let line = match node.mismatch {
            Some(rate) => format!(
                "node {number} ({}): BTR0={btr0:02X} BTR1={btr1:02X} give {rate} bit/s, the bus runs at {bus} bit/s: this node cannot communicate",
                node.name
            ),
            None => format!(
                "node {number} ({}): BTR0={btr0:02X} BTR1={btr1:02X} give {rate} bit/s (bus {bus} bit/s)",
                node.name
            ),
        };
        self.say(line);
        Ok(())
    }

    /// Whether every chip is idle with nothing to send and the bus has been recessive long
    /// enough: then stepping changes nothing but time.
    fn all_idle(&mut self) -> bool {
        if self.load.recessive_run < 11 {
            return false;
        }
        let scenario_idle = self.scenario.as_ref().is_none_or(|s| s.is_idle());
        scenario_idle
            && self.nodes.iter_mut().all(|n| {
                if n.mismatch.is_some() || !n.tx.is_empty() || n.driver.tx_pending() {
                    return false;
                }
                // SR: RS, TS clear; BS clear (a bus-off chip counts recessive bits).
                let sr = n.driver.registers().peek(2);
                sr & 0xB0 == 0
            })
    }

    /// Simulates up to (not including) bit-time `end`.
    pub fn run_until(&mut self, end: u64) {
        self.feed_all();
        while self.now < end {
            let stop = end.min(self.next_window);
            // Scenario traffic or a fault due now must be stepped with the chips, not skipped.
            let skip = self
                .scenario
                .as_ref()
                .map_or(stop, |s| s.next_activity().min(stop));
            if skip > self.now && self.all_idle() {
                if let Some(s) = &mut self.scenario {
                    // Nothing is due before `skip`: the scenario jumps too.
                    s.run_until(skip);
                }
                self.load.idle(skip - self.now);
                self.now = skip;
            } else {
                let mut k = 0u32;
                while self.now < stop {
                    self.step();
                    k += 1;
                    if k.is_multiple_of(16) && self.load.recessive_run >= 11 && self.all_idle() {
                        break;
                    }
                }
            }
            if self.now >= self.next_window {
                self.load.close_window();
                self.next_window += self.bitrate as u64;
                self.check_restarts();
            }
        }
        self.check_restarts();
    }

    /// One bit-time.
    fn step(&mut self) {
        let mut recessive = true;
        for n in &mut self.nodes {
            recessive &= n.driver.registers().output().bit();
        }
        let mut bus = Level::from_bit(recessive);
        if let Some(s) = &mut self.scenario {
            bus = s.step_external(bus);
        }
        let now = self.now;
        for i in 0..self.nodes.len() {
            let node = &mut self.nodes[i];
            let seen = if node.mismatch.is_some() {
                // Sampling at the wrong instants: what it reads has nothing to do with the bus.
                self.rng ^= self.rng << 13;
                self.rng ^= self.rng >> 7;
                self.rng ^= self.rng << 17;
                Level::from_bit(self.rng & 1 == 1)
            } else {
                bus
            };
            let chip = node.driver.registers();
            chip.sample(seen);
            if chip.interrupt() {
                self.service(i, now);
            }
        }
        self.load.bit(bus);
        self.now += 1;
    }

    /// The interrupt handler: the driver's poll, then the next frame into the TX buffer.
    #[inline(never)]
    fn service(&mut self, i: usize, now: u64) {
        let events = self.nodes[i].driver.poll();
        let mut lines = Vec::new();
        let node = &mut self.nodes[i];
        for event in events {
            match event {
                DriverEvent::Received(frame) => {
                    node.counters.received += 1;
                    node.rx.push(Delivery { frame, time: now });
                }
                DriverEvent::TxDone(frame) => {
                    node.counters.sent += 1;
                    self.load.frames += 1;
                    self.load.window_frames += 1;
                    if node.receive_own {
                        node.rx.push(Delivery { frame, time: now });
                    }
                }
                DriverEvent::TxFailed { frame, reason } => {
                    node.counters.tx_failed += 1;
                    if reason != TxFailure::Aborted {
                        lines.push(format!(
                            "node {} ({}): frame {frame} not sent: {reason}",
                            node.number, node.name
                        ));
                    }
                }
                DriverEvent::DataOverrun => {
                    node.counters.overruns += 1;
                    lines.push(format!(
                        "node {} ({}): RX FIFO overrun, frames lost in the chip",
                        node.number, node.name
                    ));
                }
                DriverEvent::StateChanged { from, to } => {
                    if to == ControllerState::BusOff {
                        node.counters.bus_off += 1;
                        node.bus_off_at = Some(now);
                    }
                    let class = match to {
                        ControllerState::BusOff => error_class::BUS_OFF,
                        _ => error_class::CONTROLLER,
                    };
                    error_frame(node, class, now);
                    lines.push(format!(
                        "node {} ({}): {from} -> {to} (TXERR {}, RXERR {})",
                        node.number,
                        node.name,
                        node.driver.registers().peek(15),
                        node.driver.registers().peek(14),
                    ));
                }
                DriverEvent::BusError(_) => {
                    node.counters.bus_errors += 1;
                    self.load.errors += 1;
                    error_frame(node, error_class::PROTOCOL | error_class::BUS_ERROR, now);
                }
                DriverEvent::ArbitrationLost(_) => {
                    node.counters.arbitration_lost += 1;
                    error_frame(node, error_class::LOST_ARBITRATION, now);
                }
                DriverEvent::WakeUp => {}
            }
        }
        feed(node);
        for line in lines {
            self.say(line);
        }
    }

    /// Hands waiting frames to free TX buffers (after the network side queued some).
    pub fn feed_all(&mut self) {
        for n in &mut self.nodes {
            feed(n);
        }
    }

    /// Restarts bus-off nodes after [`RESTART_AFTER_MS`].
    fn check_restarts(&mut self) {
        let wait = self.bitrate as u64 * RESTART_AFTER_MS / 1000;
        let now = self.now;
        let mut lines = Vec::new();
        for n in &mut self.nodes {
            if let Some(t) = n.bus_off_at
                && now >= t + wait
            {
                n.bus_off_at = None;
                let result = n.driver.restart();
                error_frame(n, error_class::RESTARTED, now);
                lines.push(match result {
                    Ok(()) => format!("node {} ({}): restarted after bus-off", n.number, n.name),
                    Err(e) => format!("node {} ({}): restart failed: {e}", n.number, n.name),
                });
                // The driver's state follows at the next poll.
                n.driver.poll();
                feed(n);
            }
        }
        for line in lines {
            self.say(line);
        }
    }

    /// The status of a node as `key=value` fields (see docs/bus.md).
    pub fn status(&mut self, node: &NodeRef) -> Result<(u32, String, Fields), VbusError> {
        let bus = self.bitrate;
        let load = self.load;
        let n = self.node_mut(node)?;
        let rate = n.bitrate();
        let sr = n.driver.status();
        let errs = n.driver.error_registers();
        let (btr0, btr1) = n.driver.registers().bit_timing().registers();
        let mut f: Vec<(String, String)> = Vec::new();
        let mut put = |k: &str, v: String| f.push((k.to_string(), v));
        put("state", state_word(n.driver.state()).to_string());
        put("sr", format!("{:02X}", sr.0));
        if let Some(e) = errs {
            put("txerr", e.txerr.to_string());
            put("rxerr", e.rxerr.to_string());
            if let Some(alc) = e.alc {
                put("alc", format!("{:02X}", alc.0));
            }
            if let Some(ecc) = e.ecc {
                put("ecc", format!("{:02X}", ecc.0));
            }
        }
        put("btr0", format!("{btr0:02X}"));
        put("btr1", format!("{btr1:02X}"));
        put("bitrate", rate.to_string());
        put("bus_bitrate", bus.to_string());
        put(
            "timing",
            if n.mismatch.is_some() {
                "mismatch"
            } else {
                "ok"
            }
            .to_string(),
        );
        let c = n.counters;
        put("sent", c.sent.to_string());
        put("received", c.received.to_string());
        put("tx_failed", c.tx_failed.to_string());
        put("bus_errors", c.bus_errors.to_string());
        put("arbitration_lost", c.arbitration_lost.to_string());
        put("overruns", c.overruns.to_string());
        put("bus_off", c.bus_off.to_string());
        put("rx_lost", c.rx_lost.to_string());
        put(
            "tx_queued",
            (n.tx.len() + n.driver.tx_pending() as usize).to_string(),
        );
        put("bus_load", format!("{:.1}%", load.last_second_percent()));
        put("bus_frames", load.frames.to_string());
        put("bus_errors_total", load.errors.to_string());
        Ok((n.number, n.name.clone(), f))
    }

    /// A node's register dump: mode and values (`None` where not readable).
    pub fn regs(
        &mut self,
        node: &NodeRef,
    ) -> Result<(u32, String, buslab_canbus::RegisterDump), VbusError> {
        let n = self.node_mut(node)?;
        Ok((n.number, n.name.clone(), n.driver.register_dump()))
    }
}

/// Queues an error frame if the node's client asked for them.
fn error_frame(n: &mut Node, class: u32, time: u64) {
    if n.error_frames {
        n.errors.push(ErrorFrame { class, time });
    }
}

fn feed(n: &mut Node) {
    if n.driver.tx_pending() || n.bus_off_at.is_some() {
        return;
    }
    // A refused frame (bus-off, reset mode) cannot be fixed by retrying now: it is counted.
    if let Some(frame) = n.tx.pop_front()
        && n.driver.send(&frame).is_err()
    {
        n.counters.tx_failed += 1;
    }
}

/// The configuration every client's chip gets: PeliCAN, accept all, the bus's bit rate.
pub fn node_config(bitrate: u32) -> Sja1000Config {
    Sja1000Config {
        timing: Timing::Bitrate {
            bitrate,
            sample_point_permille: None,
        },
        crystal_hz: CRYSTAL_HZ,
        ..Sja1000Config::default()
    }
}

/// python-can's names for the error states (warning is still error-active).
pub fn state_word(state: ControllerState) -> &'static str {
    match state {
        ControllerState::Active | ControllerState::Warning => "error-active",
        ControllerState::Passive => "error-passive",
        ControllerState::BusOff => "bus-off",
    }
}

/// The bit timing a node gets for `bitrate` (for the log and docs).
pub fn timing_for(bitrate: u32) -> Option<BitTiming> {
    node_config(bitrate).bit_timing().ok()
}
