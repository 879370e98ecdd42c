//! Calibration from what a laser tracker measures: a bundle fit in ball coordinates.
//!
//! Unknowns `x` (mm, rad), all deviations from the start so that the solver's relative
//! tolerances act on small numbers, in this order:
//! * the 36 joint coordinates, `theta = theta_nominal + x[0..36]` (as in
//!   [`crate::calib::ParamVec`]);
//! * the centres `c_k` of the target balls in frame M (3 per ball), `c = c_nominal + dc`:
//!   only their nominal positions are known (nuisance parameters);
//! * the registration, the transform from base to tracker coordinates
//!   `y = Q0 (Rz(g) Ry(b) Rx(a) x + d) + tau0` (`Q0`, `tau0` from the fiducials' Kabsch
//!   fit, `[a, b, g]` a small rotation, rad, `d` a small translation, mm): 6 values.
//!
//! The residuals are evaluated in the base-aligned coordinates of the start registration,
//! `z = Q0^T (y - tau0)` (a few hundred mm instead of the tracker's metres, so rounding
//! is 30 times smaller); the whitening `L^-1 Q0` makes them identical to the
//! tracker-frame ones.
//!
//! Observations, each a point in the tracker frame with its covariance `S` (the tracker's
//! noise model, plus the drawing tolerance for a fiducial):
//! * fiducial `m`: `y_m = Q f_m + tau` (`f_m` its drawing position in B);
//! * ball `k` at pose `j`: `y_jk = Q (p0 + t_j + R_j c_k) + tau`, where `P_j = (t_j, R_j)`
//!   is the forward kinematics of the encoder strokes `s_j` with the trial joints
//!   (`P_j = FK(s_j, theta)`; the encoders, 0.1 um, are taken as exact against the tracker).
//!
//! Residuals are whitened, `r = L^-1 (y_measured - y_model)` with `S = L L^T`, so the
//! objective `sum r^2` is the negative log-likelihood and its Jacobian's normal matrix is
//! the Fisher information. Optional priors toward nominal (`(theta - theta_nom) /
//! sigma_joint`, `(c - c_nom) / sigma_ball`) make it a MAP estimate. Levenberg-Marquardt
//! (`levenberg-marquardt` crate) with the analytic Jacobian ([`Bundle::evaluate`]):
//!
//! ```text
//! dP_j/dtheta = -J_P^-1 D        J_P = d s / d P (FK Jacobian), D = d IK / d theta
//! d x_B / d P = [ I | R (e_x x c) | (Rz(gamma) e_y) x (R c) | e_z x (R c) ]
//! d z / d theta = Rd (d x_B / d P) (dP/dtheta),  d z / d c_k = Rd R_j,  d z / d d = I
//! d z / d a = Rd (e_x x x),  d z / d b = (Rz(g) e_y) x (Rd x),  d z / d g = e_z x (Rd x)
//! ```
//!
//! The posterior covariance `(J^T J)^-1` at the solution propagates to the predicted pose
//! accuracy of the calibrated mechanism ([`predict_accuracy`]): commanding a pose `P`
//! with `theta_hat`, the true mechanism reaches `P + G (theta_hat - theta_true)` to first
//! order, `G = J_P^-1 D` at `P`.
//!
//! The parts, one job each (their items are re-exported here, the one public path):
//! `observations` (what is measured), `settings` (priors, budget, errors), `jacobians`
//! (the analytic derivatives), `engine` (the unknowns' layout and the residual and
//! Jacobian evaluation), `fit` (the solver and its results), `accuracy` (predicted pose
//! accuracy) and `observability` (what the data can and cannot see of the joints).

mod accuracy;
mod engine;
mod fit;
mod jacobians;
mod observability;
mod observations;
mod settings;

pub use accuracy::{pose_measurement_sigma, predict_accuracy, PredictedAccuracy};
pub use engine::{Bundle, Layout};
pub use fit::{check_count, data_rms, finish, fit, fit_plain, solve, BundleFit};
pub use jacobians::pose_sensitivity;
pub use observability::{observability, Direction, Observability};
pub use observations::{
    BallObs, BundleData, Component, FiducialObs, PointObs, PoseObs, N_COMPONENTS,
};
pub use settings::{
    BundleConfig, BundleError, Priors, DEFAULT_JOINT_PRIOR_SIGMA_MM, DEFAULT_PATIENCE,
    DEFAULT_TOL_EPS,
};

/// Parameters of the registration correction (3 angles, 3 translations).
pub const REGISTRATION_PARAMS: usize = 6;
/// Whitened residual given to the balls of a pose whose forward kinematics fails with the
/// trial joints: large against any real residual (a few units), finite.
pub const FAILED_POSE_RESIDUAL: f64 = 1.0e6;
/// Most Newton steps of a pose's FK inside the fit (warm-started at the nominal FK).
pub const BUNDLE_FK_ITERATIONS: u8 = 20;
/// Largest Mahalanobis distance of a measured point from the fit (its 3 whitened
/// residual components): a chi distribution with 3 degrees of freedom exceeds 8 with
/// probability 1e-13, so a larger one is a mis-measured, swapped or moved point.
pub const MAX_POINT_SIGMAS: f64 = 8.0;
/// Default Monte-Carlo draws of the predicted maximum error.
pub const DEFAULT_MC_DRAWS: usize = 400;
/// Relative eigenvalue floor of a covariance computed by pseudo-inverse (unregularised
/// fits whose information matrix is numerically singular).
pub const PSEUDO_INVERSE_FLOOR: f64 = 1.0e-15;
