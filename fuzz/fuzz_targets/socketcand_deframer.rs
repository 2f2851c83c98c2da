//! The socketcand deframer over arbitrary bytes, pushed whole and in arbitrary pieces: no
//! panic, elements hold no `<`/`>` and fit MAX_ELEMENT, the buffer stays bounded, and how the
//! bytes are split does not change the elements found.
#![no_main]

use buslab_socketcand::{Deframer, ElementError, MAX_ELEMENT};
use libfuzzer_sys::fuzz_target;

/// Every result until the deframer needs more bytes; checks the buffer bound after each.
fn drain(d: &mut Deframer, out: &mut Vec<Result<String, ElementError>>) {
    while let Some(result) = d.next_element() {
        if let Ok(e) = &result {
            assert!(e.len() <= MAX_ELEMENT, "element of {} bytes", e.len());
            assert!(!e.contains(['<', '>']), "element {e:?} holds < or >");
        }
        out.push(result);
    }
    assert!(
        d.len() <= MAX_ELEMENT + 1,
        "{} bytes left buffered",
        d.len()
    );
}

fuzz_target!(|data: &[u8]| {
    // The first byte picks the piece size (1..=16) for the second run.
    let Some((&split, bytes)) = data.split_first() else {
        return;
    };
    let mut whole = Vec::new();
    let mut d = Deframer::new();
    d.push(bytes);
    drain(&mut d, &mut whole);

    let mut pieces = Vec::new();
    let mut d = Deframer::new();
    for chunk in bytes.chunks(usize::from(split % 16) + 1) {
        d.push(chunk);
        drain(&mut d, &mut pieces);
    }
    let elements = |r: &[Result<String, ElementError>]| -> Vec<String> {
        r.iter().filter_map(|r| r.as_ref().ok().cloned()).collect()
    };
    assert_eq!(elements(&whole), elements(&pieces));
});
