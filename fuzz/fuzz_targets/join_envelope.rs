//! Join envelopes (`buslab_join::Envelope::decode`, what the `mqtt:` backend reads from the
//! broker) through a receiver's accounting: no panic, an envelope read encodes and reads back
//! the same, and the tracker's counts add up.
#![no_main]

use buslab_join::{Accepted, Envelope, Tracker};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut tracker = Tracker::new(1);
    let mut delivered = 0u64;
    // The input as several envelopes back to back, each prefixed with its length (u16).
    let mut rest = data;
    while let Some((len, after)) = rest.split_first_chunk::<2>() {
        let len = usize::from(u16::from_be_bytes(*len)).min(after.len());
        let (bytes, next) = after.split_at(len);
        rest = next;
        if let Ok(envelope) = Envelope::decode(bytes) {
            let again = envelope.encode().expect("a decoded envelope encodes");
            assert_eq!(Envelope::decode(&again).as_ref(), Ok(&envelope));
            if let Accepted::Frames(frames) = tracker.accept(envelope) {
                delivered += frames.len() as u64;
            }
        }
    }
    let received: u64 = tracker.peers().map(|p| p.received).sum();
    assert_eq!(received, delivered);
});
