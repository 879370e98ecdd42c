//! Inverse kinematics: mirror pose -> six slider strokes.
//!
//! The paper's equation for leg i, with `b'_i = R b_i + p0 + t`:
//!
//! ```text
//! dl_i = b'_iz - a_iz - sqrt(l_i0^2 - (b'_ix - a_ix)^2 - (b'_iy - a_iy)^2)
//! ```
//!
//! evaluated naively in f32 loses ~30 nm: it subtracts numbers of ~100 mm and takes the
//! root of ~5000 mm^2. Here every quantity is relative to the home pose. With the home rod
//! vector `d0 = b + p0 - a` (derived in f64) and the small joint displacement
//! `u = (R - I) b + t` (a few mm, `R - I` formed without cancellation):
//!
//! ```text
//! delta = u_x (2 d0_x + u_x) + u_y (2 d0_y + u_y)      (change of the horizontal rod length^2)
//! q     = sqrt(d0_z^2 - delta)                          (vertical rod component now)
//! dl    = u_z + delta / (q + d0_z)                      (= d0_z + u_z - q, without cancellation)
//! ```
//!
//! `q` enters only a denominator of size ~2 d0_z, so its rounding is damped ~100-fold.
//! A negative radicand `d0_z^2 - delta` means the leg cannot reach the pose.

use super::geometry::{Geometry, Leg, LEGS};
use super::linalg::{add3, mat_vec3};
use super::pose::{Pose, RotationDelta};
use super::real::Real;
use super::workspace::Refusals;

/// Why a pose has no strokes. Leg sets are bit masks, bit i = leg i+1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IkError {
    /// A pose component is NaN or infinite.
    NonFinite,
    /// Pose outside the configured workspace; bit k = axis k of `[x, y, z, alpha, beta, gamma]`.
    OutsideWorkspace {
        /// Bit mask of the offending axes.
        axes: u8,
    },
    /// Negative radicand: the rod cannot reach (bit mask of legs).
    Unreachable {
        /// Bit mask of the legs that cannot reach.
        legs: u8,
    },
    /// A stroke is outside its slider limits (bit mask of legs).
    StrokeLimit {
        /// Bit mask of the legs beyond a limit.
        legs: u8,
    },
}

impl IkError {
    /// Stable numeric code for telemetry.
    pub const fn code(&self) -> u16 {
        match self {
            IkError::NonFinite => 0x0201,
            IkError::OutsideWorkspace { .. } => 0x0202,
            IkError::Unreachable { .. } => 0x0203,
            IkError::StrokeLimit { .. } => 0x0204,
        }
    }
}

/// One leg evaluated at a pose: the stroke and what the Jacobian needs.
#[derive(Clone, Copy, Debug, Default)]
pub struct LegState<T: Real> {
    /// Slider stroke (mm).
    pub stroke_mm: T,
    /// Horizontal rod components `b'_x - a_x`, `b'_y - a_y` at the pose (mm).
    pub h_mm: [T; 2],
    /// Vertical rod component at the pose (mm), > 0.
    pub q_mm: T,
    /// `R b = b + (R - I) b` (mm, frame B): the upper joint relative to M's origin.
    pub rb_mm: [T; 3],
}

/// Evaluates one leg; `None` when the radicand is not positive (leg cannot reach).
#[inline(always)]
pub fn leg_state<T: Real>(leg: &Leg<T>, rot: &RotationDelta<T>, t: &[T; 3]) -> Option<LegState<T>> {
    let b = &leg.b_mm.data.0[0];
    let wb = mat_vec3(&rot.w, b);
    let u = add3(&wb, t);
    let d0 = &leg.d0_mm;
    let delta = u[0] * (leg.two_d0_xy_mm[0] + u[0]) + u[1] * (leg.two_d0_xy_mm[1] + u[1]);
    let radicand = leg.d0z_sq_mm2 - delta;
    // `!(x > 0)` also rejects NaN.
    if !(radicand > T::ZERO) {
        return None;
    }
    let q = if delta.abs() <= leg.fast_sqrt_delta_mm2 {
        // First-order guess d0_z - delta / (2 d0_z), then two Newton steps (see
        // `SQRT_FAST_FRACTION`): cheaper than a general square root.
        let mut q = d0[2] - delta * leg.inv_two_d0z_per_mm;
        q = T::HALF * (q + radicand / q);
        T::HALF * (q + radicand / q)
    } else {
        radicand.sqrt()
    };
    Some(LegState {
        stroke_mm: u[2] + delta / (q + d0[2]),
        h_mm: [d0[0] + u[0], d0[1] + u[1]],
        q_mm: q,
        rb_mm: add3(b, &wb),
    })
}

/// Strokes for a pose without any limit check, and the bit mask of the legs whose
/// radicand is not positive (their stroke is left 0). The pose must be finite.
#[inline]
pub(crate) fn strokes_unchecked<T: Real>(geom: &Geometry<T>, pose: &Pose<T>) -> ([T; LEGS], u8) {
    let rot = RotationDelta::new_inline(&pose.rotation_rad);
    let mut strokes = [T::ZERO; LEGS];
    let mut bad = 0u8;
    for (i, (s, leg)) in strokes.iter_mut().zip(geom.legs.iter()).enumerate() {
        match leg_state(leg, &rot, &pose.translation_mm) {
            Some(st) => *s = st.stroke_mm,
            None => bad |= 1 << i,
        }
    }
    (strokes, bad)
}

/// Inverse kinematics with every check: finite input, workspace (if configured),
/// reachability of every leg, slider limits (if configured). Strokes in mm, slider order.
///
/// When several checks fail the error reports the first in that order; use
/// [`super::workspace::check`] for every reason at once.
///
/// Never inlined: one copy per float type serves every caller (flash), and it is the
/// code the benchmarks measure.
#[inline(never)]
pub fn ik<T: Real>(geom: &Geometry<T>, pose: &Pose<T>) -> Result<[T; LEGS], IkError> {
    let (strokes, refusals) = super::workspace::evaluate(geom, pose);
    match refusals.first_error() {
        None => Ok(strokes),
        Some(e) => Err(e),
    }
}

impl Refusals {
    /// The [`IkError`] for the first failing check, `None` if the pose is accepted.
    pub fn first_error(&self) -> Option<IkError> {
        if self.non_finite {
            Some(IkError::NonFinite)
        } else if self.axes_outside != 0 {
            Some(IkError::OutsideWorkspace {
                axes: self.axes_outside,
            })
        } else if self.legs_unreachable != 0 {
            Some(IkError::Unreachable {
                legs: self.legs_unreachable,
            })
        } else if self.legs_below_min | self.legs_above_max != 0 {
            Some(IkError::StrokeLimit {
                legs: self.legs_below_min | self.legs_above_max,
            })
        } else {
            None
        }
    }
}
