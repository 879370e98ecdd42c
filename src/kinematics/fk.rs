//! Forward kinematics: six measured strokes -> pose, by Newton-Raphson on
//! `f(P) = s_measured - IK(P) = 0` with the analytic Jacobian, warm-started.
//!
//! Jacobian of leg i (`n = (h_x/q, h_y/q, 1)`, `h` the horizontal rod components and `q`
//! the vertical one at the pose, `Rb = b + (R - I) b`, `m = Rb x n`). A rotation by a
//! small angle about a unit axis `k` (frame B) moves the upper joint by `k x Rb`, so the
//! stroke changes by `n . (k x Rb) = k . m`; the three pose angles turn about:
//!
//! ```text
//! d dl / d t     = n                       (n_z = 1: the z column is all ones)
//! d dl / d alpha = (R e_x) . m             (dR/d alpha = R [e_x]x = [R e_x]x R)
//! d dl / d beta  = (Rz e_y) . m            (dR/d beta  = [Rz e_y]x R)
//! d dl / d gamma = e_z . m = m_z           (dR/d gamma = [e_z]x R)
//! ```
//!
//! The Newton system is solved with that structure ([`UnitZJacobian::factor`]).
//!
//! Termination. Newton's method converges quadratically: after a step `d_k` the error
//! left is of order `K |d_k|^2`. Steps are measured in units of the step tolerances
//! (`|d|` = the larger of `max |d_t| / step_tol_mm` and `max |d_angle| / step_tol_rad`).
//!
//! * If `|d_k| <= 1` the step is applied and the iteration has converged: what is left,
//!   `K |d_k|^2`, is below rounding.
//! * Otherwise the strokes are evaluated at the new iterate (the next step needs them)
//!   and the next Newton step is first estimated with the factorization of the last
//!   Jacobian, `c = J_k^-1 r_(k+1)`: a sixth of the cost of a new factorization, and
//!   equal to the true next step `J_(k+1)^-1 r_(k+1)` up to a relative `O(K |d_k|)`. If
//!   `|c| <= 1` the quadratic bound is already met: `c` is applied as the final step and
//!   what is left is `O(K |d_k| |c|)`, below rounding again; if `|c|` is even below
//!   [`FK_NEGLIGIBLE_STEP`] the iterate is returned as it is. Only otherwise is a new
//!   Jacobian computed. So no Jacobian is computed just to confirm convergence.
//!
//! The strokes are then evaluated at the pose to be returned (the last such evaluation
//! is the residual check, never skipped) and every leg's `|s_measured - IK(P)|` must be
//! below the residual tolerance, else the call fails: a half-converged pose is never
//! returned as good.

use super::geometry::{Geometry, LEGS};
use super::ik::{leg_state, LegState};
use super::linalg::{cross3, dot3, UnitZJacobian, UnitZLu};
use super::pose::{Pose, RotationDelta};
use super::real::Real;

/// Newton-Raphson settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FkConfig<T> {
    /// Most Newton steps before giving up.
    pub max_iterations: u8,
    /// Step tolerance in translation (mm): converged when a step (a Newton step, or the
    /// final correction with the last Jacobian) is below this on every translation
    /// axis...
    pub step_tol_mm: T,
    /// ...and below this on every rotation axis (rad).
    pub step_tol_rad: T,
    /// After convergence, every leg's `|s_measured - IK(P)|` must be below this (mm).
    pub residual_tol_mm: T,
    /// Jacobian pivots below `pivot_ratio * max|J|` count as singular.
    pub pivot_ratio: T,
}

/// Default most Newton steps (from a 10 um warm start two are used, three from home).
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
/// A final correction below this fraction of the step tolerances is not applied: with
/// the default tolerances it is one machine epsilon of 1 mm (f32: 0.12 nm; rotation
/// 1.2e-9 rad), below the rounding of the pose itself, so the iterate whose strokes
/// were just evaluated is returned as it is.
pub const FK_NEGLIGIBLE_STEP: f64 = 1.0 / FK_STEP_TOL_EPS;

impl<T: Real> Default for FkConfig<T> {
    /// Out of line: inlined at its three flight call sites (the controller's estimate,
    /// the validation's corners, the boot self-test), 80 bytes of flash more.
    #[inline(never)]
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
    /// Newton steps taken (Jacobians factored); a final correction with the last
    /// factorization is not counted.
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

/// The six legs evaluated at one pose: strokes, and what the Jacobian needs.
struct Evaluation<T: Real> {
    rot: RotationDelta<T>,
    legs: [LegState<T>; LEGS],
}

/// Evaluates every leg at `pose` into `ev` (in place: the evaluation is large and the
/// iteration keeps one). `Err(mask)`: legs that cannot reach (`ev` is then partly
/// updated and must not be used).
#[inline(always)]
fn evaluate_into<T: Real>(
    geom: &Geometry<T>,
    pose: &Pose<T>,
    ev: &mut Evaluation<T>,
) -> Result<(), u8> {
    ev.rot = RotationDelta::new(&pose.rotation_rad);
    let mut bad = 0u8;
    for (i, (st, leg)) in ev.legs.iter_mut().zip(geom.legs.iter()).enumerate() {
        match leg_state(leg, &ev.rot, &pose.translation_mm) {
            Some(s) => *st = s,
            None => bad |= 1 << i,
        }
    }
    if bad == 0 {
        Ok(())
    } else {
        Err(bad)
    }
}

impl<T: Real> Evaluation<T> {
    /// An evaluation at home of a mechanism without legs (to be overwritten).
    fn blank() -> Self {
        Self {
            rot: RotationDelta::new(&[T::ZERO; 3]),
            legs: [LegState::default(); LEGS],
        }
    }
}

/// The Jacobian `d strokes / d pose` at an evaluation (see the module docs).
#[inline(always)]
fn jacobian<T: Real>(ev: &Evaluation<T>) -> UnitZJacobian<T> {
    let w = &ev.rot.w;
    // R e_x (first column of R) and Rz e_y = (-sin gamma, cos gamma, 0).
    let c0 = &w.data.0[0];
    let ax = [T::ONE + c0[0], c0[1], c0[2]];
    let (sg, cg) = (ev.rot.sg, ev.rot.cg);
    let rows = ev.legs.each_ref().map(|st| {
        let inv_q = T::ONE / st.q_mm;
        let (nx, ny) = (st.h_mm[0] * inv_q, st.h_mm[1] * inv_q);
        // m = Rb x n with n = (nx, ny, 1).
        let m = cross3(&st.rb_mm, &[nx, ny, T::ONE]);
        [nx, ny, dot3(&ax, &m), cg * m[1] - sg * m[0], m[2]]
    });
    UnitZJacobian { rows }
}

/// Strokes at `pose` and the Jacobian `d strokes / d pose` (rows legs, columns
/// `[x, y, z, alpha, beta, gamma]`, units mm/mm and mm/rad). `Err(mask)`: unreachable legs.
pub fn strokes_and_jacobian<T: Real>(
    geom: &Geometry<T>,
    pose: &Pose<T>,
) -> Result<([T; LEGS], [[T; 6]; LEGS]), u8> {
    let mut ev = Evaluation::blank();
    evaluate_into(geom, pose, &mut ev)?;
    Ok((ev.legs.map(|st| st.stroke_mm), jacobian(&ev).to_matrix()))
}

/// The largest step component in units of the step tolerances (dimensionless).
/// Not inlined: used twice per iteration (about 100 bytes of flash less).
#[inline(never)]
fn step_in_tolerances<T: Real>(step: &[T; 6], cfg: &FkConfig<T>) -> T {
    let [x, y, z, a, b, g] = *step;
    let t = x.abs().max(y.abs()).max(z.abs());
    let r = a.abs().max(b.abs()).max(g.abs());
    (t / cfg.step_tol_mm).max(r / cfg.step_tol_rad)
}

/// The largest |residual| over the legs (mm); NaN if any is NaN.
#[inline(always)]
fn max_abs<T: Real>(r: &[T; LEGS]) -> T {
    let mut m = T::ZERO;
    for v in r.iter() {
        // `!(a <= m)` also takes a NaN, which then sticks.
        let a = v.abs();
        if !(a <= m) {
            m = a;
        }
    }
    m
}

/// Forward kinematics from measured strokes (mm), warm-started at `start`.
///
/// Never inlined: one copy per float type serves every caller (flash), and it is the
/// code the benchmarks measure.
#[inline(never)]
pub fn fk<T: Real>(
    geom: &Geometry<T>,
    strokes_mm: &[T; LEGS],
    start: &Pose<T>,
    cfg: &FkConfig<T>,
) -> Result<FkSolution<T>, FkError> {
    if !strokes_mm.iter().all(|s| s.is_finite()) || !start.is_finite() {
        return Err(FkError::NonFinite);
    }
    let negligible = T::from_f64(FK_NEGLIGIBLE_STEP);
    let mut p = start.to_array();
    let mut iterations = 0u8;
    let mut ev = Evaluation::blank();
    let mut lu = UnitZLu::blank();
    // What the strokes evaluated at the top of the loop are for. One evaluation site:
    // the (inlined) leg evaluation is in the code once, not once per use.
    let mut phase = Phase::Start;
    // One exit through `finish`: the residual of the last evaluation (its check and
    // the solution are in the code once).
    let r = loop {
        let r = residual_at(geom, strokes_mm, &p, &mut ev, iterations)?;
        let mut reuse = None;
        match phase {
            Phase::Final => break r,
            Phase::AfterStep(step) => {
                // `<=` is false for NaN: a NaN step never counts as converged.
                if step_in_tolerances(&step, cfg) <= T::ONE {
                    break r;
                }
                // The next step, estimated with this factorization (see the module docs).
                let next = lu.solve(&r);
                let size = step_in_tolerances(&next, cfg);
                if size <= negligible {
                    break r;
                }
                if size <= T::ONE {
                    reuse = Some(next);
                }
            }
            Phase::Start => {}
        }
        // One step applied per pass, in one place: the estimated one (then the final
        // evaluation) or a fresh Newton step.
        let (step, next_phase) = match reuse {
            Some(next) => (next, Phase::Final),
            None => {
                if iterations >= cfg.max_iterations {
                    return Err(FkError::NotConverged { iterations });
                }
                if !lu.refactor(&jacobian(&ev), cfg.pivot_ratio) {
                    return Err(FkError::SingularJacobian { iterations });
                }
                let step = lu.solve(&r);
                iterations += 1;
                (step, Phase::AfterStep(step))
            }
        };
        apply(&mut p, &step, iterations)?;
        phase = next_phase;
    };
    finish(p, &r, iterations, cfg)
}

/// The use of the strokes evaluated at the top of [`fk`]'s loop.
#[derive(Clone, Copy)]
enum Phase<T> {
    /// At the start pose: the first Newton step follows.
    Start,
    /// After a Newton step `d_k` (pose units): converged if it was within the step
    /// tolerances, else the next step is estimated with the same factorization.
    AfterStep([T; 6]),
    /// After the final (estimated) step: the residual check, then return.
    Final,
}

/// Evaluates the legs at `p` into `ev`; returns the residual `s_measured - IK(p)` (mm).
#[inline(always)]
fn residual_at<T: Real>(
    geom: &Geometry<T>,
    strokes_mm: &[T; LEGS],
    p: &[T; 6],
    ev: &mut Evaluation<T>,
    iterations: u8,
) -> Result<[T; LEGS], FkError> {
    evaluate_into(geom, &Pose::from_array(*p), ev)
        .map_err(|legs| FkError::Unreachable { legs, iterations })?;
    let mut r = [T::ZERO; LEGS];
    for ((ri, m), st) in r.iter_mut().zip(strokes_mm.iter()).zip(ev.legs.iter()) {
        *ri = *m - st.stroke_mm;
    }
    Ok(r)
}

/// The residual check at the pose to be returned: every leg's `|r|` below the
/// residual tolerance, else [`FkError::ResidualTooLarge`].
#[inline(always)]
fn finish<T: Real>(
    p: [T; 6],
    r: &[T; LEGS],
    iterations: u8,
    cfg: &FkConfig<T>,
) -> Result<FkSolution<T>, FkError> {
    let residual = max_abs(r);
    // `!(x <= tol)` also catches NaN.
    if !(residual <= cfg.residual_tol_mm) {
        return Err(FkError::ResidualTooLarge { iterations });
    }
    Ok(FkSolution {
        pose: Pose::from_array(p),
        iterations,
        residual_mm: residual,
    })
}

/// `p += step`; a non-finite result ends the iteration.
#[inline(always)]
fn apply<T: Real>(p: &mut [T; 6], step: &[T; 6], iterations: u8) -> Result<(), FkError> {
    for (pk, dk) in p.iter_mut().zip(step.iter()) {
        *pk += *dk;
    }
    if p.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(FkError::NotConverged { iterations })
    }
}
