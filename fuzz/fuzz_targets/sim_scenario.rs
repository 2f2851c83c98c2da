//! Scenario files (`Scenario::from_toml`, what `buslab sim` loads): no panic reading one, and a
//! small accepted scenario builds (or says why not) and runs for a while without panicking.
#![no_main]

use buslab_bench::Scenario;
use buslab_can::BitTime;
use buslab_fuzz::text;
use libfuzzer_sys::fuzz_target;

/// Bit-times a small accepted scenario runs (enough for a few frames and faults to start).
const RUN_BITS: BitTime = BitTime::new(2_000);

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    let Ok(scenario) = Scenario::from_toml(text) else {
        return;
    };
    for i in 0..scenario.faults.len() {
        let _ = scenario.describe_fault(i);
    }
    // A node the factory cannot make (an SJA1000 at a bit rate its crystal cannot reach) is
    // an error, not a panic.
    if scenario.nodes.len() <= 8
        && let Ok(mut sim) = scenario.build()
    {
        sim.run_for(RUN_BITS.min(scenario.duration));
    }
});
