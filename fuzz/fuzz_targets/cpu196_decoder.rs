//! The CPU196 stream decoder (what the board and the host client run on every received byte)
//! over arbitrary bytes at arbitrary gaps, with arbitrary user-command lengths: no panic, no
//! partial frame left once the time-out has passed, and every message it delivers encodes to
//! a frame that decodes to the same message.
#![no_main]

use buslab_cpu196::{Decoder, Event};
use buslab_device::Nanos;
use libfuzzer_sys::fuzz_target;

/// Input: a header byte, then the bytes on the line. Header bits 0..1: how many user commands
/// get a parameter count (each two bytes after the header: command, count mod 33); bit 7: a
/// pause longer than the time-out before every Nth byte, N = header bits 2..6, plus 1.
fn run(data: &[u8]) {
    let Some((&header, mut rest)) = data.split_first() else {
        return;
    };
    let mut decoder = Decoder::new();
    let mut user = Vec::new();
    for _ in 0..header & 3 {
        let [cmd, len, tail @ ..] = rest else { return };
        decoder.set_user_len(*cmd, len % 33);
        user.push((*cmd, len % 33));
        rest = tail;
    }
    let every = usize::from((header >> 2) & 0x1F) + 1;
    let mut now = Nanos::ZERO;
    for (i, &byte) in rest.iter().enumerate() {
        now += if header & 0x80 != 0 && i % every == every - 1 {
            Nanos::from_secs(1)
        } else {
            Nanos::from_millis(1)
        };
        let adcont = decoder.adcont_len();
        if let Some(Event::Message(m)) = decoder.push(now, byte) {
            let bytes = m.to_bytes().expect("a decoded message encodes");
            let mut again = Decoder::new();
            for &(cmd, len) in &user {
                again.set_user_len(cmd, len);
            }
            again.set_adcont_len(adcont);
            let events: Vec<Event> = bytes.iter().filter_map(|&b| again.push(now, b)).collect();
            assert_eq!(events, [Event::Message(m)], "re-decoding {bytes:02X?}");
        }
        if let Some(deadline) = decoder.deadline() {
            assert!(deadline >= now);
        }
    }
    let _ = decoder.poll(now.saturating_add(Nanos::from_secs(1)));
    assert!(!decoder.in_frame());
}

fuzz_target!(|data: &[u8]| run(data));
