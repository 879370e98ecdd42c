//! Manufacturing errors: a "true" geometry drawn around the nominal one.

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;

use crate::kinematics::GeometryParams;

/// Default standard deviation of each joint-centre coordinate's error (mm): machining
/// and assembly of the order of the paper's Table 1 differences.
pub const DEFAULT_JOINT_SIGMA_MM: f64 = 0.1;
/// Errors are truncated at this many standard deviations, so that a drawn mechanism
/// stays inside a calibration box of a few sigma.
pub const TRUNCATION_SIGMAS: f64 = 3.0;

/// Nominal geometry with every joint-centre coordinate (a_i and b_i, x/y/z) offset by a
/// truncated Gaussian error of standard deviation `sigma_mm`; p0 and limits unchanged.
/// Deterministic for a given seed.
pub fn perturbed(nominal: &GeometryParams, sigma_mm: f64, seed: u64) -> GeometryParams {
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut out = *nominal;
    let limit = TRUNCATION_SIGMAS * sigma_mm;
    let normal = Normal::new(0.0, sigma_mm.abs()).ok();
    let draw = |rng: &mut Pcg64| -> f64 {
        match &normal {
            Some(n) => n.sample(rng).clamp(-limit.abs(), limit.abs()),
            None => 0.0,
        }
    };
    for leg in out.legs.iter_mut() {
        for v in leg.a_mm.iter_mut().chain(leg.b_mm.iter_mut()) {
            *v += draw(&mut rng);
        }
    }
    out
}
