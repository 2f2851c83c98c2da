//! A CAN bus interface in the spirit of python-can's `BusABC`: send frames, receive
//! timestamped messages (and, when asked for, error frames), filter by ID and mask, ask for the
//! error state.

/// The bus vocabulary and the [`CanBus`] trait live in `buslab-bus`; these paths stay for the
/// users of this crate.
pub use buslab_bus::bus::{
    BusError, BusEvent, ErrorMessage, ErrorState, Filter, Human, Message, matches_any,
};
pub use buslab_bus::interface::CanBus;
