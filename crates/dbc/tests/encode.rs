//! Encode is decode's inverse: generated messages (Intel and Motorola signals at any bit
//! offset, unsigned, signed, float and double, scaled, multiplexed) encoded from values and
//! decoded back to the same raw values; and what encoding refuses, with the signal and the
//! allowed range named.

use buslab_dbc::{Database, EncodeError, Message, ValueKind};
use proptest::prelude::*;

/// A generated signal: where it is and how it reads.
#[derive(Clone, Debug)]
struct Gen {
    offset: u32,
    size: u32,
    motorola: bool,
    kind: ValueKind,
    factor: f64,
    offset_value: f64,
}

fn signal() -> impl Strategy<Value = Gen> {
    let kind = prop_oneof![
        4 => Just(ValueKind::Unsigned),
        4 => Just(ValueKind::Signed),
        1 => Just(ValueKind::Float32),
        1 => Just(ValueKind::Float64),
    ];
    (
        0u32..8,
        1u32..=64,
        any::<bool>(),
        kind,
        prop_oneof![Just(1.0), Just(0.5), Just(0.25), Just(2.0), Just(10.0)],
        prop_oneof![Just(0.0), Just(-40.0), Just(100.0)],
    )
        .prop_map(|(offset, size, motorola, kind, factor, offset_value)| {
            let size = match kind {
                ValueKind::Float32 => 32,
                ValueKind::Float64 => 64,
                _ => size,
            };
            // Floats as stored (IEEE bits need factor 1, offset 0 to round-trip exactly).
            let (factor, offset_value) = match kind {
                ValueKind::Float32 | ValueKind::Float64 => (1.0, 0.0),
                _ => (factor, offset_value),
            };
            Gen {
                offset,
                size,
                motorola,
                kind,
                factor,
                offset_value,
            }
        })
}

/// A DBC message of the generated signals side by side, each in its own bytes (Motorola
/// signals numbered from their most significant bit), the first as a multiplexor of the
/// others when `mux` is set: signal `i` is sent when the multiplexor is `i % 3`.
fn dbc(signals: &[Gen], mux: bool) -> (String, usize) {
    let mut text = String::from("BO_ 1234 Gen: LEN Node\n");
    let mut byte = 0u32;
    let mut value_types = String::new();
    for (i, s) in signals.iter().enumerate() {
        let bytes = (s.offset + s.size).div_ceil(8);
        let start = if s.motorola {
            8 * byte + 7 - s.offset
        } else {
            8 * byte + s.offset
        };
        let marker = match (mux, i) {
            (false, _) => String::new(),
            (true, 0) => " M".into(),
            (true, _) => format!(" m{}", i % 3),
        };
        let sign = if s.kind == ValueKind::Signed {
            '-'
        } else {
            '+'
        };
        text += &format!(
            " SG_ S{i}{marker} : {start}|{}@{}{sign} ({},{}) [0|0] \"\" Vector__XXX\n",
            s.size,
            if s.motorola { 0 } else { 1 },
            s.factor,
            s.offset_value
        );
        match s.kind {
            ValueKind::Float32 => value_types += &format!("SIG_VALTYPE_ 1234 S{i} : 1;\n"),
            ValueKind::Float64 => value_types += &format!("SIG_VALTYPE_ 1234 S{i} : 2;\n"),
            _ => {}
        }
        byte += bytes;
    }
    let length = byte as usize;
    (
        text.replace("LEN", &length.to_string()) + "\n" + &value_types,
        length,
    )
}

/// Raw bits a signal can hold, as its value reads them (floats: finite ones).
fn raw_for(s: &Gen, bits: u64) -> u64 {
    let mask = if s.size == 64 {
        u64::MAX
    } else {
        (1u64 << s.size) - 1
    };
    let raw = bits & mask;
    match s.kind {
        ValueKind::Float32 if !f32::from_bits(raw as u32).is_finite() => 0,
        ValueKind::Float64 if !f64::from_bits(raw).is_finite() => 0,
        // Physical values are f64: integers beyond 2^53 steps do not come back exactly.
        ValueKind::Unsigned | ValueKind::Signed if s.size > 50 => raw & ((1 << 50) - 1),
        _ => raw,
    }
}

fn message(db: &Database) -> &Message {
    db.message_by_name("Gen").unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn encode_then_decode_gives_the_raw_values_back(
        signals in prop::collection::vec(signal(), 1..6),
        bits in prop::collection::vec(any::<u64>(), 6),
    ) {
        let (text, length) = dbc(&signals, false);
        prop_assume!(length <= 64);
        let db = Database::parse(&text).unwrap();
        let message = message(&db);
        let raws: Vec<u64> = signals.iter().zip(&bits).map(|(s, &b)| raw_for(s, b)).collect();
        let values: Vec<(String, f64)> = message
            .signals()
            .iter()
            .zip(&raws)
            .map(|(s, &raw)| (s.name().to_string(), s.physical(raw)))
            .collect();
        let values: Vec<(&str, f64)> = values.iter().map(|(n, v)| (n.as_str(), *v)).collect();
        let payload = message.encode(&values).unwrap();
        prop_assert_eq!(payload.len(), length);
        let decoded = message.decode(&payload);
        prop_assert_eq!(decoded.len(), signals.len());
        for (d, &raw) in decoded.iter().zip(&raws) {
            prop_assert_eq!(d.raw, raw, "{}\n{:?}", text, signals[d.signal]);
        }
    }

    #[test]
    fn encode_then_decode_a_multiplexed_branch(
        signals in prop::collection::vec(signal(), 2..7),
        bits in prop::collection::vec(any::<u64>(), 7),
        branch in 0u64..3,
    ) {
        // The multiplexor: an unsigned integer that holds 0..=2.
        let mut signals = signals;
        signals[0].kind = ValueKind::Unsigned;
        signals[0].size = signals[0].size.clamp(2, 16);
        signals[0].factor = 1.0;
        signals[0].offset_value = 0.0;
        let (text, length) = dbc(&signals, true);
        prop_assume!(length <= 64);
        let db = Database::parse(&text).unwrap();
        let message = message(&db);
        let mut values: Vec<(String, f64)> = vec![("S0".into(), branch as f64)];
        let mut expected = vec![(0usize, branch)];
        for (i, s) in signals.iter().enumerate().skip(1) {
            if i as u64 % 3 == branch {
                let raw = raw_for(s, bits[i]);
                values.push((format!("S{i}"), message.signals()[i].physical(raw)));
                expected.push((i, raw));
            }
        }
        let values: Vec<(&str, f64)> = values.iter().map(|(n, v)| (n.as_str(), *v)).collect();
        let payload = message.encode(&values).unwrap();
        let decoded: Vec<(usize, u64)> =
            message.decode(&payload).iter().map(|d| (d.signal, d.raw)).collect();
        // Exactly the branch's signals, with their raw values.
        let mut branch_signals: Vec<(usize, u64)> = decoded;
        branch_signals.sort();
        expected.sort();
        prop_assert_eq!(branch_signals, expected, "{}", text);
    }
}

const ENGINE: &str = r#"
BO_ 291 Engine: 8 ECU
 SG_ Speed : 0|16@1+ (0.1,0) [0|6553.5] "km/h" Vector__XXX
 SG_ Torque : 16|12@1- (0.5,0) [-500|500] "Nm" Vector__XXX
 SG_ Mode M : 28|4@1+ (1,0) [0|15] "" Vector__XXX
 SG_ Idle m0 : 32|8@1+ (1,0) [0|255] "rpm" Vector__XXX
 SG_ Boost m1 : 32|8@1+ (1,0) [0|255] "kPa" Vector__XXX
 SG_ Lamp : 40|2@1+ (1,0) [0|3] "" Vector__XXX

BA_DEF_ SG_ "GenSigStartValue" INT 0 65535;
BA_DEF_DEF_ "GenSigStartValue" 0;
BA_ "GenSigStartValue" SG_ 291 Lamp 2;
BA_ "GenSigStartValue" SG_ 291 Idle 80;
"#;

#[test]
fn out_of_range_names_the_signal_and_the_allowed_range() {
    let db = Database::parse(ENGINE).unwrap();
    let engine = db.message_by_name("Engine").unwrap();
    let error = engine.encode(&[("Torque", 600.0)]).unwrap_err();
    assert_eq!(
        error,
        EncodeError::OutOfRange {
            message: "Engine".into(),
            signal: "Torque".into(),
            value: 600.0,
            min: -500.0,
            max: 500.0,
        }
    );
    assert_eq!(
        error.to_string(),
        "Engine.Torque = 600 is out of range: allowed -500 ..= 500"
    );
}

#[test]
fn an_unknown_signal_lists_the_known_ones() {
    let db = Database::parse(ENGINE).unwrap();
    let engine = db.message_by_name("Engine").unwrap();
    let error = engine.encode(&[("Sped", 1.0)]).unwrap_err();
    assert_eq!(
        error.to_string(),
        "message Engine has no signal Sped (its signals: Speed, Torque, Mode, Idle, Boost, Lamp)"
    );
    let nan = engine.encode(&[("Speed", f64::NAN)]).unwrap_err();
    assert!(matches!(nan, EncodeError::NotANumber { .. }), "{nan}");
}

#[test]
fn a_signal_of_a_branch_not_selected_is_refused() {
    let db = Database::parse(ENGINE).unwrap();
    let engine = db.message_by_name("Engine").unwrap();
    let error = engine
        .encode(&[("Mode", 0.0), ("Boost", 100.0)])
        .unwrap_err();
    assert_eq!(error.to_string(), "Engine.Boost is not sent when Mode = 0");
    assert!(engine.encode(&[("Mode", 1.0), ("Boost", 100.0)]).is_ok());
}

#[test]
fn signals_not_given_are_sent_with_their_start_value() {
    let db = Database::parse(ENGINE).unwrap();
    let engine = db.message_by_name("Engine").unwrap();
    assert_eq!(
        engine.signal_by_name("Lamp").unwrap().1.start_value(),
        Some(2.0)
    );
    // The attribute's default (BA_DEF_DEF_) is not a start value of its own, as in cantools.
    assert_eq!(
        engine.signal_by_name("Speed").unwrap().1.start_value(),
        None
    );
    let payload = engine.encode(&[("Speed", 100.0)]).unwrap();
    let value = |name: &str| {
        let (index, _) = engine.signal_by_name(name).unwrap();
        engine
            .decode(&payload)
            .into_iter()
            .find(|d| d.signal == index)
            .map(|d| d.physical)
    };
    assert_eq!(value("Speed"), Some(100.0));
    assert_eq!(value("Lamp"), Some(2.0));
    // Mode 0 selects Idle, which is sent with its start value; Boost is not in the frame.
    assert_eq!(value("Idle"), Some(80.0));
    assert_eq!(value("Boost"), None);
    // A value given wins over the start value.
    let payload = engine.encode(&[("Lamp", 1.0)]).unwrap();
    assert_eq!(payload[5] & 0b11, 1);
}
