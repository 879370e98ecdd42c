//! Forward kinematics: six measured strokes -> pose, by Newton-Raphson on
//! `f(P) = s_measured - IK(P) = 0` with the analytic Jacobian, warm-started.
//!
//! Jacobian of leg i (`n = (h_x/q, h_y/q, 1)`, `h` the horizontal rod components and `q`
//! the vertical one at the pose, `Rb = b + (R - I) b`):
//!
//! ```text
//! d dl / d t     = n
//! d dl / d alpha = n . R (e_x x b)                (dR/d alpha = R [e_x]x)
//! d dl / d beta  = n . ((Rz e_y) x R b)           (dR/d beta  = [Rz e_y]x R)
//! d dl / d gamma = n . (e_z x R b)                (dR/d gamma = [e_z]x R)
//! ```
//!
//! Termination: converged when a Newton step is below the step tolerances (the step is
//! applied); then the residual at the result is evaluated and must be below the residual
//! tolerance, so a half-converged pose is never returned as good.

use super::geometry::{Geometry, LEGS};
use super::ik::{leg_state, strokes_unchecked};
use super::linalg::solve6;
use super::pose::{Pose, RotationDelta};
use super::real::Real;

/// Newton-Raphson settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FkConfig<T> {
    /// Most Newton steps before giving up.
    pub max_iterations: u8,
    /// Converged when every translation step component is below this (mm)...
    pub step_tol_mm: T,
    /// ...and every rotation step component is below this (rad).
    pub step_tol_rad: T,
    /// After convergence, every leg's `|s_measured - IK(P)|` must be below this (mm).
    pub residual_tol_mm: T,
    /// Jacobian pivots below `pivot_ratio * max|J|` count as singular.
    pub pivot_ratio: T,
}

/// Default most Newton steps (from a 10 um warm start two are used, three from 1 mm).
pub const FK_MAX_ITERATIONS: u8 = 8;
/// Step tolerance in machine epsilons of 1 mm: far above the rounding noise of a step,
/// far below anything physical (f32: 30 nm; the step is applied, so the error left is
/// of order step^2 / 100 mm).
pub const FK_STEP_TOL_EPS: f64 = 256.0;
/// Rotation step tolerance: the translation one divided by this lever arm (mm).
pub const FK_STEP_LEVER_MM: f64 = 100.0;
/// Residual tolerance in machine epsilons of 1 mm (f32: 7.6 nm, f64: 1.4e-14 mm).
pub const FK_RESIDUAL_TOL_EPS: f64 = 64.0;
/// Singular-pivot ratio in machine epsilons.
pub const FK_PIVOT_RATIO_EPS: f64 = 1024.0;

impl<T: Real> Default for FkConfig<T> {
    fn default() -> Self {
        let eps = T::EPSILON.to_f64();
        Self {
            max_iterations: FK_MAX_ITERATIONS,
            step_tol_mm: T::from_f64(FK_STEP_TOL_EPS * eps),
            step_tol_rad: T::from_f64(FK_STEP_TOL_EPS * eps / FK_STEP_LEVER_MM),
            residual_tol_mm: T::from_f64(FK_RESIDUAL_TOL_EPS * eps),
            pivot_ratio: T::from_f64(FK_PIVOT_RATIO_EPS * eps),
        }
    }
}

/// A converged forward-kinematics result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FkSolution<T> {
    /// The pose whose strokes match the measured ones.
    pub pose: Pose<T>,
    /// Newton steps taken (Jacobian solves).
    pub iterations: u8,
    /// Largest `|s_measured - IK(pose)|` over the legs (mm).
    pub residual_mm: T,
}

/// Why forward kinematics produced no pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FkError {
    /// A measured stroke or the warm start is NaN or infinite.
    NonFinite,
    /// The iterate left the reachable set (bit mask of legs) after `iterations` steps.
    Unreachable {
        /// Legs with a negative radicand.
        legs: u8,
        /// Steps taken before.
        iterations: u8,
    },
    /// The Jacobian is numerically singular at the iterate.
    SingularJacobian {
        /// Steps taken before.
        iterations: u8,
    },
    /// No convergence within the iteration budget.
    NotConverged {
        /// Steps taken.
        iterations: u8,
    },
    /// The steps converged but the strokes do not match (e.g. inconsistent readings).
    ResidualTooLarge {
        /// Steps taken.
        iterations: u8,
    },
}

impl FkError {
    /// Stable numeric code for telemetry.
    pub const fn code(&self) -> u16 {
        match self {
            FkError::NonFinite => 0x0301,
            FkError::Unreachable { .. } => 0x0302,
            FkError::SingularJacobian { .. } => 0x0303,
            FkError::NotConverged { .. } => 0x0304,
            FkError::ResidualTooLarge { .. } => 0x0305,
        }
    }
}

/// Strokes at `pose` and the Jacobian `d strokes / d pose` (rows legs, columns
/// `[x, y, z, alpha, beta, gamma]`, units mm/mm and mm/rad). `Err(mask)`: unreachable legs.
pub fn strokes_and_jacobian<T: Real>(
    geom: &Geometry<T>,
    pose: &Pose<T>,
) -> Result<([T; LEGS], [[T; 6]; LEGS]), u8> {
    let rot = RotationDelta::new(&pose.rotation_rad);
    let (sg, cg) = (rot.sg, rot.cg);
    let mut strokes = [T::ZERO; LEGS];
    let mut jac = [[T::ZERO; 6]; LEGS];
    let mut bad = 0u8;
    for (i, ((s, row), leg)) in strokes
        .iter_mut()
        .zip(jac.iter_mut())
        .zip(geom.legs.iter())
        .enumerate()
    {
        let Some(st) = leg_state(leg, &rot, &pose.translation_mm) else {
            bad |= 1 << i;
            continue;
        };
        *s = st.stroke_mm;
        let inv_q = T::ONE / st.q_mm;
        let n = [st.h_mm[0] * inv_q, st.h_mm[1] * inv_q, T::ONE];
        let b = &leg.b_mm;
        // R b
        let rb = [b[0] + st.wb_mm[0], b[1] + st.wb_mm[1], b[2] + st.wb_mm[2]];
        // R (e_x x b) = v + (R - I) v with v = (0, -b_z, b_y)
        let v = [T::ZERO, -b[2], b[1]];
        let wv = rot.apply_delta(&v);
        let d_alpha = [wv[0], v[1] + wv[1], v[2] + wv[2]];
        // (Rz e_y) x Rb with Rz e_y = (-sg, cg, 0)
        let d_beta = [cg * rb[2], sg * rb[2], -sg * rb[1] - cg * rb[0]];
        // e_z x Rb
        let d_gamma = [-rb[1], rb[0], T::ZERO];
        let dot = |d: [T; 3]| n[0] * d[0] + n[1] * d[1] + d[2];
        *row = [n[0], n[1], T::ONE, dot(d_alpha), dot(d_beta), dot(d_gamma)];
    }
    if bad == 0 {
        Ok((strokes, jac))
    } else {
        Err(bad)
    }
}

/// Forward kinematics from measured strokes (mm), warm-started at `start`.
pub fn fk<T: Real>(
    geom: &Geometry<T>,
    strokes_mm: &[T; LEGS],
    start: &Pose<T>,
    cfg: &FkConfig<T>,
) -> Result<FkSolution<T>, FkError> {
    if !strokes_mm.iter().all(|s| s.is_finite()) || !start.is_finite() {
        return Err(FkError::NonFinite);
    }
    let mut p = start.to_array();
    let mut iterations = 0u8;
    while iterations < cfg.max_iterations {
        let pose = Pose::from_array(p);
        let (s, jac) = strokes_and_jacobian(geom, &pose)
            .map_err(|legs| FkError::Unreachable { legs, iterations })?;
        let mut r = [T::ZERO; LEGS];
        for ((ri, m), c) in r.iter_mut().zip(strokes_mm.iter()).zip(s.iter()) {
            *ri = *m - *c;
        }
        let step =
            solve6(jac, r, cfg.pivot_ratio).ok_or(FkError::SingularJacobian { iterations })?;
        iterations += 1;
        let mut small = true;
        for (k, (pk, dk)) in p.iter_mut().zip(step.iter()).enumerate() {
            *pk += *dk;
            let tol = if k < 3 {
                cfg.step_tol_mm
            } else {
                cfg.step_tol_rad
            };
            // `!(x <= tol)` also catches NaN.
            if !(dk.abs() <= tol) {
                small = false;
            }
        }
        if !p.iter().all(|v| v.is_finite()) {
            return Err(FkError::NotConverged { iterations });
        }
        if small {
            let pose = Pose::from_array(p);
            let (s, bad) = strokes_unchecked(geom, &pose);
            if bad != 0 {
                return Err(FkError::Unreachable {
                    legs: bad,
                    iterations,
                });
            }
            let mut residual = T::ZERO;
            for (m, c) in strokes_mm.iter().zip(s.iter()) {
                residual = residual.max((*m - *c).abs());
            }
            if !(residual <= cfg.residual_tol_mm) {
                return Err(FkError::ResidualTooLarge { iterations });
            }
            return Ok(FkSolution {
                pose,
                iterations,
                residual_mm: residual,
            });
        }
    }
    Err(FkError::NotConverged { iterations })
}
