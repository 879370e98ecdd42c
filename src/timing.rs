//! The control cycle's period, defined once as an integer, and everything derived from
//! it: the control rate, the motion time step, the housekeeping and scrub periods, the
//! telemetry clock. The board derives its timer reload from [`CONTROL_RATE_HZ`].

use crate::units::US_PER_S;

/// Control period (microseconds): one control cycle.
pub const CYCLE_US: u32 = 1_000;
/// Control rate (Hz): control cycles per second.
pub const CONTROL_RATE_HZ: u32 = US_PER_S / CYCLE_US;
/// Control period (s), for the motion profiles.
pub const CYCLE_S: f32 = CYCLE_US as f32 / US_PER_S as f32;
/// Control period (s) in f64 (exact to the f64 rounding of the microsecond count, unlike
/// `f64::from(CYCLE_S)`), for the ground tools and the tests.
pub const CYCLE_S_F64: f64 = CYCLE_US as f64 / US_PER_S as f64;
/// Periodic housekeeping TM[3,25]: one report per second (cycles).
pub const HK_PERIOD_CYCLES: u32 = CONTROL_RATE_HZ;
/// RAM scrub of the running table and the supervision thresholds: one check per
/// second (cycles).
pub const SCRUB_PERIOD_CYCLES: u32 = CONTROL_RATE_HZ;

/// Temperature sensors (`hw::TemperatureInputs`): every channel read once per 100 ms
/// (cycles), the rate `thermal::STUCK_SAMPLES` and `thermal::MEAN_SAMPLES` are sized
/// for (a stuck channel found in 6.4 s, a mean every 1.6 s).
pub const TEMPERATURE_PERIOD_CYCLES: u32 = CONTROL_RATE_HZ / 10;
/// The cycle within each [`TEMPERATURE_PERIOD_CYCLES`] the sensors are read on: half a
/// period after the cycles that are whole seconds, where the default housekeeping
/// report and the scrub fall (reading on those cycles too made the largest control
/// cycle 17,719 instructions instead of 16,550: `scripts/bench.sh`).
pub const TEMPERATURE_PHASE_CYCLES: u32 = TEMPERATURE_PERIOD_CYCLES / 2;

/// The cycle within each second (`thermal::compensation::STEP_PERIOD_CYCLES`) the
/// thermal compensation steps on: a quarter of a temperature period after the whole
/// seconds, off the housekeeping and scrub cycles (whole seconds) and off the sensor
/// readings ([`TEMPERATURE_PHASE_CYCLES`] within each 100 ms), so that no control cycle
/// carries two of them.
pub const COMPENSATION_PHASE_CYCLES: u32 = TEMPERATURE_PERIOD_CYCLES / 4;

/// Microseconds since boot of control cycle `cycle` (the telemetry clock).
pub const fn cycle_to_us(cycle: u64) -> u64 {
    cycle * CYCLE_US as u64
}

// The period must divide a second exactly, so that the derived rates are exact.
const _: () = assert!(US_PER_S % CYCLE_US == 0);
// ... and 100 ms a whole number of cycles.
const _: () = assert!(CONTROL_RATE_HZ % 10 == 0);
