//! Rigid registration of point sets (Kabsch / Horn, weighted least squares) and the
//! pose of the moving platform from its measured target balls.
//!
//! [`kabsch`] finds the rotation `Q` and translation `t` minimising
//! `sum_i w_i |Q x_i + t - y_i|^2`: with the weighted centroids `xc`, `yc` and
//! `H = sum_i w_i (x_i - xc)(y_i - yc)^T = U S V^T`, `Q = V diag(1, 1, det(V U^T)) U^T` (the
//! sign guard keeps a proper rotation), `t = yc - Q xc`. Exact for noise-free data (to
//! rounding) as soon as three points are not collinear.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

use m2ctl::kinematics::Pose;

/// Smallest ratio of the second to the first singular value of the centred point set
/// (the spread across its main direction): below it the points are (nearly) collinear and
/// a rotation about that line is undetermined.
pub const MIN_SPREAD_RATIO: f64 = 1.0e-6;

/// Why a registration failed.
#[derive(Clone, Debug, PartialEq)]
pub enum RegistrationError {
    /// Fewer than three point pairs, or the two lists differ in length.
    TooFewPoints(usize),
    /// The points are (nearly) collinear.
    Degenerate,
    /// A weight is not positive and finite, or a coordinate is not finite.
    BadInput,
}

impl std::fmt::Display for RegistrationError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RegistrationError::TooFewPoints(n) => {
                write!(f, "{n} point pairs: a registration needs at least 3")
            }
            RegistrationError::Degenerate => {
                f.write_str("the points are collinear: the rotation about their line is free")
            }
            RegistrationError::BadInput => f.write_str("a coordinate or weight is not finite"),
        }
    }
}

impl std::error::Error for RegistrationError {}

/// The weighted least-squares rigid transform taking `from` onto `to`
/// (`to_i ~ Q from_i + t`), weights `w` (> 0; all ones if `None`).
pub fn kabsch(
    from: &[[f64; 3]],
    to: &[[f64; 3]],
    w: Option<&[f64]>,
) -> Result<Isometry3<f64>, RegistrationError> {
    let n = from.len();
    if n < 3 || to.len() != n || w.is_some_and(|w| w.len() != n) {
        return Err(RegistrationError::TooFewPoints(n.min(to.len())));
    }
    let weight = |i: usize| w.map_or(1.0, |w| w[i]);
    let finite = |p: &[f64; 3]| p.iter().all(|v| v.is_finite());
    if (0..n).any(|i| !(weight(i) > 0.0 && weight(i).is_finite()))
        || !from.iter().all(finite)
        || !to.iter().all(finite)
    {
        return Err(RegistrationError::BadInput);
    }
    let wsum: f64 = (0..n).map(weight).sum();
    let mut xc = Vector3::zeros();
    let mut yc = Vector3::zeros();
    for i in 0..n {
        xc += Vector3::from(from[i]) * weight(i);
        yc += Vector3::from(to[i]) * weight(i);
    }
    xc /= wsum;
    yc /= wsum;
    let mut h = Matrix3::zeros();
    let mut spread = Matrix3::zeros();
    for i in 0..n {
        let dx = Vector3::from(from[i]) - xc;
        let dy = Vector3::from(to[i]) - yc;
        h += dx * dy.transpose() * weight(i);
        spread += dx * dx.transpose() * weight(i);
    }
    let sv = spread.singular_values();
    let mut s: Vec<f64> = sv.iter().copied().collect();
    s.sort_by(|a, b| b.total_cmp(a));
    if s[0].is_nan() || s[0] <= 0.0 || s[1] < MIN_SPREAD_RATIO * s[0] {
        return Err(RegistrationError::Degenerate);
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Err(RegistrationError::Degenerate);
    };
    let v = vt.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let q = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    let rot = Rotation3::from_matrix_unchecked(q);
    let t = yc - rot * xc;
    Ok(Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&rot),
    ))
}

/// The rotation angles `[alpha, beta, gamma]` (rad) of `R = Rz(gamma) Ry(beta) Rx(alpha)`.
pub fn rotation_angles(r: &Matrix3<f64>) -> [f64; 3] {
    let (a, b, g) = Rotation3::from_matrix_unchecked(*r).euler_angles();
    [a, b, g]
}

/// The platform pose from its balls: `balls_m` (ball centres in frame M, mm) and the same
/// balls measured in frame B (`balls_b`, mm, already mapped from the tracker frame with
/// the registration). The fit `x_B = R c + o` gives `t = o - p0` and the angles of `R`.
pub fn pose_from_balls(
    balls_m: &[[f64; 3]],
    balls_b: &[[f64; 3]],
    weights: Option<&[f64]>,
    p0_mm: &[f64; 3],
) -> Result<Pose<f64>, RegistrationError> {
    let iso = kabsch(balls_m, balls_b, weights)?;
    let r = iso.rotation.to_rotation_matrix();
    let o = iso.translation.vector;
    Ok(Pose {
        translation_mm: [o.x - p0_mm[0], o.y - p0_mm[1], o.z - p0_mm[2]],
        rotation_rad: rotation_angles(r.matrix()),
    })
}
