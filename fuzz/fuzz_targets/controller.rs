//! The controller's `control_cycle` and telecommand handling, through the real link
//! service and worker on the simulated bench, driven by arbitrary decision sequences:
//! telecommands valid and invalid, plant faults, power cuts, time passing. The soak's
//! invariants (`m2ctl::sim::soak`) are the assertions: any violation aborts.
#![no_main]

use libfuzzer_sys::fuzz_target;
use m2ctl::sim::soak::{ByteChoices, Soak};

/// Longest quiet gap between two actions (cycles).
const MAX_GAP_CYCLES: usize = 200;
/// Cycles to let the last telecommands finish.
const DRAIN_CYCLES: u32 = 500;

fuzz_target!(|bytes: &[u8]| {
    let mut s = Soak::new(ByteChoices::new(bytes));
    while !s.is_exhausted() {
        s.round(MAX_GAP_CYCLES);
    }
    s.drain(DRAIN_CYCLES);
    assert!(
        s.violations().is_empty(),
        "{} violations, first: {:?}",
        s.violations().len(),
        s.violations().first()
    );
});
