//! S-record files (`srec::parse`, what `buslab load` and the PowerPC node's loader read, and
//! `loader::check` against the node's memory map): no panic; a file that parses writes back
//! (`srec::write`) to one that parses to the same data and entry point.
#![no_main]

use buslab_loader::memory::MemoryMap;
use buslab_loader::{loader, srec};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = loader::check(&MemoryMap::ppc403(), data);
    let Ok(program) = srec::parse(data) else {
        return;
    };
    let written = srec::write(
        program.header.as_deref().unwrap_or_default(),
        program
            .segments
            .iter()
            .map(|s| (s.address, s.data.as_slice())),
        program.start,
    );
    let again = srec::parse(&written).expect("buslab's own S-records read back");
    let bytes = |p: &srec::Program| -> Vec<(u32, u8)> {
        p.segments
            .iter()
            .flat_map(|s| {
                s.data
                    .iter()
                    .enumerate()
                    .map(move |(i, &b)| (s.address.wrapping_add(i as u32), b))
            })
            .collect()
    };
    assert_eq!(bytes(&again), bytes(&program));
    assert_eq!(again.start, program.start);
});
