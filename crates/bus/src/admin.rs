//! The typed vocabulary of a bus that has more to tell than frames (buslab's virtual bus):
//! its nodes, their counters and timing, the bus's summary, faults to put on its wire and the
//! limits that refuse them, a demo board's switches.
//!
//! The values are typed here; a transport carries them however it must (the socketcand
//! extension as `key=value` text) and turns them back into these types at its edge.

use std::fmt;
use std::time::Duration;

use buslab_chips::slio::{LED_PINS, SlioId, VDD};
use buslab_device::Human;

use crate::decode::{ErrorRegisters, RegisterDump, Status};
use buslab_can::controller::ErrorState;

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

/// A node's status: error state, registers, counters.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeStatus {
    pub number: u32,
    pub name: String,
    pub state: ErrorState,
    /// TXERR, RXERR and the last captured ALC and ECC, for nodes that have these registers
    /// (an SJA1000 in PeliCAN mode; BasicCAN cannot read its counters).
    pub errors: Option<ErrorRegisters>,
    /// The status register, for nodes that are SJA1000 chips.
    pub sr: Option<Status>,
    /// The bit timing, for nodes whose timing is programmable.
    pub timing: Option<NodeTiming>,
    pub counters: NodeCounters,
    /// Frames waiting to be sent (the client's queue and the chip's buffer).
    pub tx_queued: u64,
    pub bus: BusSummary,
}

/// Several lines: the node, its state, SR in words, the counters, ALC and ECC in words, then
/// the timing and the node's and the bus's counters.
impl fmt::Display for NodeStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fn row(f: &mut fmt::Formatter<'_>, label: &str, value: impl fmt::Display) -> fmt::Result {
            writeln!(f, "{:<18}{value}", format!("{label}:"))
        }
        writeln!(f, "node {} ({})", self.number, self.name)?;
        row(f, "state", self.state)?;
        if let Some(sr) = self.sr {
            row(f, "STATUS", sr)?;
        }
        if let Some(e) = self.errors {
            row(f, "TXERR", e.txerr)?;
            row(f, "RXERR", e.rxerr)?;
            match e.alc {
                Some(alc) => row(f, "ALC", format_args!("0x{:02X} {alc}", alc.0))?,
                None => row(f, "ALC", "none captured")?,
            }
            match e.ecc {
                Some(ecc) => row(f, "ECC", format_args!("0x{:02X} {ecc}", ecc.0))?,
                None => row(f, "ECC", "none captured")?,
            }
        }
        if let Some(t) = self.timing {
            row(
                f,
                "timing",
                format_args!(
                    "BTR0=0x{:02X} BTR1=0x{:02X}: {} bit/s{}",
                    t.btr0,
                    t.btr1,
                    t.bitrate,
                    if t.matches_bus {
                        ""
                    } else {
                        " (does not match the bus: cannot communicate)"
                    }
                ),
            )?;
        }
        let c = self.counters;
        row(f, "sent", c.sent)?;
        row(f, "received", c.received)?;
        row(f, "tx_failed", c.tx_failed)?;
        row(f, "bus_errors", c.bus_errors)?;
        row(f, "arbitration_lost", c.arbitration_lost)?;
        row(f, "overruns", c.overruns)?;
        row(f, "bus_off", c.bus_off)?;
        row(f, "rx_lost", c.rx_lost)?;
        row(f, "tx_queued", self.tx_queued)?;
        let b = self.bus;
        row(
            f,
            "bus",
            format_args!(
                "{} bit/s, load {:.1} % (last second), {} frames, {} errors",
                b.bitrate, b.load_percent, b.frames, b.errors
            ),
        )
    }
}

/// A node's register dump with the node it came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeRegisters {
    pub number: u32,
    pub name: String,
    pub dump: RegisterDump,
}

/// A level on an analog input of a demo board: 0..=5 V (its supply), never NaN.
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd)]
pub struct BoardVolts(f64);

impl Eq for BoardVolts {}

/// A level the board's analog inputs cannot take.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("{0} V: a demo board's analog inputs take 0..=5 V (its supply)")]
pub struct BadVolts(pub f64);

impl BoardVolts {
    pub fn new(volts: f64) -> Result<Self, BadVolts> {
        if (0.0..=VDD).contains(&volts) {
            // -0.0 + 0.0 is 0.0: one zero.
            Ok(Self(volts + 0.0))
        } else {
            Err(BadVolts(volts))
        }
    }

    pub fn get(self) -> f64 {
        self.0
    }
}

impl fmt::Display for BoardVolts {
    /// Millivolts are the finest step shown (the ADC's is 4.9 mV).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.3}", self.0)
    }
}

/// What a person at the bench does to a SLIO demo board's inputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoardInput {
    /// One input switch on or off.
    Switch { switch: BoardSwitch, on: bool },
    /// The four input switches at once (bit 0 = the switch on P0).
    Switches(u8),
    /// The potentiometer (P6, ADC2) turned to a level; it stays there.
    Potentiometer(BoardVolts),
}

impl fmt::Display for BoardInput {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BoardInput::Switch { switch, on } => {
                write!(f, "switch {switch} {}", if *on { "on" } else { "off" })
            }
            BoardInput::Switches(bits) => write!(f, "switches {}", switch_bits(*bits)),
            BoardInput::Potentiometer(v) => write!(f, "potentiometer at {v} V"),
        }
    }
}

/// A SLIO demo board as a person at the bench sees it: its inputs and what its outputs do.
#[derive(Clone, Debug, PartialEq)]
pub struct BoardState {
    pub slio: SlioId,
    /// Its node on the bus.
    pub node: NodeInfo,
    /// The four input switches (bit 0 = P0).
    pub switches: u8,
    /// The potentiometer (P6, ADC2) and the level on ADC1 (P5), in volts, now.
    pub potentiometer: f64,
    pub adc1: f64,
    /// The pins whose LED is lit (of P7, P8, P9, P11, P12).
    pub leds: u16,
    /// DPM1 (P10) and DPM2 (P4): their mean level in volts, `None` while the pin floats.
    pub dpm: [Option<f64>; 2],
}

/// `SLIO 3 (node 6, slio3): switches 0101, potentiometer 2.500 V, ADC1 1.250 V, LEDs P7 P11,
/// DPM1 0.000 V, DPM2 floating`.
impl fmt::Display for BoardState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "SLIO {} (node {}, {}): switches {} (P3..P0), potentiometer {:.3} V, ADC1 {:.3} V, LEDs ",
            self.slio,
            self.node.number,
            self.node.name,
            switch_bits(self.switches),
            self.potentiometer,
            self.adc1
        )?;
        let lit: Vec<String> = LED_PINS
            .iter()
            .filter(|&&p| self.leds & 1 << p != 0)
            .map(|p| format!("P{p}"))
            .collect();
        if lit.is_empty() {
            f.write_str("off")?;
        } else {
            f.write_str(&lit.join(" "))?;
        }
        for (k, dpm) in self.dpm.iter().enumerate() {
            match dpm {
                Some(v) => write!(f, ", DPM{} {v:.3} V", k + 1)?,
                None => write!(f, ", DPM{} floating", k + 1)?,
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod node_tests {
    use super::*;
    use crate::decode::{Alc, Ecc};

    #[test]
    fn board_inputs_are_checked_and_read_like_the_board() {
        assert_eq!(BoardSwitch::new(4), Err(BadSwitch(4)));
        assert_eq!(
            BadSwitch(4).to_string(),
            "switch 4: a demo board has input switches 0..=3 (on P0..P3)"
        );
        assert!(BoardVolts::new(f64::NAN).is_err());
        assert!(BoardVolts::new(5.01).is_err());
        assert!(BoardVolts::new(-0.0).is_ok());
        assert_eq!(BoardVolts::new(2.5).unwrap().to_string(), "2.500");
        let state = BoardState {
            slio: SlioId::new(3).unwrap(),
            node: NodeInfo {
                number: 6,
                name: "slio3".into(),
            },
            switches: 0b0101,
            potentiometer: 2.5,
            adc1: 1.25,
            leds: 0x0880,
            dpm: [Some(0.0), None],
        };
        assert_eq!(
            state.to_string(),
            "SLIO 3 (node 6, slio3): switches 0101 (P3..P0), potentiometer 2.500 V, ADC1 1.250 V, LEDs P7 P11, DPM1 0.000 V, DPM2 floating"
        );
        let switch = BoardInput::Switch {
            switch: BoardSwitch::new(2).unwrap(),
            on: true,
        };
        assert_eq!(switch.to_string(), "switch 2 on");
    }

    #[test]
    fn status_prints_in_the_layout_of_buslab_status() {
        let mut st = NodeStatus {
            number: 3,
            name: "loser".into(),
            state: ErrorState::Passive,
            errors: Some(ErrorRegisters {
                alc: Some(Alc(0)),
                ecc: Some(Ecc(0x0A)),
                rxerr: 0,
                txerr: 128,
            }),
            sr: Some(Status(0x0C)),
            timing: Some(NodeTiming {
                btr0: 0x07,
                btr1: 0x4D,
                bitrate: 50_000,
                matches_bus: false,
            }),
            counters: NodeCounters {
                sent: 1,
                ..NodeCounters::default()
            },
            tx_queued: 2,
            bus: BusSummary {
                bitrate: 500_000,
                load_percent: 12.34,
                frames: 7,
                errors: 9,
            },
        };
        let text = st.to_string();
        for line in [
            "node 3 (loser)\n",
            "\nstate:            error-passive\n",
            "\nTXERR:            128\n",
            "\nALC:              0x00 arbitration lost at bit 0 (ID.28)\n",
            "\nECC:              0x0A bit error during transmission in data field\n",
            "\ntiming:           BTR0=0x07 BTR1=0x4D: 50000 bit/s (does not match the bus: cannot communicate)\n",
            "\nsent:             1\n",
            "\ntx_queued:        2\n",
            "\nbus:              500000 bit/s, load 12.3 % (last second), 7 frames, 9 errors\n",
        ] {
            assert!(text.contains(line), "{line:?} in\n{text}");
        }
        // No registers to show: the lines are left out, not printed as zeros.
        st.errors = None;
        st.sr = None;
        st.timing = None;
        let text = st.to_string();
        for absent in ["TXERR", "ALC", "STATUS", "timing"] {
            assert!(!text.contains(absent), "{absent} in\n{text}");
        }
    }
}
