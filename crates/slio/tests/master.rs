//! The host side (`Master`) driving demo boards on the one bus engine through a host
//! controller, as the PowerPC node does through its SJA1000.

use buslab_can::controller::{ControllerConfig, Event};
use buslab_can::{BitTime, Nanos};
use buslab_sim::{Happening, Simulation};
use buslab_slio::board::{CONVERT_ADC2, OUTPUT_ENABLE, volts_to_code};
use buslab_slio::{DemoBoard, Master, MasterEvent, Register, SlioId};

const RATE: u32 = 125_000;

struct Host {
    sim: Simulation,
    master: Master,
    events: Vec<MasterEvent>,
}

impl Host {
    fn new(ids: &[u8]) -> Self {
        let mut sim = Simulation::new(RATE, 1);
        sim.add_node("ppc", ControllerConfig::default());
        for &n in ids {
            let board = DemoBoard::new(SlioId::new(n).unwrap(), RATE, Box::new(0.0), Box::new(2.5))
                .unwrap();
            sim.add_device(format!("slio{n:X}"), Box::new(board));
        }
        Self {
            sim,
            master: Master::new(RATE, Nanos::ZERO),
            events: Vec::new(),
        }
    }

    /// Runs the adapter for `bits` bit-times: one frame at a time into the host controller
    /// (single-shot when the master says so), received frames and timeouts into the master.
    fn run(&mut self, bits: u64) {
        let end = self.sim.now() + BitTime::new(bits);
        while self.sim.now() < end {
            let now_ns = self.sim.now().at_bitrate(RATE);
            self.master.handle_timeout(now_ns);
            if self.sim.node(0).device().pending() == 0
                && let Some(t) = self.master.poll_transmit(now_ns)
            {
                let c = self.sim.controller_mut(0).unwrap();
                c.set_single_shot(t.single_shot);
                c.enqueue(t.frame).unwrap();
            }
            self.sim.run_for(BitTime::new(16));
            for r in self.sim.take_records() {
                if let Happening::Node {
                    node: 0,
                    event: Event::Received(f),
                } = r.what
                {
                    self.master.handle_frame(r.time.at_bitrate(RATE), &f);
                }
            }
            while let Some(e) = self.master.poll_event() {
                self.events.push(e);
            }
        }
    }
}

#[test]
fn the_master_calibrates_finds_and_drives_three_boards() {
    let mut h = Host::new(&[0, 3, 10]);
    h.run(48 * 200);
    let present: Vec<u8> = h
        .events
        .iter()
        .filter_map(|e| match e {
            MasterEvent::Present { slio, .. } => Some(slio.number()),
            _ => None,
        })
        .collect();
    assert_eq!(present, [0, 3, 10]);
    let s3 = SlioId::new(3).unwrap();
    h.master.write(s3, Register::OutputEnable, OUTPUT_ENABLE);
    h.master.write(s3, Register::DataOutput, 0x0100);
    let adc = h.master.write(s3, Register::AnalogConfig, CONVERT_ADC2);
    h.run(2000);
    let confirmed: Vec<(Register, u16)> = h
        .events
        .iter()
        .filter_map(|e| match e {
            MasterEvent::Confirmed {
                register, value, ..
            } => Some((*register, *value)),
            _ => None,
        })
        .collect();
    assert_eq!(
        confirmed,
        [
            (Register::OutputEnable, OUTPUT_ENABLE),
            (Register::DataOutput, 0x0100),
            (Register::Adc, volts_to_code(2.5))
        ]
    );
    assert!(
        h.events
            .iter()
            .any(|e| matches!(e, MasterEvent::Confirmed { request, .. } if *request == adc))
    );
    let board = h.sim.node(2).get::<DemoBoard>().unwrap();
    assert_eq!(board.leds(), [false, true, false, false, false]);
    // The master keeps them calibrated: long after the watchdog would have tripped, they
    // still answer (DATA_INPUT: P8, an output, reads back high).
    h.run(40_000);
    h.events.clear();
    h.master.read(s3, Register::DataInput).unwrap();
    h.run(2000);
    assert!(
        h.events.iter().any(|e| matches!(
            e,
            MasterEvent::Confirmed {
                register: Register::DataInput,
                value,
                ..
            } if value & 0x0100 != 0
        )),
        "{:?}",
        h.events
    );
}
