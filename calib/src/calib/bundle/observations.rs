//! What a bundle fit measures: tracker points with their covariance and whitening, the
//! fiducials, the balls pose by pose, and the data set that gathers them.

use nalgebra::{Matrix3, Vector3};

use m2ctl::kinematics::{GeometryParams, LEGS};

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
    pub(super) whiten: Matrix3<f64>,
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
pub(super) struct LocalObs {
    /// `Q0^T (y - tau0)` (mm).
    pub(super) z_mm: Vector3<f64>,
    /// `L^-1 Q0` (1/mm).
    pub(super) whiten: Matrix3<f64>,
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
