//! The node factory: the models a scenario (or a bench) puts on the wire, made for the bus's
//! bit rate. The engine (`buslab-sim`) takes any `BusNode`; which ones exist is known here.

use buslab_canbus::BusOffRecovery;
use buslab_canbus::node::{Sja1000Node, node_config};
use buslab_slio::{DemoBoard, SlioError, SlioId};

/// How a scenario's SJA1000 node is set up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sja1000Spec {
    /// Linux's fast restart after bus-off (`recovery = "fast"`) instead of the seed's
    /// (`"counted"`, the default): reset mode cleared, the chip counting TXERR down.
    pub fast_restart: bool,
}

/// An SJA1000 at the bus's bit rate operated by the host library's driver, with the seed's
/// bus-off recovery unless `spec` asks for the fast restart. The reason names the bit rate if
/// the chip cannot run at it.
pub fn sja1000(spec: &Sja1000Spec, bitrate: u32) -> Result<Sja1000Node, String> {
    let mut config = node_config(bitrate);
    if spec.fast_restart {
        config.bus_off_recovery = BusOffRecovery::Fast;
    }
    Sja1000Node::with_config(config, bitrate, false)
}

/// A P82C150 SLIO on the seed's demo board, its ID switches set to `id`, ADC1 (P5) and the
/// potentiometer (P6) at constant voltages.
pub fn slio_board(
    id: SlioId,
    bitrate: u32,
    adc1: f64,
    potentiometer: f64,
) -> Result<DemoBoard, SlioError> {
    DemoBoard::new(id, bitrate, Box::new(adc1), Box::new(potentiometer))
}
