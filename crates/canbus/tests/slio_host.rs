//! `SlioHost` and `send_single_shot` against a scripted bus with an administration side, as a
//! buslab bus behaves: a frame handed over is done (acknowledged or given up) when a flush
//! says so, frames that happened before are delivered before the flush's answer, and the
//! node's bus-error counter shows an attempt nobody acknowledged.

use std::collections::VecDeque;
use std::time::Duration;

use buslab_can::Frame;
use buslab_canbus::slio::{SingleShot, SlioHost, send_single_shot};
use buslab_canbus::{
    BusAdmin, BusError, BusSummary, CanBus, ErrorState, Filter, Message, NodeCounters, NodeInfo,
    NodeRef, NodeRegisters, NodeStatus, TxReport,
};
use buslab_slio::{
    Direction, MasterEvent, Register, Reply, Request, SlioId, Status, calibration_frame,
};

const RATE: u32 = 125_000;

/// A bus with SLIOs that calibrate on the n-th calibration frame on the wire.
#[derive(Default)]
struct ScriptedBus {
    /// (number, inputs, the calibration frame on which it calibrates, counting from 1).
    slios: Vec<(u8, u16, usize)>,
    /// The frame handed over and not done yet.
    pending: Option<Frame>,
    /// Calibration frames that were on the wire.
    calibrations: usize,
    /// Frames that happened and wait for delivery with the next flush's answer.
    on_wire: Vec<Frame>,
    inbox: VecDeque<Frame>,
    bus_errors: u64,
    /// Frames handed over, in order.
    sent: Vec<Frame>,
    aborts: usize,
    /// The wire never lets a frame start (a bus held by others).
    blocked: bool,
}

impl ScriptedBus {
    fn calibrated(&self) -> bool {
        self.slios.iter().any(|s| s.2 <= self.calibrations)
    }

    /// The pending frame's next attempt, if the wire lets it start.
    fn attempt(&mut self) -> bool {
        let Some(frame) = self.pending else {
            return true;
        };
        if self.blocked {
            return false;
        }
        if frame == calibration_frame() {
            let acknowledged = self.calibrated();
            self.calibrations += 1;
            // Those that calibrate on this frame sign on after it.
            for &(n, inputs, on) in &self.slios {
                if on == self.calibrations {
                    let id = SlioId::new(n).unwrap().reply_id();
                    let [hi, lo] = inputs.to_be_bytes();
                    self.on_wire.push(Frame::data(id, &[0x30, hi, lo]).unwrap());
                }
            }
            if !acknowledged {
                self.bus_errors += 1;
                return false;
            }
        }
        self.pending = None;
        true
    }
}

impl CanBus for ScriptedBus {
    fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
        assert!(self.pending.is_none(), "one frame at a time");
        self.pending = Some(*frame);
        self.sent.push(*frame);
        Ok(())
    }
    fn recv(&mut self, _timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
        Ok(self
            .inbox
            .pop_front()
            .map(|f| Message::rx(buslab_can::Timestamp::EPOCH, "scripted", f)))
    }
    fn set_filters(&mut self, _: &[Filter]) -> Result<(), BusError> {
        Ok(())
    }
    fn state(&mut self) -> Result<ErrorState, BusError> {
        Ok(ErrorState::Active)
    }
    fn channel_info(&self) -> String {
        "scripted".into()
    }
    fn admin(&mut self) -> Option<&mut dyn BusAdmin> {
        Some(self)
    }
}

/// This host's node as the fake buses report it: its bus errors and queued frames.
fn host_status(bus_errors: u64, tx_queued: u64) -> NodeStatus {
    NodeStatus {
        number: 1,
        name: "host".into(),
        state: ErrorState::Active,
        errors: None,
        sr: None,
        timing: None,
        counters: NodeCounters {
            bus_errors,
            ..NodeCounters::default()
        },
        tx_queued,
        bus: BusSummary {
            bitrate: RATE,
            ..BusSummary::default()
        },
    }
}

impl BusAdmin for ScriptedBus {
    fn nodes(&mut self) -> Result<Vec<NodeInfo>, BusError> {
        Ok(Vec::new())
    }
    fn node_status(&mut self, _: Option<&NodeRef>) -> Result<NodeStatus, BusError> {
        Ok(host_status(
            self.bus_errors,
            u64::from(self.pending.is_some()),
        ))
    }
    fn register_dump(&mut self, _: Option<&NodeRef>) -> Result<NodeRegisters, BusError> {
        Err(BusError::Other("no registers".into()))
    }
    fn set_name(&mut self, _: &str) -> Result<(), BusError> {
        Ok(())
    }
    fn set_btr(&mut self, _: u8, _: u8) -> Result<(), BusError> {
        Ok(())
    }
    /// What happened on the wire since the last flush is delivered, then the pending frame
    /// has an attempt (what follows it on the wire comes with the next flush).
    fn flush(&mut self, timeout: Duration) -> Result<TxReport, BusError> {
        self.inbox.extend(self.on_wire.drain(..));
        let done = self.attempt();
        if done {
            Ok(TxReport::default())
        } else {
            Err(BusError::Timeout {
                what: "flush".into(),
                after: timeout,
            })
        }
    }
    fn abort(&mut self) -> Result<(), BusError> {
        self.aborts += 1;
        self.pending = None;
        Ok(())
    }
}

#[test]
fn a_frame_nobody_acknowledges_is_aborted_after_its_attempt() {
    let mut bus = ScriptedBus {
        slios: vec![(3, 0x0003, 3)],
        ..ScriptedBus::default()
    };
    let within = Duration::from_secs(60);
    // The first three: an attempt each, no acknowledgement (the SLIO calibrates on the
    // third), aborted; then acknowledged.
    for _ in 0..3 {
        let got = send_single_shot(&mut bus, &calibration_frame(), RATE, within).unwrap();
        assert_eq!(got, SingleShot::Aborted);
    }
    assert_eq!((bus.calibrations, bus.aborts), (3, 3));
    let got = send_single_shot(&mut bus, &calibration_frame(), RATE, within).unwrap();
    assert_eq!(got, SingleShot::Sent);
    assert_eq!((bus.calibrations, bus.aborts), (4, 3));
}

#[test]
fn a_frame_that_never_reaches_the_wire_is_given_up_unsent() {
    let mut bus = ScriptedBus {
        blocked: true,
        ..ScriptedBus::default()
    };
    let got = send_single_shot(&mut bus, &calibration_frame(), RATE, Duration::ZERO).unwrap();
    assert_eq!(got, SingleShot::NotTried);
    assert_eq!((bus.calibrations, bus.aborts), (0, 1));
    assert!(bus.pending.is_none());
}

/// Issue 25: the census listened in a window opened before the 48 calibration frames were
/// sent, and returned without reading the sign-ons received meanwhile. Now it reads them all,
/// and one that follows the last calibration frame on the wire, which the bus delivers only
/// with its answer to the flush that closes the window, counts too; a SLIO that signed on
/// twice is listed once, with its last inputs.
#[test]
fn the_census_counts_every_sign_on_up_to_the_bus_confirmation_after_the_last_frame() {
    let mut bus = ScriptedBus {
        slios: vec![(0, 0x0000, 3), (0, 0x0001, 10), (3, 0x0003, 48)],
        ..ScriptedBus::default()
    };
    let mut host = SlioHost::new(&mut bus, RATE, true);
    host.set_answer_within(Duration::from_secs(60));
    let signed = host.settle().unwrap();
    assert_eq!(
        signed,
        [
            (SlioId::new(0).unwrap(), 0x0001),
            (SlioId::new(3).unwrap(), 0x0003)
        ]
    );
    drop(host);
    // The 48 start-up frames, each tried once until SLIO 0 acknowledged; nothing else yet
    // (the periodic calibration is due when the window closes, and goes with the next call).
    assert_eq!(bus.calibrations, 48);
    assert_eq!(bus.aborts, 3);
    assert_eq!(bus.sent.len(), 48);
}

/// One SLIO on a bus that runs in wall-clock time, as a served buslab bus does: it calibrates
/// on the second calibration frame it sees (the first counts as the valid frame before it),
/// loses its calibration when no calibration frame came within its watchdog, executes a
/// command while it is not calibrated but answers only once calibrated. The wire runs when the
/// host looks (a receive or a flush); a frame nobody acknowledges stays at the head of the
/// queue and is tried again, holding up the frames behind it.
struct WatchdogBus {
    slio: SlioId,
    /// Another node (a `buslab dump` beside) acknowledges every frame.
    others_acknowledge: bool,
    /// The host stops running this long right after handing over its first request.
    stall_after_request: Option<Duration>,
    calibrated: bool,
    /// Calibration frames seen since it lost its calibration.
    seen: u32,
    last_calibration: std::time::Instant,
    output: u16,
    queue: VecDeque<Frame>,
    inbox: VecDeque<Frame>,
    bus_errors: u64,
}

/// 8192 bit-times at [`RATE`].
const WATCHDOG: Duration = Duration::from_micros(8192 * 8);

impl WatchdogBus {
    fn new(others_acknowledge: bool, stall_after_request: Option<Duration>) -> Self {
        Self {
            slio: SlioId::new(3).unwrap(),
            others_acknowledge,
            stall_after_request,
            calibrated: false,
            seen: 0,
            last_calibration: std::time::Instant::now(),
            output: 0,
            queue: VecDeque::new(),
            inbox: VecDeque::new(),
            bus_errors: 0,
        }
    }

    fn reply(&mut self, register: Register, value: u16, reset_detected: bool) {
        let reply = Reply {
            status: Status {
                reset_detected,
                ew: true,
                bus_mode: 0,
            },
            register,
            value,
        };
        let frame = Frame::data(self.slio.reply_id(), &reply.encode()).unwrap();
        self.inbox.push_back(frame);
    }

    /// The frames at the head of the queue have their attempt.
    fn run_wire(&mut self) {
        if self.calibrated && self.last_calibration.elapsed() > WATCHDOG {
            self.calibrated = false;
            self.seen = 0;
            self.output = 0;
        }
        while let Some(&frame) = self.queue.front() {
            let was_calibrated = self.calibrated;
            if frame == calibration_frame() {
                self.seen += 1;
                self.last_calibration = std::time::Instant::now();
                if !self.calibrated && self.seen >= 2 {
                    self.calibrated = true;
                    self.reply(Register::DataInput, 0x0003, true);
                }
            } else if SlioId::from_id(frame.id()) == Some((self.slio, Direction::ToSlio))
                && let Ok(Request::Write {
                    register: Register::DataOutput,
                    value,
                }) = Request::parse(frame.is_remote(), frame.payload())
            {
                self.output = value;
                if was_calibrated {
                    self.reply(Register::DataOutput, value, false);
                }
            }
            if !(was_calibrated || self.others_acknowledge) {
                self.bus_errors += 1;
                return;
            }
            self.queue.pop_front();
        }
    }
}

impl CanBus for WatchdogBus {
    fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
        self.queue.push_back(*frame);
        if frame != &calibration_frame()
            && let Some(stall) = self.stall_after_request.take()
        {
            std::thread::sleep(stall);
        }
        Ok(())
    }
    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
        self.run_wire();
        if let Some(frame) = self.inbox.pop_front() {
            return Ok(Some(Message::rx(
                buslab_can::Timestamp::EPOCH,
                "watchdog",
                frame,
            )));
        }
        std::thread::sleep(
            timeout
                .unwrap_or(Duration::MAX)
                .min(Duration::from_micros(200)),
        );
        Ok(None)
    }
    fn set_filters(&mut self, _: &[Filter]) -> Result<(), BusError> {
        Ok(())
    }
    fn state(&mut self) -> Result<ErrorState, BusError> {
        Ok(ErrorState::Active)
    }
    fn channel_info(&self) -> String {
        "watchdog".into()
    }
    fn admin(&mut self) -> Option<&mut dyn BusAdmin> {
        Some(self)
    }
}

impl BusAdmin for WatchdogBus {
    fn nodes(&mut self) -> Result<Vec<NodeInfo>, BusError> {
        Ok(Vec::new())
    }
    fn node_status(&mut self, _: Option<&NodeRef>) -> Result<NodeStatus, BusError> {
        Ok(host_status(self.bus_errors, self.queue.len() as u64))
    }
    fn register_dump(&mut self, _: Option<&NodeRef>) -> Result<NodeRegisters, BusError> {
        Err(BusError::Other("no registers".into()))
    }
    fn set_name(&mut self, _: &str) -> Result<(), BusError> {
        Ok(())
    }
    fn set_btr(&mut self, _: u8, _: u8) -> Result<(), BusError> {
        Ok(())
    }
    fn flush(&mut self, timeout: Duration) -> Result<TxReport, BusError> {
        self.run_wire();
        if self.queue.is_empty() {
            Ok(TxReport::default())
        } else {
            Err(BusError::Timeout {
                what: "flush".into(),
                after: timeout,
            })
        }
    }
    fn abort(&mut self) -> Result<(), BusError> {
        self.queue.clear();
        Ok(())
    }
}

/// CI, 2026-11-28 (`slio_cli calibrate_then_drive_a_demo_board`): `buslab slio --calibrate
/// write` did not run for longer than the SLIOs' watchdog (a loaded machine); the SLIO lost
/// its calibration, executed the write without answering, and was calibrated again by the
/// next periodic frame; the write was never answered. Now the host calibrates again after such
/// a pause and repeats its request: whether it stopped before the request or right after
/// handing it over, and whether another node acknowledged the frame meanwhile or nobody did
/// (the frame then held up the calibration behind it).
#[test]
fn a_host_that_stopped_running_past_the_watchdog_still_gets_its_write_answered() {
    let stall = 3 * WATCHDOG;
    for others_acknowledge in [true, false] {
        for stall_after_request in [None, Some(stall)] {
            let case = format!(
                "others acknowledge: {others_acknowledge}, stall after the request: {stall_after_request:?}"
            );
            let mut bus = WatchdogBus::new(others_acknowledge, stall_after_request);
            let mut host = SlioHost::new(&mut bus, RATE, true);
            let signed = host.settle().unwrap();
            assert_eq!(signed, [(SlioId::new(3).unwrap(), 0x0003)], "{case}");
            if stall_after_request.is_none() {
                std::thread::sleep(stall);
            }
            let got = host
                .write(
                    SlioId::new(3).unwrap(),
                    Register::DataOutput,
                    0x2080,
                    Duration::from_secs(60),
                )
                .unwrap_or_else(|e| panic!("{case}: {e}"));
            assert_eq!(got, 0x2080, "{case}");
            let lost = host
                .take_events()
                .into_iter()
                .filter(|e| matches!(e, MasterEvent::CalibrationLost { .. }))
                .count();
            assert!(lost >= 1, "{case}: the pause went unnoticed");
            drop(host);
            assert_eq!(bus.output, 0x2080, "{case}");
        }
    }
}
