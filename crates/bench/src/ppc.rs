//! The PowerPC node of a bench: MoniCAN on the seed's PPC403 board, on the bus as `ppc`.

use buslab_ppc::{PpcError, PpcNode};

/// The PowerPC node's name on the bus (its terminal and control socket find it by it).
pub const NAME: &str = "ppc";

/// The PowerPC node running MoniCAN at the bus's bit rate, as `bus serve --ppc` and the lab
/// put it on the bus.
pub fn node(bitrate: u32) -> Result<PpcNode, PpcError> {
    PpcNode::new(buslab_monican::Config {
        bitrate,
        ..buslab_monican::Config::default()
    })
}
