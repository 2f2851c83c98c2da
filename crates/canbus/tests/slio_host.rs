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
use buslab_slio::{SlioId, calibration_frame};

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
    fn recv(&mut self, _timeout: Option<Duration>) -> Result<Option<Message>, BusError> {
        Ok(self
            .inbox
            .pop_front()
            .map(|f| Message::rx(0.0, "scripted", f)))
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

impl BusAdmin for ScriptedBus {
    fn nodes(&mut self) -> Result<Vec<NodeInfo>, BusError> {
        Ok(Vec::new())
    }
    fn node_status(&mut self, _: Option<&NodeRef>) -> Result<NodeStatus, BusError> {
        Ok(NodeStatus {
            number: 1,
            name: "host".into(),
            state: ErrorState::Active,
            errors: None,
            sr: None,
            timing: None,
            counters: NodeCounters {
                bus_errors: self.bus_errors,
                ..NodeCounters::default()
            },
            tx_queued: u64::from(self.pending.is_some()),
            bus: BusSummary {
                bitrate: RATE,
                ..BusSummary::default()
            },
        })
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
