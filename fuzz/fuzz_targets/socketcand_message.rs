//! socketcand server messages as the client backend reads them (`ServerMessage::parse`): no
//! panic, and an accepted message prints as an element that parses to the same message.
#![no_main]

use buslab_fuzz::{element_inside, text};
use buslab_socketcand::ServerMessage;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some(inner) = text(data) else { return };
    let Ok(message) = ServerMessage::parse(inner) else {
        return;
    };
    let printed = message.to_string();
    match ServerMessage::parse(element_inside(&printed)) {
        Ok(again) if again == message => {}
        // A free error text whose control characters became spaces may then begin like an
        // error frame (`error 004 1.0 …`): socketcand's protocol cannot tell the two apart.
        Ok(ServerMessage::ErrorFrame { .. }) | Err(_)
            if matches!(message, ServerMessage::Error(_)) => {}
        Ok(again) => panic!("{message:?} printed as {printed:?} parses as {again:?}"),
        Err(e) => panic!("{message:?} printed as {printed:?} does not parse: {e}"),
    }
});
