//! Any bytes are a value or an error, never a panic; what is formatted parses back.

use buslab_can::{Frame, Id, Nanos};
use buslab_slcan::{
    Adapter, Command, LineSplitter, MAX_LINE, MAX_OUTPUT, Reply, format_command, format_reply,
    parse_command, parse_reply,
};
use proptest::prelude::*;

fn frame() -> impl Strategy<Value = Frame> {
    let id = prop_oneof![
        (0u16..=0x7FF).prop_map(|r| Id::standard(r).unwrap()),
        (0u32..=0x1FFF_FFFF).prop_map(|r| Id::extended(r).unwrap()),
    ];
    (
        id,
        any::<bool>(),
        proptest::collection::vec(any::<u8>(), 0..=8),
        0u8..=8,
    )
        .prop_map(|(id, remote, data, dlc)| {
            if remote {
                Frame::remote(id, dlc).unwrap()
            } else {
                Frame::data(id, &data).unwrap()
            }
        })
}

proptest! {
    #[test]
    fn parsers_take_any_line(line in proptest::collection::vec(any::<u8>(), 0..80), bell: bool) {
        let _ = parse_command(&line);
        let _ = parse_reply(&line, bell);
    }

    #[test]
    fn frames_round_trip_both_ways(f in frame(), stamp in proptest::option::of(0u16..60_000)) {
        let mut out = Vec::new();
        format_command(&Command::Transmit(f), &mut out);
        prop_assert_eq!(parse_command(&out[..out.len() - 1]), Ok(Command::Transmit(f)));
        let reply = Reply::Frame { frame: f, timestamp_ms: stamp };
        let mut out = Vec::new();
        format_reply(&reply, &mut out);
        prop_assert!(out.len() <= 31);
        prop_assert_eq!(parse_reply(&out[..out.len() - 1], false), Ok(reply));
    }

    #[test]
    fn the_adapter_takes_any_bytes_and_stays_bounded(
        chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..200), 0..50),
    ) {
        let mut adapter = Adapter::default();
        let mut splitter = LineSplitter::new();
        for chunk in &chunks {
            adapter.receive(chunk);
            adapter.deliver(&"123#1122".parse().unwrap(), Nanos::from_millis(1));
            for &b in chunk {
                splitter.push(b);
                prop_assert!(splitter.pending() <= MAX_LINE);
            }
            prop_assert!(adapter.output().len() <= MAX_OUTPUT);
            while adapter.poll_event().is_some() {}
        }
    }

    #[test]
    fn typed_commands_survive_a_byte_stream(cmds in proptest::collection::vec(
        prop_oneof![
            Just(Command::Open), Just(Command::Close), Just(Command::Status),
            (0u8..=8).prop_map(Command::Bitrate), frame().prop_map(Command::Transmit),
        ], 0..20)) {
        let mut bytes = Vec::new();
        for c in &cmds {
            format_command(c, &mut bytes);
        }
        let mut splitter = LineSplitter::new();
        let mut back = Vec::new();
        for &b in &bytes {
            if let Some(buslab_slcan::Line::Text(t)) = splitter.push(b) {
                back.push(parse_command(t).unwrap());
            }
        }
        prop_assert_eq!(back, cmds);
    }
}
