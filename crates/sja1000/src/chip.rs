//! The chip: register file, command logic and interrupts around one protocol controller.

use std::collections::VecDeque;
use std::ops::Range;

use buslab_can::controller::{ErrorKind, ErrorState, Event, FrameRole, FrameStart, WireFrame};
use buslab_can::{Frame, Level};

use crate::fifo::RxFifo;
use crate::filter::{self, FilterMode};
use crate::layout::{self, CanMode};
use crate::mac::Mac;
use crate::regs::*;
use crate::timing::BitTiming;

/// One SJA1000: read and write its registers like a CPU on its bus; step it on the CAN bus with
/// [`output`](Sja1000::output) and [`sample`](Sja1000::sample) once per bit-time.
#[derive(Debug)]
pub struct Sja1000 {
    mode: CanMode,
    /// MOD.RM / CR.RR.
    reset: bool,
    /// PeliCAN MOD bits LOM, STM, AFM, SM.
    mod_bits: u8,
    /// BasicCAN CR bits 1..4 (interrupt enables) and bit 6 (kept as written).
    cr_bits: u8,
    ier: u8,
    /// Latched interrupt flags. In PeliCAN RI is not latched but follows the FIFO.
    ir: u8,
    tbs: bool,
    tcs: bool,
    dos: bool,
    es: bool,
    bs: bool,
    btr0: u8,
    btr1: u8,
    ocr: u8,
    cdr: u8,
    ewlr: u8,
    alc: u8,
    alc_armed: bool,
    ecc: u8,
    ecc_armed: bool,
    txerr: u8,
    rxerr: u8,
    acr: [u8; 4],
    amr: [u8; 4],
    tx_buf: [u8; 13],
    free_ram: [u8; 3],
    fifo: RxFifo,
    /// The frames of the messages in the FIFO, oldest first, for [`Self::received_frame`].
    rx_frames: VecDeque<Frame>,
    mac: Mac,
    /// The transmission requested by TR/SRR, until it ends.
    pending: Option<Pending>,
    sleeping: bool,
    /// Recessive bits in a row during bus-off recovery (TXERR counts down every 11).
    recovery_run: u8,
    /// The protocol controller's events, for the bus engine's observers (bounded: the oldest
    /// go when nobody reads them).
    bus_events: VecDeque<Event>,
}

/// Protocol events kept for [`Sja1000::poll_bus_event`] when nobody reads them.
const BUS_EVENTS_KEPT: usize = 64;

#[derive(Clone, Copy, Debug)]
struct Pending {
    self_reception: bool,
}

impl Default for Sja1000 {
    fn default() -> Self {
        Self::new()
    }
}

impl Sja1000 {
    /// A chip after a hardware reset: BasicCAN, reset mode, Intel interface.
    pub fn new() -> Self {
        Self {
            mode: CanMode::Basic,
            reset: true,
            mod_bits: 0,
            cr_bits: 0,
            ier: 0,
            ir: 0,
            tbs: true,
            tcs: true,
            dos: false,
            es: false,
            bs: false,
            btr0: 0,
            btr1: 0,
            ocr: 0,
            cdr: 0,
            ewlr: 96,
            alc: 0,
            alc_armed: true,
            ecc: 0,
            ecc_armed: true,
            txerr: 0,
            rxerr: 0,
            acr: [0; 4],
            amr: [0xFF; 4],
            tx_buf: [0; 13],
            free_ram: [0; 3],
            fifo: RxFifo::default(),
            rx_frames: VecDeque::new(),
            mac: Mac::new(false, false, 0, 0),
            pending: None,
            sleeping: false,
            recovery_run: 0,
            bus_events: VecDeque::new(),
        }
    }

    pub fn mode(&self) -> CanMode {
        self.mode
    }

    pub fn in_reset_mode(&self) -> bool {
        self.reset
    }

    /// The bit timing programmed in BTR0/BTR1.
    pub fn bit_timing(&self) -> BitTiming {
        BitTiming::from_registers(self.btr0, self.btr1)
    }

    /// The INT pin (active low on the chip; `true` here means asserted).
    #[inline]
    pub fn interrupt(&self) -> bool {
        match self.mode {
            CanMode::Peli => self.ir_value() != 0,
            CanMode::Basic => self.ir & 0x1F != 0,
        }
    }

    /// Error state of the protocol controller as the registers show it.
    #[inline]
    pub fn error_state(&self) -> ErrorState {
        if self.bs {
            ErrorState::BusOff
        } else if self.txerr > 127 || self.rxerr > 127 {
            ErrorState::Passive
        } else {
            ErrorState::Active
        }
    }

    // ---------------------------------------------------------------- CPU side

    /// A CPU read. Reading IR, ALC and ECC has side effects, as on the chip.
    #[inline]
    pub fn read(&mut self, addr: u8) -> u8 {
        let addr = addr as usize;
        match self.mode {
            CanMode::Peli => self.read_peli(addr),
            CanMode::Basic => self.read_basic(addr),
        }
    }

    /// Reads without side effects (for register dumps and viewers).
    pub fn peek(&self, addr: u8) -> u8 {
        let addr = addr as usize;
        match (self.mode, addr) {
            (CanMode::Peli, peli::IR) => self.ir_value(),
            (CanMode::Basic, basic::IR) => self.ir | 0xE0,
            (CanMode::Peli, _) => self.read_peli_plain(addr),
            (CanMode::Basic, _) => self.read_basic_plain(addr),
        }
    }

    /// A CPU write.
    #[inline]
    pub fn write(&mut self, addr: u8, value: u8) {
        let addr = addr as usize;
        match self.mode {
            CanMode::Peli => self.write_peli(addr, value),
            CanMode::Basic => self.write_basic(addr, value),
        }
    }

    /// Reads `buf.len()` consecutive registers from `addr` on, as that many [`Self::read`]s
    /// would; a block inside the receive window is copied at once.
    pub fn read_block(&mut self, addr: u8, buf: &mut [u8]) {
        let from = addr as usize;
        match self.rx_window() {
            Some(window) if window.start <= from && from + buf.len() <= window.end => {
                self.fifo.copy_window(from - window.start, buf);
            }
            _ => {
                for (k, byte) in buf.iter_mut().enumerate() {
                    *byte = self.read(addr.wrapping_add(k as u8));
                }
            }
        }
    }

    /// Writes `bytes` to consecutive registers from `addr` on, as that many [`Self::write`]s
    /// would; a block inside a writable transmit buffer is copied at once.
    pub fn write_block(&mut self, addr: u8, bytes: &[u8]) {
        let from = addr as usize;
        match self.tx_window() {
            Some(window) if window.start <= from && from + bytes.len() <= window.end => {
                let at = from - window.start;
                self.tx_buf[at..at + bytes.len()].copy_from_slice(bytes);
            }
            _ => {
                for (k, &byte) in bytes.iter().enumerate() {
                    self.write(addr.wrapping_add(k as u8), byte);
                }
            }
        }
    }

    /// The frame that decoding the receive window's bytes from `addr` on in `mode` gives, when
    /// the chip still has it (the message was stored in `mode`'s layout and the window starts
    /// at `addr`); `None` otherwise. Reading the window has no side effects, so a driver may
    /// take this in place of the bytes: every stored message is its frame encoded, and FIFO
    /// RAM is written only in reset mode, which empties the FIFO.
    pub fn received_frame(&self, mode: CanMode, addr: u8) -> Option<Frame> {
        let window = self.rx_window()?;
        let in_step = self.rx_frames.len() == self.fifo.count() as usize;
        if mode != self.mode || addr as usize != window.start || !in_step {
            return None;
        }
        self.rx_frames.front().copied()
    }

    /// The addresses that read the receive window (without side effects), if any do now.
    fn rx_window(&self) -> Option<Range<usize>> {
        match self.mode {
            CanMode::Peli if self.reset => None, // acceptance code and mask
            CanMode::Peli => Some(peli::WINDOW..peli::WINDOW + 13),
            CanMode::Basic => Some(basic::RX..basic::RX + 10),
        }
    }

    /// The addresses that write the transmit buffer, if any do now (TBS, operating mode).
    fn tx_window(&self) -> Option<Range<usize>> {
        if self.reset || !self.tbs {
            return None;
        }
        Some(match self.mode {
            CanMode::Peli => peli::WINDOW..peli::WINDOW + 13,
            CanMode::Basic => basic::TX..basic::TX + 10,
        })
    }

    #[inline]
    fn read_peli(&mut self, addr: usize) -> u8 {
        match addr {
            peli::IR => {
                let value = self.ir_value();
                self.ir = 0; // RI is not latched: it comes back while the FIFO holds messages
                value
            }
            peli::ALC => {
                self.alc_armed = true;
                self.alc
            }
            peli::ECC => {
                self.ecc_armed = true;
                self.ecc
            }
            _ => self.read_peli_plain(addr),
        }
    }

    fn read_peli_plain(&self, addr: usize) -> u8 {
        match addr {
            peli::MOD => self.reset as u8 | self.mod_bits,
            peli::CMR => 0,
            peli::SR => self.status(),
            peli::IR => self.ir_value(),
            peli::IER => self.ier,
            peli::BTR0 => self.btr0,
            peli::BTR1 => self.btr1,
            peli::OCR => self.ocr,
            peli::ALC => self.alc,
            peli::ECC => self.ecc,
            peli::EWLR => self.ewlr,
            peli::RXERR => self.rxerr,
            peli::TXERR => self.txerr,
            16..=28 if self.reset => match addr {
                16..=19 => self.acr[addr - 16],
                20..=23 => self.amr[addr - 20],
                _ => 0,
            },
            16..=28 => self.fifo.window(addr - peli::WINDOW),
            peli::RMC => self.fifo.count(),
            peli::RBSA => self.fifo.start(),
            peli::CDR => self.cdr,
            32..=95 => self.fifo.ram(addr - peli::FIFO_RAM),
            96..=108 => self.tx_buf[addr - peli::TX_RAM],
            109..=111 => self.free_ram[addr - 109],
            _ => 0,
        }
    }

    fn write_peli(&mut self, addr: usize, value: u8) {
        match addr {
            peli::MOD => {
                if self.reset {
                    self.mod_bits = value & (MOD_LOM | MOD_STM | MOD_AFM);
                } else if value & MOD_SM != 0 {
                    self.request_sleep();
                } else if self.sleeping {
                    self.wake_up();
                }
                self.set_reset(value & MOD_RM != 0);
            }
            peli::CMR => self.command(value),
            peli::IER => self.ier = value,
            peli::BTR0 if self.reset => self.btr0 = value,
            peli::BTR1 if self.reset => self.btr1 = value,
            peli::OCR if self.reset => self.ocr = value,
            peli::EWLR if self.reset => self.ewlr = value,
            peli::RXERR if self.reset && !self.bs => self.rxerr = value,
            peli::TXERR if self.reset => self.write_txerr(value),
            16..=23 if self.reset => {
                if addr < 20 {
                    self.acr[addr - 16] = value;
                } else {
                    self.amr[addr - 20] = value;
                }
            }
            16..=28 if !self.reset && self.tbs => self.tx_buf[addr - peli::WINDOW] = value,
            peli::RBSA if self.reset => self.fifo.set_start(value & 0x3F),
            peli::CDR => self.write_cdr(value),
            32..=95 if self.reset => self.fifo.set_ram(addr - peli::FIFO_RAM, value),
            96..=108 if self.reset => self.tx_buf[addr - peli::TX_RAM] = value,
            109..=111 if self.reset => self.free_ram[addr - 109] = value,
            _ => {} // read-only, reserved, or not writable in this mode
        }
    }

    fn read_basic(&mut self, addr: usize) -> u8 {
        if addr == basic::IR {
            let value = self.ir | 0xE0;
            self.ir = 0;
            return value;
        }
        self.read_basic_plain(addr)
    }

    fn read_basic_plain(&self, addr: usize) -> u8 {
        match addr {
            basic::CR => self.reset as u8 | self.cr_bits | 0x20,
            basic::CMR => 0xFF,
            basic::SR => self.status(),
            basic::IR => self.ir | 0xE0,
            basic::ACR if self.reset => self.acr[0],
            basic::AMR if self.reset => self.amr[0],
            basic::BTR0 if self.reset => self.btr0,
            basic::BTR1 if self.reset => self.btr1,
            basic::OCR if self.reset => self.ocr,
            10..=19 if !self.reset => self.tx_buf[addr - basic::TX],
            20..=29 => self.fifo.window(addr - basic::RX),
            basic::CDR => self.cdr,
            _ => 0xFF,
        }
    }

    fn write_basic(&mut self, addr: usize, value: u8) {
        match addr {
            basic::CR => {
                self.cr_bits = value & 0x5E;
                self.set_reset(value & MOD_RM != 0);
            }
            basic::CMR => self.command(value),
            basic::ACR if self.reset => self.acr[0] = value,
            basic::AMR if self.reset => self.amr[0] = value,
            basic::BTR0 if self.reset => self.btr0 = value,
            basic::BTR1 if self.reset => self.btr1 = value,
            basic::OCR if self.reset => self.ocr = value,
            10..=19 if !self.reset && self.tbs => self.tx_buf[addr - basic::TX] = value,
            basic::CDR => self.write_cdr(value),
            _ => {}
        }
    }

    fn write_cdr(&mut self, value: u8) {
        if self.reset {
            self.cdr = value & !0x10;
            self.mode = if value & CDR_PELICAN != 0 {
                CanMode::Peli
            } else {
                CanMode::Basic
            };
        } else {
            self.cdr = self.cdr & !0x07 | value & 0x07;
        }
    }

    fn write_txerr(&mut self, value: u8) {
        self.txerr = value;
        // While bus-off, a value below 255 ends bus-off at once (Linux's fast restart).
        if self.bs && value < 255 {
            self.bs = false;
            self.raise(IR_EI);
        }
    }

    /// SR, computed from the current state.
    fn status(&self) -> u8 {
        let waiting = self.mode == CanMode::Peli && (self.reset || self.bs);
        let mut sr = 0;
        sr |= flag(self.fifo.count() > 0, SR_RBS);
        sr |= flag(self.dos, SR_DOS);
        sr |= flag(self.tbs, SR_TBS);
        sr |= flag(self.tcs, SR_TCS);
        sr |= flag(waiting || !self.reset && self.mac.is_receiving(), SR_RS);
        sr |= flag(waiting || !self.reset && self.mac.is_transmitting(), SR_TS);
        sr |= flag(self.es, SR_ES);
        sr |= flag(self.bs, SR_BS);
        sr
    }

    #[inline]
    fn ir_value(&self) -> u8 {
        let ri = self.mode == CanMode::Peli && self.enabled(IR_RI) && self.fifo.count() > 0;
        self.ir | flag(ri, IR_RI)
    }

    /// Whether interrupt source `bit` is enabled (IER in PeliCAN, CR in BasicCAN).
    #[inline]
    fn enabled(&self, bit: u8) -> bool {
        match self.mode {
            CanMode::Peli => self.ier & bit != 0,
            CanMode::Basic => match bit {
                IR_RI => self.cr_bits & CR_RIE != 0,
                IR_TI => self.cr_bits & CR_TIE != 0,
                IR_EI => self.cr_bits & CR_EIE != 0,
                IR_DOI => self.cr_bits & CR_OIE != 0,
                IR_WUI => true,
                _ => false,
            },
        }
    }

    fn raise(&mut self, bit: u8) {
        if self.enabled(bit) {
            self.ir |= bit;
        }
    }

    fn set_reset(&mut self, reset: bool) {
        match (self.reset, reset) {
            (false, true) => self.enter_reset(),
            (true, false) => self.leave_reset(),
            _ => {}
        }
    }

    /// CPU sets RM/RR: abort everything, empty the FIFO (RBSA kept).
    fn enter_reset(&mut self) {
        self.reset = true;
        self.mod_bits &= !MOD_SM;
        self.sleeping = false;
        self.fifo.clear();
        self.rx_frames.clear();
        self.dos = false;
        self.tbs = true;
        self.pending = None;
        self.mac.abort_pending();
    }

    /// CPU clears RM/RR: take part in bus traffic again after the bus is free.
    fn leave_reset(&mut self) {
        self.reset = false;
        if self.bs {
            if self.txerr == 255 {
                return self.enter_bus_off();
            }
            // Wait 128 × 11 recessive bits (the controller counts them). A bus-off the CPU forced
            // with TXERR 255 has a controller that is not bus-off yet: give it one that is.
            if !self.mac.is_bus_off() {
                self.mac = Mac::bus_off(self.mac.is_listen_only(), self.mac.is_self_test());
            }
            self.recovery_run = 0;
            self.mac.recover();
            return;
        }
        if self.txerr == 255 {
            // A CPU-forced bus-off happens when reset mode is left.
            return self.enter_bus_off();
        }
        let listen_only = self.mode == CanMode::Peli && self.mod_bits & MOD_LOM != 0;
        let self_test = self.mode == CanMode::Peli && self.mod_bits & MOD_STM != 0;
        self.mac = Mac::new(listen_only, self_test, self.txerr, self.rxerr);
        self.update_error_status();
    }

    fn enter_bus_off(&mut self) {
        self.enter_reset();
        self.bs = true;
        self.txerr = 127;
        self.rxerr = 0;
        // EI on bus-off entry whether or not ES changes.
        self.raise(IR_EI);
        self.set_error_status(true);
    }

    fn command(&mut self, cmd: u8) {
        if cmd & CMR_CDO != 0 {
            self.dos = false;
        }
        if cmd & CMR_RRB != 0 {
            if self.fifo.count() > 0 {
                self.rx_frames.pop_front();
            }
            self.fifo.release(self.mode);
            if self.mode == CanMode::Basic && self.fifo.count() > 0 {
                self.raise(IR_RI);
            }
        }
        let transmit = cmd & CMR_TR != 0;
        let abort = cmd & CMR_AT != 0;
        let self_rx = self.mode == CanMode::Peli && cmd & CMR_SRR != 0;
        if transmit || self_rx {
            // TR+SRR: SRR is ignored; SRR+AT: single-shot self-reception.
            self.start_transmission(abort, self_rx && !transmit);
        } else if abort && self.pending.is_some() && self.mac.abort_pending() {
            self.pending = None;
            self.tbs = true;
            self.raise(IR_TI);
        }
        if self.mode == CanMode::Basic && cmd & CMR_SRR != 0 {
            self.request_sleep(); // GTS
        } else if self.mode == CanMode::Basic && self.sleeping {
            self.wake_up();
        }
    }

    fn start_transmission(&mut self, single_shot: bool, self_reception: bool) {
        if self.reset || !self.tbs || self.mac.is_listen_only() {
            return;
        }
        let frame = layout::decode_tx(self.mode, &self.tx_buf);
        let dlc = layout::raw_dlc(self.mode, &self.tx_buf);
        if self.mac.enqueue(frame, dlc, single_shot) {
            self.tbs = false;
            self.tcs = false;
            self.pending = Some(Pending { self_reception });
        }
    }

    fn request_sleep(&mut self) {
        if self.reset {
            return;
        }
        if self.interrupt() || !self.mac.is_bus_idle() {
            self.raise(IR_WUI);
            return;
        }
        self.sleeping = true;
        self.mod_bits |= MOD_SM;
    }

    fn wake_up(&mut self) {
        self.sleeping = false;
        self.mod_bits &= !MOD_SM;
        self.raise(IR_WUI);
        // After waking the chip waits for 11 recessive bits before it takes part again.
        let (lom, stm) = (self.mac.is_listen_only(), self.mac.is_self_test());
        self.mac = Mac::new(lom, stm, self.txerr, self.rxerr);
    }

    // ---------------------------------------------------------------- bus side

    /// The level this chip drives during the current bit-time.
    #[inline]
    pub fn output(&self) -> Level {
        if self.reset || self.sleeping {
            Level::Recessive
        } else {
            self.mac.output()
        }
    }

    /// The bus level sampled during the current bit-time.
    pub fn sample(&mut self, bus: Level) {
        if self.reset {
            return;
        }
        if self.sleeping {
            if bus == Level::Dominant {
                self.wake_up();
            }
            return;
        }
        if self.bs {
            self.count_recovery_bit(bus);
        }
        self.mac.sample(bus);
        self.after_bits();
    }

    /// Whether the chip may take the next frame whole (see [`FrameStart`]): taking part in bus
    /// traffic (not in reset mode, asleep or bus-off) and its controller lined up at a frame
    /// start, error-active. Otherwise the engine steps it bit by bit.
    #[inline]
    pub fn frame_start(&self) -> FrameStart<'_> {
        if self.reset || self.sleeping || self.bs {
            return FrameStart::NotReady;
        }
        self.mac.frame_start()
    }

    /// Wire bits `bits` of a whole frame have passed with this chip as `role`, after
    /// [`Self::frame_start`] said `Ready`: the registers, FIFO, status and interrupts end as
    /// sampling each bit leaves them (events act at the last bit of the range; the engine ends
    /// a range at each bit where one happens).
    pub fn advance_frame(&mut self, frame: &WireFrame, role: FrameRole, bits: Range<u32>) {
        if self.reset {
            return; // as `sample`: a chip put in reset mode ignores the bus
        }
        self.mac.advance_frame(frame, role, bits);
        self.after_bits();
    }

    // ------------------------------------------------ receptions counted for a serviced chip

    /// Whether a clean frame received whole from now on leaves this chip exactly as a CPU that
    /// services RI at once leaves it (RI raised, the message read and released, nothing else):
    /// PeliCAN in operating mode, awake, not bus-off, RI enabled, IR clear, FIFO empty, no data
    /// overrun, no transmission requested, RXERR 0 (a good reception then changes no counter)
    /// and no protocol event kept unread. Such a frame may be counted: whether the CPU reads
    /// it is [`Self::accepts`]; its message goes to the FIFO RAM with
    /// [`Self::store_released`] (or [`Self::pass_over_released`] when later ones overwrite
    /// it), and the controller is brought up later with [`Self::settle_received`].
    #[inline]
    pub fn counts_receptions(&self) -> bool {
        self.mode == CanMode::Peli
            && !self.reset
            && !self.sleeping
            && !self.bs
            && self.ier & IR_RI != 0
            && self.ir == 0
            && self.fifo.count() == 0
            && !self.dos
            && self.pending.is_none()
            && self.bus_events.is_empty()
            && self.mac.pending() == 0
            && self.mac.rec() == 0
    }

    /// Whether the PeliCAN acceptance filter takes `frame` into the FIFO (for a frame counted
    /// while [`Self::counts_receptions`] held).
    #[inline]
    pub fn accepts(&self, frame: &Frame) -> bool {
        let filter_mode = if self.mod_bits & MOD_AFM != 0 {
            FilterMode::Single
        } else {
            FilterMode::Dual
        };
        filter::accepts(filter_mode, self.acr, self.amr, frame)
    }

    /// An accepted counted frame as the register side keeps it once its CPU has read and
    /// released it: its message written to the (empty) FIFO RAM and RBSA moved past it.
    pub fn store_released(&mut self, frame: &Frame) {
        let mut message = [0u8; 13];
        let len = layout::encode(self.mode, frame, &mut message);
        if self.fifo.store(&message[..len]).is_ok() {
            self.fifo.release(self.mode);
        }
    }

    /// [`Self::store_released`] for a message whose bytes the later ones overwrite: only RBSA
    /// moves past it.
    #[inline]
    pub fn pass_over_released(&mut self, frame: &Frame) {
        self.fifo.pass_over(layout::message_len(self.mode, frame));
    }

    /// The controller's side of counted frames (see [`Self::counts_receptions`]): wire bits
    /// `bits` of `frame`, the last one counted, pass as a receiver, and its events (the node
    /// that counted the frame reported them) are dropped. The earlier counted frames need
    /// nothing: a good reception with RXERR 0 leaves a receiver's controller as the frame's end
    /// alone says.
    pub fn settle_received(&mut self, frame: &WireFrame, bits: Range<u32>) {
        self.mac.advance_frame(frame, FrameRole::Receiver, bits);
        while self.mac.poll_event().is_some() {}
        self.update_error_status();
    }

    /// What the register logic does after the controller moved on: its events, then the
    /// counters and SR.ES.
    fn after_bits(&mut self) {
        if self.mac.has_events() {
            self.take_controller_events();
        }
        self.update_error_status();
    }

    /// The controller's events: kept for the bus engine and acted on by the register logic.
    #[inline(never)]
    fn take_controller_events(&mut self) {
        while let Some(event) = self.mac.poll_event() {
            // The chip's own warning is SR.ES (against EWLR, and during the bus-off recovery
            // against TXERR counting down): it is reported in place of the controller's.
            if !matches!(event, Event::Warning { .. }) {
                self.report(event.clone());
            }
            self.on_event(event);
        }
    }

    /// Keeps an event for [`poll_bus_event`](Self::poll_bus_event) (the last 64).
    fn report(&mut self, event: Event) {
        if self.bus_events.len() == BUS_EVENTS_KEPT {
            self.bus_events.pop_front();
        }
        self.bus_events.push_back(event);
    }

    /// SR.ES changed: EI, and the change reported as the chip's error warning.
    fn set_error_status(&mut self, es: bool) {
        if es != self.es {
            self.error_status_changed(es);
        }
    }

    #[cold]
    #[inline(never)]
    fn error_status_changed(&mut self, es: bool) {
        self.es = es;
        self.raise(IR_EI);
        self.report(Event::Warning {
            above: es,
            tec: self.txerr.into(),
            rec: self.rxerr.into(),
        });
    }

    /// The error warning limit ES is computed against.
    fn warning_limit(&self) -> u8 {
        match self.mode {
            CanMode::Peli => self.ewlr,
            CanMode::Basic => 96,
        }
    }

    /// The next event of the chip's protocol controller (frames on the wire, errors, state
    /// changes), as the bus engine's observers see every node's; the register side is not
    /// affected by reading them. The last 64 are kept.
    #[inline]
    pub fn poll_bus_event(&mut self) -> Option<Event> {
        self.bus_events.pop_front()
    }

    /// Whether a recessive bus changes nothing in the chip: in reset mode or asleep, or idle
    /// on the bus with no transmission requested.
    pub fn is_quiescent(&self) -> bool {
        self.reset
            || self.sleeping
            || (!self.bs
                && self.pending.is_none()
                && self.mac.is_bus_idle()
                && self.mac.pending() == 0)
    }

    /// Whether a transmission request is in progress (TR or SRR until it ends).
    pub fn transmission_pending(&self) -> bool {
        self.pending.is_some()
    }

    fn on_event(&mut self, event: Event) {
        match event {
            Event::Received(frame) => self.store(&frame),
            Event::Transmitted(frame) => {
                if self.pending.is_some_and(|p| p.self_reception) {
                    self.store(&frame);
                }
                self.pending = None;
                self.tcs = true;
                self.tbs = true;
                self.raise(IR_TI);
            }
            Event::Dropped(_) => {
                self.pending = None;
                self.tbs = true;
                self.raise(IR_TI);
            }
            Event::ArbitrationLost { bit, .. } => {
                if self.alc_armed {
                    // ALC counts from ID.28 (the first bit after SOF).
                    self.alc = (bit.saturating_sub(1) as u8) & 0x1F;
                    self.alc_armed = false;
                    self.raise(IR_ALI);
                }
            }
            Event::Error {
                kind, transmitter, ..
            } => {
                if self.ecc_armed {
                    let code = match kind {
                        ErrorKind::Bit => 0b00,
                        ErrorKind::Form => 0b01,
                        ErrorKind::Stuff => 0b10,
                        ErrorKind::Crc | ErrorKind::Ack => 0b11,
                    };
                    let segment = self.mac.last_error_segment();
                    self.ecc = code << 6 | (!transmitter as u8) << 5 | segment;
                    self.ecc_armed = false;
                    self.raise(IR_BEI);
                }
            }
            Event::StateChanged { from, to, .. } => match (from, to) {
                (_, ErrorState::BusOff) => self.enter_bus_off(),
                (ErrorState::BusOff, _) => {
                    self.bs = false;
                    self.txerr = 0;
                    self.rxerr = 0;
                    self.raise(IR_EI);
                }
                _ => self.raise(IR_EPI),
            },
            Event::Warning { .. } | Event::Overload => {}
        }
    }

    /// Puts a received frame through the acceptance filter into the FIFO.
    fn store(&mut self, frame: &Frame) {
        let filter_mode = match self.mode {
            CanMode::Basic if frame.is_extended() => return, // "CAN 2.0B passive"
            CanMode::Basic => FilterMode::Basic,
            CanMode::Peli if self.mod_bits & MOD_AFM != 0 => FilterMode::Single,
            CanMode::Peli => FilterMode::Dual,
        };
        if !filter::accepts(filter_mode, self.acr, self.amr, frame) {
            return;
        }
        let mut message = [0u8; 13];
        let len = layout::encode(self.mode, frame, &mut message);
        match self.fifo.store(&message[..len]) {
            Ok(()) => {
                self.rx_frames.push_back(*frame);
                if self.mode == CanMode::Basic {
                    self.raise(IR_RI);
                }
            }
            Err(_overrun) => {
                if !self.dos {
                    self.dos = true;
                    self.raise(IR_DOI);
                }
            }
        }
    }

    /// Bus-off recovery progress: TXERR counts down from 127 once per 11 recessive bits, and
    /// ES clears as it passes below the warning limit (the seed watched it: "Lorsqu'il atteint
    /// 96, le bit Error Status repasse à OK"); BS clears at the end.
    fn count_recovery_bit(&mut self, bus: Level) {
        if bus == Level::Dominant {
            self.recovery_run = 0;
            return;
        }
        self.recovery_run += 1;
        if self.recovery_run == 11 {
            self.recovery_run = 0;
            self.txerr = self.txerr.saturating_sub(1);
            if self.txerr < self.warning_limit() && self.rxerr < self.warning_limit() {
                self.set_error_status(false);
            }
        }
    }

    /// Mirrors the counters and recomputes ES (EI on every change of ES).
    fn update_error_status(&mut self) {
        if self.reset || self.bs {
            return;
        }
        self.txerr = self.mac.tec().min(255) as u8;
        self.rxerr = self.mac.rec().min(255) as u8;
        let limit = self.warning_limit();
        self.set_error_status(self.txerr >= limit || self.rxerr >= limit);
    }
}

/// `mask` if `on`, else 0.
const fn flag(on: bool, mask: u8) -> u8 {
    if on { mask } else { 0 }
}

/// The chip on the one bus engine. A bare chip has no CPU: frames reach its transmit buffer
/// only through register writes (the host library's driver wraps the chip for that), so
/// [`BusNode::enqueue`](buslab_can::node::BusNode::enqueue) refuses them.
impl buslab_can::node::BusNode for Sja1000 {
    fn output(&self) -> Level {
        Sja1000::output(self)
    }
    fn sample(&mut self, _now: buslab_can::BitTime, bus: Level) {
        Sja1000::sample(self, bus)
    }
    fn poll_event(&mut self) -> Option<Event> {
        self.poll_bus_event()
    }
    /// TXERR as the CPU reads it (127 on entering bus-off, then counting down during the
    /// recovery, as the seed watched it fall).
    fn tec(&self) -> u16 {
        self.txerr as u16
    }
    fn rec(&self) -> u16 {
        self.rxerr as u16
    }
    fn state(&self) -> ErrorState {
        self.error_state()
    }
    fn quiet_until(&self) -> Option<buslab_can::BitTime> {
        Sja1000::is_quiescent(self).then_some(buslab_can::BitTime::MAX)
    }
    fn enqueue(&mut self, _frame: Frame) -> Result<(), buslab_can::controller::QueueFull> {
        Err(buslab_can::controller::QueueFull { capacity: 0 })
    }
    fn pending(&self) -> usize {
        self.pending.is_some() as usize
    }
    fn frame_start(&self) -> FrameStart<'_> {
        Sja1000::frame_start(self)
    }
    fn advance_frame(&mut self, frame: &WireFrame, role: FrameRole, bits: Range<u32>) {
        Sja1000::advance_frame(self, frame, role, bits)
    }
    fn as_any(&self) -> &dyn core::any::Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn core::any::Any {
        self
    }
}
