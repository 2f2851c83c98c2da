//! A controller's error state: python-can's three ([`BusState`]) and Linux's four
//! ([`ControllerState`]).

use std::fmt;

/// The error state of a controller, as python-can names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BusState {
    /// Error-active (including the warning level).
    Active,
    /// Error-passive: a counter is above 127.
    Passive,
    /// Bus-off: the controller takes no part in bus traffic.
    BusOff,
}

impl fmt::Display for BusState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            BusState::Active => "error-active",
            BusState::Passive => "error-passive",
            BusState::BusOff => "bus-off",
        })
    }
}

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
    /// The python-can view (warning counts as active).
    pub fn bus_state(self) -> BusState {
        match self {
            ControllerState::Active | ControllerState::Warning => BusState::Active,
            ControllerState::Passive => BusState::Passive,
            ControllerState::BusOff => BusState::BusOff,
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
