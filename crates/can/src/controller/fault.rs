//! Fault confinement: the error counters and the state they imply (facts §5).

use super::{ErrorState, Event};

/// Error-warning limit: either counter at or above it.
pub(super) const WARNING_LIMIT: u16 = 96;
/// Error-passive at or above this.
pub(super) const PASSIVE_LIMIT: u16 = 128;
/// Bus-off above this TEC.
pub(super) const BUS_OFF_LIMIT: u16 = 255;
/// REC saturates here (an 8-bit counter, as in the SJA1000's RXERR).
const REC_MAX: u16 = 255;
/// Where a successful reception puts a REC above 127 (the protocol allows 119..=127).
const REC_AFTER_PASSIVE: u16 = 127;

#[derive(Debug, Clone, Copy)]
pub(super) struct Counters {
    pub(super) tec: u16,
    pub(super) rec: u16,
    state: ErrorState,
    warning: bool,
}

impl Counters {
    pub(super) const fn new() -> Self {
        Self {
            tec: 0,
            rec: 0,
            state: ErrorState::Active,
            warning: false,
        }
    }

    pub(super) const fn state(&self) -> ErrorState {
        self.state
    }

    pub(super) fn add_tec(&mut self, n: u16) {
        self.tec = self.tec.saturating_add(n);
    }

    pub(super) fn add_rec(&mut self, n: u16) {
        self.rec = (self.rec + n).min(REC_MAX);
    }

    pub(super) fn transmit_ok(&mut self) {
        self.tec = self.tec.saturating_sub(1);
    }

    pub(super) fn receive_ok(&mut self) {
        if self.rec > PASSIVE_LIMIT - 1 {
            self.rec = REC_AFTER_PASSIVE;
        } else {
            self.rec = self.rec.saturating_sub(1);
        }
    }

    /// Back to error-active with both counters 0 (after bus-off recovery).
    pub(super) fn reset(&mut self) {
        self.tec = 0;
        self.rec = 0;
    }

    /// Recompute state and warning from the counters; report what changed.
    pub(super) fn update(&mut self, mut emit: impl FnMut(Event)) {
        let (tec, rec) = (self.tec, self.rec);
        let state = if tec > BUS_OFF_LIMIT {
            ErrorState::BusOff
        } else if tec >= PASSIVE_LIMIT || rec >= PASSIVE_LIMIT {
            ErrorState::Passive
        } else {
            ErrorState::Active
        };
        let warning = tec >= WARNING_LIMIT || rec >= WARNING_LIMIT;
        if warning != self.warning {
            self.warning = warning;
            emit(Event::Warning {
                above: warning,
                tec,
                rec,
            });
        }
        if state != self.state {
            emit(Event::StateChanged {
                from: self.state,
                to: state,
                tec,
                rec,
            });
            self.state = state;
        }
    }
}
