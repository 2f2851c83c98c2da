//! The seed's PowerPC node (seed 002 §4): a PPC403 board with an SJA1000, running MoniCAN on
//! a VT100 terminal at 19200 baud, and the programs its CAN loader loads on the PPC403 core
//! ([`buslab_ppc403`]) with the board around it ([`board`], [`spu`], [`program`]).
//!
//! [`PpcNode`] is a [`BusNode`](buslab_can::node::BusNode): it sits on the one bus engine like
//! any node. Its SJA1000 ([`buslab_sja1000::Sja1000`]) is driven only through its registers:
//! by the resident firmware — the SJA1000 driver the host library runs too
//! ([`buslab_sja1000_driver::Sja1000Driver`], PeliCAN as the seed's `sja_init_pelican`), with
//! [`buslab_monican::MoniCan`] and the CAN loader as its program — or, once the loader has
//! jumped to a loaded program, by that program through the card's ports. The serial port is
//! sans-IO too: [`PpcNode::key`] takes a byte from the terminal, [`PpcNode::take_screen`]
//! gives the bytes for it; whoever serves the port paces them (19200 baud, 8N1).
#![forbid(unsafe_code)]

pub mod board;
pub mod clocks;
pub mod node;
pub mod program;
pub mod sampling;
pub mod spu;

pub use node::{
    Activity, CRYSTAL_HZ, GIVE_UP, IMAGE_HEADER, LoadRecord, MAX_KEYS, PpcError, PpcNode,
    chip_config, slio_timing,
};
pub use program::{Ending, registers_line};

/// The PowerPC node's serial line: 19200 baud (seed §4.3.3.1), 8 data bits, no parity, 1 stop
/// bit.
pub const BAUD: u32 = 19_200;
