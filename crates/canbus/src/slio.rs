//! SLIOs from any bus (CANAPI's `SlIo` class, finished): [`buslab_slio::Master`] driven over
//! a [`CanBus`] with the wall clock.
//!
//! Single-shot transmissions (the start-up calibration frames, which nobody acknowledges
//! before the SLIOs are calibrated) are tried once, as the seed's `calibration_slio` does: on a
//! buslab bus a frame is aborted once it has been on the wire without an acknowledgement
//! ([`send_single_shot`]); on other backends it is simply sent and the adapter retries it
//! until a SLIO calibrates on the repetitions and acknowledges.
//!
//! Every window this host listens in opens once the frames it waits for are out: a request's
//! answer is awaited from the moment its frame is handed over ([`Master::poll_transmit`]), and
//! the sign-ons after the start-up calibration from the moment the bus confirmed the last
//! calibration frame ([`SlioHost::settle`]).

use std::time::{Duration, Instant};

use buslab_can::{Frame, Nanos};
use buslab_slio::slio::LONGEST_FRAME;
use buslab_slio::{Master, MasterEvent, NotReadable, Register, RequestId, SlioId, Transmit};

use crate::bus::{BusError, CanBus, Message, Record};

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
    NotReadable(#[from] NotReadable),
    #[error(transparent)]
    Bus(#[from] BusError),
}

/// How a frame meant to be tried once ended ([`send_single_shot`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SingleShot {
    /// Transmitted and acknowledged.
    Sent,
    /// On the wire without an acknowledgement, then given up (the seed's CMR.AT).
    Aborted,
    /// It never reached the wire within the allowance (a bus that never let it start): given
    /// up unsent.
    NotTried,
    /// Handed to a bus that can neither confirm nor abort (its adapter retries it until
    /// somebody acknowledges).
    HandedOver,
}

/// How long one look at a single-shot frame lasts: its attempt, the error frame after it
/// and a frame ahead of it, twice over.
fn attempt_time(bitrate: u32) -> Duration {
    (LONGEST_FRAME * 4).at_bitrate(bitrate).as_duration()
}

/// Sends `frame` to be tried once, as the seed's `calibration_slio` does (TR, wait until the
/// chip transmits, AT). On a bus with an administration side (a buslab bus) it returns once
/// the bus confirms it is done with the frame: acknowledged, or aborted after an attempt
/// nobody acknowledged (the node reported a bus error since it was handed over), or aborted
/// unsent after `within`. Other buses just take it.
pub fn send_single_shot<B: CanBus + ?Sized>(
    bus: &mut B,
    frame: &Frame,
    bitrate: u32,
    within: Duration,
) -> Result<SingleShot, BusError> {
    let errors_before = match bus.admin() {
        Some(admin) => admin.node_status(None)?.counters.bus_errors,
        None => {
            bus.send(frame)?;
            return Ok(SingleShot::HandedOver);
        }
    };
    bus.send(frame)?;
    let Some(admin) = bus.admin() else {
        return Ok(SingleShot::HandedOver);
    };
    let give_up = Instant::now() + within;
    loop {
        match admin.flush(attempt_time(bitrate)) {
            Ok(_) => return Ok(SingleShot::Sent),
            Err(BusError::Timeout { .. }) => {}
            Err(e) => return Err(e),
        }
        let tried = admin.node_status(None)?.counters.bus_errors > errors_before;
        if tried || Instant::now() >= give_up {
            admin.abort()?;
            // An attempt on the wire finishes: done once the bus says so.
            admin.flush(within)?;
            return Ok(if tried {
                SingleShot::Aborted
            } else {
                SingleShot::NotTried
            });
        }
    }
}

/// SLIOs on a bus, seen from a host.
pub struct SlioHost<'a> {
    bus: &'a mut (dyn CanBus + Send),
    master: Master,
    bitrate: u32,
    epoch: Instant,
    /// How long a request waits for its answer, and a frame for the bus's confirmations.
    wait: Duration,
    /// Everything learned, in order.
    events: Vec<MasterEvent>,
}

impl<'a> SlioHost<'a> {
    /// A host for a bus at `bitrate`; with `calibrate`, the 48 start-up calibration frames are
    /// sent first. Periodic calibration runs while the host is used.
    pub fn new(bus: &'a mut (dyn CanBus + Send), bitrate: u32, calibrate: bool) -> Self {
        let master = if calibrate {
            Master::new(bitrate, Nanos::ZERO)
        } else {
            Master::keeping(bitrate, Nanos::ZERO)
        };
        let wait = buslab_slio::master::ANSWER_WITHIN
            .at_bitrate(bitrate)
            .as_duration();
        Self {
            bus,
            master,
            bitrate,
            epoch: Instant::now(),
            wait,
            events: Vec::new(),
        }
    }

    fn now(&self) -> Nanos {
        Nanos::from_duration(self.epoch.elapsed())
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
        done: impl FnMut(&MasterEvent) -> bool,
    ) -> Result<bool, BusError> {
        let until = Nanos::from_duration(until.saturating_duration_since(self.epoch));
        self.pump(Some(until), done)
    }

    /// Moves frames both ways until `done` holds for an event, or until `until` (on the
    /// host's clock) if given. At `until` it returns before the timers that fall due then
    /// (the periodic calibration is left for the next call).
    fn pump(
        &mut self,
        until: Option<Nanos>,
        mut done: impl FnMut(&MasterEvent) -> bool,
    ) -> Result<bool, BusError> {
        loop {
            let now = self.now();
            if until.is_some_and(|u| now >= u) {
                return Ok(false);
            }
            self.master.handle_timeout(now);
            self.transmit_queued()?;
            if self.take_master_events(&mut done) {
                return Ok(true);
            }
            let now = self.now();
            let wait = [self.master.next_deadline(), until]
                .into_iter()
                .flatten()
                .min()
                .map_or(self.wait, |t| t.saturating_sub(now).as_duration());
            if let Some(event) = self
                .bus
                .recv_event(Some(wait.max(Duration::from_micros(100))))?
            {
                self.handle(event);
            }
        }
    }

    fn handle(&mut self, event: Message) {
        if let Record::Frame(frame) = event.record {
            self.master.handle_frame(self.now(), &frame);
        }
    }

    /// Moves the master's events into the record; whether `done` held for one.
    fn take_master_events(&mut self, done: &mut impl FnMut(&MasterEvent) -> bool) -> bool {
        let mut finished = false;
        while let Some(e) = self.master.poll_event() {
            if let MasterEvent::CalibrationLost { silent } = e {
                // The first start-up frame, tried once, also gives up what the bus still
                // retries for this host ([`send_single_shot`] aborts after its attempt).
                tracing::warn!(
                    "this host did not run for {} ms, near the SLIOs' watchdog: calibrating them again",
                    silent.as_duration().as_millis()
                );
            }
            finished |= done(&e);
            self.events.push(e);
        }
        finished
    }

    /// Hands the master's frames to the bus, each at the time it goes. After single-shot
    /// frames (the start-up calibration, each confirmed done before the next) the periodic
    /// calibration restarts from the last of them.
    fn transmit_queued(&mut self) -> Result<(), BusError> {
        let mut start_up = false;
        while let Some(t) = self.master.poll_transmit(self.now()) {
            self.transmit(t)?;
            start_up |= t.single_shot;
        }
        if start_up {
            self.master.start_up_sent(self.now());
        }
        Ok(())
    }

    fn transmit(&mut self, t: Transmit) -> Result<(), BusError> {
        if t.single_shot {
            send_single_shot(self.bus, &t.frame, self.bitrate, self.wait)?;
            Ok(())
        } else {
            self.bus.send(&t.frame)
        }
    }

    /// How long a request waits for its answer (and how long the bus may take to confirm a
    /// frame); default [`ANSWER_WITHIN`](buslab_slio::master::ANSWER_WITHIN).
    pub fn set_answer_within(&mut self, wait: Duration) {
        self.wait = wait;
        self.master.set_answer_within(Nanos::from_duration(wait));
    }

    /// The census after a start-up calibration: sends the calibration frames queued (the 48 if
    /// the host was made to calibrate), each confirmed done by the bus, then listens from the
    /// last of them on for one calibration period (5000 bit-times: 16 sign-ons take at most
    /// 2560), and until the bus confirms it ran that far and delivered every frame before
    /// (a flush, on a buslab bus). Returns the SLIOs that signed on or answered meanwhile.
    pub fn settle(&mut self) -> Result<Vec<(SlioId, u16)>, BusError> {
        self.transmit_queued()?;
        // The periodic calibration is due one period after the last start-up frame: the
        // window ends there, before it goes.
        let end = self
            .master
            .next_calibration()
            .unwrap_or_else(|| self.now() + self.master.calibration_period());
        let mut heard = [false; 16];
        for (slio, _) in self.present() {
            heard[slio.number() as usize] = true;
        }
        self.pump(Some(end), |e| {
            if let MasterEvent::Present { slio, .. } = e {
                heard[slio.number() as usize] = true;
            }
            heard.iter().all(|&h| h)
        })?;
        self.sync()?;
        Ok(self.present())
    }

    /// The SLIOs that signed on or answered so far, each once in the order they first did,
    /// with the inputs of their last sign-on (a SLIO that lost its calibration in between
    /// signs on again).
    fn present(&self) -> Vec<(SlioId, u16)> {
        let mut present: Vec<(SlioId, u16)> = Vec::new();
        for e in &self.events {
            let MasterEvent::Present { slio, inputs } = *e else {
                continue;
            };
            match present.iter_mut().find(|(s, _)| *s == slio) {
                Some(entry) => entry.1 = inputs,
                None => present.push((slio, inputs)),
            }
        }
        present
    }

    /// Waits until the bus confirms that every frame sent so far is done and every frame
    /// before that moment was delivered (a buslab bus answers a flush after catching up with
    /// the clock and delivering), then takes in what arrived. Other buses: what arrived.
    fn sync(&mut self) -> Result<(), BusError> {
        if let Some(admin) = self.bus.admin() {
            match admin.flush(self.wait) {
                Ok(_) => {}
                // Nobody acknowledges a frame of ours (no SLIO, no other node): give it up, the
                // bus then confirms.
                Err(BusError::Timeout { .. }) => {
                    admin.abort()?;
                    admin.flush(self.wait)?;
                }
                Err(e) => return Err(e),
            }
        }
        while let Some(event) = self.bus.recv_event(Some(Duration::ZERO))? {
            self.handle(event);
        }
        self.take_master_events(&mut |_| false);
        Ok(())
    }

    /// Runs for `wait` and returns the SLIOs that signed on or answered meanwhile.
    pub fn listen(&mut self, wait: Duration) -> Result<Vec<(SlioId, u16)>, BusError> {
        self.transmit_queued()?;
        let end = self.now().saturating_add(Nanos::from_duration(wait));
        self.pump(Some(end), |_| false)?;
        Ok(self.present())
    }

    /// Asks every SLIO number for its inputs; those that answer within `wait` of their
    /// request's going out are on the bus.
    pub fn scan(&mut self, wait: Duration) -> Result<Vec<(SlioId, u16)>, BusError> {
        self.set_answer_within(wait);
        let mut asked = Vec::new();
        for slio in SlioId::all() {
            // DATA_INPUT is read-only: it always has a read.
            if let Ok(request) = self.master.read(slio, Register::DataInput) {
                asked.push(request);
            }
        }
        let mut answered = Vec::new();
        let mut outstanding = asked.len();
        // Every request ends in an answer or in NoAnswer `wait` after it went out.
        self.pump(None, |e| {
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
        self.set_answer_within(wait);
        let request = self.master.write(slio, register, value);
        self.answer(slio, request, format!("{register} := 0x{value:04X}"), wait)
    }

    /// Reads a read-only register (DATA_INPUT; ADC: converts again); a writable one has no
    /// read ([`NotReadable`]).
    pub fn read(
        &mut self,
        slio: SlioId,
        register: Register,
        wait: Duration,
    ) -> Result<u16, SlioError> {
        self.set_answer_within(wait);
        let request = self.master.read(slio, register)?;
        self.answer(slio, request, format!("reading {register}"), wait)
    }

    /// Waits for the answer to `request`: the master gives it up `wait` after its frame went
    /// out.
    fn answer(
        &mut self,
        slio: SlioId,
        request: RequestId,
        what: String,
        wait: Duration,
    ) -> Result<u16, SlioError> {
        let mut got = None;
        self.pump(None, |e| match e {
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
