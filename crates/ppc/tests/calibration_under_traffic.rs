//! Regression: the PowerPC node's periodic calibration frames were single-shot, so one that
//! lost arbitration to a higher-priority frame (the lab's `080#` every 20 ms) was dropped and
//! the next came 5000 bit-times later: past the SLIOs' 8192-bit watchdog, they lost their
//! calibration every few seconds of the lab.

use buslab_can::BitTime;
use buslab_can::Frame;
use buslab_can::controller::ControllerConfig;
use buslab_ppc::PpcNode;
use buslab_sim::{Simulation, Traffic};
use buslab_slio::{DemoBoard, ModeChangeCause, SlioId, SlioNotice};

#[test]
fn slios_stay_calibrated_beside_higher_priority_traffic() {
    let rate = 125_000u32;
    let ms = |m: u64| m * rate as u64 / 1000;
    let frame = |t: &str| -> Frame { t.parse().unwrap() };
    let mut sim = Simulation::new(rate, 1);
    let brakes = sim.add_node("brakes", ControllerConfig::default());
    sim.add_traffic(
        brakes,
        Traffic::Periodic {
            frame: frame("080#0140"),
            period: BitTime::new(ms(20)),
            start: BitTime::ZERO,
            count: None,
        },
    );
    let engine = sim.add_node("engine", ControllerConfig::default());
    sim.add_traffic(
        engine,
        Traffic::Periodic {
            frame: frame("0C0#0FA0003C00000000"),
            period: BitTime::new(ms(10)),
            start: BitTime::new(ms(1)),
            count: None,
        },
    );
    let boards: Vec<usize> = [0u8, 3, 10]
        .iter()
        .map(|&id| {
            let board = DemoBoard::new(
                SlioId::new(id).unwrap(),
                rate,
                Box::new(1.25),
                Box::new(2.5),
            )
            .unwrap();
            sim.add_device(format!("slio{id}"), Box::new(board))
        })
        .collect();
    let ppc = PpcNode::new(buslab_monican::Config {
        bitrate: rate,
        ..Default::default()
    })
    .unwrap();
    let ppc = sim.add_device("ppc", Box::new(ppc));
    // Ten seconds of bus time with conversions asked now and then, at irregular times.
    let mut lost = Vec::new();
    for step in 0..300u64 {
        if step % 3 == 0 {
            for &k in b"3I6" {
                sim.node_mut(ppc).get_mut::<PpcNode>().unwrap().key(k);
            }
        }
        sim.run_for(BitTime::new(ms(33) + (step * 7919) % 500));
        sim.node_mut(ppc)
            .get_mut::<PpcNode>()
            .unwrap()
            .take_screen();
        for &b in &boards {
            let board = sim.node_mut(b).get_mut::<DemoBoard>().unwrap();
            for (t, n) in board.take_notices() {
                if n == SlioNotice::BusModeChange(ModeChangeCause::Watchdog) {
                    lost.push((t, b));
                }
            }
        }
    }
    assert!(lost.is_empty(), "SLIOs lost their calibration at {lost:?}");
}
