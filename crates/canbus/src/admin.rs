//! Administration of a bus that has more to tell than frames: buslab's virtual bus lists its
//! nodes and reports each one's error state, counters and registers ([`BusAdmin`]).
//!
//! The values and the trait are bus vocabulary (`buslab-bus`); these paths stay for the users
//! of this crate.

pub use buslab_bus::admin::*;
pub use buslab_bus::interface::BusAdmin;
