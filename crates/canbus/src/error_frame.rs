//! SocketCAN error frames: the codec lives in `buslab-bus` (re-exported here, so
//! `buslab_canbus::error_frame::…` paths stay); this module turns the SJA1000 driver's
//! events and captures into them, as Linux's SJA1000 driver does.

pub use buslab_bus::error_frame::*;

use crate::decode::ErrorRegisters;
use crate::driver::DriverEvent;

/// The error frame Linux's SJA1000 driver would send for a driver event, if any (frames
/// and transmit results are not errors). `registers` gives the counters.
pub fn from_driver_event(
    event: &DriverEvent,
    registers: Option<ErrorRegisters>,
) -> Option<ErrorFrame> {
    let counters = registers.map(|r| ErrorCounters {
        tx: r.txerr,
        rx: r.rxerr,
    });
    Some(match event {
        DriverEvent::BusError(ecc) => ErrorFrame::sja1000_bus_error(*ecc, counters),
        DriverEvent::ArbitrationLost(alc) => ErrorFrame::sja1000_arbitration_lost(*alc, counters),
        DriverEvent::StateChanged { to, .. } => {
            ErrorFrame::state_change(*to, counters.unwrap_or_default())
        }
        DriverEvent::DataOverrun => ErrorFrame::new(
            vec![CanError::Controller(ControllerProblems(
                ControllerProblems::RX_OVERFLOW,
            ))],
            counters,
        ),
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::{Alc, Ecc};
    use crate::driver::ControllerState;

    #[test]
    fn sja1000_events_map_as_linux_does() {
        let regs = ErrorRegisters {
            alc: None,
            ecc: None,
            rxerr: 0,
            txerr: 8,
        };
        // 0x0A: bit error, during transmission, data field.
        let e = from_driver_event(&DriverEvent::BusError(Ecc(0x0A)), Some(regs)).unwrap();
        assert_eq!(e.encode(), (0x288, [0, 0, 0x81, 0x0A, 0, 0, 8, 0]));
        // 0xA2: stuff error during reception in ID.28..21.
        let e = ErrorFrame::sja1000_bus_error(Ecc(0xA2), None);
        assert_eq!(e.encode(), (0x088, [0, 0, 0x04, 0x02, 0, 0, 0, 0]));
        let e = ErrorFrame::sja1000_arbitration_lost(Alc(0x21), None);
        assert_eq!(e.encode(), (0x002, [1, 0, 0, 0, 0, 0, 0, 0]));
        let c = ErrorCounters { tx: 128, rx: 5 };
        assert_eq!(
            ErrorFrame::state_change(ControllerState::Passive, c).encode(),
            (0x204, [0, 0x20, 0, 0, 0, 0, 128, 5])
        );
        let even = ErrorCounters { tx: 96, rx: 96 };
        assert_eq!(
            ErrorFrame::state_change(ControllerState::Warning, even)
                .encode()
                .1[1],
            0x0C
        );
        assert_eq!(
            ErrorFrame::state_change(ControllerState::BusOff, c).class(),
            0x240
        );
        assert_eq!(
            ErrorFrame::state_change(ControllerState::Active, ErrorCounters::default()).to_string(),
            "controller-problem{back-to-error-active},error-counter-tx-rx{{0}{0}}"
        );
        assert_eq!(ErrorFrame::restarted().class(), 0x100);
        assert!(from_driver_event(&DriverEvent::WakeUp, None).is_none());
    }
}
