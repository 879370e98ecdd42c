//! The analytic derivatives of the bundle fit: rotation and point-pose Jacobians, the
//! kinematic Jacobians of a pose and the pose's sensitivity to the joint errors.

use nalgebra::{DMatrix, Matrix3, Matrix6, Vector3};

use crate::calib::{stroke_gradient, N_PARAMS, PARAMS_PER_LEG};
use m2ctl::kinematics::fk::strokes_and_jacobian;
use m2ctl::kinematics::ik::leg_state;
use m2ctl::kinematics::pose::RotationDelta;
use m2ctl::kinematics::{Geometry, Pose, LEGS};

/// The three columns `d(R v)/d[alpha, beta, gamma]` for `R = Rz(g) Ry(b) Rx(a)`:
/// `R (e_x x v)`, `(Rz(g) e_y) x (R v)`, `e_z x (R v)`.
pub(super) fn rotation_columns(
    r: &Matrix3<f64>,
    gamma: f64,
    v: &Vector3<f64>,
) -> [Vector3<f64>; 3] {
    let rv = r * v;
    let rz_ey = Vector3::new(-gamma.sin(), gamma.cos(), 0.0);
    [
        r * Vector3::x().cross(v),
        rz_ey.cross(&rv),
        Vector3::z().cross(&rv),
    ]
}

/// `d x_B / d P` (3 x 6) of a point `c` (frame M) at a pose with rotation `r`, `gamma`.
pub(super) fn point_pose_jacobian(
    r: &Matrix3<f64>,
    gamma: f64,
    c: &Vector3<f64>,
) -> nalgebra::Matrix3x6<f64> {
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
pub(super) fn kinematic_jacobians(
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
