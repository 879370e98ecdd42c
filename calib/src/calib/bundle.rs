//! Calibration from what a laser tracker measures: a bundle fit in ball coordinates.
//!
//! Unknowns `x` (mm, rad), all deviations from the start so that the solver's relative
//! tolerances act on small numbers, in this order:
//! * the 36 joint coordinates, `theta = theta_nominal + x[0..36]` (as in
//!   [`super::ParamVec`]);
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

use std::time::{Duration, Instant};

use levenberg_marquardt::LeastSquaresProblem;
use nalgebra::{
    storage::Owned, DMatrix, DVector, Dyn, Isometry3, Matrix3, Matrix6, Point3, Translation3,
    UnitQuaternion, Vector3,
};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64;

use super::registration::kabsch;
use super::{from_vec, param_name, stroke_gradient, to_vec, ParamVec, N_PARAMS, PARAMS_PER_LEG};
use m2ctl::kinematics::fk::strokes_and_jacobian;
use m2ctl::kinematics::ik::leg_state;
use m2ctl::kinematics::pose::RotationDelta;
use m2ctl::kinematics::{fk, FkConfig, Geometry, GeometryParams, Pose, LEGS};
use m2ctl::sim::tracker::rotation_matrix;
use m2ctl::units::{ARCSEC_PER_RAD, UM_PER_MM};

/// Parameters of the registration correction (3 angles, 3 translations).
pub const REGISTRATION_PARAMS: usize = 6;
/// Whitened residual given to the balls of a pose whose forward kinematics fails with the
/// trial joints: large against any real residual (a few units), finite.
pub const FAILED_POSE_RESIDUAL: f64 = 1.0e6;
/// Most Newton steps of a pose's FK inside the fit (warm-started at the nominal FK).
pub const BUNDLE_FK_ITERATIONS: u8 = 20;
// The LM budget and tolerances: the same defaults as calib::lm's fit.
pub use super::lm::{DEFAULT_PATIENCE, DEFAULT_TOL_EPS};
/// Largest Mahalanobis distance of a measured point from the fit (its 3 whitened
/// residual components): a chi distribution with 3 degrees of freedom exceeds 8 with
/// probability 1e-13, so a larger one is a mis-measured, swapped or moved point.
pub const MAX_POINT_SIGMAS: f64 = 8.0;
/// Default Monte-Carlo draws of the predicted maximum error.
pub const DEFAULT_MC_DRAWS: usize = 400;
/// Relative eigenvalue floor of a covariance computed by pseudo-inverse (unregularised
/// fits whose information matrix is numerically singular).
pub const PSEUDO_INVERSE_FLOOR: f64 = 1.0e-15;

/// The variance component a whitened residual row belongs to (variance component
/// estimation scales each component's tracker variance by its own factor).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Component {
    /// The tracker's range (distance meter) error, along the line of sight.
    Range = 0,
    /// The tracker's transverse (angle encoder) errors, across the line of sight.
    Transverse = 1,
    /// A point with its own 1-sigma from the export (isotropic).
    Export = 2,
}

/// Number of observation variance components ([`Component`]).
pub const N_COMPONENTS: usize = 3;

/// One measured point: tracker-frame coordinates, covariance and its whitening.
///
/// The covariance is diagonal in an orthonormal basis (rows of `basis`: the line of
/// sight and two transverse directions for a tracker point), each row's variance the
/// sum of a tracker part, scaled by its [`Component`]'s variance factor in a variance
/// component estimation, and a fixed isotropic part (a fiducial's drawing tolerance).
#[derive(Clone, Debug, PartialEq)]
pub struct PointObs {
    /// 1-based line of the point export (0 for generated data).
    pub line: usize,
    /// Measured coordinates, tracker frame (mm).
    pub y_mm: [f64; 3],
    /// Covariance of the measurement (mm^2), variance factors 1.
    pub cov_mm2: Matrix3<f64>,
    /// Orthonormal basis of the covariance's principal directions (rows).
    pub basis: Matrix3<f64>,
    /// Tracker variance along each basis row (mm^2), scaled by the component's factor.
    pub tracker_var_mm2: [f64; 3],
    /// Fixed isotropic variance (mm^2), not scaled.
    pub fixed_var_mm2: f64,
    /// Component of each basis row.
    pub components: [Component; 3],
    /// `diag(1 / sqrt(var)) basis` (1/mm): the whitening, `W^T W = cov^-1`.
    whiten: Matrix3<f64>,
}

impl PointObs {
    fn from_parts(
        line: usize,
        y_mm: [f64; 3],
        basis: Matrix3<f64>,
        tracker_var_mm2: [f64; 3],
        fixed_var_mm2: f64,
        components: [Component; 3],
    ) -> Option<Self> {
        let var = tracker_var_mm2.map(|v| v + fixed_var_mm2);
        if !var.iter().all(|v| v.is_finite() && *v > 0.0) {
            return None;
        }
        let d = Matrix3::from_diagonal(&Vector3::from(var));
        let cov_mm2 = basis.transpose() * d * basis;
        let whiten = Matrix3::from_diagonal(&Vector3::from(var.map(|v| 1.0 / v.sqrt()))) * basis;
        Some(Self {
            line,
            y_mm,
            cov_mm2,
            basis,
            tracker_var_mm2,
            fixed_var_mm2,
            components,
            whiten,
        })
    }

    /// A point with a general covariance (one [`Component::Export`] component); `None`
    /// if the covariance is not positive definite.
    pub fn new(line: usize, y_mm: [f64; 3], cov_mm2: Matrix3<f64>) -> Option<Self> {
        let eig = cov_mm2.symmetric_eigen();
        let basis = eig.eigenvectors.transpose();
        let v = eig.eigenvalues;
        Self::from_parts(
            line,
            y_mm,
            basis,
            [v[0], v[1], v[2]],
            0.0,
            [Component::Export; 3],
        )
    }

    /// A point measured by a tracker at the frame's origin with `noise`: range variance
    /// along the line of sight ([`Component::Range`]), transverse across it
    /// ([`Component::Transverse`]), plus a fixed isotropic `fixed_var_mm2`.
    pub fn tracker(
        line: usize,
        y_mm: [f64; 3],
        noise: &m2ctl::sim::tracker::TrackerNoise,
        fixed_var_mm2: f64,
    ) -> Option<Self> {
        let y = Vector3::from(y_mm);
        let d = y.norm();
        if !(d.is_finite() && d > 0.0) {
            return None;
        }
        let u = y / d;
        let (e1, e2) = m2ctl::sim::tracker::transverse_basis(&u);
        let basis = Matrix3::from_rows(&[u.transpose(), e1.transpose(), e2.transpose()]);
        let (sr, st) = noise.sigmas_mm(d);
        Self::from_parts(
            line,
            y_mm,
            basis,
            [sr * sr, st * st, st * st],
            fixed_var_mm2,
            [
                Component::Range,
                Component::Transverse,
                Component::Transverse,
            ],
        )
    }

    /// A point with its own isotropic 1-sigma `sigma_mm` ([`Component::Export`]), plus
    /// a fixed isotropic `fixed_var_mm2`.
    pub fn isotropic(
        line: usize,
        y_mm: [f64; 3],
        sigma_mm: f64,
        fixed_var_mm2: f64,
    ) -> Option<Self> {
        Self::from_parts(
            line,
            y_mm,
            Matrix3::identity(),
            [sigma_mm * sigma_mm; 3],
            fixed_var_mm2,
            [Component::Export; 3],
        )
    }

    /// Scale of each whitened row for variance factors `k` (per [`Component`]):
    /// `sqrt(var(1) / var(k))`, `var(k) = k_c tracker_var + fixed_var`.
    pub fn row_scales(&self, k: &[f64; N_COMPONENTS]) -> [f64; 3] {
        [0, 1, 2].map(|i| {
            let t = self.tracker_var_mm2[i];
            let f = self.fixed_var_mm2;
            ((t + f) / (k[self.components[i] as usize] * t + f)).sqrt()
        })
    }

    /// The whitening `W` (1/mm, rows as `basis`) with variance factors 1.
    pub fn whitening(&self) -> Matrix3<f64> {
        self.whiten
    }
}

/// An observation in the start registration's base-aligned coordinates.
#[derive(Clone, Debug)]
struct LocalObs {
    /// `Q0^T (y - tau0)` (mm).
    z_mm: Vector3<f64>,
    /// `L^-1 Q0` (1/mm).
    whiten: Matrix3<f64>,
}

/// A fiducial: drawing position in B and its measurement.
#[derive(Clone, Debug, PartialEq)]
pub struct FiducialObs {
    /// Name.
    pub name: String,
    /// Drawing centre in frame B (mm).
    pub drawing_b_mm: [f64; 3],
    /// The measurement (covariance includes the drawing tolerance).
    pub obs: PointObs,
}

/// A ball measured at a pose.
#[derive(Clone, Debug, PartialEq)]
pub struct BallObs {
    /// Index into [`BundleData::ball_names`].
    pub ball: usize,
    /// The measurement.
    pub obs: PointObs,
}

/// One mechanism pose: the encoder strokes and the balls measured there.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseObs {
    /// Pose number of the files.
    pub pose: u32,
    /// 1-based line of the stroke file (0 for generated data).
    pub stroke_line: usize,
    /// Encoder strokes (mm).
    pub strokes_mm: [f64; LEGS],
    /// Balls measured at this pose.
    pub balls: Vec<BallObs>,
}

/// Everything a bundle fit needs.
#[derive(Clone, Debug, PartialEq)]
pub struct BundleData {
    /// Nominal geometry (start and prior of the joints; p0 and limits kept).
    pub nominal: GeometryParams,
    /// Ball names.
    pub ball_names: Vec<String>,
    /// Nominal ball centres in frame M (mm).
    pub balls_nominal_m: Vec<[f64; 3]>,
    /// Base fiducials.
    pub fiducials: Vec<FiducialObs>,
    /// The poses.
    pub poses: Vec<PoseObs>,
}

/// Priors toward nominal (1 sigma, mm); `None` leaves the parameter group free.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Priors {
    /// Spread of the true joint coordinates about nominal.
    pub joint_sigma_mm: Option<f64>,
    /// Spread of the true ball centres about nominal.
    pub ball_sigma_mm: Option<f64>,
}

impl Priors {
    /// No prior at all: the plain maximum-likelihood fit.
    pub const NONE: Priors = Priors {
        joint_sigma_mm: None,
        ball_sigma_mm: None,
    };
}

/// Bundle-fit settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BundleConfig {
    /// Priors.
    pub priors: Priors,
    /// LM residual-evaluation budget per (parameter + 1).
    pub patience: usize,
    /// LM tolerances in machine epsilons.
    pub tol_eps: f64,
}

/// Default prior spread of the joints (mm): the simulated plant's manufacturing sigma.
pub const DEFAULT_JOINT_PRIOR_SIGMA_MM: f64 = m2ctl::sim::manufacturing::DEFAULT_JOINT_SIGMA_MM;

impl BundleConfig {
    /// With a joint prior of `joint_sigma_mm` and a ball prior of `ball_sigma_mm`.
    pub fn with_priors(joint_sigma_mm: f64, ball_sigma_mm: f64) -> Self {
        Self {
            priors: Priors {
                joint_sigma_mm: Some(joint_sigma_mm),
                ball_sigma_mm: Some(ball_sigma_mm),
            },
            patience: DEFAULT_PATIENCE,
            tol_eps: DEFAULT_TOL_EPS,
        }
    }

    /// The unregularised fit.
    pub fn unbounded() -> Self {
        Self {
            priors: Priors::NONE,
            patience: DEFAULT_PATIENCE,
            tol_eps: DEFAULT_TOL_EPS,
        }
    }
}

/// Why a bundle fit failed.
#[derive(Clone, Debug, PartialEq)]
pub enum BundleError {
    /// The data cannot be fitted (too few poses, a degenerate registration...).
    Data(String),
    /// A measured point is far from the fit: `(file line, distance in sigmas, which)`.
    Outlier {
        /// Line in the point export.
        line: usize,
        /// Mahalanobis distance from the fit.
        sigmas: f64,
        /// Which point.
        what: String,
    },
    /// The solver failed.
    Solver(String),
}

impl std::fmt::Display for BundleError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BundleError::Data(s) => write!(f, "{s}"),
            BundleError::Outlier { line, sigmas, what } => write!(
                f,
                "line {line}: {what} is {sigmas:.1} sigma from the fit (limit {MAX_POINT_SIGMAS}): a mis-measured, swapped or moved point?"
            ),
            BundleError::Solver(s) => write!(f, "solver: {s}"),
        }
    }
}

impl std::error::Error for BundleError {}

/// Index layout of the unknown vector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Number of balls.
    pub n_balls: usize,
}

impl Layout {
    /// First index of ball `k`'s centre.
    pub const fn ball(&self, k: usize) -> usize {
        N_PARAMS + 3 * k
    }
    /// First index of the registration correction.
    pub const fn registration(&self) -> usize {
        N_PARAMS + 3 * self.n_balls
    }
    /// Number of unknowns.
    pub const fn n(&self) -> usize {
        self.registration() + REGISTRATION_PARAMS
    }
    /// Number of nuisance unknowns (balls and registration).
    pub const fn n_nuisance(&self) -> usize {
        self.n() - N_PARAMS
    }
}

/// The three columns `d(R v)/d[alpha, beta, gamma]` for `R = Rz(g) Ry(b) Rx(a)`:
/// `R (e_x x v)`, `(Rz(g) e_y) x (R v)`, `e_z x (R v)`.
fn rotation_columns(r: &Matrix3<f64>, gamma: f64, v: &Vector3<f64>) -> [Vector3<f64>; 3] {
    let rv = r * v;
    let rz_ey = Vector3::new(-gamma.sin(), gamma.cos(), 0.0);
    [
        r * Vector3::x().cross(v),
        rz_ey.cross(&rv),
        Vector3::z().cross(&rv),
    ]
}

/// `d x_B / d P` (3 x 6) of a point `c` (frame M) at a pose with rotation `r`, `gamma`.
fn point_pose_jacobian(r: &Matrix3<f64>, gamma: f64, c: &Vector3<f64>) -> nalgebra::Matrix3x6<f64> {
    let mut h = nalgebra::Matrix3x6::zeros();
    h.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&Matrix3::identity());
    for (k, col) in rotation_columns(r, gamma, c).iter().enumerate() {
        h.set_column(3 + k, col);
    }
    h
}

/// `d IK / d theta` at a pose (6 x 36: leg i's row has its 6 gradient entries in columns
/// `6i..6i+6`) and the FK Jacobian `d s / d P` there; `None` if a leg cannot reach.
fn kinematic_jacobians(
    geom: &Geometry<f64>,
    pose: &Pose<f64>,
) -> Option<(DMatrix<f64>, Matrix6<f64>)> {
    let (_, jp) = strokes_and_jacobian(geom, pose).ok()?;
    let rot = RotationDelta::new(&pose.rotation_rad);
    let mut d = DMatrix::zeros(LEGS, N_PARAMS);
    for (i, leg) in geom.legs.iter().enumerate() {
        let st = leg_state(leg, &rot, &pose.translation_mm)?;
        for (m, g) in stroke_gradient(leg, &rot, &st).iter().enumerate() {
            d[(i, i * PARAMS_PER_LEG + m)] = *g;
        }
    }
    let mut j = Matrix6::zeros();
    for (i, row) in jp.iter().enumerate() {
        for (k, v) in row.iter().enumerate() {
            j[(i, k)] = *v;
        }
    }
    Some((d, j))
}

/// Sensitivity of the reached pose to the joint errors when commanding `pose` with the
/// calibrated geometry: `G = J_P^-1 D` (6 x 36; rows x, y, z in mm/mm, angles in rad/mm).
pub fn pose_sensitivity(geom: &Geometry<f64>, pose: &Pose<f64>) -> Option<DMatrix<f64>> {
    let (d, jp) = kinematic_jacobians(geom, pose)?;
    let inv = jp.try_inverse()?;
    let inv_d = DMatrix::from_fn(6, 6, |r, c| inv[(r, c)]);
    Some(inv_d * d)
}

/// The evaluation engine of a bundle fit.
#[derive(Clone, Debug)]
pub struct Bundle<'a> {
    data: &'a BundleData,
    layout: Layout,
    /// Nominal geometry without limits (trial joints replace its legs).
    base: GeometryParams,
    /// Registration rotation from the fiducials' Kabsch fit.
    q0: Matrix3<f64>,
    /// Registration translation from the fiducials' Kabsch fit (mm).
    tau0: Vector3<f64>,
    /// FK start of each pose (FK with the nominal joints).
    starts: Vec<Pose<f64>>,
    priors: Priors,
    /// Data rows (3 per point).
    n_data_rows: usize,
    /// Nominal joints (mm).
    theta0: ParamVec,
    /// Fiducial observations, local coordinates.
    fid_local: Vec<LocalObs>,
    /// Ball observations pose by pose, local coordinates.
    ball_local: Vec<Vec<LocalObs>>,
    /// Scale of each data row (variance factors, [`Bundle::set_variance_factors`]).
    row_scale: Vec<f64>,
}

impl<'a> Bundle<'a> {
    /// Prepares the fit: registration from the fiducials (weighted Kabsch), FK of every
    /// pose with the nominal joints.
    pub fn new(data: &'a BundleData, priors: Priors) -> Result<Self, BundleError> {
        let layout = Layout {
            n_balls: data.ball_names.len(),
        };
        if data.balls_nominal_m.len() != layout.n_balls {
            return Err(BundleError::Data(
                "ball list and nominal centres differ".into(),
            ));
        }
        let from: Vec<[f64; 3]> = data.fiducials.iter().map(|f| f.drawing_b_mm).collect();
        let to: Vec<[f64; 3]> = data.fiducials.iter().map(|f| f.obs.y_mm).collect();
        let w: Vec<f64> = data
            .fiducials
            .iter()
            .map(|f| 3.0 / f.obs.cov_mm2.trace())
            .collect();
        let reg = kabsch(&from, &to, Some(&w))
            .map_err(|e| BundleError::Data(format!("fiducial registration: {e}")))?;
        let base = GeometryParams::new(data.nominal.legs, data.nominal.p0_mm);
        let nom = Geometry::<f64>::new(&base)
            .map_err(|e| BundleError::Data(crate::files::describe_geometry_error(&e)))?;
        let cfg = FkConfig {
            max_iterations: BUNDLE_FK_ITERATIONS,
            ..FkConfig::default()
        };
        let starts = data
            .poses
            .iter()
            .map(|p| {
                fk(&nom, &p.strokes_mm, &Pose::home(), &cfg)
                    .map(|s| s.pose)
                    .map_err(|e| {
                        BundleError::Data(format!(
                            "line {}: pose {}: nominal forward kinematics: {}",
                            p.stroke_line,
                            p.pose,
                            crate::ikfk::describe_fk_error(&e)
                        ))
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let n_points =
            data.fiducials.len() + data.poses.iter().map(|p| p.balls.len()).sum::<usize>();
        let q0 = *reg.rotation.to_rotation_matrix().matrix();
        let tau0 = reg.translation.vector;
        let local = |o: &PointObs| LocalObs {
            z_mm: q0.transpose() * (Vector3::from(o.y_mm) - tau0),
            whiten: o.whiten * q0,
        };
        Ok(Self {
            data,
            layout,
            base,
            q0,
            tau0,
            starts,
            priors,
            n_data_rows: 3 * n_points,
            theta0: to_vec(&data.nominal),
            fid_local: data.fiducials.iter().map(|f| local(&f.obs)).collect(),
            ball_local: data
                .poses
                .iter()
                .map(|p| p.balls.iter().map(|b| local(&b.obs)).collect())
                .collect(),
            row_scale: vec![1.0; 3 * n_points],
        })
    }

    /// The observations in row order (fiducials, then the balls pose by pose).
    pub fn observations(&self) -> impl Iterator<Item = &PointObs> {
        self.data.fiducials.iter().map(|f| &f.obs).chain(
            self.data
                .poses
                .iter()
                .flat_map(|p| p.balls.iter().map(|b| &b.obs)),
        )
    }

    /// Scales every point's tracker variance by its component's factor `k` (1: the
    /// noise model as given).
    pub fn set_variance_factors(&mut self, k: &[f64; N_COMPONENTS]) {
        let scales: Vec<f64> = self.observations().flat_map(|o| o.row_scales(k)).collect();
        self.row_scale = scales;
    }

    /// Replaces the priors (the number of prior rows must not change: `Some` stays
    /// `Some`).
    pub fn set_priors(&mut self, priors: Priors) {
        debug_assert_eq!(
            priors.joint_sigma_mm.is_some(),
            self.priors.joint_sigma_mm.is_some()
        );
        debug_assert_eq!(
            priors.ball_sigma_mm.is_some(),
            self.priors.ball_sigma_mm.is_some()
        );
        self.priors = priors;
    }

    /// The scale of each data row set by [`Bundle::set_variance_factors`].
    pub fn row_scales(&self) -> &[f64] {
        &self.row_scale
    }

    /// The priors in force.
    pub fn priors(&self) -> Priors {
        self.priors
    }

    /// The data the bundle fits.
    pub fn data(&self) -> &BundleData {
        self.data
    }

    /// Index layout of the unknowns.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// Number of unknowns.
    pub fn n_params(&self) -> usize {
        self.layout.n()
    }

    /// Number of data rows (3 per measured point).
    pub fn n_data_rows(&self) -> usize {
        self.n_data_rows
    }

    /// Number of residual rows (data and priors).
    pub fn n_rows(&self) -> usize {
        self.n_data_rows
            + if self.priors.joint_sigma_mm.is_some() {
                N_PARAMS
            } else {
                0
            }
            + if self.priors.ball_sigma_mm.is_some() {
                3 * self.layout.n_balls
            } else {
                0
            }
    }

    /// The start: nominal joints, nominal balls, the fiducial registration (all zero).
    pub fn start(&self) -> Vec<f64> {
        vec![0.0; self.n_params()]
    }

    /// The registration (base -> tracker) of an unknown vector:
    /// `y = Q0 Rd x + Q0 d + tau0`.
    pub fn registration(&self, x: &[f64]) -> Isometry3<f64> {
        let (rd, d) = self.reg_parts(x);
        let rot = nalgebra::Rotation3::from_matrix_unchecked(self.q0 * rd);
        Isometry3::from_parts(
            Translation3::from(self.q0 * d + self.tau0),
            UnitQuaternion::from_rotation_matrix(&rot),
        )
    }

    /// `Rd` and `d` of the registration correction.
    fn reg_parts(&self, x: &[f64]) -> (Matrix3<f64>, Vector3<f64>) {
        let r = self.layout.registration();
        let rd = rotation_matrix(&[x[r], x[r + 1], x[r + 2]]);
        (rd, Vector3::new(x[r + 3], x[r + 4], x[r + 5]))
    }

    /// Joint coordinates of an unknown vector (mm).
    pub fn joints(&self, x: &[f64]) -> ParamVec {
        let mut v = self.theta0;
        for (vk, dk) in v.iter_mut().zip(x.iter()) {
            *vk += dk;
        }
        v
    }

    /// Ball centres (frame M, mm) of an unknown vector.
    pub fn balls(&self, x: &[f64]) -> Vec<[f64; 3]> {
        self.data
            .balls_nominal_m
            .iter()
            .enumerate()
            .map(|(k, c)| {
                let i = self.layout.ball(k);
                [c[0] + x[i], c[1] + x[i + 1], c[2] + x[i + 2]]
            })
            .collect()
    }

    /// The poses `FK(s_j, theta)` (None where FK fails).
    pub fn poses(&self, x: &[f64]) -> Vec<Option<Pose<f64>>> {
        let Ok(geom) = Geometry::<f64>::new(&from_vec(&self.joints(x), &self.base)) else {
            return vec![None; self.data.poses.len()];
        };
        let cfg = FkConfig {
            max_iterations: BUNDLE_FK_ITERATIONS,
            ..FkConfig::default()
        };
        self.data
            .poses
            .iter()
            .zip(self.starts.iter())
            .map(|(p, s)| fk(&geom, &p.strokes_mm, s, &cfg).ok().map(|s| s.pose))
            .collect()
    }

    /// Residuals (whitened, dimensionless): fiducials, then the balls pose by pose, then
    /// the priors. With `jac` (row-major, [`Bundle::n_rows`] x [`Bundle::n_params`]), also
    /// the analytic Jacobian `d r / d x`.
    pub fn evaluate(&self, x: &[f64], mut jac: Option<&mut [f64]>) -> Vec<f64> {
        let n = self.n_params();
        let mut res = vec![0.0; self.n_rows()];
        if let Some(j) = jac.as_deref_mut() {
            j.iter_mut().for_each(|v| *v = 0.0);
        }
        let (rd, dreg) = self.reg_parts(x);
        let rr = self.layout.registration();
        let gamma_d = x[rr + 2];
        let balls = self.balls(x);
        let mut row = 0;
        // Writes one point's whitened residual and its registration columns.
        let point = |row: usize,
                     obs: &LocalObs,
                     x_b: &Vector3<f64>,
                     res: &mut [f64],
                     jac: &mut Option<&mut [f64]>| {
            let z = rd * x_b + dreg;
            let r = obs.whiten * (obs.z_mm - z);
            res[row..row + 3].copy_from_slice(r.as_slice());
            if let Some(j) = jac.as_deref_mut() {
                let cols = rotation_columns(&rd, gamma_d, x_b);
                for (k, c) in cols.iter().enumerate() {
                    let d = -(obs.whiten * c);
                    for a in 0..3 {
                        j[(row + a) * n + rr + k] = d[a];
                    }
                }
                for a in 0..3 {
                    for k in 0..3 {
                        j[(row + a) * n + rr + 3 + k] = -obs.whiten[(a, k)];
                    }
                }
            }
        };
        for (f, obs) in self.data.fiducials.iter().zip(self.fid_local.iter()) {
            point(row, obs, &Vector3::from(f.drawing_b_mm), &mut res, &mut jac);
            row += 3;
        }
        let geom = Geometry::<f64>::new(&from_vec(&self.joints(x), &self.base)).ok();
        let cfg = FkConfig {
            max_iterations: BUNDLE_FK_ITERATIONS,
            ..FkConfig::default()
        };
        let p0 = Vector3::from(self.data.nominal.p0_mm);
        for ((pose, start), local) in self
            .data
            .poses
            .iter()
            .zip(self.starts.iter())
            .zip(self.ball_local.iter())
        {
            let solved = geom.as_ref().and_then(|g| {
                let p = fk(g, &pose.strokes_mm, start, &cfg).ok()?.pose;
                if jac.is_some() {
                    let (d, jp) = kinematic_jacobians(g, &p)?;
                    let inv = jp.try_inverse()?;
                    let inv_d = DMatrix::from_fn(6, 6, |r, c| inv[(r, c)]);
                    Some((p, Some(-(inv_d * d))))
                } else {
                    Some((p, None))
                }
            });
            let Some((p, dp_dtheta)) = solved else {
                for _ in &pose.balls {
                    res[row..row + 3]
                        .iter_mut()
                        .for_each(|v| *v = FAILED_POSE_RESIDUAL);
                    row += 3;
                }
                continue;
            };
            let r = rotation_matrix(&p.rotation_rad);
            let t = Vector3::from(p.translation_mm);
            for (b, obs) in pose.balls.iter().zip(local.iter()) {
                let c = Vector3::from(balls[b.ball]);
                let x_b = p0 + t + r * c;
                point(row, obs, &x_b, &mut res, &mut jac);
                if let (Some(j), Some(m)) = (jac.as_deref_mut(), dp_dtheta.as_ref()) {
                    let h = point_pose_jacobian(&r, p.rotation_rad[2], &c);
                    let wq = obs.whiten * rd;
                    // d r / d theta = -W Q0 Rd H dP/dtheta
                    let wqh = -(wq * h);
                    let wqh_d = DMatrix::from_fn(3, 6, |a, k| wqh[(a, k)]);
                    let dth = wqh_d * m;
                    for a in 0..3 {
                        for k in 0..N_PARAMS {
                            j[(row + a) * n + k] = dth[(a, k)];
                        }
                    }
                    // d r / d c = -W Q0 Rd R
                    let dc = -(wq * r);
                    let cb = self.layout.ball(b.ball);
                    for a in 0..3 {
                        for k in 0..3 {
                            j[(row + a) * n + cb + k] = dc[(a, k)];
                        }
                    }
                }
                row += 3;
            }
        }
        if let Some(s) = self.priors.joint_sigma_mm {
            for k in 0..N_PARAMS {
                res[row] = x[k] / s;
                if let Some(j) = jac.as_deref_mut() {
                    j[row * n + k] = 1.0 / s;
                }
                row += 1;
            }
        }
        if let Some(s) = self.priors.ball_sigma_mm {
            for k in 0..self.layout.n_balls {
                for a in 0..3 {
                    let i = self.layout.ball(k) + a;
                    res[row] = x[i] / s;
                    if let Some(j) = jac.as_deref_mut() {
                        j[row * n + i] = 1.0 / s;
                    }
                    row += 1;
                }
            }
        }
        for (i, c) in self.row_scale.iter().enumerate() {
            if *c != 1.0 {
                res[i] *= c;
                if let Some(j) = jac.as_deref_mut() {
                    j[i * n..(i + 1) * n].iter_mut().for_each(|v| *v *= c);
                }
            }
        }
        res
    }

    /// The Jacobian at `x` as a matrix (rows as [`Bundle::evaluate`]).
    pub fn jacobian(&self, x: &[f64]) -> DMatrix<f64> {
        let mut j = vec![0.0; self.n_rows() * self.n_params()];
        self.evaluate(x, Some(&mut j));
        DMatrix::from_row_slice(self.n_rows(), self.n_params(), &j)
    }

    /// Line and description of every data row block (3 rows per point), in row order.
    pub fn point_labels(&self) -> Vec<(usize, String)> {
        let mut out: Vec<(usize, String)> = self
            .data
            .fiducials
            .iter()
            .map(|f| (f.obs.line, format!("fiducial {}", f.name)))
            .collect();
        for p in &self.data.poses {
            for b in &p.balls {
                out.push((
                    b.obs.line,
                    format!("ball {} of pose {}", self.data.ball_names[b.ball], p.pose),
                ));
            }
        }
        out
    }
}

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
/// [`super::adjust`] instead, which estimates the noise and tests each point).
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
    let lm = super::lm::solver(cfg.tol_eps, cfg.patience);
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

// ---------------------------------------------------------------------------------------
// Predicted accuracy
// ---------------------------------------------------------------------------------------

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

// ---------------------------------------------------------------------------------------
// Observability
// ---------------------------------------------------------------------------------------

/// One direction of the joint-parameter space and how well the data see it.
#[derive(Clone, Debug, PartialEq)]
pub struct Direction {
    /// Singular value with the balls and the registration free (marginal information,
    /// in units of the scale: 1 = the data know it as well as one scale sigma).
    pub singular_free: f64,
    /// The same direction's singular value with the balls and registration known.
    pub singular_known: f64,
    /// The unit direction (36, in scale units).
    pub vector: Vec<f64>,
    /// Plain-words description.
    pub description: String,
}

/// What the data can and cannot see of the joints.
#[derive(Clone, Debug, PartialEq)]
pub struct Observability {
    /// Scale of the joint coordinates (mm): singular values are relative to it.
    pub scale_mm: f64,
    /// Singular values of the marginal joint information, balls and registration free,
    /// largest first.
    pub singular_free: Vec<f64>,
    /// Singular values with the balls and registration known, largest first.
    pub singular_known: Vec<f64>,
    /// The weakest directions (balls and registration free), weakest first.
    pub weakest: Vec<Direction>,
    /// The directions that freeing the balls and registration hides most, by the
    /// fraction of information kept (smallest first).
    pub hidden: Vec<(f64, Direction)>,
}

/// Named patterns of the joint space (unit vectors in raw mm): global translations, the
/// rotation about B's z and the per-leg common shifts.
fn describe_direction(v: &[f64], nominal: &ParamVec) -> String {
    let norm = |u: &[f64]| u.iter().map(|x| x * x).sum::<f64>().sqrt();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut shares = Vec::new();
    // Global translations: every a and b shifted by e_axis.
    let mut trans2 = 0.0;
    for axis in 0..3 {
        let mut u = vec![0.0; N_PARAMS];
        for leg in 0..LEGS {
            u[leg * PARAMS_PER_LEG + axis] = 1.0;
            u[leg * PARAMS_PER_LEG + 3 + axis] = 1.0;
        }
        let p = dot(v, &u) / norm(&u);
        trans2 += p * p;
    }
    shares.push(("global translation", trans2));
    // Rotation about B's z: d a = e_z x a, d b = e_z x b.
    let mut u = vec![0.0; N_PARAMS];
    for leg in 0..LEGS {
        let a = leg * PARAMS_PER_LEG;
        u[a] = -nominal[a + 1];
        u[a + 1] = nominal[a];
        u[a + 3] = -nominal[a + 4];
        u[a + 4] = nominal[a + 3];
    }
    let p = dot(v, &u) / norm(&u);
    shares.push(("rotation about z", p * p));
    // Per-leg common shifts (a_i and b_i by the same vector): an 18-dim subspace.
    let mut common2 = 0.0;
    for leg in 0..LEGS {
        for axis in 0..3 {
            let i = leg * PARAMS_PER_LEG;
            let p = (v[i + axis] + v[i + 3 + axis]) / 2f64.sqrt();
            common2 += p * p;
        }
    }
    shares.push(("per-leg common shifts", common2));
    let mut idx: Vec<usize> = (0..N_PARAMS).collect();
    idx.sort_by(|a, b| v[*b].abs().total_cmp(&v[*a].abs()));
    let top: Vec<String> = idx
        .iter()
        .take(4)
        .map(|k| format!("{:+.2} {}", v[*k], param_name(*k)))
        .collect();
    format!(
        "{}; largest: {}",
        shares
            .iter()
            .map(|(n, s)| format!("{:.0} % {n}", 100.0 * s))
            .collect::<Vec<_>>()
            .join(", "),
        top.join(", ")
    )
}

/// Sorted (descending) square roots of the eigenvalues of a symmetric matrix.
fn sqrt_spectrum(m: &DMatrix<f64>) -> Vec<f64> {
    let mut s: Vec<f64> = m
        .clone()
        .symmetric_eigen()
        .eigenvalues
        .iter()
        .map(|v| v.max(0.0).sqrt())
        .collect();
    s.sort_by(|a, b| b.total_cmp(a));
    s
}

/// The observability of the joints from the data alone (priors left out) at `x`:
/// marginal information `S = A_tt - A_tn A_nn^-1 A_nt` (balls and registration free)
/// against `A_tt` (known), both in units of `scale_mm`; `n_report` weakest and most
/// hidden directions.
pub fn observability(
    data: &BundleData,
    x: &[f64],
    scale_mm: f64,
    n_report: usize,
) -> Result<Observability, BundleError> {
    let bundle = Bundle::new(data, Priors::NONE)?;
    let j = bundle.jacobian(x);
    let a = j.transpose() * &j;
    let nt = N_PARAMS;
    let nn = bundle.layout().n_nuisance();
    let att = a.view((0, 0), (nt, nt)).into_owned() * (scale_mm * scale_mm);
    let atn = a.view((0, nt), (nt, nn)).into_owned() * scale_mm;
    let ann = a.view((nt, nt), (nn, nn)).into_owned();
    let ann_inv = ann
        .cholesky()
        .ok_or_else(|| {
            BundleError::Data("balls and registration not determined by the data".into())
        })?
        .inverse();
    let s = &att - &atn * ann_inv * atn.transpose();
    let nominal = to_vec(&data.nominal);
    let rayleigh =
        |m: &DMatrix<f64>, v: &DVector<f64>| (v.transpose() * m * v)[(0, 0)].max(0.0).sqrt();
    let eig = s.clone().symmetric_eigen();
    let mut order: Vec<usize> = (0..nt).collect();
    order.sort_by(|p, q| eig.eigenvalues[*p].total_cmp(&eig.eigenvalues[*q]));
    let weakest = order
        .iter()
        .take(n_report)
        .map(|k| {
            let v = eig.eigenvectors.column(*k).into_owned();
            Direction {
                singular_free: eig.eigenvalues[*k].max(0.0).sqrt(),
                singular_known: rayleigh(&att, &v),
                description: describe_direction(v.as_slice(), &nominal),
                vector: v.as_slice().to_vec(),
            }
        })
        .collect();
    // Generalised problem S v = mu A_tt v via A_tt^-1/2 S A_tt^-1/2.
    let ke = att.clone().symmetric_eigen();
    let k_inv_sqrt = &ke.eigenvectors
        * DMatrix::from_diagonal(
            &ke.eigenvalues
                .map(|v| 1.0 / v.max(f64::MIN_POSITIVE).sqrt()),
        )
        * ke.eigenvectors.transpose();
    let g = (&k_inv_sqrt * &s * &k_inv_sqrt).symmetric_eigen();
    let mut gorder: Vec<usize> = (0..nt).collect();
    gorder.sort_by(|p, q| g.eigenvalues[*p].total_cmp(&g.eigenvalues[*q]));
    let hidden = gorder
        .iter()
        .take(n_report)
        .map(|k| {
            let w = g.eigenvectors.column(*k).into_owned();
            let v = &k_inv_sqrt * w;
            let v = &v / v.norm();
            (
                g.eigenvalues[*k].max(0.0),
                Direction {
                    singular_free: rayleigh(&s, &v),
                    singular_known: rayleigh(&att, &v),
                    description: describe_direction(v.as_slice(), &nominal),
                    vector: v.as_slice().to_vec(),
                },
            )
        })
        .collect();
    Ok(Observability {
        scale_mm,
        singular_free: sqrt_spectrum(&s),
        singular_known: sqrt_spectrum(&att),
        weakest,
        hidden,
    })
}
