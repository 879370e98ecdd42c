//! Evaluation as the paper scores a calibration: accuracy when commanding with the
//! calibrated parameters. For each held-out target pose, command
//! `IK(target, calibrated)`, let the true mechanism move (FK with the true parameters)
//! and compare the reached pose with the target, per axis (um, arcsec).

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use super::campaign::{command, geometry, CampaignError};
use super::plan::DEFAULT_AXIS_MM;
use m2ctl::kinematics::{GeometryParams, Pose};

/// Default number of held-out evaluation poses.
pub const DEFAULT_EVAL_POSES: usize = 200;
/// Default translation half-range of held-out poses (mm): the paper's stroke, 1 mm.
pub const DEFAULT_EVAL_TRANSLATION_MM: f64 = DEFAULT_AXIS_MM;
/// Default rotation half-range of held-out poses (arcsec): the paper's stroke, 1'.
pub const DEFAULT_EVAL_ROTATION_ARCSEC: f64 = 60.0;

/// Axis names of a pose error row.
pub const AXES: [&str; 6] = ["x", "y", "z", "alpha", "beta", "gamma"];

/// `n` poses uniformly in `+-translation_mm` and `+-rotation_arcsec` per axis, from `seed`.
pub fn random_poses(
    n: usize,
    translation_mm: f64,
    rotation_arcsec: f64,
    seed: u64,
) -> Vec<Pose<f64>> {
    let mut rng = Pcg64::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let t = [0; 3].map(|_| rng.random_range(-1.0..=1.0) * translation_mm);
            let r = [0; 3].map(|_| rng.random_range(-1.0..=1.0) * rotation_arcsec);
            Pose::from_mm_arcsec(t, r)
        })
        .collect()
}

/// Per-axis pose errors of a calibration on a set of targets.
#[derive(Clone, Debug, PartialEq)]
pub struct Accuracy {
    /// Per target: reached - target, `[x, y, z]` um and `[alpha, beta, gamma]` arcsec.
    pub errors: Vec<[f64; 6]>,
    /// Largest |error| per axis (um x3, arcsec x3).
    pub max_abs: [f64; 6],
    /// RMS error per axis (um x3, arcsec x3).
    pub rms: [f64; 6],
}

impl Accuracy {
    /// Largest translation error over x, y, z (um).
    pub fn max_um(&self) -> f64 {
        self.max_abs[..3].iter().fold(0.0, |m, v| m.max(*v))
    }

    /// Largest rotation error over alpha, beta, gamma (arcsec).
    pub fn max_arcsec(&self) -> f64 {
        self.max_abs[3..].iter().fold(0.0, |m, v| m.max(*v))
    }

    /// The per-axis `max/RMS` cells of a report line, `decimals` after the point:
    /// `x 0.123/0.045um  ...  gamma 0.100/0.050"`.
    pub fn max_rms_cells(&self, decimals: usize) -> String {
        let cells: Vec<String> = AXES
            .iter()
            .zip(self.max_abs.iter().zip(self.rms.iter()))
            .enumerate()
            .map(|(k, (n, (m, r)))| {
                let unit = if k < 3 { "um" } else { "\"" };
                format!("{n} {m:.decimals$}/{r:.decimals$}{unit}")
            })
            .collect();
        cells.join("  ")
    }

    /// Per target: the largest translation error (um) and rotation error (arcsec).
    pub fn per_pose_max(&self) -> Vec<(f64, f64)> {
        self.errors
            .iter()
            .map(|e| {
                (
                    e[..3].iter().fold(0.0f64, |m, v| m.max(v.abs())),
                    e[3..].iter().fold(0.0f64, |m, v| m.max(v.abs())),
                )
            })
            .collect()
    }
}

/// Commands each target with `commanded` parameters on the `truth` mechanism.
pub fn accuracy(
    commanded: &GeometryParams,
    truth: &GeometryParams,
    targets: &[Pose<f64>],
) -> Result<Accuracy, CampaignError> {
    let cmd = geometry(commanded)?;
    let tru = geometry(truth)?;
    let mut errors = Vec::with_capacity(targets.len());
    for (k, t) in targets.iter().enumerate() {
        let (_, p) = command(&cmd, &tru, k, t)?;
        errors.push(pose_error(&p, t));
    }
    Ok(Accuracy::from_errors(errors))
}

/// `reached - target` per axis (um, arcsec): defined with the simulated plant.
pub use m2ctl::sim::pose_error;

impl Accuracy {
    /// Max |error| and RMS per axis of per-pose errors (um x3, arcsec x3).
    pub fn from_errors(errors: Vec<[f64; 6]>) -> Accuracy {
        let mut max_abs = [0.0f64; 6];
        let mut sumsq = [0.0f64; 6];
        for e in &errors {
            for a in 0..6 {
                max_abs[a] = max_abs[a].max(e[a].abs());
                sumsq[a] += e[a] * e[a];
            }
        }
        let n = errors.len().max(1) as f64;
        Accuracy {
            errors,
            max_abs,
            rms: sumsq.map(|s| (s / n).sqrt()),
        }
    }
}

/// Largest |calibrated - true| over the 36 joint coordinates (mm); reported, not scored.
pub fn max_param_error_mm(calibrated: &GeometryParams, truth: &GeometryParams) -> f64 {
    let a = super::calib::to_vec(calibrated);
    let b = super::calib::to_vec(truth);
    a.iter()
        .zip(b.iter())
        .fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}
