//! DBC files (`buslab_dbc::Database::from_bytes`): no panic on any bytes; in a file that
//! loads, every message decodes any payload (longer, shorter, all zeros, all ones) the same
//! way through `decode` and `decode_into`, prints as text, and encodes what it decoded
//! (an error is fine, a panic is not).
#![no_main]

use buslab_dbc::Database;
use buslab_dbc::text::DecodedMessage;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(db) = Database::from_bytes(data) else {
        return;
    };
    // Payloads from the input itself, and the two constant ones.
    let head = &data[..data.len().min(64)];
    let tail = &data[data.len().saturating_sub(9)..];
    let payloads: [&[u8]; 4] = [head, tail, &[0; 64], &[0xFF; 64]];
    let mut reused = Vec::new();
    for message in db.messages() {
        assert!(message.length() <= 64);
        for payload in payloads {
            for payload in [payload, &payload[..payload.len().min(message.length())]] {
                let decoded = message.decode(payload);
                message.decode_into(payload, &mut reused);
                // Bit for bit (a float signal's NaN is not equal to itself).
                let bits = |v: &[buslab_dbc::Decoded]| -> Vec<(usize, u64, u64)> {
                    v.iter()
                        .map(|d| (d.signal, d.raw, d.physical.to_bits()))
                        .collect()
                };
                assert_eq!(bits(&decoded), bits(&reused));
                let _ = DecodedMessage {
                    message,
                    values: &decoded,
                }
                .to_string();
                let values: Vec<(&str, f64)> = decoded
                    .iter()
                    .map(|d| (message.signals()[d.signal].name(), d.physical))
                    .collect();
                if let Ok(encoded) = message.encode(&values) {
                    assert_eq!(encoded.len(), message.length());
                }
            }
        }
    }
});
