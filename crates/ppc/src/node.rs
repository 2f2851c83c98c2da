//! The PowerPC node as a [`BusNode`]: its SJA1000 on the wire, MoniCAN as the CPU's program
//! driving the chip through its registers (the host library's driver, PeliCAN as the seed's
//! `sja_init_pelican`), and a serial port that is bytes in, bytes out.

use std::any::Any;
use std::collections::VecDeque;

use buslab_can::controller::{ErrorState, Event, QueueFull};
use buslab_can::node::BusNode;
use buslab_can::{Frame, Level};
use buslab_canbus::{
    ControllerState, DriverError, DriverEvent, Sja1000Config, Sja1000Driver, Timing, TxFailure,
};
use buslab_monican::{Config, ConfigError, MoniCan, Transmit};
use buslab_sja1000::{BitTiming, Sja1000, TimingError};
use tracing::{debug, warn};

/// The PowerPC board's SJA1000 crystal (the seed: "Xtal de 16MHz"); the CAN clock is half.
pub const CRYSTAL_HZ: u32 = 16_000_000;
/// Keys waiting for the CPU at most; beyond, a key is lost as on an overrun UART (counted).
pub const MAX_KEYS: usize = 256;
/// A frame that stays in the TX buffer this many bit-times (nobody acknowledges it: the
/// PowerPC alone on the bus) is aborted, so the periodic calibration never waits behind it.
pub const GIVE_UP_BITS: u64 = buslab_slio::master::ANSWER_WITHIN_BITS;
/// How long a bus-off SJA1000 waits before MoniCAN restarts it.
pub const RESTART_AFTER_MS: u64 = 100;

/// Why the PowerPC node cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum PpcError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(
        "the PowerPC node's SJA1000 cannot run at {bitrate} bit/s from its {CRYSTAL_HZ} Hz crystal: {source}"
    )]
    Timing { bitrate: u32, source: TimingError },
    #[error("the PowerPC node's SJA1000 did not initialise: {0}")]
    Driver(#[from] DriverError),
}

/// The bit timing closest to the SLIOs' own (10 time quanta, sample point at 60 %, SJW 4:
/// seed §2.1, facts §1.2). A 16 MHz crystal gives it exactly where 8 MHz / (10 × bit rate) is
/// a whole prescaler (20, 40, 50, 80, 100 kbit/s...); elsewhere (125 kbit/s) Linux's algorithm
/// picks the timing with the sample point nearest below 60 %.
pub fn slio_timing(bitrate: u32) -> Result<BitTiming, TimingError> {
    let clock = CRYSTAL_HZ / 2;
    if let Some(quanta) = bitrate.checked_mul(10).filter(|&q| q > 0)
        && clock.is_multiple_of(quanta)
    {
        let brp = clock / quanta;
        if let Ok(timing) = BitTiming::new(brp, 5, 4, 4, false) {
            return Ok(timing);
        }
    }
    BitTiming::for_bitrate(clock, bitrate, Some(600))
}

/// The SJA1000 set-up of the seed's `sja_init_pelican`: PeliCAN, every frame accepted (single
/// filter), the SLIOs' bit timing. Two differences, both without effect on the bus model: the
/// interrupt enables stay on (the CPU services the chip when its interrupt line rises rather
/// than reading SR every bit-time; the seed polls with IER = 0), and OCR is the library's
/// normal output mode (the seed's 0xDB selects OCMODE = 11, clock output).
pub fn chip_config(bitrate: u32) -> Result<Sja1000Config, PpcError> {
    let timing = slio_timing(bitrate).map_err(|source| PpcError::Timing { bitrate, source })?;
    let (btr0, btr1) = timing.registers();
    Ok(Sja1000Config {
        timing: Timing::Registers { btr0, btr1 },
        crystal_hz: CRYSTAL_HZ,
        ..Sja1000Config::default()
    })
}

/// The frame MoniCAN gave the SJA1000.
#[derive(Clone, Copy, Debug)]
struct InFlight {
    frame: Frame,
    /// Aborted once it starts (the calibration frames, as the seed's `calibration_slio`).
    single_shot: bool,
    /// CMR.AT was written.
    abort_requested: bool,
    /// The bit-time it was handed to the chip.
    since: u64,
}

/// The PowerPC node running MoniCAN.
pub struct PpcNode {
    driver: Sja1000Driver<Sja1000>,
    app: MoniCan,
    bitrate: u32,
    keys: VecDeque<u8>,
    keys_dropped: u64,
    in_flight: Option<InFlight>,
    /// A frame taken from MoniCAN that waits for the chip (a calibration frame waits until the
    /// previous transmission is over, SR.TS = 0, as the seed's `calibration_slio` does).
    next: Option<Transmit>,
    restart_at: Option<u64>,
    now: u64,
}

impl core::fmt::Debug for PpcNode {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("PpcNode")
            .field("bitrate", &self.bitrate)
            .field("state", &self.driver.state())
            .field("keys", &self.keys.len())
            .field("in_flight", &self.in_flight)
            .finish()
    }
}

impl PpcNode {
    /// A PowerPC node on a bus at `config.bitrate` whose clock starts at bit-time 0: MoniCAN
    /// starts (screen init), the SJA1000 is initialised, and the calibration frames are queued
    /// (§4.3.2.1).
    pub fn new(config: Config) -> Result<Self, PpcError> {
        let bitrate = config.bitrate;
        let app = MoniCan::new(config, 0)?;
        let mut driver = Sja1000Driver::new(Sja1000::new());
        driver.init(&chip_config(bitrate)?)?;
        Ok(Self {
            driver,
            app,
            bitrate,
            keys: VecDeque::new(),
            keys_dropped: 0,
            in_flight: None,
            next: None,
            restart_at: None,
            now: 0,
        })
    }

    /// A byte the terminal sent; MoniCAN takes it at the node's next bit-time.
    pub fn key(&mut self, byte: u8) {
        if self.keys.len() >= MAX_KEYS {
            self.keys_dropped += 1;
            if self.keys_dropped == 1 {
                warn!(
                    "the PowerPC node's serial port overran: keys beyond {MAX_KEYS} waiting are lost"
                );
            }
            return;
        }
        self.keys.push_back(byte);
    }

    /// Keys lost because too many were waiting.
    pub fn keys_dropped(&self) -> u64 {
        self.keys_dropped
    }

    /// The VT100 bytes MoniCAN produced for the terminal since the last call (the screen is
    /// diffed now: call it when the serial line has room, not at every bit-time).
    pub fn take_screen(&mut self) -> Vec<u8> {
        self.app.take_screen()
    }

    /// The next [`take_screen`](Self::take_screen) redraws the whole screen (a terminal that
    /// connected late).
    pub fn redraw(&mut self) {
        self.app.redraw();
    }

    /// MoniCAN, to look at (what the screen shows of each SLIO, the inventory).
    pub fn app(&self) -> &MoniCan {
        &self.app
    }

    pub fn app_mut(&mut self) -> &mut MoniCan {
        &mut self.app
    }

    /// The SJA1000 (registers, counters).
    pub fn chip(&self) -> &Sja1000 {
        self.driver.chip()
    }

    pub fn driver(&mut self) -> &mut Sja1000Driver<Sja1000> {
        &mut self.driver
    }

    pub fn bitrate(&self) -> u32 {
        self.bitrate
    }

    /// Nanoseconds at bit-time `bits`.
    fn ns(&self, bits: u64) -> u64 {
        (u128::from(bits) * 1_000_000_000 / u128::from(self.bitrate)) as u64
    }

    /// The first bit-time at or after `ns` nanoseconds.
    fn bits_at(&self, ns: u64) -> u64 {
        let bits = (u128::from(ns) * u128::from(self.bitrate)).div_ceil(1_000_000_000);
        u64::try_from(bits).unwrap_or(u64::MAX)
    }

    /// The interrupt handler: frames to MoniCAN, the end of a transmission, bus-off.
    fn service(&mut self, now: u64) {
        let ns = self.ns(now);
        for event in self.driver.poll() {
            match event {
                DriverEvent::Received(frame) => self.app.handle_frame(ns, &frame),
                DriverEvent::TxDone(frame) => {
                    debug!("PowerPC sent {frame}");
                    self.in_flight = None;
                }
                DriverEvent::TxFailed { frame, reason } => {
                    let expected = self.in_flight.is_some_and(|t| t.single_shot)
                        && matches!(reason, TxFailure::Aborted | TxFailure::SingleShot);
                    if expected {
                        debug!("PowerPC: {frame} not acknowledged, aborted");
                    } else {
                        warn!("the PowerPC node gave up {frame}: {reason}");
                    }
                    self.in_flight = None;
                }
                DriverEvent::DataOverrun => {
                    warn!("the PowerPC node's SJA1000 lost received frames (RX FIFO overrun)");
                }
                DriverEvent::StateChanged { to, .. } => {
                    if to == ControllerState::BusOff {
                        warn!(
                            "the PowerPC node's SJA1000 went bus-off; restarting it in {RESTART_AFTER_MS} ms"
                        );
                        self.in_flight = None;
                        self.next = None;
                        self.restart_at =
                            Some(now + u64::from(self.bitrate) * RESTART_AFTER_MS / 1000);
                    }
                }
                DriverEvent::BusError(_)
                | DriverEvent::ArbitrationLost(_)
                | DriverEvent::WakeUp => {}
            }
        }
    }

    /// The seed's `calibration_slio` aborts a calibration frame once it is on the wire
    /// (CMR.AT after SR.TS): one attempt, no retry while nobody acknowledges. Any other frame
    /// still unsent after [`GIVE_UP_BITS`] is aborted too.
    fn watch_transmission(&mut self, now: u64) {
        let Some(tx) = self.in_flight else { return };
        if tx.abort_requested {
            return;
        }
        let abort = if tx.single_shot {
            self.driver.status().transmitting()
        } else {
            now >= tx.since + GIVE_UP_BITS
        };
        if abort {
            if !tx.single_shot {
                warn!(
                    "the PowerPC node aborts {} after {GIVE_UP_BITS} bit-times unsent (nobody acknowledges it)",
                    tx.frame
                );
            }
            self.driver.abort();
            self.in_flight = Some(InFlight {
                abort_requested: true,
                ..tx
            });
        }
    }

    /// The next frame of MoniCAN's into a free TX buffer.
    fn feed(&mut self, now: u64) {
        if self.in_flight.is_some() || self.restart_at.is_some() || self.driver.tx_pending() {
            return;
        }
        let Some(t) = self.next.take().or_else(|| self.app.poll_transmit()) else {
            return;
        };
        if t.single_shot && self.driver.status().transmitting() {
            // The error frame of the previous attempt is still ours on the wire: a request now
            // would be aborted before it ever started.
            self.next = Some(t);
            return;
        }
        match self.driver.send(&t.frame) {
            Ok(()) => {
                self.in_flight = Some(InFlight {
                    frame: t.frame,
                    single_shot: t.single_shot,
                    abort_requested: false,
                    since: now,
                });
            }
            Err(e) => warn!("the PowerPC node cannot send {}: {e}", t.frame),
        }
    }
}

impl BusNode for PpcNode {
    fn output(&self) -> Level {
        self.driver.chip().output()
    }

    fn sample(&mut self, now: u64, bus: Level) {
        self.now = now;
        let chip = self.driver.registers();
        chip.sample(bus);
        let interrupt = chip.interrupt();
        let ns = self.ns(now);
        while let Some(key) = self.keys.pop_front() {
            self.app.handle_key(ns, key);
        }
        if interrupt {
            self.service(now);
        }
        self.watch_transmission(now);
        if self.app.next_deadline().is_some_and(|t| t <= ns) {
            self.app.handle_timeout(ns);
        }
        if self.restart_at.is_some_and(|t| now >= t) {
            self.restart_at = None;
            if let Err(e) = self.driver.restart() {
                warn!("the PowerPC node's SJA1000 did not restart: {e}");
            }
            self.service(now);
        }
        self.feed(now);
    }

    fn poll_event(&mut self) -> Option<Event> {
        self.driver.registers().poll_bus_event()
    }

    fn tec(&self) -> u16 {
        BusNode::tec(self.driver.chip())
    }

    fn rec(&self) -> u16 {
        BusNode::rec(self.driver.chip())
    }

    fn state(&self) -> ErrorState {
        self.driver.chip().error_state()
    }

    fn quiet_until(&self) -> Option<u64> {
        if !self.keys.is_empty()
            || self.in_flight.is_some()
            || self.next.is_some()
            || self.driver.tx_pending()
        {
            return None;
        }
        if let Some(t) = self.restart_at {
            return Some(t);
        }
        if self.app.queued() > 0 || !self.driver.chip().is_quiescent() {
            return None;
        }
        // MoniCAN's own timers (the periodic calibration, answers it waits for) wake it.
        Some(
            self.app
                .next_deadline()
                .map_or(u64::MAX, |t| self.bits_at(t)),
        )
    }

    /// MoniCAN alone decides what the PowerPC sends: traffic generators and scenario
    /// one-shots are refused.
    fn enqueue(&mut self, _frame: Frame) -> Result<(), QueueFull> {
        Err(QueueFull { capacity: 0 })
    }

    fn pending(&self) -> usize {
        self.app.queued() + usize::from(self.next.is_some()) + usize::from(self.driver.tx_pending())
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_slio_timing_where_the_crystal_allows_it() {
        for rate in [20_000, 50_000, 100_000] {
            let t = slio_timing(rate).unwrap();
            assert_eq!((t.quanta_per_bit(), t.sample_point_permille()), (10, 600));
            assert_eq!(t.bitrate(CRYSTAL_HZ / 2), rate);
        }
        // 125 kbit/s: 64 CAN clocks a bit, no whole prescaler for 10 quanta.
        let t = slio_timing(125_000).unwrap();
        assert_eq!(t.bitrate(CRYSTAL_HZ / 2), 125_000);
        assert_eq!((t.quanta_per_bit(), t.sample_point_permille()), (16, 562));
        assert!(slio_timing(0).is_err());
    }

    #[test]
    fn keys_beyond_the_port_buffer_are_counted() {
        let mut node = PpcNode::new(Config::default()).unwrap();
        for _ in 0..MAX_KEYS + 3 {
            node.key(b'x');
        }
        assert_eq!(node.keys_dropped(), 3);
        assert_eq!(node.quiet_until(), None, "keys wake the node");
    }
}
