//! The byte-level fast path of the candump reader gives exactly what the reference parser
//! (`parse_line`) gives, on lines near the grammar and on arbitrary text.

use buslab_logs::Message;
use buslab_logs::candump::{parse_line, parse_line_into};
use proptest::prelude::*;

fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("(1700000000.123456)".to_string()),
        "\\([0-9:/ ]{10}\\.[0-9a ]{6}\\)",
        Just("(1700000000.12345a)".to_string()),
        Just("(17000:0000.123456)".to_string()),
        Just("(0.5)".to_string()),
        Just("(12.1234567890)".to_string()),
        Just("(99999999999999999999.1)".to_string()),
        "\\([0-9]{0,21}\\.[0-9]{0,11}\\)",
        Just("vcan0".to_string()),
        Just("can1".to_string()),
        "[a-z0-9\u{e9}]{1,6}",
        "[0-9A-Fa-f]{1,9}#[0-9A-Fa-f.]{0,18}",
        "[0-9A-F]{3}#[Rr][0-9]?",
        "[0-9A-F]{8}#R[0-9]{0,2}",
        "2[0-9A-F]{7}#[0-9A-F]{0,16}",
        "[0-9A-F]{3}##[0-9][0-9A-F]{0,8}",
        "[0-9A-Fa-f]{3}##[0-9A-Fa-f][0-9A-Fa-f.]{0,30}",
        "[0-9A-F]{8}##[0-9A-FG]([0-9A-F]{2}){0,12}",
        "[0-9A-F]{3}##[0-7]([0-9A-F]{24}|[0-9A-F]{32}|[0-9A-F]{128}|[0-9A-F]{130})",
        Just("R".to_string()),
        Just("T".to_string()),
        Just("X".to_string()),
    ]
}

fn line() -> impl Strategy<Value = String> {
    (
        prop::collection::vec(token(), 0..6),
        prop::collection::vec(prop::sample::select(vec![" ", "  ", "\t", " \t"]), 6),
        prop::sample::select(vec!["", " ", "\t", "  "]),
    )
        .prop_map(|(tokens, seps, lead)| {
            let mut s = lead.to_string();
            for (i, t) in tokens.iter().enumerate() {
                if i > 0 {
                    s.push_str(seps[i]);
                }
                s.push_str(t);
            }
            s
        })
}

fn check(text: &str) {
    let mut entry = Message::default();
    entry.channel.push_str("stale");
    let fast = parse_line_into(text.as_bytes(), &mut entry).map(|()| entry);
    assert_eq!(fast, parse_line(text), "{text:?}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    #[test]
    fn fast_path_equals_the_reference_near_the_grammar(text in line()) {
        check(&text);
    }

    #[test]
    fn fast_path_equals_the_reference_on_any_text(text in ".{0,60}") {
        check(&text);
    }
}

#[test]
fn ordinary_lines() {
    for text in [
        "(1700000000.123456) vcan0 123#1122334455667788",
        "(1700000000.123456) can1 12345678#DEADBEEF T",
        "(0000000001.000000)  can0  7FF#R",
        "(1.000000000) can0 7FF#r8 R",
        "(1.0) can0 000#",
        "(1.000000) can0 20000088#0000000000000000",
        "(1.000000) can0 123#11.22",
        "(1700000000.123456) vcan0 123##1112233",
        "(1700000000.123456) vcan0 12345678##5112233445566778899AABBCC R",
        "(1700000000.123456) vcan0 7FF##3",
    ] {
        check(text);
        assert!(parse_line(text).is_ok(), "{text}");
    }
}
