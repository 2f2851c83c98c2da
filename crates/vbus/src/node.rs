//! A client's node: an SJA1000 with the CPU that services it through the host library's
//! driver ([`buslab_canbus::node::Sja1000Node`], which scenario files use too).

pub use buslab_canbus::node::{
    CRYSTAL_HZ, Delivery, NodeNotice, RESTART_AFTER, Sja1000Node, TOLERANCE_PERMILLE, TX_QUEUE,
    TimedErrorFrame, node_config,
};

/// Every TCP client's node.
pub type ClientNode = Sja1000Node;
