//! A simulated calibration campaign on the idealised path: the "true" mechanism (nominal
//! plus manufacturing errors drawn from a seed), commanded with the nominal parameters,
//! measured by the idealised [`PoseTracker`] (Gaussian noise on the measured pose). The
//! instrument models live in [`m2ctl::sim::tracker`]; the realistic campaign (target
//! balls measured by a laser tracker) is [`super::tracker`].
//!
//! Encoders are taken as exact (the strokes read are the commanded ones): the paper's
//! mechanism resolves 0.1 um, far below the tracker noise.

use rand::SeedableRng;
use rand_pcg::Pcg64;

use super::calib::Measurement;
use m2ctl::kinematics::{ik, Geometry, GeometryParams, Pose};
use m2ctl::sim::tracker::PoseTracker;

/// Default standard deviation of the manufacturing error of each joint coordinate (mm),
/// the simulated plant's default.
pub const DEFAULT_MANUFACTURING_SIGMA_MM: f64 = m2ctl::sim::manufacturing::DEFAULT_JOINT_SIGMA_MM;
/// True geometry = nominal + truncated Gaussian manufacturing errors on the 36 joint
/// coordinates, from a seed: the simulated plant's generator.
pub use m2ctl::sim::manufacturing::perturbed;

/// Why a simulated campaign failed.
#[derive(Clone, Debug, PartialEq)]
pub struct CampaignError(pub String);

impl std::fmt::Display for CampaignError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CampaignError {}

/// Where the true mechanism goes for `strokes_mm` (the simulated instrument's
/// [`sim::tracker::true_motion`](m2ctl::sim::tracker::true_motion)), the error in words.
pub(crate) fn reached(
    truth: &Geometry<f64>,
    strokes_mm: &[f64; 6],
    near: &Pose<f64>,
) -> Result<Pose<f64>, CampaignError> {
    m2ctl::sim::tracker::true_motion(truth, strokes_mm, near).map_err(|e| {
        CampaignError(format!(
            "true mechanism: {}",
            super::ikfk::describe_fk_error(&e)
        ))
    })
}

/// The working geometry of `params`, the error in words.
pub(crate) fn geometry(params: &GeometryParams) -> Result<Geometry<f64>, CampaignError> {
    Geometry::<f64>::new(params)
        .map_err(|e| CampaignError(super::files::describe_geometry_error(&e)))
}

/// Commands target `k` (0-based) with the `commanded` geometry on the `truth` mechanism:
/// the strokes `IK(target, commanded)` (mm) and the pose the true mechanism reaches with
/// them; an error names the target (1-based).
pub(crate) fn command(
    commanded: &Geometry<f64>,
    truth: &Geometry<f64>,
    k: usize,
    target: &Pose<f64>,
) -> Result<([f64; 6], Pose<f64>), CampaignError> {
    let strokes = ik(commanded, target).map_err(|e| {
        CampaignError(format!(
            "target {}: {}",
            k + 1,
            super::ikfk::describe_ik_error(&e)
        ))
    })?;
    let actual = reached(truth, &strokes, target)?;
    Ok((strokes, actual))
}

/// Simulates the campaign: for each target, command `IK(target, nominal)`, let the true
/// mechanism move, measure its pose with `tracker` (noise drawn from `noise_seed`) and
/// read the commanded strokes.
pub fn simulate(
    nominal: &GeometryParams,
    truth: &GeometryParams,
    targets: &[Pose<f64>],
    tracker: &PoseTracker,
    noise_seed: u64,
) -> Result<Vec<Measurement>, CampaignError> {
    let nom = geometry(nominal)?;
    let tru = geometry(truth)?;
    let mut rng = Pcg64::seed_from_u64(noise_seed);
    let mut out = Vec::with_capacity(targets.len());
    for (k, target) in targets.iter().enumerate() {
        let (strokes, actual) = command(&nom, &tru, k, target)?;
        out.push(Measurement {
            line: 0,
            pose: tracker.measure(&actual, &mut rng),
            strokes_mm: strokes,
        });
    }
    Ok(out)
}
