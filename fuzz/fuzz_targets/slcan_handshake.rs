//! Opening an SLCAN adapter (`buslab_slcan::Handshake`, the `slcan:` backend): whatever the
//! adapter sends, leftovers, garbage, version lines at any moment. No panic; what it asks to
//! send stays bounded (a handful of exchanges); once open or failed it stays so; frames are
//! given back only once `O`/`L` went out.
//!
//! Input: the first byte picks the plan (bit rate, listen-only, an FD data bit rate); then data bytes are the
//! adapter's output, cut into lines as the client does, and `FF` + any op byte means the line
//! went quiet (`settled`).
#![no_main]

use buslab_fuzz::{Item, items};
use buslab_slcan::Command;
use buslab_slcan::codec::{Line, LineSplitter, MAX_REPLY_LINE, parse_reply};
use buslab_slcan::handshake::{Handshake, Plan, Status};
use libfuzzer_sys::fuzz_target;

/// Every exchange is one command and `V`: at most nine of them (sync, Z1, N, CANable's mode,
/// the bit rate, the data bit rate, L, and the M1 + O fallback), each under 16 bytes.
const MAX_SENT: usize = 9 * 16;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    let bitrate = match pick & 3 {
        0 => None,
        1 => Some((500_000, Some(Command::Bitrate(6)))),
        2 => Some((750_000, None)),
        _ => Some((
            33_333,
            Some(Command::Btr {
                btr0: 0x0B,
                btr1: 0x2F,
            }),
        )),
    };
    let mut hs = Handshake::new(Plan {
        bitrate,
        listen_only: pick & 4 != 0,
        data_bitrate: (pick & 8 != 0).then_some(2),
    });
    let mut splitter = LineSplitter::with_limit(MAX_REPLY_LINE);
    let mut sent = Vec::new();
    let mut ended: Option<Status> = None;
    for item in items(rest) {
        if let Some(bytes) = hs.poll_transmit() {
            sent.extend_from_slice(&bytes);
            assert!(sent.len() <= MAX_SENT, "sent {sent:?}");
        }
        match item {
            Item::Data(byte) => {
                let parsed = match splitter.push(byte) {
                    None => continue,
                    Some(Line::Text(t)) => parse_reply(t, false),
                    Some(Line::Bell(t)) => parse_reply(t, true),
                    Some(Line::TooLong) => {
                        hs.handle_garbage();
                        continue;
                    }
                };
                match parsed {
                    Ok(reply) => {
                        if hs.handle(reply).is_some() {
                            let opening = sent.ends_with(b"O\rV\r") || sent.ends_with(b"L\rV\r");
                            assert!(opening || hs.status() == Status::Open, "{sent:?}");
                        }
                    }
                    Err(_) => hs.handle_garbage(),
                }
            }
            Item::Op(_) => hs.settled(),
        }
        let status = hs.status();
        if let Some(end) = &ended {
            assert_eq!(&status, end, "an ended handshake changed");
        } else if matches!(status, Status::Open | Status::Failed(_)) {
            ended = Some(status);
        }
    }
});
