//! Message (`FE`) and alert (`FD`) numbers, defined once.
//!
//! The seed names them (`msg_time_out`, ...) but their values were in a header file (`PRO196.h`)
//! that is lost; buslab's numbering is documented in `docs/cpu196.md`.

use core::fmt;

/// A message number carried by `FE`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct MsgCode(pub u8);

impl MsgCode {
    pub const NO_ERROR: Self = Self(0x00);
    /// No complete command (command and complement, then its parameters) arrived in time.
    pub const TIME_OUT: Self = Self(0x01);
    /// A command byte was not followed by its one's complement.
    pub const RECEPTION_ERROR: Self = Self(0x02);
    pub const COMPLETED: Self = Self(0x03);
    pub const INVALID_PARAMETER_VALUE: Self = Self(0x04);
    pub const NOT_BLANK_ERROR: Self = Self(0x05);
    /// A kernel command refused in the lower loop, or one the board never accepts from a PC.
    pub const INVALID_COMMAND: Self = Self(0x06);
    /// A command this kernel model does not implement (`F7` CPUFORMAT).
    pub const NOT_SUPPORTED: Self = Self(0x07);
    /// The acquisition configuration cannot run (sampling faster than the line can carry).
    pub const AD_CONFIG_ERROR: Self = Self(0x08);
    /// The PC could not open, read or write a file the board asked for.
    pub const FILE_ERROR: Self = Self(0x09);
    /// A checksum (`FA`) did not match its data.
    pub const CHECKSUM_ERROR: Self = Self(0x0A);

    const NAMES: [(MsgCode, &'static str); 11] = [
        (Self::NO_ERROR, "msg_no_error"),
        (Self::TIME_OUT, "msg_time_out"),
        (Self::RECEPTION_ERROR, "msg_reception_error"),
        (Self::COMPLETED, "msg_completed"),
        (Self::INVALID_PARAMETER_VALUE, "msg_invalid_parameter_value"),
        (Self::NOT_BLANK_ERROR, "msg_not_blank_error"),
        (Self::INVALID_COMMAND, "msg_invalid_command"),
        (Self::NOT_SUPPORTED, "msg_not_supported"),
        (Self::AD_CONFIG_ERROR, "msg_ad_config_error"),
        (Self::FILE_ERROR, "msg_file_error"),
        (Self::CHECKSUM_ERROR, "msg_checksum_error"),
    ];

    /// The seed-style name, e.g. `msg_not_blank_error`; `None` for numbers buslab does not define.
    pub fn name(self) -> Option<&'static str> {
        Self::NAMES
            .iter()
            .find(|(c, _)| *c == self)
            .map(|(_, n)| *n)
    }

    /// Every defined message, for documentation and tests.
    pub fn all() -> impl Iterator<Item = (MsgCode, &'static str)> {
        Self::NAMES.into_iter()
    }
}

impl fmt::Display for MsgCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.name() {
            Some(name) => write!(f, "{name} ({:02X}h)", self.0),
            None => write!(f, "message {:02X}h", self.0),
        }
    }
}

/// An alert number carried by `FD`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Alert(pub u8);

impl Alert {
    /// Battery (PIC channel 0) fell below the first threshold.
    pub const BATTERY_DISCHARGED: Self = Self(0x10);
    /// Battery between the first and second thresholds.
    pub const BATTERY_LOW: Self = Self(0x11);
    /// Battery between the second and third thresholds.
    pub const BATTERY_OK: Self = Self(0x12);
    /// Above the third threshold: the board runs from mains.
    pub const BATTERY_MAINS: Self = Self(0x13);
    /// The PC's watchdog stopped arriving; the lower loop was stopped for safety.
    pub const LINK_LOST: Self = Self(0x20);
    /// The A/D FIFO overflowed: samples were lost.
    pub const AD_OVERRUN: Self = Self(0x21);
    /// The PIC reported an error event.
    pub const PIC_ERROR: Self = Self(0x22);
    /// A user program was stopped by the kernel: it ran past its share of CPU time (fuel),
    /// trapped, or misused the kernel API (a THREAD line says which).
    pub const USER_PROGRAM_STOPPED: Self = Self(0x23);
    /// A user program raised an alarm (e.g. the shipped threshold alarm).
    pub const USER_ALARM: Self = Self(0x30);

    const NAMES: [(Alert, &'static str); 9] = [
        (Self::BATTERY_DISCHARGED, "alert_battery_discharged"),
        (Self::BATTERY_LOW, "alert_battery_low"),
        (Self::BATTERY_OK, "alert_battery_ok"),
        (Self::BATTERY_MAINS, "alert_battery_mains"),
        (Self::LINK_LOST, "alert_link_lost"),
        (Self::AD_OVERRUN, "alert_ad_overrun"),
        (Self::PIC_ERROR, "alert_pic_error"),
        (Self::USER_PROGRAM_STOPPED, "alert_user_program_stopped"),
        (Self::USER_ALARM, "alert_user_alarm"),
    ];

    pub fn name(self) -> Option<&'static str> {
        Self::NAMES
            .iter()
            .find(|(c, _)| *c == self)
            .map(|(_, n)| *n)
    }

    pub fn all() -> impl Iterator<Item = (Alert, &'static str)> {
        Self::NAMES.into_iter()
    }

    /// The alert for a battery state 0 (discharged) ..= 3 (mains).
    pub fn battery(state: u8) -> Self {
        Self(Self::BATTERY_DISCHARGED.0 + state.min(3))
    }
}

impl fmt::Display for Alert {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.name() {
            Some(name) => write!(f, "{name} ({:02X}h)", self.0),
            None => write!(f, "alert {:02X}h", self.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_unique_and_named() {
        let msgs: Vec<_> = MsgCode::all().map(|(c, _)| c.0).collect();
        let mut dedup = msgs.clone();
        dedup.sort();
        dedup.dedup();
        assert_eq!(msgs.len(), dedup.len());
        assert_eq!(MsgCode(5).to_string(), "msg_not_blank_error (05h)");
        assert_eq!(MsgCode(0x77).to_string(), "message 77h");
        assert_eq!(Alert::battery(1), Alert::BATTERY_LOW);
        assert_eq!(Alert(0x20).name(), Some("alert_link_lost"));
    }
}
