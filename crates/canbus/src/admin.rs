//! Administration of a bus that has more to tell than frames: buslab's virtual bus lists its
//! nodes and reports each one's error state, counters and registers ([`BusAdmin`]).
//!
//! The values are typed here; a transport carries them however it must (the socketcand
//! extension as `key=value` text) and turns them back into these types at its edge. The
//! values that need no SJA1000 or SLIO facts live in `buslab-bus` and are re-exported here.

use std::fmt;

pub use buslab_bus::admin::*;
use buslab_bus::{BusError, BusState};
use buslab_slio::SlioId;
use buslab_slio::board::{LED_PINS, VDD};

use crate::decode::{ErrorRegisters, RegisterDump, Status};

/// A node's status: error state, registers, counters.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeStatus {
    pub number: u32,
    pub name: String,
    pub state: BusState,
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

/// The administration side of a bus: nodes, status, registers, and settings of this client's
/// own node. Backends that have none of it return `None` from
/// [`CanBus::admin`](crate::CanBus::admin).
pub trait BusAdmin {
    /// Every node on the bus.
    fn nodes(&mut self) -> Result<Vec<NodeInfo>, BusError>;
    /// A node's status (this client's own node if `None`).
    fn node_status(&mut self, node: Option<&NodeRef>) -> Result<NodeStatus, BusError>;
    /// A node's registers (this client's own node if `None`).
    fn register_dump(&mut self, node: Option<&NodeRef>) -> Result<NodeRegisters, BusError>;
    /// Names this client's node.
    fn set_name(&mut self, name: &str) -> Result<(), BusError>;
    /// Reprograms this client's chip with BTR0/BTR1.
    fn set_btr(&mut self, btr0: u8, btr1: u8) -> Result<(), BusError>;
    /// Waits until every frame this client sent so far was transmitted or given up, and says
    /// how many of each since it joined; an error after `timeout`.
    fn flush(&mut self, timeout: std::time::Duration) -> Result<TxReport, BusError>;
    /// Gives up the frame this client's controller is trying (as CMR.AT: a frame already on
    /// the wire finishes its attempt but is not retried) and the frames queued behind it.
    fn abort(&mut self) -> Result<(), BusError>;
    /// How this client's chip comes back after bus-off (the bus's policy until then). Only
    /// a virtual bus lets a client choose.
    fn set_bus_off_recovery(&mut self, recovery: crate::BusOffRecovery) -> Result<(), BusError> {
        let _ = recovery;
        Err(BusError::Unsupported {
            what: "choosing the bus-off recovery",
            backend: "this bus".into(),
        })
    }
    /// Puts a fault on the wire from now on, for `lasting` (until [`BusAdmin::repair`] if
    /// `None`). Only a virtual bus has a wire to break.
    fn inject_fault(
        &mut self,
        fault: &WireFault,
        lasting: Option<std::time::Duration>,
    ) -> Result<(), BusError> {
        let _ = (fault, lasting);
        Err(BusError::Unsupported {
            what: "fault injection",
            backend: "this bus".into(),
        })
    }
    /// Ends every fault on the wire now (injected or from a scenario).
    fn repair(&mut self) -> Result<(), BusError> {
        Err(BusError::Unsupported {
            what: "fault injection",
            backend: "this bus".into(),
        })
    }
    /// Reprograms this client's own controller with the parts of `settings` that are given
    /// (mode, bit timing, acceptance filter, output control, clock output), the others kept.
    /// Only a bus whose clients have a controller of their own has one to program.
    fn configure(&mut self, settings: &crate::ControllerSettings) -> Result<(), BusError> {
        let _ = settings;
        Err(BusError::Unsupported {
            what: "controller settings",
            backend: "this bus".into(),
        })
    }
    /// A SLIO demo board on the bus, after `change` to its inputs if given (a switch flipped,
    /// the potentiometer turned). Only a virtual bus has boards to reach.
    fn demo_board(
        &mut self,
        slio: SlioId,
        change: Option<BoardInput>,
    ) -> Result<BoardState, BusError> {
        let _ = (slio, change);
        Err(BusError::Unsupported {
            what: "demo boards",
            backend: "this bus".into(),
        })
    }
}

#[cfg(test)]
mod tests {
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
            state: BusState::Passive,
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
