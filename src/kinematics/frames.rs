//! The operator's frames: a **pivot** (tool point) on the moving platform and a **user
//! frame** fixed to the base, and the map between the operator's pose and the internal
//! pose the kinematics use.
//!
//! * Internal pose (everything else in [`super`]): translation `t` of M's origin from p0
//!   along B's axes, rotation `R = Rz(gamma) Ry(beta) Rx(alpha)` of M in B.
//! * Operator pose: translation `u` of the **pivot** `c` (a point fixed in M, given in M's
//!   coordinates, mm) from its home position, along the **user frame's** axes, and rotation
//!   `Q` (same Euler convention) expressed in the user frame: the mirror's rotation in B is
//!   `R = U Q U^T`, with `U` the user frame's orientation in B.
//!
//! The pivot's position in B is `p0 + t + R c`; at home `p0 + c`. So the pivot moves by
//! `t + (R - I) c`, and
//!
//! ```text
//! to internal:  R - I = U (Q - I) U^T        t = U u - (R - I) c
//! to operator:  Q - I = U^T (R - I) U        u = U^T (t + (R - I) c)
//! ```
//!
//! Only the small `R - I` and `Q - I` (formed without cancellation,
//! [`super::pose::RotationDelta`]) enter the products, and the Euler angles are read
//! back from `I + W` with the small terms carrying the precision, so the composed map
//! stays within the f32 budget (host test: <= 1 nm over the workspace against f64). With
//! the identity user frame the angles pass through unchanged; with a zero pivot as well
//! the map is the identity, bit for bit. A pure rotation commanded about the pivot
//! (`u = 0`) keeps the pivot where it is along the whole path, because the trajectory is
//! interpolated in operator coordinates and mapped point by point.
//!
//! The user frame's origin does not enter (poses are displacements from home).

use nalgebra::{Matrix3, Vector3};

use super::linalg::{add3, mat_mul3, sub3};
use super::pose::{Pose, RotationDelta};
use super::real::Real;

/// The pivot and the user frame (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frames<T: Real> {
    /// The pivot `c` in M's coordinates (mm).
    pivot_mm: Vector3<T>,
    /// `U`, the user frame's orientation in B; `None`: the base frame itself.
    user: Option<Matrix3<T>>,
}

impl<T: Real> Default for Frames<T> {
    fn default() -> Self {
        Self::identity()
    }
}

/// The Euler angles `[alpha, beta, gamma]` of `R = I + w` for `R = Rz Ry Rx`.
fn euler_of<T: Real>(w: &Matrix3<T>) -> [T; 3] {
    let beta = (-w[(2, 0)]).asin();
    let alpha = w[(2, 1)].atan2(T::ONE + w[(2, 2)]);
    let gamma = w[(1, 0)].atan2(T::ONE + w[(0, 0)]);
    [alpha, beta, gamma]
}

impl<T: Real> Frames<T> {
    /// No pivot offset, the base frame: the operator's pose is the internal pose.
    pub fn identity() -> Self {
        Self {
            pivot_mm: Vector3::zeros(),
            user: None,
        }
    }

    /// A pivot at `pivot_mm` (M's coordinates, mm) and a user frame rotated by
    /// `user_rotation_rad` (`[alpha, beta, gamma]`, same convention as a pose) from B.
    pub fn new(pivot_mm: [T; 3], user_rotation_rad: [T; 3]) -> Self {
        let user = if user_rotation_rad.iter().all(|a| *a == T::ZERO) {
            None
        } else {
            Some(Matrix3::identity() + RotationDelta::new(&user_rotation_rad).w)
        };
        Self {
            pivot_mm: Vector3::new(pivot_mm[0], pivot_mm[1], pivot_mm[2]),
            user,
        }
    }

    /// The identity map (no work is done then).
    pub fn is_identity(&self) -> bool {
        self.user.is_none() && self.pivot_mm.iter().all(|v| *v == T::ZERO)
    }

    /// The internal pose of an operator pose.
    pub fn to_internal(&self, op: &Pose<T>) -> Pose<T> {
        if self.is_identity() {
            return *op;
        }
        let q = RotationDelta::new(&op.rotation_rad).w;
        let u = op.translation_mm;
        let (w, rotation_rad, moved) = match &self.user {
            None => (q, op.rotation_rad, u),
            Some(r_u) => {
                let w = mat_mul3(&mat_mul3(r_u, &q), &tr3(r_u));
                (w, euler_of(&w), mv3(r_u, &u))
            }
        };
        Pose {
            translation_mm: sub3(&moved, &mv3(&w, &self.pivot_mm.data.0[0])),
            rotation_rad,
        }
    }

    /// The operator pose of an internal pose.
    pub fn to_operator(&self, int: &Pose<T>) -> Pose<T> {
        if self.is_identity() {
            return *int;
        }
        let w = RotationDelta::new(&int.rotation_rad).w;
        let moved = add3(&int.translation_mm, &mv3(&w, &self.pivot_mm.data.0[0]));
        let (u, rotation_rad) = match &self.user {
            None => (moved, int.rotation_rad),
            Some(r_u) => {
                let r_t = tr3(r_u);
                let q = mat_mul3(&mat_mul3(&r_t, &w), r_u);
                (mv3(&r_t, &moved), euler_of(&q))
            }
        };
        Pose {
            translation_mm: u,
            rotation_rad,
        }
    }
}

/// [`super::linalg::mat_vec3`], out of line: the frame maps use it four times (not a
/// hot path; the IK's copy stays inlined). Same operations, same bits.
#[inline(never)]
fn mv3<T: Real>(m: &nalgebra::Matrix3<T>, v: &[T; 3]) -> [T; 3] {
    super::linalg::mat_vec3(m, v)
}

/// [`super::linalg::transpose3`], out of line (used twice by the frame maps).
#[inline(never)]
fn tr3<T: Real>(a: &nalgebra::Matrix3<T>) -> nalgebra::Matrix3<T> {
    super::linalg::transpose3(a)
}
