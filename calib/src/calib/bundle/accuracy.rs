//! Predicted accuracy of a calibrated mechanism: the joint covariance propagated to the
//! pose error over a set of targets, and the noise of one pose measured from its balls.

use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Matrix6, Point3, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64;

use super::jacobians::{point_pose_jacobian, pose_sensitivity};
use crate::calib::N_PARAMS;
use m2ctl::kinematics::{Geometry, GeometryParams, Pose};
use m2ctl::sim::tracker::rotation_matrix;
use m2ctl::units::{ARCSEC_PER_RAD, UM_PER_MM};

/// Predicted pose accuracy of a calibrated mechanism over a set of poses (um x3, arcsec
/// x3 per axis).
#[derive(Clone, Debug, PartialEq)]
pub struct PredictedAccuracy {
    /// Per pose: 1-sigma error per axis.
    pub sigma: Vec<[f64; 6]>,
    /// RMS over the poses of the 1-sigma (the expected RMS error).
    pub rms_sigma: [f64; 6],
    /// Largest 1-sigma over the poses.
    pub max_sigma: [f64; 6],
    /// Expected largest |error| over the poses (mean over Monte-Carlo draws of the
    /// parameter error).
    pub expected_max: [f64; 6],
    /// Expected largest |error| over the poses and the three translation axes (um) and
    /// the three rotation axes (arcsec).
    pub expected_max_combined: [f64; 2],
}

/// Converts a pose error from (mm, rad) to (um, arcsec).
fn to_um_arcsec(k: usize) -> f64 {
    if k < 3 {
        UM_PER_MM
    } else {
        ARCSEC_PER_RAD
    }
}

/// Propagates a joint covariance (`cov_theta`, 36 x 36, mm^2) to the pose error of
/// commanding each of `targets` with `params`: `Cov = G C G^T` with
/// [`pose_sensitivity`]; the expected maximum from `mc_draws` draws (seeded).
pub fn predict_accuracy(
    params: &GeometryParams,
    cov_theta: &DMatrix<f64>,
    targets: &[Pose<f64>],
    mc_draws: usize,
    seed: u64,
) -> Result<PredictedAccuracy, String> {
    let geom = Geometry::<f64>::new(&GeometryParams::new(params.legs, params.p0_mm))
        .map_err(|e| crate::files::describe_geometry_error(&e))?;
    let gs = targets
        .iter()
        .enumerate()
        .map(|(k, t)| {
            pose_sensitivity(&geom, t).ok_or_else(|| format!("target {}: singular", k + 1))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut sigma = Vec::with_capacity(gs.len());
    let mut ms = [0.0f64; 6];
    let mut max_sigma = [0.0f64; 6];
    for g in &gs {
        let c = g * cov_theta * g.transpose();
        let mut s = [0.0; 6];
        for k in 0..6 {
            s[k] = c[(k, k)].max(0.0).sqrt() * to_um_arcsec(k);
            ms[k] += s[k] * s[k];
            max_sigma[k] = max_sigma[k].max(s[k]);
        }
        sigma.push(s);
    }
    let n = gs.len().max(1) as f64;
    // Monte Carlo of the maximum: theta errors ~ N(0, C) through every target's G.
    let l = match cov_theta.clone().cholesky() {
        Some(ch) => ch.l(),
        None => {
            let eig = cov_theta.clone().symmetric_eigen();
            &eig.eigenvectors * DMatrix::from_diagonal(&eig.eigenvalues.map(|v| v.max(0.0).sqrt()))
        }
    };
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut expected_max = [0.0f64; 6];
    let mut expected_max_combined = [0.0f64; 2];
    let draws = mc_draws.max(1);
    for _ in 0..draws {
        let z = DVector::from_fn(N_PARAMS, |_, _| StandardNormal.sample(&mut rng));
        let dtheta = &l * z;
        let mut m = [0.0f64; 6];
        for g in &gs {
            let e = g * &dtheta;
            for k in 0..6 {
                m[k] = m[k].max(e[k].abs() * to_um_arcsec(k));
            }
        }
        for k in 0..6 {
            expected_max[k] += m[k] / draws as f64;
        }
        expected_max_combined[0] += m[..3].iter().fold(0.0f64, |a, v| a.max(*v)) / draws as f64;
        expected_max_combined[1] += m[3..].iter().fold(0.0f64, |a, v| a.max(*v)) / draws as f64;
    }
    Ok(PredictedAccuracy {
        sigma,
        rms_sigma: ms.map(|v| (v / n).sqrt()),
        max_sigma,
        expected_max,
        expected_max_combined,
    })
}

/// 1-sigma noise of one pose measured from its balls (um x3, arcsec x3): the covariance
/// `(H^T S^-1 H)^-1` of the least-squares pose from the balls at `pose`, `H` the
/// tracker-frame Jacobian of the ball centres with respect to the pose, `cov_of` the
/// tracker's covariance of a point at given tracker coordinates.
pub fn pose_measurement_sigma(
    balls_m: &[[f64; 3]],
    registration: &Isometry3<f64>,
    p0_mm: &[f64; 3],
    pose: &Pose<f64>,
    cov_of: &dyn Fn(&[f64; 3]) -> Matrix3<f64>,
) -> Option<[f64; 6]> {
    let r = rotation_matrix(&pose.rotation_rad);
    let q = *registration.rotation.to_rotation_matrix().matrix();
    let mut info = Matrix6::zeros();
    for c in balls_m {
        let cv = Vector3::from(*c);
        let xb = Vector3::from(*p0_mm) + Vector3::from(pose.translation_mm) + r * cv;
        let y = registration * Point3::from(xb);
        let s = cov_of(&[y.x, y.y, y.z]);
        let w = s.try_inverse()?;
        let h = q * point_pose_jacobian(&r, pose.rotation_rad[2], &cv);
        info += h.transpose() * w * h;
    }
    let c = info.try_inverse()?;
    let mut out = [0.0; 6];
    for (k, o) in out.iter_mut().enumerate() {
        *o = c[(k, k)].max(0.0).sqrt() * to_um_arcsec(k);
    }
    Some(out)
}
