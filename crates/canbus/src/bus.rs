//! A CAN bus interface in the spirit of python-can's `BusABC`: send frames, receive
//! timestamped messages (and, when asked for, error frames), filter by ID and mask, ask for the
//! error state.

pub use buslab_bus::Timestamp;
/// The bus vocabulary and the [`CanBus`] trait live in `buslab-bus`; these paths stay for the
/// users of this crate.
pub use buslab_bus::bus::{
    BusError, Direction, ErrorState, Filter, Human, Message, Record, matches_any, wall_clock,
};
pub use buslab_bus::interface::CanBus;
