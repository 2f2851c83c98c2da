//! Scenario files (`Scenario::from_toml`, what `buslab sim` loads): no panic reading one, and a
//! small accepted scenario builds (or says why not) and runs for a while without panicking.
#![no_main]

use buslab_fuzz::text;
use buslab_sim::Scenario;
use libfuzzer_sys::fuzz_target;

/// Bit-times a small accepted scenario runs (enough for a few frames and faults to start).
const RUN_BITS: u64 = 2_000;

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    let Ok(scenario) = Scenario::from_toml(text) else {
        return;
    };
    for i in 0..scenario.faults.len() {
        let _ = scenario.describe_fault(i);
    }
    // Nodes that need a host model (SJA1000 nodes run by `buslab sim`) do not build on the
    // bare engine: an error, not a panic.
    if scenario.nodes.len() <= 8
        && let Ok(mut sim) = scenario.build()
    {
        sim.run_for(RUN_BITS.min(scenario.duration));
    }
});
