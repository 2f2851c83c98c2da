//! The SJA1000 driver: BasicCAN and PeliCAN behind one interface, talking to the chip only
//! through [`RegisterAccess`] reads and writes (the recipes of Linux's `sja1000.c` and the
//! seed's PowerPC init).
//!
//! The driver is polled: [`Sja1000Driver::poll`] reads IR and SR like an interrupt handler and
//! returns what happened. Completion of a transmission and received frames are taken from SR
//! (TBS/TCS, RBS), so they are reported whatever the interrupt enables; ALC and ECC captures
//! need the arbitration-lost and bus-error interrupts enabled (they are by default).

use std::fmt;

use buslab_can::Frame;
use buslab_sja1000::regs::*;
use buslab_sja1000::{CanMode, layout};

use crate::config::{ConfigError, Sja1000Config};
use crate::decode::{Alc, Ecc, ErrorRegisters, RegisterDump, Status};
use crate::regs::RegisterAccess;

/// How many times a wait loop writes and reads back a register before giving up.
pub const DEFAULT_MAX_TRIES: u32 = 100;

/// At most this many messages are drained per poll (the FIFO holds at most 21).
const MAX_RX_PER_POLL: usize = 64;

/// How a frame is sent (CMR bits).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum TxMode {
    /// TR: retried until it succeeds (or the controller goes bus-off).
    #[default]
    Normal,
    /// TR + AT: one attempt only (no retry after an error or lost arbitration).
    SingleShot,
    /// SRR: sent and received by this node too (PeliCAN only).
    SelfReception,
    /// SRR + AT (PeliCAN only).
    SingleShotSelfReception,
}

impl TxMode {
    fn command(self) -> u8 {
        match self {
            TxMode::Normal => CMR_TR,
            TxMode::SingleShot => CMR_TR | CMR_AT,
            TxMode::SelfReception => CMR_SRR,
            TxMode::SingleShotSelfReception => CMR_SRR | CMR_AT,
        }
    }

    fn self_reception(self) -> bool {
        matches!(
            self,
            TxMode::SelfReception | TxMode::SingleShotSelfReception
        )
    }
}

pub use buslab_bus::state::ControllerState;

/// Why a requested transmission ended without success.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TxFailure {
    /// [`Sja1000Driver::abort`] stopped it.
    Aborted,
    /// A single-shot transmission had its one attempt and failed.
    SingleShot,
    /// The controller went bus-off (which aborts the transmission).
    BusOff,
}

impl fmt::Display for TxFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            TxFailure::Aborted => "aborted",
            TxFailure::SingleShot => "single-shot attempt failed",
            TxFailure::BusOff => "controller went bus-off",
        })
    }
}

/// What [`Sja1000Driver::poll`] found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DriverEvent {
    /// A frame from the RX FIFO (already released with RRB).
    Received(Frame),
    /// The frame in the TX buffer was sent (SR.TCS).
    TxDone(Frame),
    /// The frame in the TX buffer was released without success.
    TxFailed { frame: Frame, reason: TxFailure },
    /// Frames were lost because the RX FIFO was full (SR.DOS; cleared with CDO).
    DataOverrun,
    /// The error state changed.
    StateChanged {
        from: ControllerState,
        to: ControllerState,
    },
    /// A bus error was captured in ECC (PeliCAN, bus-error interrupt enabled).
    BusError(Ecc),
    /// Arbitration was lost; ALC says where (PeliCAN, arbitration-lost interrupt enabled).
    ArbitrationLost(Alc),
    /// The chip woke up from sleep (or refused to sleep).
    WakeUp,
}

impl fmt::Display for DriverEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DriverEvent::Received(frame) => write!(f, "received {frame}"),
            DriverEvent::TxDone(frame) => write!(f, "sent {frame}"),
            DriverEvent::TxFailed { frame, reason } => write!(f, "not sent {frame}: {reason}"),
            DriverEvent::DataOverrun => f.write_str("data overrun: received frames were lost"),
            DriverEvent::StateChanged { from, to } => write!(f, "state {from} -> {to}"),
            DriverEvent::BusError(ecc) => write!(f, "bus error: {ecc}"),
            DriverEvent::ArbitrationLost(alc) => write!(f, "{alc}"),
            DriverEvent::WakeUp => f.write_str("wake-up"),
        }
    }
}

/// Why a driver operation failed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DriverError {
    #[error("invalid configuration: {0}")]
    Config(#[from] ConfigError),
    #[error("no SJA1000 answers: {register} reads 0xFF (nothing drives the data bus)")]
    NoChip { register: &'static str },
    #[error(
        "the chip did not {step}: {register} reads 0x{value:02X} after {tries} tries (wrote 0x{wrote:02X})"
    )]
    NoAnswer {
        step: &'static str,
        register: &'static str,
        wrote: u8,
        value: u8,
        tries: u32,
    },
    #[error("{register} reads 0x{read:02X} after writing 0x{wrote:02X} in reset mode")]
    Readback {
        register: &'static str,
        wrote: u8,
        read: u8,
    },
    #[error("the driver is not initialised: call init() first")]
    NotInitialized,
    #[error("the controller is in reset mode; init() or restart() it first")]
    ResetMode,
    #[error("the transmit buffer is busy (SR.TBS = 0): the previous frame is still pending")]
    TxBusy,
    #[error("frame {frame} has an extended ID; BasicCAN mode sends 11-bit IDs only")]
    ExtendedIdInBasicCan { frame: Frame },
    #[error("self-reception exists only in PeliCAN mode")]
    SelfReceptionInBasicCan,
    #[error("a listen-only controller cannot transmit")]
    ListenOnly,
    #[error("the controller is bus-off; restart() it first")]
    BusOff,
}

/// The transmission the driver handed to the chip.
#[derive(Clone, Copy, Debug)]
struct InFlight {
    frame: Frame,
    mode: TxMode,
    aborting: bool,
}

impl InFlight {
    /// How the transmission ended, once the chip released the TX buffer (or went bus-off).
    fn outcome(self, status: Status) -> DriverEvent {
        let reason = if status.bus_off() {
            TxFailure::BusOff
        } else if status.transmission_complete() {
            return DriverEvent::TxDone(self.frame);
        } else if self.aborting {
            TxFailure::Aborted
        } else if matches!(
            self.mode,
            TxMode::SingleShot | TxMode::SingleShotSelfReception
        ) {
            TxFailure::SingleShot
        } else {
            // A retried transmission only ends without TCS when aborted, e.g. by reset mode
            // entered behind the driver's back.
            TxFailure::Aborted
        };
        DriverEvent::TxFailed {
            frame: self.frame,
            reason,
        }
    }
}

/// An SJA1000 driven through its registers.
#[derive(Debug)]
pub struct Sja1000Driver<R: RegisterAccess> {
    regs: R,
    config: Option<Sja1000Config>,
    state: ControllerState,
    tx: Option<InFlight>,
    last_alc: Option<Alc>,
    last_ecc: Option<Ecc>,
    max_tries: u32,
}

impl<R: RegisterAccess> Sja1000Driver<R> {
    /// A driver for the chip behind `regs`; nothing is written until [`init`](Self::init).
    pub fn new(regs: R) -> Self {
        Self {
            regs,
            config: None,
            state: ControllerState::Active,
            tx: None,
            last_alc: None,
            last_ecc: None,
            max_tries: DEFAULT_MAX_TRIES,
        }
    }

    /// How many times each wait loop polls before reporting that the chip does not answer.
    pub fn with_max_tries(mut self, tries: u32) -> Self {
        self.max_tries = tries.max(1);
        self
    }

    /// The register access (e.g. to step a model).
    pub fn registers(&mut self) -> &mut R {
        &mut self.regs
    }

    /// The register access, read-only (e.g. to see a model's bus level).
    pub fn chip(&self) -> &R {
        &self.regs
    }

    pub fn into_registers(self) -> R {
        self.regs
    }

    /// The configuration of the last successful [`init`](Self::init).
    pub fn config(&self) -> Option<&Sja1000Config> {
        self.config.as_ref()
    }

    /// The mode of the last successful init (PeliCAN before any).
    pub fn mode(&self) -> CanMode {
        self.config.as_ref().map_or(CanMode::Peli, |c| c.mode)
    }

    /// The error state seen at the last poll.
    pub fn state(&self) -> ControllerState {
        self.state
    }

    /// Whether a transmission is in the TX buffer.
    pub fn tx_pending(&self) -> bool {
        self.tx.is_some()
    }

    /// Initialises the chip in the seed's order: reset → PeliCAN/BasicCAN (CDR) → acceptance
    /// code and mask → bit timing → interrupt enables → output control → operating mode.
    /// Every wait loop writes, reads back and gives up after the retry count.
    pub fn init(&mut self, config: &Sja1000Config) -> Result<(), DriverError> {
        config.validate()?;
        let timing = config.bit_timing()?;
        self.config = None;
        self.tx = None;
        self.last_alc = None;
        self.last_ecc = None;
        if self.regs.read(0) == 0xFF {
            return Err(DriverError::NoChip {
                register: "MOD/CR (address 0)",
            });
        }
        self.enter_reset()?;
        let cdr = config.cdr();
        self.wait_until("select the CAN mode", "CDR", 31, cdr, |v| {
            v & CDR_PELICAN == cdr & CDR_PELICAN
        })?;
        let (code, mask) = config.filter.registers();
        let (btr0, btr1) = timing.registers();
        match config.mode {
            CanMode::Peli => {
                for k in 0..4 {
                    self.regs.write(peli::ACR0 as u8 + k, code[k as usize]);
                    self.regs.write(peli::AMR0 as u8 + k, mask[k as usize]);
                }
                self.write_checked("BTR0", peli::BTR0, btr0)?;
                self.write_checked("BTR1", peli::BTR1, btr1)?;
                self.regs.write(peli::IER as u8, config.interrupts.ier());
                self.write_checked("OCR", peli::OCR, config.output_control)?;
                self.regs
                    .write(peli::EWLR as u8, config.error_warning_limit);
                self.regs.write(peli::TXERR as u8, 0);
                self.regs.write(peli::RXERR as u8, 0);
                self.regs.read(peli::ECC as u8);
                self.regs.read(peli::ALC as u8);
                self.regs.read(peli::IR as u8);
                let mode = config.mod_bits();
                self.wait_until("leave reset mode", "MOD", 0, mode, |v| v & MOD_RM == 0)?;
            }
            CanMode::Basic => {
                self.regs.write(basic::ACR as u8, code[0]);
                self.regs.write(basic::AMR as u8, mask[0]);
                self.write_checked("BTR0", basic::BTR0, btr0)?;
                self.write_checked("BTR1", basic::BTR1, btr1)?;
                self.write_checked("OCR", basic::OCR, config.output_control)?;
                self.regs.read(basic::IR as u8);
                let cr = config.interrupts.cr_bits();
                self.wait_until("leave reset mode", "CR", 0, cr, |v| v & MOD_RM == 0)?;
            }
        }
        self.config = Some(config.clone());
        self.state = ControllerState::Active;
        Ok(())
    }

    fn enter_reset(&mut self) -> Result<(), DriverError> {
        self.wait_until("enter reset mode", "MOD", 0, MOD_RM, |v| v & MOD_RM != 0)
    }

    /// Writes `value` to `addr` and reads it back until `done` holds.
    fn wait_until(
        &mut self,
        step: &'static str,
        register: &'static str,
        addr: u8,
        value: u8,
        done: impl Fn(u8) -> bool,
    ) -> Result<(), DriverError> {
        let mut read = 0;
        for _ in 0..self.max_tries {
            self.regs.write(addr, value);
            read = self.regs.read(addr);
            if done(read) {
                return Ok(());
            }
        }
        if read == 0xFF {
            return Err(DriverError::NoChip { register });
        }
        Err(DriverError::NoAnswer {
            step,
            register,
            wrote: value,
            value: read,
            tries: self.max_tries,
        })
    }

    /// A reset-mode register write that must read back.
    fn write_checked(
        &mut self,
        register: &'static str,
        addr: usize,
        value: u8,
    ) -> Result<(), DriverError> {
        self.regs.write(addr as u8, value);
        let read = self.regs.read(addr as u8);
        if read != value {
            return Err(DriverError::Readback {
                register,
                wrote: value,
                read,
            });
        }
        Ok(())
    }

    /// Sends `frame` with automatic retransmission.
    pub fn send(&mut self, frame: &Frame) -> Result<(), DriverError> {
        self.send_with(frame, TxMode::Normal)
    }

    /// Loads the TX buffer and requests the transmission. The outcome arrives from
    /// [`poll`](Self::poll) as [`DriverEvent::TxDone`] or [`DriverEvent::TxFailed`].
    pub fn send_with(&mut self, frame: &Frame, mode: TxMode) -> Result<(), DriverError> {
        let config = self.config.as_ref().ok_or(DriverError::NotInitialized)?;
        let can_mode = config.mode;
        if config.listen_only {
            return Err(DriverError::ListenOnly);
        }
        if can_mode == CanMode::Basic {
            if frame.is_extended() {
                return Err(DriverError::ExtendedIdInBasicCan { frame: *frame });
            }
            if mode.self_reception() {
                return Err(DriverError::SelfReceptionInBasicCan);
            }
        }
        let status = self.status();
        if status.bus_off() {
            return Err(DriverError::BusOff);
        }
        if self.regs.read(0) & MOD_RM != 0 {
            return Err(DriverError::ResetMode);
        }
        if !status.transmit_buffer_released() || self.tx.is_some() {
            return Err(DriverError::TxBusy);
        }
        let mut buf = [0u8; 13];
        let len = layout::encode(can_mode, frame, &mut buf);
        let base = match can_mode {
            CanMode::Peli => peli::WINDOW,
            CanMode::Basic => basic::TX,
        } as u8;
        self.regs.write_block(base, &buf[..len]);
        self.regs.write(peli::CMR as u8, mode.command());
        self.tx = Some(InFlight {
            frame: *frame,
            mode,
            aborting: false,
        });
        Ok(())
    }

    /// Requests abortion of the pending transmission (CMR.AT). A transmission already on the
    /// bus still completes; the outcome arrives from [`poll`](Self::poll).
    pub fn abort(&mut self) {
        if let Some(tx) = &mut self.tx {
            tx.aborting = true;
            self.regs.write(peli::CMR as u8, CMR_AT);
        }
    }

    /// Reads IR and SR like the Linux interrupt handler and returns what happened: received
    /// frames (drained with RRB), the end of the pending transmission, data overrun (cleared
    /// with CDO), error-state changes, bus errors (ECC) and lost arbitration (ALC).
    pub fn poll(&mut self) -> Vec<DriverEvent> {
        let mut events = Vec::new();
        self.poll_into(&mut events);
        events
    }

    /// [`poll`](Self::poll), appending to `events` (a caller polling often keeps one buffer).
    pub fn poll_into(&mut self, events: &mut Vec<DriverEvent>) {
        let Some(mode) = self.config.as_ref().map(|c| c.mode) else {
            return;
        };
        let ir = self.regs.read(peli::IR as u8);
        if mode == CanMode::Peli {
            if ir & IR_ALI != 0 {
                let alc = Alc(self.regs.read(peli::ALC as u8) & 0x1F);
                self.last_alc = Some(alc);
                events.push(DriverEvent::ArbitrationLost(alc));
            }
            if ir & IR_BEI != 0 {
                let ecc = Ecc(self.regs.read(peli::ECC as u8));
                self.last_ecc = Some(ecc);
                events.push(DriverEvent::BusError(ecc));
            }
        }
        if ir & IR_WUI != 0 {
            events.push(DriverEvent::WakeUp);
        }
        let status = self.status();
        if status.data_overrun() {
            events.push(DriverEvent::DataOverrun);
        }
        self.drain_rx(mode, events);
        if status.data_overrun() {
            self.regs.write(peli::CMR as u8, CMR_CDO);
        }
        let state = self.read_state(mode, status);
        if state != self.state {
            events.push(DriverEvent::StateChanged {
                from: self.state,
                to: state,
            });
            self.state = state;
        }
        if let Some(tx) = self.tx
            && (status.transmit_buffer_released() || status.bus_off())
        {
            self.tx = None;
            events.push(tx.outcome(status));
        }
    }

    fn drain_rx(&mut self, mode: CanMode, events: &mut Vec<DriverEvent>) {
        for _ in 0..MAX_RX_PER_POLL {
            if !self.status().receive_buffer_full() {
                break;
            }
            let base = match mode {
                CanMode::Peli => peli::WINDOW,
                CanMode::Basic => basic::RX,
            } as u8;
            let frame = self.regs.read_received_frame(mode, base);
            self.regs.write(peli::CMR as u8, CMR_RRB);
            events.push(DriverEvent::Received(frame));
        }
    }

    fn read_state(&mut self, mode: CanMode, status: Status) -> ControllerState {
        if status.bus_off() {
            return ControllerState::BusOff;
        }
        if mode == CanMode::Peli {
            let rx = self.regs.read(peli::RXERR as u8);
            let tx = self.regs.read(peli::TXERR as u8);
            if rx > 127 || tx > 127 {
                return ControllerState::Passive;
            }
        }
        if status.error_status() {
            ControllerState::Warning
        } else {
            ControllerState::Active
        }
    }

    /// Back on the bus after bus-off, Linux's `CAN_MODE_START` recipe: interrupts off, reset
    /// mode, (re-init if the chip lost its mode), TXERR := RXERR := 0 (which ends bus-off at
    /// once in PeliCAN), clear ECC/IR, operating mode, interrupts on. BasicCAN cannot write
    /// its counters: leaving reset mode starts the chip's 128 × 11 recessive-bit recovery.
    pub fn restart(&mut self) -> Result<(), DriverError> {
        let config = self.config.clone().ok_or(DriverError::NotInitialized)?;
        self.tx = None;
        if config.mode == CanMode::Peli {
            self.regs.write(peli::IER as u8, 0);
        }
        self.enter_reset()?;
        let cdr = self.regs.read(31);
        if cdr & CDR_PELICAN != config.cdr() & CDR_PELICAN {
            return self.init(&config);
        }
        match config.mode {
            CanMode::Peli => {
                self.regs.write(peli::TXERR as u8, 0);
                self.regs.write(peli::RXERR as u8, 0);
                self.regs.read(peli::ECC as u8);
                self.regs.read(peli::IR as u8);
                let mode = config.mod_bits();
                self.wait_until("leave reset mode", "MOD", 0, mode, |v| v & MOD_RM == 0)?;
                self.regs.write(peli::IER as u8, config.interrupts.ier());
            }
            CanMode::Basic => {
                self.regs.read(basic::IR as u8);
                let cr = config.interrupts.cr_bits();
                self.wait_until("leave reset mode", "CR", 0, cr, |v| v & MOD_RM == 0)?;
            }
        }
        Ok(())
    }

    /// Back on the bus after bus-off, as the configuration says
    /// ([`BusOffRecovery`](crate::BusOffRecovery)): `Counted`, the seed's way, only clears
    /// reset mode (the chip set it) and lets the chip wait its 128 × 11 recessive bits, TXERR
    /// falling and SR.ES clearing below the warning limit on the way; `poll` reports
    /// `BusOff → Active` when it is back. `Fast` is [`restart`](Self::restart). `Manual`
    /// means nobody calls this at bus-off; called anyway, it recovers as `Counted`.
    pub fn recover(&mut self) -> Result<(), DriverError> {
        let config = self.config.clone().ok_or(DriverError::NotInitialized)?;
        if config.bus_off_recovery == crate::BusOffRecovery::Fast {
            return self.restart();
        }
        self.tx = None;
        match config.mode {
            CanMode::Peli => {
                let mode = config.mod_bits();
                self.wait_until("leave reset mode", "MOD", 0, mode, |v| v & MOD_RM == 0)
            }
            CanMode::Basic => {
                let cr = config.interrupts.cr_bits();
                self.wait_until("leave reset mode", "CR", 0, cr, |v| v & MOD_RM == 0)
            }
        }
    }

    /// SR decoded (reading SR has no side effects).
    pub fn status(&mut self) -> Status {
        Status(self.regs.read(peli::SR as u8))
    }

    /// RXERR and TXERR now, ALC and ECC as last captured by [`poll`](Self::poll). `None` in
    /// BasicCAN mode, which has none of these registers.
    pub fn error_registers(&mut self) -> Option<ErrorRegisters> {
        if self.mode() != CanMode::Peli || self.config.is_none() {
            return None;
        }
        Some(ErrorRegisters {
            alc: self.last_alc,
            ecc: self.last_ecc,
            rxerr: self.regs.read(peli::RXERR as u8),
            txerr: self.regs.read(peli::TXERR as u8),
        })
    }

    /// Every register, without side effects where possible: a device that can
    /// [`peek`](RegisterAccess::peek) is peeked; otherwise IR, ALC and ECC (whose reads
    /// clear or re-arm them) are left out, as is the write-only CMR.
    pub fn register_dump(&mut self) -> RegisterDump {
        let read = |regs: &mut R, addr: u8| regs.peek(addr).unwrap_or_else(|| regs.read(addr));
        let mode = if read(&mut self.regs, 31) & CDR_PELICAN != 0 {
            CanMode::Peli
        } else {
            CanMode::Basic
        };
        let reset_mode = read(&mut self.regs, 0) & MOD_RM != 0;
        let (count, unsafe_reads): (u8, &[usize]) = match mode {
            CanMode::Peli => (128, &[peli::IR, peli::ALC, peli::ECC]),
            CanMode::Basic => (32, &[basic::IR]),
        };
        let values = (0..count)
            .map(|addr| {
                if addr as usize == peli::CMR {
                    return None;
                }
                if let Some(value) = self.regs.peek(addr) {
                    return Some(value);
                }
                (!unsafe_reads.contains(&(addr as usize))).then(|| self.regs.read(addr))
            })
            .collect();
        RegisterDump {
            mode,
            reset_mode,
            values,
        }
    }
}
