//! A controller's error state as an SJA1000 reports it: Linux's four ([`ControllerState`]),
//! the warning level a state of its own. Fault confinement's three are
//! [`ErrorState`], the one error-state type; this is the
//! chip's report of it (SR.ES and SR.BS, the counters), turned into it by
//! [`ControllerState::error_state`].

use std::fmt;

use buslab_can::controller::ErrorState;

/// Error state as the SJA1000 shows it (Linux's four states).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ControllerState {
    /// Both counters below the warning limit.
    Active,
    /// A counter at or above the warning limit (SR.ES), still error-active.
    Warning,
    /// A counter above 127 (PeliCAN only: BasicCAN cannot read its counters).
    Passive,
    /// SR.BS: the controller left the bus.
    BusOff,
}

impl ControllerState {
    /// The fault confinement state (warning counts as active), python-can's `ErrorState`.
    pub fn error_state(self) -> ErrorState {
        match self {
            ControllerState::Active | ControllerState::Warning => ErrorState::Active,
            ControllerState::Passive => ErrorState::Passive,
            ControllerState::BusOff => ErrorState::BusOff,
        }
    }
}

impl fmt::Display for ControllerState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ControllerState::Active => "error-active",
            ControllerState::Warning => "error warning",
            ControllerState::Passive => "error-passive",
            ControllerState::BusOff => "bus-off",
        })
    }
}
