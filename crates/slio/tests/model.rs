//! The P82C150 model on the one bus engine, bit by bit, against a host controller doing what
//! the seed's `slio.s` does.

use buslab_can::controller::{ControllerConfig, ErrorKind, Event};
use buslab_can::{BitTime, Frame};
use buslab_sim::{Happening, Simulation};
use buslab_slio::board::{CONVERT_ADC1, CONVERT_ADC2, OUTPUT_ENABLE, volts_to_code};
use buslab_slio::slio::WATCHDOG;
use buslab_slio::{
    Calibration, DemoBoard, ModeChangeCause, Register, Reply, Request, Slio, SlioId, SlioNotice,
    calibration_frame,
};

const RATE: u32 = 125_000;

struct Bench {
    sim: Simulation,
    host: usize,
    boards: Vec<usize>,
}

fn id(n: u8) -> SlioId {
    SlioId::new(n).unwrap()
}

impl Bench {
    /// A host (a protocol controller, single-shot like the seed's aborted transmissions) and
    /// demo boards with these IDs; ADC1 reads 1.25 V, the potentiometer 3.75 V.
    fn new(ids: &[u8]) -> Self {
        let mut sim = Simulation::new(RATE, 1);
        let host = sim.add_node(
            "host",
            ControllerConfig {
                single_shot: true,
                ..ControllerConfig::default()
            },
        );
        let boards = ids
            .iter()
            .map(|&n| {
                let board = DemoBoard::new(id(n), RATE, Box::new(1.25), Box::new(3.75)).unwrap();
                sim.add_device(format!("slio{n:X}"), Box::new(board))
            })
            .collect();
        Self { sim, host, boards }
    }

    fn board(&self, i: usize) -> &DemoBoard {
        self.sim.node(self.boards[i]).get::<DemoBoard>().unwrap()
    }

    /// Sends a frame from the host and runs until its attempt is over.
    fn send(&mut self, frame: Frame) {
        self.sim.enqueue(self.host, frame).unwrap();
        let host = self.host;
        let limit = self.sim.now() + BitTime::new(20_000);
        while self.sim.node(host).device().pending() > 0 {
            assert!(self.sim.now() < limit, "the host's frame never ended");
            self.sim.run_for(BitTime::new(1));
        }
        // Let the answers come.
        self.sim.run_for(BitTime::new(500));
    }

    /// The seed's `calibration_slio`: 48 calibration frames, each given up after one attempt.
    fn calibrate(&mut self) {
        for _ in 0..48 {
            self.send(calibration_frame());
        }
    }

    /// Frames the host received since the start (or the last `take_records`).
    fn host_received(&mut self) -> Vec<Frame> {
        let host = self.host;
        self.sim
            .take_records()
            .into_iter()
            .filter_map(|r| match r.what {
                Happening::Node {
                    node,
                    event: Event::Received(f),
                } if node == host => Some(f),
                _ => None,
            })
            .collect()
    }

    fn write(&mut self, n: u8, register: Register, value: u16) {
        let data = Request::Write { register, value }.data().unwrap();
        self.send(Frame::data(id(n).command_id(), &data).unwrap());
    }
}

fn reply_of(frames: &[Frame], n: u8) -> Vec<Reply> {
    frames
        .iter()
        .filter(|f| f.id() == id(n).reply_id())
        .map(|f| Reply::parse(f.payload()).unwrap())
        .collect()
}

#[test]
fn calibration_no_ack_before_then_sign_on() {
    let mut b = Bench::new(&[3]);
    // Alone with the host, the SLIO does not acknowledge: the first calibration frames fail
    // with an ACK error and are given up (the seed aborts them for that reason).
    b.send(calibration_frame());
    let records = b.sim.take_records();
    assert!(
        records.iter().any(|r| matches!(
            r.what,
            Happening::Node {
                node: 0,
                event: Event::Error {
                    kind: ErrorKind::Ack,
                    ..
                }
            }
        )),
        "{records:?}"
    );
    assert!(records.iter().any(|r| matches!(
        r.what,
        Happening::Node {
            node: 0,
            event: Event::Dropped(_)
        }
    )));
    assert_eq!(b.board(0).slio().calibration(), Calibration::Rough);
    // One more valid frame, then a calibration frame: calibrated, and the sign-on comes.
    b.send(calibration_frame());
    assert_eq!(b.board(0).slio().calibration(), Calibration::Rough);
    b.send(calibration_frame());
    assert_eq!(b.board(0).slio().calibration(), Calibration::Calibrated);
    let got = b.host_received();
    let sign_on = reply_of(&got, 3);
    assert_eq!(sign_on.len(), 1, "{got:?}");
    assert_eq!(sign_on[0].register, Register::DataInput);
    assert!(
        sign_on[0].status.reset_detected,
        "RSTD is reported in the sign-on"
    );
    // Its ID switches are on P0..P3 while P13 does not select the inputs.
    assert_eq!(sign_on[0].value & 0xF, 3);
    // From now on the SLIO acknowledges: the next calibration frame is sent without error.
    b.send(calibration_frame());
    let after = b.sim.take_records();
    assert!(after.iter().any(|r| matches!(
        r.what,
        Happening::Node {
            node: 0,
            event: Event::Transmitted(_)
        }
    )));
    assert!(!after.iter().any(|r| matches!(
        r.what,
        Happening::Node {
            event: Event::Error { .. },
            ..
        }
    )));
}

#[test]
fn before_calibration_commands_are_executed_silently() {
    let mut b = Bench::new(&[1]);
    b.send(calibration_frame()); // rough
    b.write(1, Register::OutputEnable, OUTPUT_ENABLE);
    assert_eq!(
        b.board(0).slio().register(Register::OutputEnable),
        OUTPUT_ENABLE
    );
    assert!(
        reply_of(&b.host_received(), 1).is_empty(),
        "no reply before calibration"
    );
}

#[test]
fn every_write_is_answered_with_the_new_content() {
    let mut b = Bench::new(&[2]);
    b.calibrate();
    b.host_received();
    for (register, value, reads_back) in [
        (Register::OutputEnable, OUTPUT_ENABLE, OUTPUT_ENABLE),
        (Register::DataOutput, 0x2080, 0x2080),
        (Register::PositiveEdge, 0x000F, 0x000F),
        (Register::NegativeEdge, 0x0003, 0x0003),
        (Register::Dpm1, 0x0200, 0x0200),
        // DPM registers hold 10 bits.
        (Register::Dpm2, 0xFFFF, 0x03FF),
        // DATA_INPUT is read-only: a write answers its content (P13 selects the input
        // switches, all open; P7 and P13 read back high; the DPM pins P10 and P4, at half
        // duty and more, read high).
        (Register::DataInput, 0x1234, 0x2490),
    ] {
        b.write(2, register, value);
        let replies = reply_of(&b.host_received(), 2);
        assert_eq!(replies.len(), 1, "{register}");
        assert_eq!(replies[0].register, register);
        assert_eq!(replies[0].value, reads_back, "{register}");
        assert!(!replies[0].status.reset_detected);
        assert!(replies[0].status.ew);
    }
    // LED on P7 lit, the others dark; DPM1 at 0x200/1024 of 5 V.
    assert_eq!(b.board(0).leds(), [true, false, false, false, false]);
    assert_eq!(b.board(0).dpm_volts()[0], Some(2.5));
}

#[test]
fn reads_remote_frames_and_extended_frames() {
    let mut b = Bench::new(&[4]);
    b.calibrate();
    b.host_received();
    // A 3-byte frame to DATA_INPUT reads it, its value bytes stored nowhere (the seed's
    // `make_slio_ffi` builds every frame with DLC 3).
    b.write(4, Register::OutputEnable, 0x0100);
    b.write(4, Register::DataOutput, 0x0100);
    b.host_received();
    b.send(
        Frame::data(
            id(4).command_id(),
            &[Register::DataInput.number(), 0xFF, 0xFF],
        )
        .unwrap(),
    );
    let r = reply_of(&b.host_received(), 4);
    assert_eq!(r.len(), 1);
    // P8 drives high and reads back; P0..P3 show the ID switches (P13 low).
    assert_eq!((r[0].register, r[0].value), (Register::DataInput, 0x0104));
    // A remote frame (to either of its identifiers, any DLC) reads DATA_INPUT.
    for (to, dlc) in [
        (id(4).command_id(), 3),
        (id(4).reply_id(), 3),
        (id(4).command_id(), 0),
    ] {
        b.send(Frame::remote(to, dlc).unwrap());
        let r = reply_of(&b.host_received(), 4);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].register, Register::DataInput);
    }
    // CAN 2.0B passive: an extended frame is ignored without an error.
    let ext = Frame::data(
        buslab_can::Id::extended(id(4).command_id().as_raw()).unwrap(),
        &[3, 0xFF, 0xFF],
    )
    .unwrap();
    b.send(ext);
    let records = b.sim.take_records();
    assert!(!records.iter().any(|r| matches!(
        r.what,
        Happening::Node {
            event: Event::Error { .. },
            ..
        }
    )));
    assert_eq!(b.board(0).slio().register(Register::DataOutput), 0x0100);
    // Garbage (2 bytes, register 9) is ignored: no reply.
    b.send(Frame::data(id(4).command_id(), &[3, 1]).unwrap());
    b.send(Frame::data(id(4).command_id(), &[9, 1, 2]).unwrap());
    assert!(reply_of(&b.host_received(), 4).is_empty());
}

/// Issue 25: MoniCAN's `3I0`, its start-up read and `buslab slio read` sent `29C#00`, and the
/// model answered it, so nothing on the bench showed that a P82C150, whose frames "ont
/// toujours 3 octets (sauf les remote frame bien sûr)" (seed §2.1.2.1), may not. A data frame
/// of any other length is no command: acknowledged (a correct CAN frame), neither executed
/// nor answered.
#[test]
fn a_one_byte_read_frame_is_not_answered() {
    let mut b = Bench::new(&[3]);
    b.calibrate();
    b.write(3, Register::OutputEnable, OUTPUT_ENABLE);
    b.write(3, Register::DataOutput, 0x2080);
    b.host_received();
    b.sim.take_records();
    for data in [
        &[Register::DataInput.number()][..],
        &[Register::OutputEnable.number()],
        &[Register::Adc.number()],
        &[],
        &[Register::DataOutput.number(), 0x00],
        &[Register::DataOutput.number(), 0x00, 0x00, 0x00],
        &[Register::DataOutput.number(), 0, 0, 0, 0, 0, 0, 0],
    ] {
        b.send(Frame::data(id(3).command_id(), data).unwrap());
        let records = b.sim.take_records();
        // Acknowledged: the host's single-shot attempt succeeded.
        assert!(
            records.iter().any(|r| matches!(
                r.what,
                Happening::Node {
                    node: 0,
                    event: Event::Transmitted(_)
                }
            )),
            "{data:02X?}: {records:?}"
        );
        let answers: Vec<_> = records
            .iter()
            .filter(|r| {
                matches!(&r.what, Happening::Node { node: 0, event: Event::Received(f) } if f.id() == id(3).reply_id())
            })
            .collect();
        assert!(answers.is_empty(), "{data:02X?} was answered: {answers:?}");
    }
    // Nothing was written either.
    assert_eq!(b.board(0).slio().register(Register::DataOutput), 0x2080);
    assert_eq!(
        b.board(0).slio().register(Register::OutputEnable),
        OUTPUT_ENABLE
    );
    // The 3-byte read that replaces it is answered.
    b.send(Frame::data(id(3).command_id(), &[Register::DataInput.number(), 0, 0]).unwrap());
    let r = reply_of(&b.host_received(), 3);
    assert_eq!(r.len(), 1);
    assert_eq!(r[0].register, Register::DataInput);
}

#[test]
fn adc_conversions_read_the_known_inputs() {
    let mut b = Bench::new(&[5]);
    b.calibrate();
    b.host_received();
    for (config, volts) in [(CONVERT_ADC1, 1.25), (CONVERT_ADC2, 3.75)] {
        b.write(5, Register::AnalogConfig, config);
        // The answer to a conversion request is the ADC register, the result.
        let r = reply_of(&b.host_received(), 5);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].register, Register::Adc);
        assert_eq!(r[0].value, volts_to_code(volts));
    }
    // Reading ADC (a 3-byte frame to it) converts again.
    b.send(Frame::data(id(5).command_id(), &[Register::Adc.number(), 0, 0]).unwrap());
    let r = reply_of(&b.host_received(), 5);
    assert_eq!(r[0].value, volts_to_code(3.75));
}

#[test]
fn input_edges_send_data_input_by_themselves() {
    let mut b = Bench::new(&[6]);
    b.calibrate();
    b.write(6, Register::OutputEnable, OUTPUT_ENABLE);
    b.write(6, Register::DataOutput, 0x2000); // select the input switches
    b.write(6, Register::PositiveEdge, 0x0001); // switch 0 rising
    b.host_received();
    let node = b.boards[0];
    let now = b.sim.now();
    b.sim
        .node_mut(node)
        .get_mut::<DemoBoard>()
        .unwrap()
        .set_switches(now, 0b0010); // switch 1: no edge register
    b.sim.run_for(BitTime::new(500));
    assert!(reply_of(&b.host_received(), 6).is_empty());
    let now = b.sim.now();
    b.sim
        .node_mut(node)
        .get_mut::<DemoBoard>()
        .unwrap()
        .set_switches(now, 0b0011);
    b.sim.run_for(BitTime::new(500));
    let r = reply_of(&b.host_received(), 6);
    assert_eq!(r.len(), 1);
    assert_eq!(
        (r[0].register, r[0].value & 0xF),
        (Register::DataInput, 0b0011)
    );
    // Falling edges need NEGATIVE_EDGE.
    let now = b.sim.now();
    b.sim
        .node_mut(node)
        .get_mut::<DemoBoard>()
        .unwrap()
        .set_switches(now, 0);
    b.sim.run_for(BitTime::new(500));
    assert!(reply_of(&b.host_received(), 6).is_empty());
}

#[test]
fn the_watchdog_trips_after_8192_bit_times_and_recalibration_recovers() {
    let mut b = Bench::new(&[7]);
    b.calibrate();
    b.write(7, Register::OutputEnable, OUTPUT_ENABLE);
    b.write(7, Register::DataOutput, 0x0080);
    assert!(b.board(0).leds()[0]);
    b.sim.take_records();
    // Nothing for a while: the watchdog counts from the last calibration frame.
    let node = b.boards[0];
    let start = b.sim.now();
    b.sim.run_for(WATCHDOG);
    let slio = b.sim.node(node).get::<DemoBoard>().unwrap().slio();
    assert_ne!(slio.calibration(), Calibration::Calibrated);
    // Registers cleared, outputs float, RSTD = 1, EW = 0, BM = 1; the ID is kept.
    assert_eq!(slio.register(Register::OutputEnable), 0);
    assert_eq!(b.board(0).leds(), [false; 5]);
    let status = b.board(0).slio().status();
    assert!(status.reset_detected && !status.ew);
    assert_eq!(status.bus_mode, 1);
    let _ = start;
    // The host's periodic calibration brings it back, with a new sign-on.
    b.calibrate();
    assert_eq!(b.board(0).slio().calibration(), Calibration::Calibrated);
    let sign_on = reply_of(&b.host_received(), 7);
    assert!(
        sign_on
            .iter()
            .any(|r| r.status.reset_detected && r.status.bus_mode == 1)
    );
    assert_eq!(b.board(0).id(), id(7));
}

#[test]
fn calibration_frames_every_few_thousand_bits_keep_it_calibrated() {
    let mut b = Bench::new(&[8]);
    b.calibrate();
    for _ in 0..10 {
        b.sim.run_for(BitTime::new(5000));
        b.send(calibration_frame());
    }
    assert_eq!(b.board(0).slio().calibration(), Calibration::Calibrated);
}

#[test]
fn sixteen_slios_each_answer_their_own_commands() {
    let ids: Vec<u8> = (0..16).collect();
    let mut b = Bench::new(&ids);
    b.calibrate();
    let got = b.host_received();
    for n in 0..16 {
        assert_eq!(reply_of(&got, n).len(), 1, "sign-on of SLIO {n:X}");
    }
    for n in 0..16 {
        b.write(n, Register::Dpm1, u16::from(n) * 10);
        // (The host keeps them calibrated: 16 writes take longer than the watchdog.)
        b.send(calibration_frame());
    }
    let got = b.host_received();
    for n in 0..16u8 {
        let r = reply_of(&got, n);
        assert_eq!(r.len(), 1, "SLIO {n:X}: {r:?}");
        assert_eq!(r[0].value, u16::from(n) * 10, "SLIO {n:X}: {r:?}");
        assert_eq!(
            b.board(n as usize).slio().register(Register::Dpm1),
            u16::from(n) * 10
        );
    }
}

#[test]
fn bus_off_changes_the_bus_mode() {
    let mut b = Bench::new(&[9]);
    b.calibrate();
    b.write(9, Register::OutputEnable, OUTPUT_ENABLE);
    let node = b.boards[0];
    b.sim
        .node_mut(node)
        .get_mut::<DemoBoard>()
        .unwrap()
        .take_notices();
    b.write(9, Register::DataOutput, 0x2000); // the input switches on P0..P3
    b.write(9, Register::PositiveEdge, 0x000F);
    b.sim
        .node_mut(node)
        .get_mut::<DemoBoard>()
        .unwrap()
        .take_notices();
    // A switch goes on: the SLIO reports it, but from now on it reads every bit inverted,
    // so each attempt fails with a bit error, its TEC climbs past 255, and a bus-off SLIO
    // changes its bus mode.
    let now = b.sim.now();
    b.sim
        .node_mut(node)
        .get_mut::<DemoBoard>()
        .unwrap()
        .set_switches(now, 0x1);
    b.sim.add_fault(buslab_sim::Fault {
        kind: buslab_sim::FaultKind::Flip { node: Some(node) },
        start: now,
        end: now + BitTime::new(4000),
    });
    b.sim.run_for(BitTime::new(4000));
    let notices = b
        .sim
        .node_mut(node)
        .get_mut::<DemoBoard>()
        .unwrap()
        .take_notices();
    assert!(
        notices
            .iter()
            .any(|(_, n)| *n == SlioNotice::BusModeChange(ModeChangeCause::BusOff)),
        "{notices:?}"
    );
    let slio = b.board(0).slio();
    assert_ne!(slio.calibration(), Calibration::Calibrated, "{slio:?}");
    assert_eq!(slio.register(Register::OutputEnable), 0);
    assert_eq!(slio.status().bus_mode, 1);
}

#[test]
fn a_bus_outside_20_to_125_kbits_is_refused_by_name() {
    for bad in [10_000, 250_000, 500_000] {
        let err = Slio::new(id(0), bad).unwrap_err().to_string();
        assert!(err.contains(&format!("bit rate {bad} bit/s")), "{err}");
        assert!(err.contains("20000..=125000"), "{err}");
    }
    assert!(Slio::new(id(0), 20_000).is_ok());
}
