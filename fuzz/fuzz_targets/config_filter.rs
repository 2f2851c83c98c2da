//! The wizard's acceptance filter text (`buslab_config::filter`): the IDs a user wants
//! (`parse_wanted`), the filter derived from them (`derive`) and its explanation (`explain`).
//! The first byte chooses the filter kind; the rest is what the user typed. Besides no panic:
//! a derived filter lets every wanted ID through (the model's own check), and its explanation
//! names at least one way through.
#![no_main]

use buslab_can::Frame;
use buslab_config::filter::{Kind, derive, explain, parse_wanted};
use buslab_fuzz::text;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&which, rest)) = data.split_first() else {
        return;
    };
    let Some(input) = text(rest) else { return };
    let Ok(wanted) = parse_wanted(input) else {
        return;
    };
    let kind = [Kind::Basic, Kind::Single, Kind::Dual][usize::from(which % 3)];
    let Ok(derived) = derive(kind, &wanted) else {
        return;
    };
    for w in &wanted {
        for id in [w.low, w.high] {
            let text = if w.extended {
                format!("{id:08X}#01")
            } else {
                format!("{id:03X}#01")
            };
            let frame: Frame = text.parse().expect("an ID parse_wanted took");
            assert!(
                derived.filter.accepts(&frame),
                "{input:?} ({kind:?}): {frame} wanted and refused by {:?}",
                derived.filter
            );
        }
    }
    assert!(!explain(&derived.filter).is_empty());
});
