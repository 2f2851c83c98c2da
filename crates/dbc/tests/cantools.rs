//! Where buslab reads a DBC file as cantools 45.1.0 does, and where it deliberately does not
//! (docs/dbc.md, "Differences from cantools"; the golden comparison in tests/golden.rs counts
//! them). Each difference is pinned here with a small file of its own.

use buslab_can::Id;
use buslab_dbc::{Database, Multiplexing};

fn value(db: &Database, message: &str, signal: &str, payload: &[u8]) -> Option<f64> {
    let message = db.message_by_name(message).unwrap();
    let (index, _) = message.signal_by_name(signal).unwrap();
    message
        .decode(payload)
        .into_iter()
        .find(|d| d.signal == index)
        .map(|d| d.physical)
}

/// cantools reads every DBC as Windows-1252 (its default encoding); buslab reads the bytes as
/// UTF-8 when they are UTF-8, else as Windows-1252. opendbc's vw_mlb.dbc and vw_mqb.dbc hold
/// UTF-8 text that cantools shows as mojibake.
#[test]
fn utf8_text_is_read_as_utf8_and_other_bytes_as_windows_1252() {
    let utf8 = "BO_ 1 M: 1 N\n SG_ T : 0|8@1+ (1,0) [0|0] \"°C\" X\n";
    let db = Database::from_bytes(utf8.as_bytes()).unwrap();
    assert_eq!(db.messages()[0].signals()[0].unit(), "°C");
    // The same unit as Vector's tools write it: one byte 0xB0.
    let cp1252 = utf8.replace('°', "\u{0}");
    let mut bytes = cp1252.into_bytes();
    let at = bytes.iter().position(|&b| b == 0).unwrap();
    bytes[at] = 0xB0;
    let db = Database::from_bytes(&bytes).unwrap();
    assert_eq!(db.messages()[0].signals()[0].unit(), "°C");
}

/// `[0|0]` is DBC's "no range"; cantools takes only that spelling so, and reads `[0.0|0.0]`
/// as the range 0 to 0 (opendbc's hyundai_2015_ccan.dbc writes it for 9 signals). buslab
/// takes any range of zero to zero as none: a signal that could only be 0 is not what the
/// file means.
#[test]
fn a_range_of_zero_to_zero_in_any_spelling_is_no_range() {
    let text = "BO_ 1 M: 8 N\n SG_ A : 0|8@1+ (1.0,0.0) [0.0|0.0] \"\" X\n SG_ B : 8|8@1+ (1,0) [0|0] \"\" X\n";
    let db = Database::parse(text).unwrap();
    let m = db.message_by_name("M").unwrap();
    assert_eq!(m.signals()[0].range(), None);
    assert_eq!(m.signals()[1].range(), None);
    assert!(m.encode(&[("A", 200.0)]).is_ok());
}

/// A message ID above 0x7FF without bit 31 cannot be a standard ID: buslab takes it as the
/// extended ID it is (opendbc writes GM low-speed, FCA, Chrysler and VW MEB IDs so); cantools
/// refuses the file ("Standard frame id ... is more than 11 bits").
#[test]
fn an_id_above_0x7ff_without_the_extended_flag_is_extended() {
    let text = "BO_ 274923520 DriverDoorStatus: 1 N\n SG_ Open : 0|1@1+ (1,0) [0|1] \"\" X\n\
                BO_ 2147483648 Zero: 1 N\n\
                BO_ 2047 Top: 1 N\n";
    let db = Database::parse(text).unwrap();
    let door = db.message(Id::extended(0x1063_0000).unwrap()).unwrap();
    assert_eq!(door.name(), "DriverDoorStatus");
    assert_eq!(db.message(Id::extended(0).unwrap()).unwrap().name(), "Zero");
    assert_eq!(
        db.message(Id::standard(0x7FF).unwrap()).unwrap().name(),
        "Top"
    );
    // Above 29 bits it is no CAN ID at all: refused, as cantools does.
    let e = Database::parse("BO_ 4294967295 X: 1 N\n").unwrap_err();
    assert!(
        e.to_string()
            .starts_with("line 1: message X: ID 4294967295"),
        "{e}"
    );
}

/// can-dbc's own ID type keeps 16 bits of such an ID: two messages 0x10630000 and
/// 0x10640000 would be one message 0 with the other's comment (the bug this pins).
#[test]
fn ids_written_without_the_flag_keep_all_their_bits() {
    let text = "BO_ 274923520 A: 1 N\nBO_ 274989056 B: 1 N\n\
                CM_ BO_ 274923520 \"first\";\nCM_ BO_ 274989056 \"second\";\n";
    let db = Database::parse(text).unwrap();
    let a = db.message(Id::extended(0x1063_0000).unwrap()).unwrap();
    let b = db.message(Id::extended(0x1064_0000).unwrap()).unwrap();
    assert_eq!((a.name(), a.comment()), ("A", Some("first")));
    assert_eq!((b.name(), b.comment()), ("B", Some("second")));
}

/// A value table or value type for a signal the file does not have is left aside; cantools
/// refuses the file ("unused VAL_ entries", opendbc's tesla_can.dbc and
/// rivian_primary_actuator.dbc).
#[test]
fn tables_of_signals_not_there_are_left_aside() {
    let text = "BO_ 1 M: 1 N\n SG_ A : 0|8@1+ (1,0) [0|0] \"\" X\n\n\
                VAL_ 1 Gone 0 \"Off\" ;\nVAL_ 1 A 1 \"On\" ;\nSIG_VALTYPE_ 1 Gone : 1;\n";
    let db = Database::parse(text).unwrap();
    let a = &db.messages()[0].signals()[0];
    assert_eq!(a.choice(1), Some("On"));
}

/// Overlapping signals (a byte and its bits, as many vehicle DBCs have) are each decoded
/// from the same bits; cantools' strict loading refuses such a file, and with strict=False
/// it cannot decode its frames ("unpacking failed").
#[test]
fn overlapping_signals_are_each_decoded() {
    let text = "BO_ 1 M: 1 N\n SG_ Byte : 0|8@1+ (1,0) [0|0] \"\" X\n SG_ Low : 0|4@1+ (1,0) [0|0] \"\" X\n";
    let db = Database::parse(text).unwrap();
    assert_eq!(value(&db, "M", "Byte", &[0xA5]), Some(165.0));
    assert_eq!(value(&db, "M", "Low", &[0xA5]), Some(5.0));
}

/// A signal past its message's length is refused with its line, as cantools' strict loading
/// refuses it ("The signal ... does not fit in message ...").
#[test]
fn a_signal_past_the_message_end_is_refused() {
    let text = "BO_ 1 M: 1 N\n SG_ A : 8|1@1+ (1,0) [0|0] \"\" X\n";
    assert_eq!(
        Database::parse(text).unwrap_err().to_string(),
        "line 2: signal M.A: its bits run past the message's 1 bytes (start bit 8, 1 bits, Intel)"
    );
}

const MUX: &str = r#"
BO_ 1 M: 2 N
 SG_ Sel M : 0|4@1+ (1,0) [0|0] "" X
 SG_ Always : 12|4@1+ (1,0) [0|0] "" X
 SG_ Zero m0 : 8|4@1+ (1,0) [0|0] "" X
 SG_ OneToThree m1 : 8|4@1+ (1,0) [0|0] "" X

SG_MUL_VAL_ 1 OneToThree Sel 2-3;
"#;

/// A frame whose multiplexor value selects no branch: cantools refuses the whole frame
/// ("expected multiplexer id 0, 1, 2 or 3, but got 9"); buslab gives the signals that do not
/// depend on the value.
#[test]
fn a_multiplexor_value_without_a_branch_gives_the_other_signals() {
    let db = Database::parse(MUX).unwrap();
    let m = db.message_by_name("M").unwrap();
    let names = |payload: &[u8]| -> Vec<&str> {
        m.decode(payload)
            .iter()
            .map(|d| m.signals()[d.signal].name())
            .collect()
    };
    assert_eq!(names(&[0x09, 0x57]), ["Sel", "Always"]);
    assert_eq!(names(&[0x00, 0x57]), ["Sel", "Always", "Zero"]);
}

/// With one multiplexor, `mN` and the signal's SG_MUL_VAL_ ranges under that multiplexor
/// together select it (cantools' reading: m1 with `2-3` is sent for 1, 2 and 3).
#[test]
fn one_multiplexor_joins_m_n_and_sg_mul_val() {
    let db = Database::parse(MUX).unwrap();
    let m = db.message_by_name("M").unwrap();
    let Multiplexing::Multiplexed { values, .. } = m.signals()[3].multiplexing() else {
        panic!("multiplexed");
    };
    assert_eq!(values, &[1..=1, 2..=3]);
    for sel in [1u8, 2, 3] {
        assert_eq!(value(&db, "M", "OneToThree", &[sel, 0x05]), Some(5.0));
    }
    assert_eq!(value(&db, "M", "OneToThree", &[4, 0x05]), None);
}

/// A payload shorter than the message gives the signals that fit, as cantools'
/// `allow_truncated=True` does (the golden comparison decodes one such frame per message).
#[test]
fn a_short_payload_gives_the_signals_that_fit() {
    let db = Database::parse(MUX).unwrap();
    let m = db.message_by_name("M").unwrap();
    let decoded = m.decode(&[0x00]);
    assert_eq!(decoded.len(), 1);
    assert_eq!(m.signals()[decoded[0].signal].name(), "Sel");
}
