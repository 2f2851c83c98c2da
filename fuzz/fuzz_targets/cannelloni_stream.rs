//! cannelloni's TCP stream (`buslab_cannelloni::StreamDecoder`, what the `cannelloni+tcp:`
//! backend reads): the same bytes cut anywhere give the same frames (the decoder's bound on
//! what it holds is checked by its own tests).
#![no_main]

use buslab_cannelloni::{GREETING, StreamDecoder};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&cut, rest)) = data.split_first() else {
        return;
    };
    let mut stream = GREETING.to_vec();
    stream.extend_from_slice(rest);
    let mut whole = StreamDecoder::new();
    let mut expected = Vec::new();
    let whole_result = whole.push(&stream, &mut expected);
    let mut pieces = StreamDecoder::new();
    let mut got = Vec::new();
    let mut pieces_result = Ok(());
    for piece in stream.chunks(usize::from(cut).max(1)) {
        pieces_result = pieces.push(piece, &mut got);
        if pieces_result.is_err() {
            break;
        }
    }
    assert_eq!(whole_result.is_ok(), pieces_result.is_ok());
    assert_eq!(got, expected);
});
