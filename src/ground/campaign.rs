//! A simulated calibration campaign: the "true" mechanism (nominal plus manufacturing
//! errors drawn from a seed), commanded with the nominal parameters, measured by a laser
//! tracker model with Gaussian noise on the measured pose.
//!
//! Encoders are taken as exact (the strokes read are the commanded ones): the paper's
//! mechanism resolves 0.1 um, far below the tracker noise.

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;

use super::calib::Measurement;
use crate::kinematics::{fk, ik, FkConfig, Geometry, GeometryParams, Pose, ARCSEC_PER_RAD};

/// Default standard deviation of the manufacturing error of each joint coordinate (mm),
/// the simulated plant's default.
pub const DEFAULT_MANUFACTURING_SIGMA_MM: f64 = crate::sim::manufacturing::DEFAULT_JOINT_SIGMA_MM;
/// mm per um.
pub const MM_PER_UM: f64 = 1.0e-3;
/// The paper's simulation noise on the measured translation (um, per axis).
pub const PAPER_NOISE_UM: f64 = 0.1;
/// The paper's simulation noise on the measured rotation (arcsec, per axis).
pub const PAPER_NOISE_ARCSEC: f64 = 0.1;
/// A realistic laser-tracker noise on the translation (um, per axis).
pub const REALISTIC_NOISE_UM: f64 = 5.0;
/// A realistic tracker (4 target balls) noise on the rotation (arcsec, per axis).
pub const REALISTIC_NOISE_ARCSEC: f64 = 1.0;

/// True geometry = nominal + truncated Gaussian manufacturing errors on the 36 joint
/// coordinates, from a seed: the simulated plant's generator.
pub use crate::sim::manufacturing::perturbed;

/// Laser-tracker model: independent Gaussian noise on each measured pose component.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tracker {
    /// Standard deviation of the measured x, y, z (um).
    pub noise_um: f64,
    /// Standard deviation of the measured alpha, beta, gamma (arcsec).
    pub noise_arcsec: f64,
}

impl Tracker {
    /// The paper's simulation noise (0.1 um, 0.1 arcsec).
    pub const PAPER: Tracker = Tracker {
        noise_um: PAPER_NOISE_UM,
        noise_arcsec: PAPER_NOISE_ARCSEC,
    };
    /// Realistic tracker noise (5 um, 1 arcsec).
    pub const REALISTIC: Tracker = Tracker {
        noise_um: REALISTIC_NOISE_UM,
        noise_arcsec: REALISTIC_NOISE_ARCSEC,
    };
    /// A noise-free tracker.
    pub const PERFECT: Tracker = Tracker {
        noise_um: 0.0,
        noise_arcsec: 0.0,
    };

    /// The measured pose of a true pose.
    pub fn measure(&self, truth: &Pose<f64>, rng: &mut Pcg64) -> Pose<f64> {
        let mut p = *truth;
        if let Ok(n) = Normal::new(0.0, self.noise_um * MM_PER_UM) {
            for t in p.translation_mm.iter_mut() {
                *t += n.sample(rng);
            }
        }
        if let Ok(n) = Normal::new(0.0, self.noise_arcsec / ARCSEC_PER_RAD) {
            for r in p.rotation_rad.iter_mut() {
                *r += n.sample(rng);
            }
        }
        p
    }
}

/// Why a simulated campaign failed.
#[derive(Clone, Debug, PartialEq)]
pub struct CampaignError(pub String);

impl std::fmt::Display for CampaignError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CampaignError {}

/// Moves the true mechanism: the pose it reaches for `strokes` (FK with the true
/// parameters, warm-started at `near`).
pub fn true_motion(
    truth: &Geometry<f64>,
    strokes_mm: &[f64; 6],
    near: &Pose<f64>,
) -> Result<Pose<f64>, CampaignError> {
    fk(truth, strokes_mm, near, &FkConfig::default())
        .map(|s| s.pose)
        .map_err(|e| {
            CampaignError(format!(
                "true mechanism: {}",
                super::ikfk::describe_fk_error(&e)
            ))
        })
}

/// Simulates the campaign: for each target, command `IK(target, nominal)`, let the true
/// mechanism move, measure its pose with `tracker` (noise drawn from `noise_seed`) and
/// read the commanded strokes.
pub fn simulate(
    nominal: &GeometryParams,
    truth: &GeometryParams,
    targets: &[Pose<f64>],
    tracker: &Tracker,
    noise_seed: u64,
) -> Result<Vec<Measurement>, CampaignError> {
    let nom = Geometry::<f64>::new(nominal)
        .map_err(|e| CampaignError(super::files::describe_geometry_error(&e)))?;
    let tru = Geometry::<f64>::new(truth)
        .map_err(|e| CampaignError(super::files::describe_geometry_error(&e)))?;
    let mut rng = Pcg64::seed_from_u64(noise_seed);
    let mut out = Vec::with_capacity(targets.len());
    for (k, target) in targets.iter().enumerate() {
        let strokes = ik(&nom, target).map_err(|e| {
            CampaignError(format!(
                "target {}: {}",
                k + 1,
                super::ikfk::describe_ik_error(&e)
            ))
        })?;
        let actual = true_motion(&tru, &strokes, target)?;
        out.push(Measurement {
            line: 0,
            pose: tracker.measure(&actual, &mut rng),
            strokes_mm: strokes,
        });
    }
    Ok(out)
}
