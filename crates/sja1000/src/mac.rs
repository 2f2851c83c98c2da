//! The chip's bit-stream processor: buslab's protocol controller, seen the way the register
//! logic needs it. Everything the chip asks of the controller goes through here.

use core::ops::Range;

use buslab_can::controller::{
    Controller, ControllerConfig, ErrorLocation, ErrorState, Event, FrameRole, FrameStart,
    WireFrame,
};
use buslab_can::wire::Field;
use buslab_can::{Frame, Level};

#[derive(Debug)]
pub(crate) struct Mac {
    controller: Controller,
}

impl Mac {
    /// A controller that integrates into the bus (11 recessive bits) before taking part, with
    /// the given error counters.
    pub fn new(listen_only: bool, self_test: bool, tec: u8, rec: u8) -> Self {
        let config = ControllerConfig {
            listen_only,
            self_test,
            // Bus-off recovery starts when the CPU leaves reset mode.
            auto_recover: false,
            tx_queue_capacity: 1,
            ..ControllerConfig::default()
        };
        let mut controller = Controller::new(config);
        controller.set_counters(tec as u16, rec as u16);
        Self { controller }
    }

    /// A controller already bus-off (the CPU forced it by writing TXERR 255), not recovering.
    pub fn bus_off(listen_only: bool, self_test: bool) -> Self {
        let mut mac = Self::new(listen_only, self_test, 0, 0);
        mac.controller.set_counters(256, 0);
        // The chip has already signalled this bus-off itself.
        while mac.controller.poll_event().is_some() {}
        mac
    }

    pub fn is_bus_off(&self) -> bool {
        self.controller.state() == ErrorState::BusOff
    }

    pub fn is_listen_only(&self) -> bool {
        self.controller.config().listen_only
    }

    pub fn is_self_test(&self) -> bool {
        self.controller.config().self_test
    }

    /// Queues the TX buffer's frame with the DLC as coded (9..15 go on the wire as they are);
    /// `single_shot` = no retransmission (CMR.AT with TR).
    pub fn enqueue(&mut self, frame: Frame, dlc: u8, single_shot: bool) -> bool {
        self.controller.set_single_shot(single_shot);
        self.controller.enqueue_with_dlc(frame, dlc).is_ok()
    }

    /// Withdraws the pending frame if it has not started (`true`); a frame already on the bus
    /// finishes this attempt and is not retried.
    pub fn abort_pending(&mut self) -> bool {
        self.controller.abort_all();
        // Only a frame on the wire survives an abort. `is_transmitting` is no test for that: it
        // stays set during the error frame of a frame already dropped, while the TX buffer's
        // next frame still waits (it would then never start, and TBS never return to 1).
        self.controller.pending() == 0
    }

    pub fn recover(&mut self) {
        self.controller.recover();
    }

    pub fn output(&self) -> Level {
        self.controller.output()
    }

    pub fn sample(&mut self, bus: Level) {
        self.controller.sample(bus);
    }

    /// Lined up at a frame start (see [`Controller::frame_start`]).
    pub fn frame_start(&self) -> FrameStart<'_> {
        self.controller.frame_start()
    }

    /// Wire bits `bits` of a whole frame have passed (see [`Controller::advance_frame`]).
    pub fn advance_frame(&mut self, frame: &WireFrame, role: FrameRole, bits: Range<u32>) {
        self.controller.advance_frame(frame, role, bits);
    }

    pub fn has_events(&self) -> bool {
        self.controller.has_events()
    }

    pub fn poll_event(&mut self) -> Option<Event> {
        self.controller.poll_event()
    }

    /// The ECC segment code (bits 4..0) of the last error.
    pub fn last_error_segment(&self) -> u8 {
        segment(self.controller.last_error_location())
    }

    pub fn tec(&self) -> u16 {
        self.controller.tec()
    }

    pub fn rec(&self) -> u16 {
        self.controller.rec()
    }

    pub fn is_transmitting(&self) -> bool {
        self.controller.is_transmitting()
    }

    pub fn is_receiving(&self) -> bool {
        self.controller.is_receiving()
    }

    pub fn is_bus_idle(&self) -> bool {
        self.controller.is_bus_idle()
    }

    pub fn pending(&self) -> usize {
        self.controller.pending()
    }
}

/// ECC bits 4..0 for an error location (datasheet segment codes; Linux's CAN_ERR_PROT_LOC_*).
fn segment(location: ErrorLocation) -> u8 {
    match location {
        ErrorLocation::Flag { overload: false } => 0x11,
        ErrorLocation::Flag { overload: true } => 0x1C,
        ErrorLocation::Delimiter { .. } => 0x17,
        ErrorLocation::Frame { field, index } => match field {
            Field::Sof => 0x03,
            // ID.28..ID.21 are de-stuffed bits 1..8, ID.20..ID.18 bits 9..11.
            Field::Id if index <= 8 => 0x02,
            Field::Id => 0x06,
            Field::Srr => 0x04,
            // Bit 12 is the SRTR position (RTR of a standard frame); bit 32 the extended RTR.
            Field::Rtr if index <= 12 => 0x04,
            Field::Rtr => 0x0C,
            Field::Ide => 0x05,
            // ID.17..ID.13 are bits 14..18, ID.12..ID.5 bits 19..26, ID.4..ID.0 bits 27..31.
            Field::IdExt if index <= 18 => 0x07,
            Field::IdExt if index <= 26 => 0x0F,
            Field::IdExt => 0x0E,
            Field::R1 => 0x0D,
            Field::R0 => 0x09,
            Field::Dlc => 0x0B,
            Field::Data => 0x0A,
            Field::Crc => 0x08,
            Field::CrcDelimiter => 0x18,
            Field::AckSlot => 0x19,
            Field::AckDelimiter => 0x1B,
            Field::Eof => 0x1A,
        },
    }
}
