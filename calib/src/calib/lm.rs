//! Levenberg-Marquardt calibration with the analytic Jacobian of the residuals
//! ([`Problem::jacobian_into`]), using the `levenberg-marquardt` crate (MINPACK port).
//!
//! Several of the 36 directions are barely observable from small-angle poses: moving
//! both joints of a leg by the same vector changes the strokes only through `(R - I)`,
//! i.e. ~1e-4 of the motion for rotations of tens of arcsec. An unbounded fit turns
//! tracker noise into large excursions along them. The bounded solver therefore:
//!
//! 1. adds a Tikhonov prior toward nominal, residuals `w (v_k - nominal_k)` with
//!    `w = sigma_noise / sigma_prior` (the maximum a posteriori estimate for Gaussian
//!    stroke noise `sigma_noise` and a Gaussian spread `sigma_prior` of the true joints
//!    about nominal); `sigma_noise` is estimated from a pilot fit's residuals;
//! 2. clamps the result into Omega (counted in the report as active bounds).

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{storage::Owned, DMatrix, DVector, Dyn};

use super::{CalibError, ParamBox, ParamVec, Problem, N_PARAMS};
use m2ctl::units::UM_PER_MM;

/// Default assumed standard deviation of the true joint centres about nominal (mm): half
/// the default Omega half-width, so Omega is a +-2 sigma box.
pub const DEFAULT_PRIOR_SIGMA_MM: f64 = 0.25;
/// Stroke noise assumed by the pilot fit that estimates the real noise (mm): 1 um, the
/// order of the tracker accuracy in the paper's experiment.
pub const PILOT_NOISE_MM: f64 = 1.0e-3;
/// Pilot fits that estimate the stroke noise, each with the prior weight of the last
/// estimate (the first with [`PILOT_NOISE_MM`]).
pub const PILOT_FITS: usize = 2;
/// Floor of the estimated stroke noise (mm): keeps the prior weight positive on
/// noise-free data without biasing a nanometre-level fit.
pub const NOISE_FLOOR_MM: f64 = 1.0e-9;
/// Default most residual evaluations of one LM run, per parameter + 1 (crate "patience").
pub const DEFAULT_PATIENCE: usize = 100;
/// Default relative tolerances (ftol, xtol, gtol) in machine epsilons.
pub const DEFAULT_TOL_EPS: f64 = 30.0;

/// LM settings.
#[derive(Clone, Debug, PartialEq)]
pub struct LmConfig {
    /// Assumed spread of the true joint centres about nominal (mm); sets the prior weight.
    pub prior_sigma_mm: f64,
    /// Stroke noise (mm) to use for the prior weight; `None` estimates it by a pilot fit.
    pub noise_mm: Option<f64>,
    /// Residual-evaluation budget per (parameter + 1).
    pub patience: usize,
    /// ftol = xtol = gtol, in machine epsilons.
    pub tol_eps: f64,
}

impl Default for LmConfig {
    fn default() -> Self {
        Self {
            prior_sigma_mm: DEFAULT_PRIOR_SIGMA_MM,
            noise_mm: None,
            patience: DEFAULT_PATIENCE,
            tol_eps: DEFAULT_TOL_EPS,
        }
    }
}

/// Result of an LM calibration.
#[derive(Clone, Debug)]
pub struct LmResult {
    /// Solution (mm).
    pub vec_mm: ParamVec,
    /// Residual evaluations of all LM runs.
    pub iterations: usize,
    /// Same as `iterations` (each LM evaluation is one objective evaluation).
    pub evaluations: usize,
    /// Prior weight used (0 for unbounded).
    pub prior_weight: f64,
    /// Termination reasons and the estimated noise.
    pub note: String,
}

struct LmProblem<'a> {
    problem: &'a Problem,
    nominal: ParamVec,
    weight: f64,
    x: ParamVec,
}

impl LmProblem<'_> {
    fn n_rows(&self) -> usize {
        self.problem.n_residuals() + if self.weight > 0.0 { N_PARAMS } else { 0 }
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for LmProblem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        for (xi, v) in self.x.iter_mut().zip(x.iter()) {
            *xi = *v;
        }
    }

    fn params(&self) -> DVector<f64> {
        DVector::from_column_slice(&self.x)
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let n = self.problem.n_residuals();
        let mut r = vec![0.0; self.n_rows()];
        self.problem.residuals_into(&self.x, &mut r[..n]);
        if self.weight > 0.0 {
            for k in 0..N_PARAMS {
                r[n + k] = self.weight * (self.x[k] - self.nominal[k]);
            }
        }
        Some(DVector::from_vec(r))
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let n = self.problem.n_residuals();
        let mut j = vec![0.0; self.n_rows() * N_PARAMS];
        self.problem.jacobian_into(&self.x, &mut j[..n * N_PARAMS]);
        if self.weight > 0.0 {
            for k in 0..N_PARAMS {
                j[(n + k) * N_PARAMS + k] = self.weight;
            }
        }
        Some(DMatrix::from_row_slice(self.n_rows(), N_PARAMS, &j))
    }
}

/// The LM solver both fits use: f-, x- and g-tolerance `tol_eps` machine epsilons, at most
/// `patience` residual evaluations per parameter + 1.
pub(crate) fn solver(tol_eps: f64, patience: usize) -> LevenbergMarquardt<f64> {
    let tol = tol_eps * f64::EPSILON;
    LevenbergMarquardt::new()
        .with_ftol(tol)
        .with_xtol(tol)
        .with_gtol(tol)
        .with_patience(patience)
}

fn run(
    problem: &Problem,
    start: &ParamVec,
    nominal: &ParamVec,
    weight: f64,
    cfg: &LmConfig,
) -> Result<(ParamVec, usize, String), CalibError> {
    let lm = solver(cfg.tol_eps, cfg.patience);
    let (p, report) = lm.minimize(LmProblem {
        problem,
        nominal: *nominal,
        weight,
        x: *start,
    });
    if report.termination.was_usage_issue() {
        return Err(CalibError::Solver(format!("{:?}", report.termination)));
    }
    if !p.x.iter().all(|v| v.is_finite()) {
        return Err(CalibError::Solver("non-finite parameters".into()));
    }
    Ok((
        p.x,
        report.number_of_evaluations,
        format!("{:?}", report.termination),
    ))
}

/// Calibrates by LM starting from `start`. `bounded`: prior toward `nominal` and clamp
/// into `omega`; otherwise a plain unregularised least-squares fit.
pub fn solve(
    problem: &Problem,
    start: &ParamVec,
    omega: &ParamBox,
    cfg: &LmConfig,
    bounded: bool,
) -> Result<LmResult, CalibError> {
    if !(cfg.prior_sigma_mm > 0.0 && cfg.prior_sigma_mm.is_finite()) {
        return Err(CalibError::BadConfig(format!(
            "LM prior sigma must be a positive number of mm, got {}",
            cfg.prior_sigma_mm
        )));
    }
    let nominal = omega.centre();
    if !bounded {
        let (x, evals, note) = run(problem, start, &nominal, 0.0, cfg)?;
        return Ok(LmResult {
            vec_mm: x,
            iterations: evals,
            evaluations: evals,
            prior_weight: 0.0,
            note: format!("lm unbounded: {note}"),
        });
    }
    let (noise_mm, pilot_evals) = match cfg.noise_mm {
        Some(n) => (n, 0),
        None => {
            // Pilot fits: the prior biases the residual upward when its weight is too
            // large, so re-estimate with the weight the last estimate gives.
            let dof = problem.n_residuals().saturating_sub(N_PARAMS).max(1);
            let mut sigma = PILOT_NOISE_MM;
            let mut evals_total = 0;
            for _ in 0..PILOT_FITS {
                let w = sigma.max(NOISE_FLOOR_MM) / cfg.prior_sigma_mm;
                let (x, evals, _) = run(problem, start, &nominal, w, cfg)?;
                evals_total += evals;
                sigma = (problem.objective(&x) / dof as f64).sqrt();
            }
            (sigma, evals_total)
        }
    };
    let weight = noise_mm.max(NOISE_FLOOR_MM) / cfg.prior_sigma_mm;
    let (mut x, evals, note) = run(problem, start, &nominal, weight, cfg)?;
    let clamped = omega.active_bounds(&x);
    omega.clamp(&mut x);
    Ok(LmResult {
        vec_mm: x,
        iterations: pilot_evals + evals,
        evaluations: pilot_evals + evals,
        prior_weight: weight,
        note: format!(
            "lm bounded: noise {:.3} um (estimated: {}), prior sigma {} mm, weight {:.3e}, {note}, {} parameters clamped",
            noise_mm * UM_PER_MM,
            cfg.noise_mm.is_none(),
            cfg.prior_sigma_mm,
            weight,
            clamped
        ),
    })
}
