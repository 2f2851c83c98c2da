//! Any bytes are a value or an error, never a panic; what is formatted parses back.

use buslab_can::{FD_LENGTHS, FdFrame, Frame, Id, Nanos};
use buslab_slcan::{
    Adapter, Command, LineSplitter, MAX_LINE, MAX_OUTPUT, Reply, format_command, format_reply,
    parse_command, parse_reply,
};
use proptest::prelude::*;

fn frame() -> impl Strategy<Value = Frame> {
    (
        id(),
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

fn id() -> impl Strategy<Value = Id> {
    prop_oneof![
        (0u16..=0x7FF).prop_map(|r| Id::standard(r).unwrap()),
        (0u32..=0x1FFF_FFFF).prop_map(|r| Id::extended(r).unwrap()),
    ]
}

/// An FD frame as SLCAN carries it: any ID, length and BRS (SLCAN has no ESI).
fn fd_frame() -> impl Strategy<Value = FdFrame> {
    (
        id(),
        any::<bool>(),
        proptest::sample::select(FD_LENGTHS.to_vec()),
        any::<[u8; 64]>(),
    )
        .prop_map(|(id, brs, len, data)| FdFrame::new(id, &data[..len]).unwrap().with_brs(brs))
}

proptest! {
    #[test]
    fn parsers_take_any_line(line in proptest::collection::vec(any::<u8>(), 0..160), bell: bool) {
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
    fn fd_frames_round_trip_both_ways(f in fd_frame(), stamp in proptest::option::of(0u16..60_000)) {
        let mut out = Vec::new();
        format_command(&Command::TransmitFd(f), &mut out);
        prop_assert_eq!(parse_command(&out[..out.len() - 1]), Ok(Command::TransmitFd(f)));
        let reply = Reply::FdFrame { frame: f, timestamp_ms: stamp };
        let mut out = Vec::new();
        format_reply(&reply, &mut out);
        prop_assert!(out.len() <= MAX_LINE + 1);
        prop_assert_eq!(parse_reply(&out[..out.len() - 1], false), Ok(reply));
    }

    /// Any FD line cut short or grown by one character is an error, never another frame.
    #[test]
    fn an_fd_line_of_the_wrong_length_is_refused(f in fd_frame(), cut in 1usize..4) {
        let mut out = Vec::new();
        format_command(&Command::TransmitFd(f), &mut out);
        out.pop();
        let short = &out[..out.len().saturating_sub(cut)];
        if short.len() > 4 {
            prop_assert!(parse_command(short).is_err());
        }
        let mut long = out.clone();
        long.push(b'0');
        prop_assert!(parse_command(&long).is_err());
    }

    #[test]
    fn the_adapter_takes_any_bytes_and_stays_bounded(
        chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..200), 0..50),
    ) {
        let mut adapter = Adapter::default().with_fd(chunks.len() % 2 == 0);
        let mut splitter = LineSplitter::new();
        let long: FdFrame = format!("1FFFFFFF##1{}", "00".repeat(64)).parse().unwrap();
        for chunk in &chunks {
            adapter.receive(chunk);
            adapter.deliver(&"123#1122".parse().unwrap(), Nanos::from_millis(1));
            adapter.deliver_fd(&long, Nanos::from_millis(1));
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
            fd_frame().prop_map(Command::TransmitFd), Just(Command::DataBitrate(2)),
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
