//! Broken DBC files: a syntax error names the line, the column and what the grammar expected
//! there; a file that parses but does not hold together names the line and what is wrong;
//! and no input, however mangled, panics.

use buslab_dbc::{Database, DbcError};
use proptest::prelude::*;

fn error(text: &str) -> DbcError {
    Database::parse(text).expect_err("a broken file")
}

const GOOD: &str = r#"VERSION ""

BU_: ECU Dash

BO_ 291 Engine: 8 ECU
 SG_ Speed : 0|16@1+ (0.1,0) [0|6553.5] "km/h" Dash
 SG_ Mode M : 16|4@1+ (1,0) [0|15] "" Dash
 SG_ Idle m0 : 24|8@1+ (1,0) [0|255] "rpm" Dash
 SG_ Temp : 39|12@0- (0.5,-40) [-40|215] "degC" Dash

CM_ SG_ 291 Speed "Vehicle speed";
VAL_ 291 Mode 0 "Idle" 1 "Drive" ;
"#;

#[test]
fn the_good_file_loads() {
    let db = Database::parse(GOOD).unwrap();
    assert_eq!(db.messages().len(), 1);
}

#[test]
fn a_missing_colon_names_its_place() {
    let text = GOOD.replace("BO_ 291 Engine: 8 ECU", "BO_ 291 Engine 8 ECU");
    assert_eq!(
        error(&text).to_string(),
        r#"line 5, column 16: expected ":", found "8 ECU""#
    );
}

#[test]
fn a_bad_byte_order_names_the_allowed_ones() {
    let text = GOOD.replace("0|16@1+", "0|16@2+");
    let DbcError::Syntax {
        line,
        column,
        expected,
    } = error(&text)
    else {
        panic!("a syntax error");
    };
    assert_eq!((line, column), (6, 19));
    assert!(expected.starts_with(r#"expected "0" or "1""#), "{expected}");
}

#[test]
fn an_unclosed_parenthesis() {
    let text = GOOD.replace("(0.1,0) [0|6553.5]", "(0.1,0 [0|6553.5]");
    assert_eq!(
        error(&text).to_string(),
        r#"line 6, column 29: expected ")", found "[0|6553.5] \"km/h\" Dash""#
    );
}

#[test]
fn a_stray_word_between_items() {
    let text = GOOD.replace("\nCM_ SG_", "\nhello\nCM_ SG_");
    assert_eq!(
        error(&text).to_string(),
        r#"line 11, column 1: expected a keyword (BO_, SG_, CM_, BA_, VAL_, ...), found "hello""#
    );
}

#[test]
fn binary_garbage_is_a_syntax_error_at_its_start() {
    let e = Database::from_bytes(&[0x00, 0x01, 0xFE, 0x81, b'x']).unwrap_err();
    assert!(
        matches!(
            e,
            DbcError::Syntax {
                line: 1,
                column: 1,
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn semantic_errors_name_the_line() {
    let cases = [
        (
            GOOD.replace("0|16@1+", "0|0@1+"),
            "line 6: signal Engine.Speed: 0 bits: a signal has 1 to 64",
        ),
        (
            GOOD.replace("0|16@1+", "0|65@1+"),
            "line 6: signal Engine.Speed: 65 bits: a signal has 1 to 64",
        ),
        (
            GOOD.replace("24|8@1+", "60|8@1+"),
            "line 8: signal Engine.Idle: its bits run past the message's 8 bytes (start bit 60, 8 bits, Intel)",
        ),
        (
            GOOD.replace("(0.1,0)", "(0,0)"),
            "line 6: signal Engine.Speed: factor 0 and offset 0: a nonzero finite factor and a finite offset",
        ),
        (
            GOOD.replace("BO_ 291 Engine: 8", "BO_ 291 Engine: 65"),
            "line 5: message Engine: 65 bytes long: at most 64 (CAN FD)",
        ),
        (
            GOOD.replace("Mode M :", "Mode :"),
            "line 8: message Engine: signal Idle is multiplexed (m0) but no multiplexor (M) or SG_MUL_VAL_ line says by what",
        ),
        (
            GOOD.replace("BO_ 291 Engine: 8", "BO_ 4294967295 Engine: 8"),
            "line 5: message Engine: ID 4294967295 is neither a standard (up to 0x7FF) nor an extended ID (bit 31 and up to 0x1FFFFFFF)",
        ),
        (
            format!("{GOOD}SIG_VALTYPE_ 291 Speed : 1;\n"),
            "line 6: signal Engine.Speed: a float is 32 bits, not 16",
        ),
        (
            format!("{GOOD}\nBO_ 291 Gearbox: 8 ECU\n"),
            "line 14: message Gearbox: ID 291 (123) is Engine's already",
        ),
    ];
    for (text, expected) in cases {
        assert_eq!(error(&text).to_string(), expected);
    }
}

#[test]
fn multiplexors_in_a_circle_are_refused() {
    let text = r#"
BO_ 10 Loop: 8 ECU
 SG_ A m1M : 0|8@1+ (1,0) [0|0] "" X
 SG_ B m1M : 8|8@1+ (1,0) [0|0] "" X

SG_MUL_VAL_ 10 A B 1-1;
SG_MUL_VAL_ 10 B A 1-1;
"#;
    assert_eq!(
        error(text).to_string(),
        "line 2: message Loop: the multiplexors of A select each other in a circle"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Random bytes: an error or a database, never a panic.
    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        let _ = Database::from_bytes(&bytes);
    }

    /// The good file with bytes changed, cut or repeated: an error or a database whose
    /// messages decode and encode any payload without a panic.
    #[test]
    fn mangled_files_never_panic(
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        cut in any::<prop::sample::Index>(),
        payload in prop::collection::vec(any::<u8>(), 0..70),
    ) {
        let mut bytes = GOOD.as_bytes().to_vec();
        for (at, byte) in edits {
            let i = at.index(bytes.len());
            bytes[i] = byte;
        }
        bytes.truncate(cut.index(bytes.len() + 1));
        if let Ok(db) = Database::from_bytes(&bytes) {
            for message in db.messages() {
                let decoded = message.decode(&payload);
                let values: Vec<(&str, f64)> = decoded
                    .iter()
                    .map(|d| (message.signals()[d.signal].name(), d.physical))
                    .collect();
                let _ = message.encode(&values);
            }
        }
    }
}
