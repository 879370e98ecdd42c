//! Running the fit: Levenberg-Marquardt over a [`Bundle`], the outlier refusal, and the
//! results at the solution ([`BundleFit`]: registration, residuals, covariance).

use std::time::{Duration, Instant};

use levenberg_marquardt::LeastSquaresProblem;
use nalgebra::{storage::Owned, DMatrix, DVector, Dyn, Isometry3, Point3, Vector3};

use super::engine::{Bundle, Layout};
use super::observations::BundleData;
use super::settings::{BundleConfig, BundleError};
use super::{FAILED_POSE_RESIDUAL, MAX_POINT_SIGMAS, PSEUDO_INVERSE_FLOOR};
use crate::calib::{from_vec, N_PARAMS};
use m2ctl::kinematics::GeometryParams;
use m2ctl::sim::tracker::rotation_matrix;
use m2ctl::units::UM_PER_MM;

struct LmAdapter<'a, 'b> {
    bundle: &'b Bundle<'a>,
    x: Vec<f64>,
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for LmAdapter<'_, '_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.x.copy_from_slice(x.as_slice());
    }

    fn params(&self) -> DVector<f64> {
        DVector::from_column_slice(&self.x)
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        Some(DVector::from_vec(self.bundle.evaluate(&self.x, None)))
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        Some(self.bundle.jacobian(&self.x))
    }
}

/// Result of a bundle fit.
#[derive(Clone, Debug)]
pub struct BundleFit {
    /// The unknowns at the solution.
    pub x: Vec<f64>,
    /// Index layout of `x`.
    pub layout: Layout,
    /// Calibrated geometry (nominal's p0 and limits, fitted joints).
    pub params: GeometryParams,
    /// Fitted ball centres, frame M (mm).
    pub balls_m: Vec<[f64; 3]>,
    /// Fitted registration, base -> tracker coordinates.
    pub registration: Isometry3<f64>,
    /// The fiducials-only registration (the fit's start).
    pub registration_fiducials: Isometry3<f64>,
    /// Posterior covariance of `x` (mm^2, rad^2; `(J^T J)^-1` with the priors).
    pub covariance: DMatrix<f64>,
    /// Whether the covariance needed a pseudo-inverse (information numerically singular).
    pub covariance_pseudo_inverse: bool,
    /// Sum of squared whitened data residuals.
    pub chi2: f64,
    /// Data rows.
    pub data_rows: usize,
    /// Largest Mahalanobis distance of a point from the fit, its line and name.
    pub worst_point: (f64, usize, String),
    /// Fiducial residuals (tracker frame, um).
    pub fiducial_residuals_um: Vec<[f64; 3]>,
    /// RMS of the ball residuals per coordinate (tracker frame, um).
    pub ball_residual_rms_um: f64,
    /// Whitened data residual RMS at the nominal start (poses' balls and fiducials).
    pub start_rms: f64,
    /// LM residual evaluations.
    pub evaluations: usize,
    /// Termination reason.
    pub note: String,
    /// Wall time.
    pub elapsed: Duration,
}

impl BundleFit {
    /// The 36 x 36 joint block of the covariance (mm^2).
    pub fn joint_covariance(&self) -> DMatrix<f64> {
        self.covariance
            .view((0, 0), (N_PARAMS, N_PARAMS))
            .into_owned()
    }

    /// Normalised residual RMS: sqrt(chi2 / data rows) (1 when the noise model is right).
    pub fn normalised_rms(&self) -> f64 {
        (self.chi2 / self.data_rows.max(1) as f64).sqrt()
    }
}

/// Covariance `(J^T J)^-1`: Cholesky, or a pseudo-inverse when it is singular.
fn covariance_of(j: &DMatrix<f64>) -> (DMatrix<f64>, bool) {
    let a = j.transpose() * j;
    if let Some(ch) = a.clone().cholesky() {
        return (ch.inverse(), false);
    }
    let eig = a.symmetric_eigen();
    let top = eig.eigenvalues.iter().fold(0.0f64, |m, v| m.max(*v));
    let inv = eig.eigenvalues.map(|v| {
        if v > PSEUDO_INVERSE_FLOOR * top {
            1.0 / v
        } else {
            0.0
        }
    });
    let c = &eig.eigenvectors * DMatrix::from_diagonal(&inv) * eig.eigenvectors.transpose();
    (c, true)
}

/// Runs the bundle fit. Refuses a point farther than [`MAX_POINT_SIGMAS`] from the fit
/// (a fixed limit on an assumed noise model: `calibrate --points` uses
/// [`crate::calib::adjust`] instead, which estimates the noise and tests each point).
pub fn fit(data: &BundleData, cfg: &BundleConfig) -> Result<BundleFit, BundleError> {
    let fit = fit_plain(data, cfg)?;
    if fit.worst_point.0 > MAX_POINT_SIGMAS {
        return Err(BundleError::Outlier {
            line: fit.worst_point.1,
            sigmas: fit.worst_point.0,
            what: fit.worst_point.2,
        });
    }
    Ok(fit)
}

/// The bundle fit with the given priors and noise model, refusing nothing after the fit
/// (the reference "fit given the true spread" of the studies).
pub fn fit_plain(data: &BundleData, cfg: &BundleConfig) -> Result<BundleFit, BundleError> {
    let started = Instant::now();
    let bundle = Bundle::new(data, cfg.priors)?;
    check_count(&bundle)?;
    let x0 = bundle.start();
    let start_rms = data_rms(&bundle, &x0);
    let (x, evaluations, note) = solve(&bundle, x0, cfg)?;
    finish(&bundle, x, start_rms, evaluations, note, started)
}

/// Refuses data with fewer observations than unknowns.
pub fn check_count(bundle: &Bundle) -> Result<(), BundleError> {
    let data = bundle.data();
    if data.poses.len() * 6 + data.fiducials.len() * 3 < bundle.n_params() {
        return Err(BundleError::Data(format!(
            "{} poses: too few for {} unknowns",
            data.poses.len(),
            bundle.n_params()
        )));
    }
    Ok(())
}

/// Whitened data residual RMS at `x`.
pub fn data_rms(bundle: &Bundle, x: &[f64]) -> f64 {
    let nd = bundle.n_data_rows();
    let r = bundle.evaluate(x, None);
    (r[..nd].iter().map(|v| v * v).sum::<f64>() / nd.max(1) as f64).sqrt()
}

/// Levenberg-Marquardt from `x0`: the unknowns, the number of evaluations and the
/// termination reason.
pub fn solve(
    bundle: &Bundle,
    x0: Vec<f64>,
    cfg: &BundleConfig,
) -> Result<(Vec<f64>, usize, String), BundleError> {
    let lm = crate::calib::lm::solver(cfg.tol_eps, cfg.patience);
    let (p, report) = lm.minimize(LmAdapter { bundle, x: x0 });
    if report.termination.was_usage_issue() {
        return Err(BundleError::Solver(format!("{:?}", report.termination)));
    }
    let x = p.x;
    if !x.iter().all(|v| v.is_finite()) {
        return Err(BundleError::Solver("non-finite unknowns".into()));
    }
    Ok((
        x,
        report.number_of_evaluations,
        format!("{:?}", report.termination),
    ))
}

/// The fit's results at the solution `x` of `bundle` (no refusal).
pub fn finish(
    bundle: &Bundle,
    x: Vec<f64>,
    start_rms: f64,
    evaluations: usize,
    note: String,
    started: Instant,
) -> Result<BundleFit, BundleError> {
    let data = bundle.data();
    let nd = bundle.n_data_rows();
    let res = bundle.evaluate(&x, None);
    let chi2: f64 = res[..nd].iter().map(|v| v * v).sum();
    if !chi2.is_finite() || chi2 >= FAILED_POSE_RESIDUAL {
        return Err(BundleError::Solver(format!(
            "no fit: forward kinematics fails or the residual is not finite (chi2 {chi2:e})"
        )));
    }
    let labels = bundle.point_labels();
    let mut worst = (0.0f64, 0usize, String::new());
    for (k, (line, what)) in labels.iter().enumerate() {
        let d = (res[3 * k].powi(2) + res[3 * k + 1].powi(2) + res[3 * k + 2].powi(2)).sqrt();
        if d > worst.0 {
            worst = (d, *line, what.clone());
        }
    }
    let registration = bundle.registration(&x);
    let fiducial_residuals_um = data
        .fiducials
        .iter()
        .map(|f| {
            let y = registration * Point3::from(f.drawing_b_mm);
            [0, 1, 2].map(|a| (f.obs.y_mm[a] - y[a]) * UM_PER_MM)
        })
        .collect();
    let poses = bundle.poses(&x);
    let balls_m = bundle.balls(&x);
    let mut ss = 0.0;
    let mut count = 0usize;
    for (pose, solved) in data.poses.iter().zip(poses.iter()) {
        let Some(p) = solved else { continue };
        let r = rotation_matrix(&p.rotation_rad);
        for b in &pose.balls {
            let xb = Vector3::from(data.nominal.p0_mm)
                + Vector3::from(p.translation_mm)
                + r * Vector3::from(balls_m[b.ball]);
            let y = registration * Point3::from(xb);
            for a in 0..3 {
                ss += ((b.obs.y_mm[a] - y[a]) * UM_PER_MM).powi(2);
                count += 1;
            }
        }
    }
    let (covariance, pinv) = covariance_of(&bundle.jacobian(&x));
    let theta = bundle.joints(&x);
    Ok(BundleFit {
        params: from_vec(&theta, &data.nominal),
        balls_m,
        registration,
        registration_fiducials: bundle.registration(&bundle.start()),
        covariance,
        covariance_pseudo_inverse: pinv,
        chi2,
        data_rows: nd,
        worst_point: worst,
        fiducial_residuals_um,
        ball_residual_rms_um: (ss / count.max(1) as f64).sqrt(),
        start_rms,
        evaluations,
        note,
        elapsed: started.elapsed(),
        layout: bundle.layout(),
        x,
    })
}
