//! socketcand commands as a client sends them (`Command::parse` of an element's inside): no
//! panic, and an accepted command prints as an element that parses to the same command.
#![no_main]

use buslab_fuzz::{assert_reparses, element_inside, text};
use buslab_socketcand::Command;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some(inner) = text(data) else { return };
    if let Ok(command) = Command::parse(inner) {
        let printed = command.to_string();
        assert_reparses(&command, element_inside(&printed), Command::parse);
    }
});
