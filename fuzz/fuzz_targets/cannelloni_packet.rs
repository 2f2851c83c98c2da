//! cannelloni UDP datagrams (`buslab_cannelloni::decode_packet`, what the `cannelloni:`
//! backend reads from the network): no panic, and a DATA packet's frames, encoded again,
//! decode to the same frames.
#![no_main]

use buslab_cannelloni::{MAX_DATAGRAM, OpCode, decode_packet, encode_packets};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(packet) = decode_packet(data)
        && packet.op == OpCode::Data
    {
        let again = encode_packets(packet.seq, &packet.frames, MAX_DATAGRAM).unwrap();
        let frames: Vec<_> = again
            .iter()
            .flat_map(|d| decode_packet(d).unwrap().frames)
            .collect();
        assert_eq!(frames, packet.frames);
    }
});
