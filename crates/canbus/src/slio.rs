//! SLIOs from any bus (CANAPI's `SlIo` class, finished): [`buslab_slio::Master`] driven over
//! a [`CanBus`] with the wall clock.
//!
//! Single-shot transmissions (the start-up calibration frames, which nobody acknowledges
//! before the SLIOs are calibrated) are sent, waited for a little, and aborted when the bus
//! can abort (a buslab bus, through [`BusAdmin::abort`]); on other backends they are simply
//! sent and the adapter retries them until a SLIO calibrates on the repetitions and
//! acknowledges.

use std::time::{Duration, Instant};

use buslab_slio::{Master, MasterEvent, Register, RequestId, SlioId, Transmit};

use crate::bus::{BusError, BusEvent, CanBus};

/// How long a single-shot frame is given before it is aborted (many frames' time at 20
/// kbit/s; a loaded machine may take that long to send it).
const SINGLE_SHOT_WAIT: Duration = Duration::from_millis(50);

/// Why a SLIO request failed.
#[derive(Debug, thiserror::Error)]
pub enum SlioError {
    #[error("SLIO {slio}: no answer to {what} within {} ms (not on the bus, not calibrated, or the bit rate is outside 20..125 kbit/s?)", .within.as_millis())]
    NoAnswer {
        slio: SlioId,
        what: String,
        within: Duration,
    },
    #[error(transparent)]
    Bus(#[from] BusError),
}

/// SLIOs on a bus, seen from a host.
pub struct SlioHost<'a> {
    bus: &'a mut (dyn CanBus + Send),
    master: Master,
    epoch: Instant,
    /// Everything learned, in order.
    events: Vec<MasterEvent>,
}

impl<'a> SlioHost<'a> {
    /// A host for a bus at `bitrate`; with `calibrate`, the 48 start-up calibration frames are
    /// sent first. Periodic calibration runs while the host is used.
    pub fn new(bus: &'a mut (dyn CanBus + Send), bitrate: u32, calibrate: bool) -> Self {
        let master = if calibrate {
            Master::new(bitrate, 0)
        } else {
            Master::keeping(bitrate, 0)
        };
        Self {
            bus,
            master,
            epoch: Instant::now(),
            events: Vec::new(),
        }
    }

    fn now(&self) -> u64 {
        self.epoch.elapsed().as_nanos() as u64
    }

    /// The master (inventory, known registers).
    pub fn master(&self) -> &Master {
        &self.master
    }

    /// Everything learned so far (and forgets it).
    pub fn take_events(&mut self) -> Vec<MasterEvent> {
        std::mem::take(&mut self.events)
    }

    /// Moves frames both ways until `until`, or until `done` holds for an event.
    pub fn run(
        &mut self,
        until: Instant,
        mut done: impl FnMut(&MasterEvent) -> bool,
    ) -> Result<bool, BusError> {
        loop {
            let now = self.now();
            self.master.handle_timeout(now);
            while let Some(t) = self.master.poll_transmit() {
                self.transmit(t)?;
            }
            let mut finished = false;
            while let Some(e) = self.master.poll_event() {
                finished |= done(&e);
                self.events.push(e);
            }
            if finished {
                return Ok(true);
            }
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(false);
            }
            let next = self
                .master
                .next_deadline()
                .map(|d| Duration::from_nanos(d.saturating_sub(self.now())));
            let wait = next.map_or(left, |n| n.min(left));
            match self
                .bus
                .recv_event(Some(wait.max(Duration::from_micros(100))))?
            {
                Some(BusEvent::Frame(m)) => {
                    self.master.handle_frame(self.now(), &m.frame);
                }
                Some(BusEvent::Error(_)) | None => {}
            }
        }
    }

    fn transmit(&mut self, t: Transmit) -> Result<(), BusError> {
        self.bus.send(&t.frame)?;
        if t.single_shot
            && let Some(admin) = self.bus.admin()
        {
            match admin.flush(SINGLE_SHOT_WAIT) {
                Ok(_) => {}
                Err(BusError::Timeout { .. }) => admin.abort()?,
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    /// How long a request waits for its answer.
    pub fn set_answer_within(&mut self, wait: Duration) {
        self.master
            .set_answer_within(wait.as_nanos().min(u64::MAX as u128) as u64);
    }

    /// Sends the start-up calibration (if the host was made to calibrate) and listens until
    /// the sign-ons are in: all 48 frames sent, then as long as 16 SLIOs take to sign on (a
    /// few frames each at the bus's bit rate, generously), at least 100 ms.
    pub fn settle(&mut self, bitrate: u32) -> Result<Vec<(SlioId, u16)>, BusError> {
        let sign_ons = Duration::from_secs_f64(16.0 * 80.0 * 4.0 / f64::from(bitrate.max(1)));
        self.listen(sign_ons.max(Duration::from_millis(100)))
    }

    /// Runs for `wait` and returns the SLIOs that signed on or answered meanwhile.
    pub fn listen(&mut self, wait: Duration) -> Result<Vec<(SlioId, u16)>, BusError> {
        self.run(Instant::now() + wait, |_| false)?;
        Ok(self
            .events
            .iter()
            .filter_map(|e| match e {
                MasterEvent::Present { slio, inputs } => Some((*slio, *inputs)),
                _ => None,
            })
            .collect())
    }

    /// Asks every SLIO number for its inputs; those that answer within `wait` are on the bus.
    pub fn scan(&mut self, wait: Duration) -> Result<Vec<(SlioId, u16)>, BusError> {
        let now = self.now();
        let asked: Vec<RequestId> = SlioId::all()
            .map(|s| self.master.read(now, s, Register::DataInput))
            .collect();
        let mut answered = Vec::new();
        let mut outstanding = asked.len();
        self.run(Instant::now() + wait, |e| {
            match e {
                MasterEvent::Confirmed {
                    slio,
                    value,
                    request,
                    ..
                } if asked.contains(request) => {
                    answered.push((*slio, *value));
                    outstanding -= 1;
                }
                MasterEvent::NoAnswer { request, .. } if asked.contains(request) => {
                    outstanding -= 1
                }
                _ => {}
            }
            outstanding == 0
        })?;
        answered.sort();
        Ok(answered)
    }

    /// Writes a register and returns the content the SLIO confirmed (for a conversion
    /// request, the ADC result).
    pub fn write(
        &mut self,
        slio: SlioId,
        register: Register,
        value: u16,
        wait: Duration,
    ) -> Result<u16, SlioError> {
        let request = self.master.write(self.now(), slio, register, value);
        self.answer(slio, request, format!("{register} := 0x{value:04X}"), wait)
    }

    /// Reads a register (ADC: converts again).
    pub fn read(
        &mut self,
        slio: SlioId,
        register: Register,
        wait: Duration,
    ) -> Result<u16, SlioError> {
        let request = self.master.read(self.now(), slio, register);
        self.answer(slio, request, format!("reading {register}"), wait)
    }

    fn answer(
        &mut self,
        slio: SlioId,
        request: RequestId,
        what: String,
        wait: Duration,
    ) -> Result<u16, SlioError> {
        let mut got = None;
        self.run(Instant::now() + wait, |e| match e {
            MasterEvent::Confirmed {
                request: r, value, ..
            } if *r == request => {
                got = Some(*value);
                true
            }
            MasterEvent::NoAnswer { request: r, .. } => *r == request,
            _ => false,
        })?;
        got.ok_or(SlioError::NoAnswer {
            slio,
            what,
            within: wait,
        })
    }
}
