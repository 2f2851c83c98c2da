//! SLIO demo boards on the virtual bus, reached through the bench's device (`buslab-bench`):
//! their inputs change and are said, what they show is read, their notices are typed events.

use buslab_can::BitTime;
use buslab_canbus::admin::{BoardInput, BoardSwitch, BoardVolts};
use buslab_slio::{Calibration, DemoBoard, SlioId, SlioNotice};
use buslab_vbus::{BusEvent, DeviceNotice, VbusError, VirtualBus};

fn bus_with_board(id: u8) -> VirtualBus {
    let mut bus = VirtualBus::new(125_000).unwrap();
    let slio = SlioId::new(id).unwrap();
    let board = DemoBoard::new(slio, 125_000, Box::new(1.25), Box::new(0.0)).unwrap();
    bus.add_node(
        &format!("slio{slio}"),
        Box::new(buslab_bench::board::on_bus(board)),
    )
    .unwrap();
    bus
}

#[test]
fn a_demo_boards_switches_and_potentiometer_change_and_are_said() {
    let mut bus = bus_with_board(3);
    let s3 = SlioId::new(3).unwrap();
    let state = bus.demo_board(s3, None).unwrap();
    assert_eq!(
        (state.switches, state.potentiometer, state.adc1),
        (0, 0.0, 1.25)
    );
    assert_eq!(state.node.name, "slio3");
    assert_eq!(
        (state.leds, state.dpm),
        (0, [None, None]),
        "not initialised"
    );
    let on = BoardInput::Switch {
        switch: BoardSwitch::new(2).unwrap(),
        on: true,
    };
    assert_eq!(bus.demo_board(s3, Some(on)).unwrap().switches, 0b0100);
    let pot = BoardInput::Potentiometer(BoardVolts::new(2.5).unwrap());
    assert_eq!(bus.demo_board(s3, Some(pot)).unwrap().potentiometer, 2.5);
    let all = BoardInput::Switches(0xF);
    assert_eq!(bus.demo_board(s3, Some(all)).unwrap().switches, 0xF);
    assert_eq!(
        bus.demo_board(s3, Some(BoardInput::Switches(0x10))),
        Err(VbusError::Switches(0x10))
    );
    let said: Vec<String> = bus
        .take_events()
        .into_iter()
        .map(|(_, e)| e.to_string())
        .collect();
    assert_eq!(
        said,
        [
            "node 1 (slio3): demo board's switch 2 on",
            "node 1 (slio3): demo board's potentiometer at 2.500 V",
            "node 1 (slio3): demo board's switches 1111",
        ]
    );
    let err = bus.demo_board(SlioId::new(5).unwrap(), None).unwrap_err();
    assert_eq!(
        err.to_string(),
        "no SLIO demo board 5 on this bus (boards: 3)"
    );
}

#[test]
fn a_bare_board_is_no_demo_board_of_the_bus() {
    let mut bus = VirtualBus::new(125_000).unwrap();
    let slio = SlioId::new(3).unwrap();
    let board = DemoBoard::new(slio, 125_000, Box::new(1.25), Box::new(0.0)).unwrap();
    bus.add_node("bare", Box::new(board)).unwrap();
    assert_eq!(
        bus.demo_board(slio, None),
        Err(VbusError::NoBoard {
            slio,
            boards: Vec::new()
        })
    );
    // Its owner still reaches it by its type.
    assert!(bus.device_mut::<DemoBoard>("bare").is_some());
}

#[test]
fn a_boards_calibration_is_a_typed_notice_and_its_registers_are_not() {
    let mut bus = bus_with_board(3);
    let host = bus.join().unwrap();
    // The calibration frame twice: the SLIO measures a bit, then is calibrated and signs on.
    for _ in 0..4 {
        let frame = buslab_slio::calibration_frame();
        while bus.submit(host, frame).unwrap().is_err() {
            let now = bus.now();
            bus.run_until(BitTime::new((now + BitTime::new(100)).get()));
        }
        let now = bus.now();
        bus.run_until(BitTime::new((now + BitTime::new(500)).get()));
    }
    let notices: Vec<DeviceNotice> = bus
        .take_events()
        .into_iter()
        .filter_map(|(_, e)| match e {
            BusEvent::Device { name, notice, .. } => {
                assert_eq!(name, "slio3");
                Some(notice)
            }
            _ => None,
        })
        .collect();
    assert!(
        notices.contains(&DeviceNotice::Slio(SlioNotice::Calibration(
            Calibration::Calibrated
        ))),
        "{notices:?}"
    );
    assert!(
        notices
            .iter()
            .all(|n| !matches!(n, DeviceNotice::Slio(SlioNotice::Register { .. }))),
        "{notices:?}"
    );
}
