//! The 403's interrupt controller: EXISR latches the interrupt inputs (the critical pin, the
//! serial port's receiver and transmitter, INT0..INT4), EXIER enables them; MSR[CE] gates the
//! critical pin (and the watchdog), MSR[EE] the others (and the PIT and FIT). The lines are
//! level-sensitive: a status bit cleared while its line is still high is set again at once.

use crate::Exception;
use crate::core::{Irq, Ppc403};
use crate::exceptions::msr;
use crate::timers::{tcr, tsr};

/// EXISR's and EXIER's bits.
pub mod exisr {
    /// The critical interrupt pin.
    pub const CIS: u32 = 0x8000_0000;
    /// Serial port receiver.
    pub const SRIS: u32 = 0x0800_0000;
    /// Serial port transmitter.
    pub const STIS: u32 = 0x0400_0000;
    /// External interrupt INT0 (INT1..INT4 are the next bits down, INT4 = bit 31).
    pub const E0IS: u32 = 0x0000_0010;
}

#[derive(Clone, Debug, Default)]
pub(crate) struct Interrupts {
    /// EXISR.
    pub status: u32,
    /// EXIER.
    pub enable: u32,
    /// The lines that are high, as EXISR bits.
    pub levels: u32,
}

impl Interrupts {
    fn bit(irq: Irq) -> u32 {
        match irq {
            Irq::Critical => exisr::CIS,
            Irq::SerialReceive => exisr::SRIS,
            Irq::SerialTransmit => exisr::STIS,
            Irq::External(n @ 0..=4) => exisr::E0IS >> n,
            Irq::External(_) => 0,
        }
    }

    pub fn set_line(&mut self, irq: Irq, level: bool) {
        let bit = Interrupts::bit(irq);
        if level {
            self.levels |= bit;
            self.status |= bit;
        } else {
            self.levels &= !bit;
        }
    }

    /// A write to EXISR: 1 bits clear, lines still high set their bits again.
    pub fn write_status(&mut self, value: u32) {
        self.status = (self.status & !value) | self.levels;
    }
}

impl Ppc403 {
    /// The interrupt to take at this instruction boundary, the most urgent first: the
    /// critical pin, the watchdog, the external inputs, the PIT, the FIT.
    pub(crate) fn deliverable_interrupt(&self) -> Option<Exception> {
        let msr = self.regs.msr;
        if msr & (msr::CE | msr::EE) == 0 {
            return None;
        }
        let pending = self.irq.status & self.irq.enable;
        let (tcr, tsr) = (self.timers.tcr, self.timers.tsr);
        if msr & msr::CE != 0 {
            if pending & exisr::CIS != 0 {
                return Some(Exception::Critical);
            }
            if tsr & tsr::WIS != 0 && tcr & tcr::WIE != 0 {
                return Some(Exception::Watchdog);
            }
        }
        if msr & msr::EE != 0 {
            if pending & !exisr::CIS != 0 {
                return Some(Exception::External);
            }
            if tsr & tsr::PIS != 0 && tcr & tcr::PIE != 0 {
                return Some(Exception::Pit);
            }
            if tsr & tsr::FIS != 0 && tcr & tcr::FIE != 0 {
                return Some(Exception::Fit);
            }
        }
        None
    }
}
