//! buslab's extension replies: typed values to the wire text docs/bus.md lists and back, and
//! garbage from a server named, never a panic.

use buslab_bus::{
    Alc, BusSummary, CanMode, Ecc, ErrorRegisters, ErrorState, NodeCounters, NodeInfo,
    NodeRegisters, NodeStatus, NodeTiming, RegisterDump, Status, TxReport,
};
use buslab_socketcand::reply::{
    flushed_fields, nodes_fields, parse_flushed, parse_nodes, parse_regs, parse_status,
    regs_fields, status_fields,
};
use buslab_socketcand::{ReplyError, ServerMessage, status_reply};
use proptest::prelude::*;

fn status() -> NodeStatus {
    NodeStatus {
        number: 2,
        name: "pc".into(),
        state: ErrorState::Active,
        errors: Some(ErrorRegisters {
            alc: Some(Alc(0x01)),
            ecc: Some(Ecc(0x1B)),
            rxerr: 0,
            txerr: 0,
        }),
        sr: Some(Status(0x0C)),
        timing: Some(NodeTiming {
            btr0: 0x00,
            btr1: 0x1C,
            bitrate: 500_000,
            matches_bus: true,
        }),
        counters: NodeCounters {
            sent: 1,
            received: 2,
            tx_failed: 3,
            bus_errors: 4,
            arbitration_lost: 5,
            overruns: 6,
            bus_off: 7,
            rx_lost: 8,
        },
        tx_queued: 9,
        bus: BusSummary {
            bitrate: 500_000,
            load_percent: 12.3,
            frames: 10,
            errors: 11,
        },
    }
}

/// The wire text of docs/bus.md, key for key in the same order (python scripts and the
/// benchmark read it).
const WIRE: &str = "2 pc state=error-active sr=0C txerr=0 rxerr=0 alc=01 ecc=1B btr0=00 btr1=1C bitrate=500000 bus_bitrate=500000 timing=ok sent=1 received=2 tx_failed=3 bus_errors=4 arbitration_lost=5 overruns=6 bus_off=7 rx_lost=8 tx_queued=9 bus_load=12.3% bus_frames=10 bus_errors_total=11";

fn tokens(text: &str) -> Vec<String> {
    text.split_whitespace().map(String::from).collect()
}

#[test]
fn status_keeps_the_documented_keys_and_order() {
    assert_eq!(status_fields(&status()).join(" "), WIRE);
    assert_eq!(
        status_reply(&status()).to_string(),
        format!("< buslab_status {WIRE} >")
    );
    assert_eq!(parse_status(&tokens(WIRE)).unwrap(), status());
}

#[test]
fn status_without_optional_parts_round_trips() {
    // Nothing captured yet, no SR, no programmable timing, no error counters (BasicCAN).
    let mut st = status();
    st.errors = None;
    st.sr = None;
    st.timing = None;
    st.state = ErrorState::BusOff;
    let wire = status_fields(&st);
    assert!(wire.contains(&"bus_bitrate=500000".to_string()), "{wire:?}");
    assert!(
        !wire
            .iter()
            .any(|f| f.starts_with("txerr") || f.starts_with("btr0"))
    );
    assert_eq!(parse_status(&wire).unwrap(), st);
    let mut st = status();
    st.errors = Some(ErrorRegisters {
        alc: None,
        ecc: None,
        rxerr: 255,
        txerr: 127,
    });
    st.timing.as_mut().unwrap().matches_bus = false;
    st.state = ErrorState::Passive;
    let wire = status_fields(&st);
    assert!(wire.contains(&"timing=mismatch".to_string()));
    assert_eq!(parse_status(&wire).unwrap(), st);
}

#[test]
fn status_from_a_newer_server_skips_keys_it_does_not_know() {
    let text = format!("{WIRE} temperature=41C");
    assert_eq!(parse_status(&tokens(&text)).unwrap(), status());
}

#[test]
fn garbage_status_names_the_key_and_value() {
    let cases: &[(&str, &str)] = &[
        ("", "expected N NAME KEY=VALUE"),
        ("x pc", "a node number first"),
        ("2", "expected N NAME"),
        ("2 pc state", "KEY=VALUE"),
        ("2 pc sent=1 sent=2", "sent= is given twice"),
        ("2 pc state=error-active", "sent= is missing"),
    ];
    for (text, want) in cases {
        let err = parse_status(&tokens(text)).unwrap_err().to_string();
        assert!(err.contains(want), "{text:?}: {err}");
    }
    for (key, value, want) in [
        ("state", "sleepy", "error-active, error-passive or bus-off"),
        ("sr", "1CC", "a hex byte"),
        ("txerr", "256", "a decimal 0..255"),
        ("rxerr", "-1", "a decimal 0..255"),
        ("alc", "zz", "a hex byte"),
        ("timing", "maybe", "ok or mismatch"),
        ("sent", "+5", "a decimal count"),
        ("sent", "18446744073709551616", "a decimal count"),
        ("bus_load", "12.3", "per cent"),
        ("bus_load", "101.0%", "per cent"),
        ("bus_load", "nan%", "per cent"),
        ("bitrate", "", "a bit rate"),
    ] {
        let text = WIRE.replacen(
            &format!(
                " {key}={}",
                WIRE.split(' ')
                    .find_map(|f| f.strip_prefix(&format!("{key}=")))
                    .unwrap()
            ),
            &format!(" {key}={value}"),
            1,
        );
        let err = parse_status(&tokens(&text)).unwrap_err();
        assert!(
            matches!(&err, ReplyError::Value { key: k, value: v, .. } if k == key && v == value),
            "{key}={value}: {err:?}"
        );
        assert!(err.to_string().contains(want), "{key}={value}: {err}");
    }
    // Half a timing: the other keys are named.
    let text = WIRE.replace(" btr1=1C", "");
    assert!(
        parse_status(&tokens(&text))
            .unwrap_err()
            .to_string()
            .contains("btr1= is missing")
    );
}

#[test]
fn registers_nodes_and_flush_round_trip() {
    let mut values: Vec<Option<u8>> = (0..128).map(|a| Some(a as u8)).collect();
    values[1] = None;
    let regs = NodeRegisters {
        number: 3,
        name: "loser".into(),
        dump: RegisterDump {
            mode: CanMode::Peli,
            reset_mode: false,
            values,
        },
    };
    let wire = regs_fields(&regs);
    assert_eq!(wire[..6], ["3", "loser", "peli", "operating", "00", "--"]);
    assert_eq!(parse_regs(&wire).unwrap(), regs);
    let nodes = [
        NodeInfo {
            number: 1,
            name: "node1".into(),
        },
        NodeInfo {
            number: 2,
            name: "pc".into(),
        },
    ];
    assert_eq!(nodes_fields(&nodes), ["1:node1", "2:pc"]);
    assert_eq!(parse_nodes(&nodes_fields(&nodes)).unwrap(), nodes);
    assert_eq!(parse_nodes(&[] as &[String]).unwrap(), []);
    let report = TxReport { sent: 7, failed: 1 };
    assert_eq!(flushed_fields(&report), ["7", "1"]);
    assert_eq!(parse_flushed(&flushed_fields(&report)).unwrap(), report);
}

#[test]
fn garbage_registers_nodes_and_flush_are_named() {
    let regs = |text: &str| parse_regs(&tokens(text)).unwrap_err().to_string();
    assert!(regs("3 x peli operating 00").contains("128 register values"));
    assert!(regs("3 x basic reset 00").contains("32 register values"));
    assert!(regs("3 x fd operating").contains("peli or basic"));
    assert!(regs("3 x peli sleeping").contains("reset or operating"));
    let mut bad = "3 x basic reset".to_string();
    for _ in 0..31 {
        bad.push_str(" 00");
    }
    bad.push_str(" GG");
    assert!(regs(&bad).contains("register 31=\"GG\""), "{}", regs(&bad));
    for bad in ["1", "x:pc", "1:", "-1:pc"] {
        let err = parse_nodes(&[bad]).unwrap_err().to_string();
        assert!(err.contains("N:NAME"), "{bad}: {err}");
    }
    for bad in ["", "1", "1 2 3", "1 x"] {
        let err = parse_flushed(&tokens(bad)).unwrap_err().to_string();
        assert!(err.contains("SENT FAILED"), "{bad}: {err}");
    }
}

#[test]
fn refusals_round_trip_and_garbage_is_named() {
    use buslab_bus::admin::FaultLimit;
    use buslab_socketcand::reply::{parse_refused, refused_fields};
    use std::time::Duration;
    let rate = FaultLimit::Rate {
        max: 20,
        per: Duration::from_secs(1),
        retry_after: Duration::from_millis(35),
    };
    assert_eq!(
        refused_fields(&rate),
        ["fault", "rate", "max=20", "per_ms=1000", "retry_ms=35"]
    );
    assert_eq!(parse_refused(&refused_fields(&rate)).unwrap(), rate);
    let active = FaultLimit::Active { max: 1024 };
    assert_eq!(refused_fields(&active), ["fault", "active", "max=1024"]);
    assert_eq!(parse_refused(&refused_fields(&active)).unwrap(), active);
    // A wait of a fraction of a millisecond is rounded up: waiting that long lets one through.
    let soon = FaultLimit::Rate {
        max: 20,
        per: Duration::from_secs(1),
        retry_after: Duration::from_micros(1),
    };
    assert!(refused_fields(&soon).contains(&"retry_ms=1".to_string()));
    for bad in [
        "",
        "fault",
        "fault active",
        "fault active 1024",
        "fault rate max=20 per_ms=1000",
        "frame active max=1",
        "fault active max=1 extra",
    ] {
        let err = parse_refused(&tokens(bad)).unwrap_err().to_string();
        assert!(err.contains("fault active max=N"), "{bad}: {err}");
    }
    for (bad, key) in [
        ("fault active max=-1", "max"),
        ("fault active max=99999999999", "max"),
        ("fault rate max=2 per_ms=x retry_ms=1", "per_ms"),
    ] {
        let err = parse_refused(&tokens(bad)).unwrap_err().to_string();
        assert!(err.contains(&format!("{key}=")), "{bad}: {err}");
    }
}

#[test]
fn a_reply_element_parses_into_its_tokens() {
    let m = ServerMessage::parse(&format!("buslab_status {WIRE}")).unwrap();
    let ServerMessage::Other { name, args } = m else {
        panic!("{m:?}")
    };
    assert_eq!(name, "buslab_status");
    assert_eq!(parse_status(&args).unwrap(), status());
}

proptest! {
    /// Any tokens: an answer or an error, never a panic.
    #[test]
    fn any_reply_tokens_parse_without_panic(tokens in proptest::collection::vec("[ -~]{0,12}", 0..40)) {
        let _ = parse_status(&tokens);
        let _ = parse_regs(&tokens);
        let _ = parse_nodes(&tokens);
        let _ = parse_flushed(&tokens);
        let _ = buslab_socketcand::parse_refused(&tokens);
    }

    #[test]
    fn any_status_round_trips(
        number in any::<u32>(), sent in any::<u64>(), txerr in any::<u8>(), ecc in proptest::option::of(any::<u8>()),
        load in 0u32..=1000, matches in any::<bool>(),
    ) {
        let mut st = status();
        st.number = number;
        st.counters.sent = sent;
        st.errors = Some(ErrorRegisters { alc: None, ecc: ecc.map(Ecc), rxerr: 1, txerr });
        st.bus.load_percent = load as f64 / 10.0;
        st.timing.as_mut().unwrap().matches_bus = matches;
        prop_assert_eq!(parse_status(&status_fields(&st)).unwrap(), st);
    }
}
