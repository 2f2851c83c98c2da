//! The socketcand codec: every element python-can and socketcand exchange, round trips, and
//! garbage.

use buslab_bus::{BusOffRecovery, Probability, WireFault};
use buslab_can::{Frame, Id};
use buslab_socketcand::{
    Command, Deframer, ElementError, NodeRef, ServerMessage, Timestamp, parse_timestamp,
};
use proptest::prelude::*;

fn elements(bytes: &[u8]) -> Vec<Result<String, ElementError>> {
    let mut d = Deframer::new();
    d.push(bytes);
    std::iter::from_fn(|| d.next_element()).collect()
}

fn cmd(text: &str) -> Command {
    Command::parse(text).unwrap_or_else(|e| panic!("{text}: {e}"))
}

fn frame(text: &str) -> Frame {
    text.parse().unwrap()
}

#[test]
fn python_can_transcript_parses() {
    // What python-can 4.6.1 sends (facts §1.6), back to back without separators.
    let got: Vec<Command> = elements(
        b"< open vcan0 >< rawmode >< send 123 2 1 f1 >< send 1AAAAAAA 2 1 f1 >< send 100 0  >< send 100 2  >",
    )
    .into_iter()
    .map(|e| cmd(&e.unwrap()))
    .collect();
    assert_eq!(
        got,
        [
            Command::Open("vcan0".into()),
            Command::RawMode,
            Command::Send(frame("123#01F1")),
            Command::Send(frame("1AAAAAAA#01F1")),
            Command::Send(frame("100#")),
            // python-can's remote frame: DLC 2, no bytes.
            Command::Send(frame("100#R2")),
        ]
    );
}

#[test]
fn an_eight_digit_id_is_extended_even_when_small() {
    assert_eq!(cmd("send 00000123 0"), Command::Send(frame("00000123#")));
    assert_eq!(
        cmd("send 123 0"),
        Command::Send(Frame::data(Id::standard(0x123).unwrap(), &[]).unwrap())
    );
}

#[test]
fn commands_round_trip_through_their_text() {
    let all = [
        Command::Open("vcan0".into()),
        Command::RawMode,
        Command::BcmMode,
        Command::ControlMode,
        Command::IsotpMode,
        Command::Echo,
        Command::Send(frame("7FF#0102030405060708")),
        Command::Send(frame("1FFFFFFF#R8")),
        Command::Send(frame("000#R0")),
        Command::Name("pc-1".into()),
        Command::Extensions,
        Command::ReceiveOwn(true),
        Command::ErrorFrames(true),
        Command::ErrorFrames(false),
        Command::BusOff(BusOffRecovery::Manual),
        Command::BusOff(BusOffRecovery::Counted),
        Command::BusOff(BusOffRecovery::Fast),
        Command::Nodes,
        Command::Flush,
        Command::Abort,
        Command::Status(None),
        Command::Status(Some(NodeRef::Number(3))),
        Command::Regs(Some(NodeRef::Name("pc".into()))),
        Command::Btr {
            btr0: 0x07,
            btr1: 0x4D,
        },
        Command::Fault {
            fault: WireFault::Cut {
                far_side: vec![NodeRef::Name("engine".into()), NodeRef::Number(2)],
                error_rate: Probability::new(0.05).unwrap(),
            },
            lasting_ms: 3000,
        },
        Command::Fault {
            fault: WireFault::Noise {
                nodes: Vec::new(),
                rate: Probability::new(0.001).unwrap(),
            },
            lasting_ms: 0,
        },
        Command::Fault {
            fault: WireFault::Flip { node: None },
            lasting_ms: 10,
        },
        Command::Fault {
            fault: WireFault::Disconnect {
                node: NodeRef::Name("pc".into()),
            },
            lasting_ms: 1,
        },
        Command::Fault {
            fault: WireFault::StuckDominant,
            lasting_ms: 5,
        },
        Command::Repair,
    ];
    for c in all {
        let text = c.to_string();
        let inner = elements(text.as_bytes()).remove(0).unwrap();
        assert_eq!(Command::parse(&inner).unwrap(), c, "{text}");
    }
}

#[test]
fn bcm_and_isotp_commands_are_recognised_as_unsupported() {
    for text in [
        "add 1 0 123 2 11 22",
        "subscribe 0 0 123",
        "statistics 1000",
        "isotpconf 123 321 0 0 0",
        "vcan0 B 500000 0 0 0 0 0 0 0",
    ] {
        assert!(matches!(cmd(text), Command::Unsupported { .. }), "{text}");
    }
}

#[test]
fn garbage_commands_name_what_is_wrong() {
    let cases = [
        ("", "empty element"),
        ("fly away", "unknown command \"fly\""),
        ("send 123", "send: expected ID DLC BYTES"),
        ("send 800 0", "ID \"800\""),
        ("send 20000000 0", "ID \"20000000\""),
        ("send xyz 0", "ID \"xyz\" is not hexadecimal"),
        (
            "send 1FFFFFFFF 0",
            "ID \"1FFFFFFFF\": an ID is 1..8 hex digits",
        ),
        (
            "send 123 9 1 2 3 4 5 6 7 8 9",
            "DLC \"9\" must be a decimal 0..8",
        ),
        ("send 123 A", "DLC \"A\""),
        ("send 123 2 11", "1 data bytes given but DLC is 2"),
        ("send 123 1 123", "byte \"123\" must be 1 or 2 hex digits"),
        ("send 123 1 zz", "byte \"zz\""),
        ("send 123 R9", "DLC \"R9\""),
        ("open", "open: expected one bus name"),
        ("rawmode now", "rawmode: expected no arguments"),
        ("buslab_btr 07", "buslab_btr: expected BTR0 BTR1"),
        ("buslab_btr 07 4DD", "BTR1 \"4DD\" is not hexadecimal"),
        ("buslab_name 123", "buslab_name: expected one name"),
        ("buslab_name a/b", "buslab_name: expected one name"),
        ("buslab_own 2", "buslab_own: expected 0 or 1"),
        ("buslab_errors yes", "buslab_errors: expected 0 or 1"),
        (
            "buslab_busoff never",
            "buslab_busoff: expected counted, fast or manual",
        ),
        ("buslab_fault", "buslab_fault: expected MS then cut"),
        (
            "buslab_fault 10 melt x",
            "buslab_fault: expected MS then cut",
        ),
        ("buslab_fault -1 stuck", "buslab_fault: expected MS"),
        ("buslab_fault 10 cut * 0.1", "buslab_fault: expected MS"),
        ("buslab_fault 10 cut a,,b 0.1", "buslab_fault: expected MS"),
        (
            "buslab_fault 10 noise * 1.5",
            "probability 1.5 is out of range 0..=1",
        ),
        (
            "buslab_fault 10 noise * NaN",
            "probability NaN is out of range",
        ),
        ("buslab_repair now", "buslab_repair: expected no arguments"),
    ];
    for (text, want) in cases {
        let err = Command::parse(text).unwrap_err().to_string();
        assert!(err.contains(want), "{text:?}: {err:?} lacks {want:?}");
    }
}

#[test]
fn server_messages_parse_as_python_can_and_socketcand_send_them() {
    let ts = Timestamp::from_secs_micros(23, 424_242);
    let cases = [
        ("hi", ServerMessage::Hi),
        ("ok", ServerMessage::Ok),
        ("echo", ServerMessage::Echo),
        (
            "frame 123 23.424242 1A220344",
            ServerMessage::frame(frame("123#1A220344"), ts),
        ),
        // The BCM layout: one byte per token.
        (
            "frame 123 23.424242 1A 22 03 44 ",
            ServerMessage::frame(frame("123#1A220344"), ts),
        ),
        (
            "frame 1ABCDEF0 23.424242 ",
            ServerMessage::frame(frame("1ABCDEF0#"), ts),
        ),
        (
            "frame 321 23.424242 R3",
            ServerMessage::frame(frame("321#R3"), ts),
        ),
        (
            "error 004 23.424242",
            ServerMessage::ErrorFrame {
                class: 4,
                timestamp: ts,
                data: vec![],
            },
        ),
        (
            "error unknown command",
            ServerMessage::Error("unknown command".into()),
        ),
        ("stat 1 2 3 4", ServerMessage::Stat([1, 2, 3, 4])),
        (
            "buslab_nodes 1:pc 2:node2",
            ServerMessage::Other {
                name: "buslab_nodes".into(),
                args: vec!["1:pc".into(), "2:node2".into()],
            },
        ),
    ];
    for (text, want) in cases {
        assert_eq!(ServerMessage::parse(text).unwrap(), want, "{text}");
    }
}

#[test]
fn server_messages_round_trip() {
    let ts = Timestamp::from_secs_micros(1_700_000_000, 100);
    for m in [
        ServerMessage::Hi,
        ServerMessage::Ok,
        ServerMessage::Echo,
        ServerMessage::frame(frame("123#1122"), ts),
        ServerMessage::frame(frame("00000000#"), ts),
        ServerMessage::frame(frame("7FF#R8"), ts),
        ServerMessage::Error("bad thing".into()),
        ServerMessage::Stat([5, 6, 7, 8]),
    ] {
        let text = m.to_string();
        let inner = elements(text.as_bytes()).remove(0).unwrap();
        assert_eq!(ServerMessage::parse(&inner).unwrap(), m, "{text}");
    }
}

#[test]
fn exact_bytes_python_can_compares() {
    assert_eq!(ServerMessage::Hi.to_string(), "< hi >");
    assert_eq!(ServerMessage::Ok.to_string(), "< ok >");
    assert_eq!(
        ServerMessage::frame(
            frame("123#1A220344"),
            Timestamp::from_secs_micros(23, 424_242)
        )
        .to_string(),
        "< frame 123 23.424242 1A220344 >"
    );
    // Empty data keeps its (empty) field, as socketcand writes it; python-can needs it.
    assert_eq!(
        ServerMessage::frame(frame("123#"), Timestamp::from_secs_micros(1, 0)).to_string(),
        "< frame 123 1.000000  >"
    );
    let mut plain = String::new();
    buslab_socketcand::message::format_frame(
        &mut plain,
        &frame("321#R3"),
        Timestamp::from_secs_micros(1, 0),
        false,
    )
    .unwrap();
    assert_eq!(plain, "< frame 321 1.000000  >");
    // An error text cannot close the element early.
    assert_eq!(
        ServerMessage::Error("a > b <c>".into()).to_string(),
        "< error a ) b (c) >"
    );
}

#[test]
fn garbage_server_messages_are_errors() {
    for text in [
        "frame 123",
        "frame 123 notatime 11",
        "frame 123 1.0 1",
        "frame 123 1.0 GG",
        "frame 123 1.0 112233445566778899",
        "frame 800 1.0 11",
        "frame 123 1.1234567 11",
        "frame 123 1.0 R9",
        "stat 1 2 x 4",
        "",
    ] {
        assert!(ServerMessage::parse(text).is_err(), "{text:?} parsed");
    }
}

#[test]
fn deframer_reports_junk_and_keeps_going() {
    let got = elements(b"hello < echo >\n< ok ><<oops> < hi >");
    assert_eq!(got[0], Err(ElementError::Outside("hello".into())));
    assert_eq!(got[1], Ok(" echo ".into()));
    assert_eq!(got[2], Ok(" ok ".into()));
    assert!(matches!(got[3], Err(ElementError::Outside(_))));
    assert_eq!(got.last().unwrap(), &Ok(" hi ".into()));
}

#[test]
fn a_flood_of_junk_is_reported_briefly() {
    let got = elements(&vec![b'x'; 10_000]);
    assert_eq!(got.len(), 1);
    let Err(ElementError::Outside(text)) = &got[0] else {
        panic!("{got:?}")
    };
    assert_eq!(text, &format!("{}…", "x".repeat(40)));
}

#[test]
fn deframer_waits_for_the_rest_of_an_element() {
    let mut d = Deframer::new();
    d.push(b"< sen");
    assert_eq!(d.next_element(), None);
    d.push(b"d 123 0 >");
    assert_eq!(d.next_element(), Some(Ok(" send 123 0 ".into())));
    assert_eq!(d.next_element(), None);
}

#[test]
fn deframer_bounds_an_endless_element_and_binary_input() {
    let mut d = Deframer::new();
    d.push(b"<");
    d.push(&vec![b'a'; 9000]);
    assert_eq!(d.next_element(), Some(Err(ElementError::TooLong)));
    assert_eq!(elements(b"< \xff\xfe >"), [Err(ElementError::NotText)]);
}

#[test]
fn timestamps_parse_strictly() {
    assert_eq!(
        parse_timestamp("1.5").unwrap(),
        Timestamp::from_secs_micros(1, 500_000)
    );
    for bad in ["1", ".5", "1.", "-1.0", "1.0000000", "a.b"] {
        assert!(parse_timestamp(bad).is_err(), "{bad}");
    }
}

fn any_frame() -> impl Strategy<Value = Frame> {
    (
        any::<bool>(),
        0u32..0x2000_0000,
        any::<bool>(),
        prop::collection::vec(any::<u8>(), 0..=8),
        0u8..=8,
    )
        .prop_map(|(ext, raw, remote, data, dlc)| {
            let id = if ext {
                Id::extended(raw).unwrap()
            } else {
                Id::standard((raw & 0x7FF) as u16).unwrap()
            };
            if remote {
                Frame::remote(id, dlc).unwrap()
            } else {
                Frame::data(id, &data).unwrap()
            }
        })
}

proptest! {
    #[test]
    fn any_frame_survives_send_and_frame(f in any_frame(), secs in 0u64..4_000_000_000, micros in 0u32..1_000_000) {
        let send = Command::Send(f).to_string();
        let inner = elements(send.as_bytes()).remove(0).unwrap();
        prop_assert_eq!(Command::parse(&inner).unwrap(), Command::Send(f));
        let m = ServerMessage::frame(f, Timestamp::from_secs_micros(secs, micros));
        let inner = elements(m.to_string().as_bytes()).remove(0).unwrap();
        prop_assert_eq!(ServerMessage::parse(&inner).unwrap(), m);
    }

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..200)) {
        let mut d = Deframer::new();
        d.push(&bytes);
        while let Some(e) = d.next_element() {
            if let Ok(text) = e {
                let _ = Command::parse(&text);
                let _ = ServerMessage::parse(&text);
            }
        }
    }
}

#[test]
fn error_replies_are_ascii_as_python_can_decodes_them() {
    // python-can decodes every read with `.decode("ascii")`: one non-ASCII byte in any reply
    // makes its `recv` raise. Garbage quoted back (U+FFFD for bad bytes, `…` for a cut) must
    // not carry any.
    let junk = elements(
        &[
            b"\xc3\xa9t\xc3\xa9 \xff\xfe".as_slice(),
            &[b'x'; 100],
            b"< echo >",
        ]
        .concat(),
    );
    let Err(e) = &junk[0] else { panic!("{junk:?}") };
    let reply = ServerMessage::Error(e.to_string()).to_string();
    assert!(reply.is_ascii(), "{reply:?}");
    assert!(reply.contains("?t? ??xxx"), "{reply:?}");
    assert!(reply.ends_with("xxx...\" >"), "{reply:?}");
}

/// Found by fuzzing (fuzz/corpus/socketcand_message/regression-error-text-control-characters):
/// a server's `< error … >` text reached the user with its control characters, so a hostile
/// server could send terminal escapes, and it did not print as it was read.
#[test]
fn server_error_text_with_control_characters_is_sanitized() {
    let message = ServerMessage::parse("error bad\u{1b}[2J\u{10} bus  name").unwrap();
    assert_eq!(message, ServerMessage::Error("bad [2J bus name".into()));
    let printed = message.to_string();
    assert_eq!(printed, "< error bad [2J bus name >");
    let inside = printed.trim_start_matches("< ").trim_end_matches(" >");
    assert_eq!(ServerMessage::parse(inside).unwrap(), message);
}

#[test]
fn a_sign_is_not_a_hex_digit() {
    // `from_str_radix` takes `+f`; socketcand's hex does not.
    for text in [
        " buslab_btr +f 4D ",
        " buslab_btr 07 +4 ",
        " send 123 1 +f ",
        " send +23 0 ",
    ] {
        assert!(Command::parse(text).is_err(), "{text:?} parsed");
    }
    assert!(Command::parse(" buslab_btr 07 4D ").is_ok());
}
