//! The simulated plant (host only): the "true" mechanism the controller drives.
//!
//! * [`manufacturing`]: a true geometry = nominal + manufacturing errors from a seed.
//! * [`plant`]: six sliders with finite speed and encoders with 0.1 um quantisation and
//!   noise, implementing the same [`crate::hw`] traits the board glue implements on the
//!   target; everything is deterministic from a seed.
//! * [`drive_train`]: the opt-in drive train between each drive and its slider
//!   (microsteps, backlash, lead error, stiction, settling).
//! * [`thermal`]: the parts' temperatures (an on-orbit profile with each part's lag),
//!   the true geometry they give the mechanism, and the temperature sensors.
//! * [`tracker`]: the measuring instruments: the idealised pose tracker and a laser
//!   tracker measuring target balls in its own frame, with its noise model.
//! * [`soak`]: the model-based soak: random operator/adversary sequences on the bench
//!   with the operator contract checked every cycle (the soak test and the fuzzer).
//! * [`bench`]: the one test bench: controller + link service + worker + plant + flash
//!   + ground station, one tick per control cycle.

// Host only (feature `host`): a ground tool or a simulation may stop on a broken
// invariant, so the flight code's panic-free rules (src/lib.rs) do not apply here.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::unreachable,
    clippy::indexing_slicing
)]

pub mod bench;
pub mod drive_train;
pub mod manufacturing;
pub mod plant;
pub mod soak;
pub mod thermal;
pub mod tracker;

pub use bench::{Bench, BenchConfig};
pub use plant::{InjectedFault, Plant, PlantConfig, SharedPlant, SwitchEnd};

/// `reached - target` per axis: `[x, y, z]` in um and `[alpha, beta, gamma]` in arcsec
/// (base frame; rotations as the poses give them). The accuracy figures of the plant's
/// tests, the mission and the calibration tools all measure with it.
pub fn pose_error(
    reached: &crate::kinematics::Pose<f64>,
    target: &crate::kinematics::Pose<f64>,
) -> [f64; 6] {
    use crate::units::{ARCSEC_PER_RAD, UM_PER_MM};
    let mut e = [0.0; 6];
    for a in 0..3 {
        e[a] = (reached.translation_mm[a] - target.translation_mm[a]) * UM_PER_MM;
        e[a + 3] = (reached.rotation_rad[a] - target.rotation_rad[a]) * ARCSEC_PER_RAD;
    }
    e
}
