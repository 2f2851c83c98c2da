//! The lab's DBC (`buslab_bench::lab::LAB_DBC`) against the bench it describes: it loads with
//! buslab-dbc, and every frame the lab's nodes send, built by the code that sends it (the
//! simulated traffic, the counter node, the SLIO register codec, MoniCAN's calibration, the
//! mail and loader identifiers), decodes to the values that code put in.

use std::collections::BTreeMap;

use buslab_bench::board;
use buslab_bench::counter::{COUNTER_PERIOD, counter_frame};
use buslab_bench::lab::{LAB_DBC, SIMULATED, SlioBench, TRAFFIC};
use buslab_can::{Frame, Id, StandardId};
use buslab_dbc::{Database, Message};
use buslab_slio::board::{VDD, volts_to_code};
use buslab_slio::registers::{CONVERT, MUX_MASK, MUX_SHIFT, TEN_BITS};
use buslab_slio::{Register, Reply, Request, Status, calibration_frame};

fn database() -> Database {
    Database::parse(LAB_DBC).expect("the lab's DBC loads")
}

/// A signal's value: raw bits, physical value, the value table's label.
#[derive(Debug, PartialEq)]
struct Value {
    raw: u64,
    physical: f64,
    label: Option<String>,
}

/// Every signal `payload` carries, by name.
fn decode(message: &Message, payload: &[u8]) -> BTreeMap<String, Value> {
    message
        .decode(payload)
        .into_iter()
        .map(|d| {
            let signal = &message.signals()[d.signal];
            (
                signal.name().to_string(),
                Value {
                    raw: d.raw,
                    physical: d.physical,
                    label: signal.choice(d.raw).map(str::to_string),
                },
            )
        })
        .collect()
}

fn message_of<'a>(db: &'a Database, frame: &Frame) -> &'a Message {
    db.message(frame.id())
        .unwrap_or_else(|| panic!("no message for {frame}"))
}

fn physical(values: &BTreeMap<String, Value>, name: &str) -> f64 {
    values
        .get(name)
        .unwrap_or_else(|| panic!("no {name} in {values:?}"))
        .physical
}

fn label<'a>(values: &'a BTreeMap<String, Value>, name: &str) -> &'a str {
    values
        .get(name)
        .and_then(|v| v.label.as_deref())
        .unwrap_or_else(|| panic!("no label for {name} in {values:?}"))
}

#[test]
fn the_simulated_nodes_frames_are_named_and_sent_by_their_nodes() {
    let db = database();
    for (node, text) in SIMULATED.iter().zip(TRAFFIC) {
        let frame: Frame = text.parse().unwrap();
        let message = message_of(&db, &frame);
        assert_eq!(message.transmitter(), Some(*node), "{text}");
        assert_eq!(message.length(), frame.payload().len(), "{text}");
        let values = decode(message, frame.payload());
        assert_eq!(values.len(), message.signals().len(), "{text}: {values:?}");
    }
    let values = |text: &str| {
        let frame: Frame = text.parse().unwrap();
        decode(message_of(&db, &frame), frame.payload())
    };
    let brakes = values(TRAFFIC[0]);
    assert_eq!(physical(&brakes, "BrakePressure"), 32.0);
    let engine = values(TRAFFIC[1]);
    assert_eq!(physical(&engine, "EngineSpeed"), 4000.0);
    assert_eq!(physical(&engine, "VehicleSpeed"), 60.0);
    let body = values(TRAFFIC[2]);
    assert_eq!(
        ["DoorFrontLeft", "DoorFrontRight", "Lights", "Wipers"].map(|s| label(&body, s)),
        ["open", "closed", "low beam", "slow"]
    );
    let dash = values(TRAFFIC[3]);
    assert!((physical(&dash, "FuelLevel") - 83.6).abs() < 1e-9);
    assert!((physical(&dash, "TripDistance") - 5422.8).abs() < 1e-9);
}

#[test]
fn the_counter_is_one_little_endian_count_at_its_period() {
    let db = database();
    let frame = counter_frame(0x0403_0201);
    let message = message_of(&db, &frame);
    assert_eq!(
        (message.name(), message.transmitter()),
        ("Counter", Some("counter"))
    );
    assert_eq!(message.cycle_time(), Some(COUNTER_PERIOD));
    let values = decode(message, frame.payload());
    assert_eq!(values["Count"].raw, 0x0403_0201);
    assert_eq!(
        decode(message, counter_frame(u32::MAX).payload())["Count"].physical,
        f64::from(u32::MAX)
    );
}

/// Values that set every bit of the 16 somewhere, and the demo board's own.
const VALUES: [u16; 8] = [
    0x0000, 0xFFFF, 0x2C85, 0x3F90, 0x1234, 0x03FF, 0x0200, 0x5A5A,
];

/// The signals a register's 16 bits are read as, checked against the register's value.
fn check_value(register: Register, value: u16, values: &BTreeMap<String, Value>, what: &str) {
    let pins = |prefix: &str| {
        for k in 0..16 {
            let (name, v) = values
                .iter()
                .find(|(name, _)| {
                    name.starts_with(&format!("{prefix}_P{k}")) && {
                        let rest = &name[prefix.len() + 2 + k.to_string().len()..];
                        rest.is_empty() || rest.starts_with('_')
                    }
                })
                .unwrap_or_else(|| panic!("{what}: no pin P{k} in {values:?}"));
            assert_eq!(v.raw, u64::from(value >> k & 1), "{what}: {name}");
        }
    };
    match register {
        Register::DataInput => pins("In"),
        Register::DataOutput => pins("Out"),
        Register::PositiveEdge => assert_eq!(values["PositiveEdge"].raw, u64::from(value)),
        Register::NegativeEdge => assert_eq!(values["NegativeEdge"].raw, u64::from(value)),
        Register::OutputEnable => assert_eq!(values["OutputEnable"].raw, u64::from(value)),
        Register::AnalogConfig => {
            assert_eq!(
                values["AdcInput"].raw,
                u64::from(value >> MUX_SHIFT & MUX_MASK),
                "{what}"
            );
            assert_eq!(
                values["Convert"].raw,
                u64::from(value & CONVERT != 0),
                "{what}"
            );
        }
        Register::Dpm1 | Register::Dpm2 => {
            let name = register.name();
            let duty = value & TEN_BITS;
            assert_eq!(values[name].raw, u64::from(duty), "{what}");
            // The mean level: duty / 1024 of the supply (as the board drives it).
            assert_eq!(
                values[name].physical,
                f64::from(duty) / 1024.0 * VDD,
                "{what}"
            );
        }
        Register::Adc => {
            let code = value & TEN_BITS;
            assert_eq!(values["ADC"].raw, u64::from(code), "{what}");
            // Volts the board's ADC reads as this code.
            assert_eq!(volts_to_code(values["ADC"].physical), code, "{what}");
        }
    }
}

#[test]
fn every_slio_frame_of_the_bench_decodes_as_the_chips_codec_builds_it() {
    let db = database();
    let bench = SlioBench::new(125_000);
    assert_eq!(bench.ids().len(), 3);
    for &slio in bench.ids() {
        let replies = db.message(slio.reply_id()).expect("replies");
        let commands = db.message(slio.command_id()).expect("commands");
        assert_eq!(replies.name(), format!("SLIO{slio}_Reply"));
        assert_eq!(commands.name(), format!("SLIO{slio}_Command"));
        assert_eq!(replies.transmitter(), Some(board::name(slio).as_str()));
        assert_eq!(commands.transmitter(), Some(buslab_bench::ppc::NAME));
        for register in Register::all() {
            for value in VALUES {
                for nibble in 0..16 {
                    let status = Status::from_nibble(nibble);
                    let data = Reply {
                        status,
                        register,
                        value,
                    }
                    .encode();
                    let what = format!("SLIO {slio} {register} {value:04X} status {nibble}");
                    let values = decode(replies, &data);
                    assert_eq!(label(&values, "Register"), register.name(), "{what}");
                    assert_eq!(
                        values["RSTD"].raw,
                        u64::from(status.reset_detected),
                        "{what}"
                    );
                    assert_eq!(values["EW"].raw, u64::from(status.ew), "{what}");
                    assert_eq!(values["BusMode"].raw, u64::from(status.bus_mode), "{what}");
                    check_value(register, value, &values, &what);
                }
                let what = format!("to SLIO {slio}: {register} {value:04X}");
                let request = match Request::read(register) {
                    Ok(read) => read,
                    Err(_) => Request::Write { register, value },
                };
                let values = decode(commands, &request.data().unwrap());
                assert_eq!(label(&values, "Register"), register.name(), "{what}");
                match request {
                    Request::Write { .. } => check_value(register, value, &values, &what),
                    // A read carries zeros, and no value to name.
                    Request::Read { .. } => assert_eq!(values.len(), 1, "{what}: {values:?}"),
                }
            }
        }
    }
}

#[test]
fn calibration_mail_and_loader_frames_are_named() {
    let db = database();
    let calibration = calibration_frame();
    assert_eq!(message_of(&db, &calibration).name(), "SlioCalibration");
    let standard = |raw| Id::Standard(StandardId::new(raw).unwrap());
    let mail = db
        .message(standard(buslab_monican::DEFAULT_MAIL_ID))
        .unwrap();
    assert_eq!(mail.name(), "MailText");
    let loader = db.message(buslab_loader::loader::loader_id()).unwrap();
    assert_eq!(loader.name(), "LoaderFile");
    // Text 8 characters a frame; the last, shorter frame gives the characters it has.
    let text = decode(loader, b"S1130");
    assert_eq!(
        text.values().map(|v| v.raw as u8).collect::<Vec<_>>(),
        b"S1130".to_vec()
    );
    // Every transmitter is one of the database's nodes.
    for message in db.messages() {
        if let Some(node) = message.transmitter() {
            assert!(
                db.nodes().iter().any(|n| n == node),
                "{}: {node}",
                message.name()
            );
        }
    }
}
