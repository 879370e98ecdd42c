//! Validation of a table before it is activated (or booted from flash).
//!
//! Like cFS table services: a candidate table is loaded into an inactive buffer,
//! [`validate`]d, and only then activated. The checks, in order (the first failure is
//! reported, with a stable code for telemetry):
//!
//! 1. the provenance tag is printable ASCII (or NUL padding);
//! 2. every number is finite;
//! 3. every joint coordinate and p0 component is within
//!    [`ValidationConfig::max_coordinate_deviation_mm`] of the reference (nominal) geometry;
//! 4. every rod length `|b + p0 - a|` is within [`ValidationConfig::max_rod_deviation_mm`]
//!    of the reference rod length;
//! 5. the geometry is usable ([`GeometryParams::validate`]: rods lean upwards, stroke
//!    limits contain home, half-ranges non-negative);
//! 6. stroke limits and workspace no wider than the compiled-in caps;
//! 7. the supervision thresholds are positive and ordered;
//! 8. **reachability**: every pose of the workspace box is reachable by every leg within
//!    its stroke limits (analytic bound + `f32` IK on a grid, see below);
//! 9. **FK**: `f32` forward kinematics started at home converges at each of the 64
//!    workspace corners and returns the corner.
//!
//! # In bounded steps
//!
//! The background worker must not run the whole validation at once (millions of
//! instructions: its `f64` arithmetic is software on the Cortex-M4F). A
//! [`ValidationState`] holds a validation between steps, each bounded: checks 1 to 4;
//! checks 5 to 7 and the configuration; the grid margins of [`MARGIN_LEGS_PER_STEP`]
//! legs; [`GRID_POSES_PER_STEP`] grid poses; the FK of one corner. It holds no
//! reference (the caller keeps the table and the configuration, and passes the same at
//! every step); [`Validation`] borrows them for a caller that can. [`validate`] is the
//! same steps in a loop (boot, ground tools), so the two cannot disagree; the host tests
//! also compare both with the implementation in one call they replaced. The grid's
//! poses are updated axis by axis (only the axes whose grid point changes: the same
//! `f32` values as computing each pose whole) and each step forms the stroke windows
//! `limit -+ margin` once, so the whole validation also takes less than half the instructions it did.
//!
//! # Why a grid suffices: the interpolation margin
//!
//! Over the workspace box each stroke `s_i(P)` is a smooth function of the six pose
//! components as long as the vertical rod component `q_i` stays positive. On a regular
//! grid with spacing `h_k` along axis `k`, the multilinear interpolant of `s_i` takes its
//! extremes on grid points, and differs from `s_i` by at most
//! `(1/8) sum_k h_k^2 max|d^2 s_i / d P_k^2|` (tensor product of the 1-D linear
//! interpolation bound; each 1-D interpolation has max-norm 1). So if every grid stroke
//! stays inside the limits by that margin, every pose of the box does.
//!
//! Bounds on the second derivatives, for leg `i` with home rod `d0 = b + p0 - a`, rod
//! length `l`, horizontal home component `h0 = |d0_xy|`, upper joint radius `|b|`:
//! * the joint moves at most `u_max = |b| (|alpha|+|beta|+|gamma|)_max + |t|_max`
//!   (`||R - I|| <= sum of the angles`), so the horizontal rod component stays below
//!   `h_max = h0 + u_max` and `q >= q_min = sqrt(l^2 - h_max^2)`; if `h_max >= l` the box
//!   is refused as possibly unreachable;
//! * `s = d0_z + u_z - q(h)`, `q(h) = sqrt(l^2 - |h|^2)`, whose Hessian has norm
//!   `<= l^2 / q^3` and gradient norm `|h| / q`;
//! * translation: `u` is linear, `|d^2 s / dt_k^2| <= l^2 / q_min^3`;
//! * rotation about one angle: `|du/dθ| <= |b|` and `|d^2u/dθ^2| <= |b|` (unit-axis cross
//!   products inside the rotation composition), so
//!   `|d^2 s / dθ^2| <= |b| (1 + h_max / q_min) + |b|^2 l^2 / q_min^3`.
//!
//! For the prototype (l ≈ 82 mm, q ≈ 70 mm, |b| ≈ 110 mm, ±2 mm, ±600") with the default
//! 3 grid points per axis the margin is ≈ 0.03 mm, against ≈ 1 mm of slack between the
//! corner strokes and the 5 mm soft limits. [`F32_STROKE_ROUNDING_MM`] is added for the
//! `f32` evaluation of the grid strokes.

// The home rod vector `b + p0 - a` (mm, frame B, f64): the geometry derivation's one copy.
use crate::kinematics::geometry::{home_rod as home_rod_mm, norm3, LegParams};
use crate::kinematics::ik::strokes_unchecked;
use crate::kinematics::{
    fk, FkConfig, Geometry, GeometryError, GeometryParams, Pose, WorkspaceLimits, LEGS,
};
use crate::nominal;

use super::layout::{SupervisionThresholds, Table, JOINT_COORDS};

/// Default largest deviation of any joint coordinate or p0 component from the reference
/// (mm): twice the ±0.5 mm search box of the calibration.
pub const DEFAULT_MAX_COORDINATE_DEVIATION_MM: f64 = 1.0;
/// Default largest deviation of a rod length from the reference rod length (mm).
pub const DEFAULT_MAX_ROD_DEVIATION_MM: f64 = 1.0;
/// Default grid points per workspace axis (3: corners, edge midpoints, face centres,
/// centre; 729 poses).
pub const DEFAULT_GRID_POINTS_PER_AXIS: u8 = 3;
/// Fewest grid points per axis (the corners only).
pub const MIN_GRID_POINTS_PER_AXIS: u8 = 2;
/// Most grid points per axis (5^6 = 15 625 poses).
pub const MAX_GRID_POINTS_PER_AXIS: u8 = 5;
/// Allowance for the `f32` evaluation of a grid stroke (mm): the IK is good to a few nm
/// (see `kinematics::ik`); 100 nm covers it and the `f32` rounding of the grid pose.
pub const F32_STROKE_ROUNDING_MM: f64 = 1.0e-4;
/// FK at a corner must return the corner within this, translation (mm, 100 nm).
pub const FK_CORNER_TOL_MM: f64 = 1.0e-4;
/// FK at a corner must return the corner within this, rotation (rad, ≈ 0.1 arcsec).
pub const FK_CORNER_TOL_RAD: f64 = 5.0e-7;
/// Number of workspace corners (2^6).
pub const WORKSPACE_CORNERS: usize = 64;
/// Printable ASCII range of the provenance tag (NUL is accepted as padding).
const ASCII_PRINTABLE: core::ops::RangeInclusive<u8> = 0x20..=0x7e;

/// What [`validate`] compares a table against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValidationConfig {
    /// Reference geometry (its limits are ignored): the compiled-in nominal.
    pub reference: GeometryParams,
    /// Largest |coordinate - reference| for joint coordinates and p0 (mm).
    pub max_coordinate_deviation_mm: f64,
    /// Largest |rod length - reference rod length| (mm).
    pub max_rod_deviation_mm: f64,
    /// Largest |stroke limit| a table may set (mm): the compiled-in soft limit, so an
    /// upload can tighten but never widen the slider range.
    pub max_abs_stroke_limit_mm: f64,
    /// Largest workspace half-ranges a table may set (mm, rad).
    pub max_workspace: WorkspaceLimits,
    /// Grid points per workspace axis for the reachability check
    /// ([`MIN_GRID_POINTS_PER_AXIS`]..=[`MAX_GRID_POINTS_PER_AXIS`]).
    pub grid_points_per_axis: u8,
}

impl ValidationConfig {
    /// The flight configuration: nominal reference, default tolerances, the nominal
    /// flight limits as caps.
    pub const fn flight() -> Self {
        let g = nominal::prototype_with_flight_limits();
        Self {
            reference: GeometryParams::new(nominal::PROTOTYPE_LEGS, nominal::PROTOTYPE_P0_MM),
            max_coordinate_deviation_mm: DEFAULT_MAX_COORDINATE_DEVIATION_MM,
            max_rod_deviation_mm: DEFAULT_MAX_ROD_DEVIATION_MM,
            max_abs_stroke_limit_mm: nominal::STROKE_LIMIT_MM,
            max_workspace: match g.workspace {
                Some(w) => w,
                None => WorkspaceLimits {
                    translation_mm: [0.0; 3],
                    rotation_rad: [0.0; 3],
                },
            },
            grid_points_per_axis: DEFAULT_GRID_POINTS_PER_AXIS,
        }
    }
}

impl Default for ValidationConfig {
    fn default() -> Self {
        Self::flight()
    }
}

/// Why a table is refused. Stable numeric codes (family 0x04xx, from 0x0410) and a
/// 16-bit detail word for telemetry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValidationError {
    /// The provenance tag holds a non-printable byte (detail: byte index).
    ProvenanceNotAscii {
        /// Index of the first bad byte.
        index: u8,
    },
    /// A number is NaN or infinite (detail: field index, see [`field_index`]).
    NonFinite {
        /// Field index.
        field: u16,
    },
    /// A joint coordinate (0..36, table order) or p0 component (36..39) is too far from
    /// the reference.
    CoordinateOffNominal {
        /// Coordinate index.
        index: u8,
    },
    /// A rod length is too far from the reference (0-based leg).
    RodLengthImplausible {
        /// 0-based leg index.
        leg: u8,
    },
    /// [`GeometryParams::validate`] refused the geometry (detail: its code).
    Geometry(GeometryError),
    /// A stroke limit is beyond the compiled-in cap (0-based leg).
    StrokeLimitBeyondCap {
        /// 0-based leg index.
        leg: u8,
    },
    /// A workspace half-range exceeds the compiled-in cap (axis 0..6 of
    /// `[x, y, z, alpha, beta, gamma]`).
    WorkspaceBeyondCap {
        /// Axis index.
        axis: u8,
    },
    /// A supervision threshold is not positive, or warning >= fault (detail: field
    /// 0..7 in layout order).
    Supervision {
        /// Field index in layout order.
        field: u8,
    },
    /// Some pose of the workspace is not reachable (bit mask of legs).
    Unreachable {
        /// Bit i = leg i+1.
        legs: u8,
    },
    /// Some pose of the workspace needs a stroke beyond (or within the interpolation
    /// margin of) a slider limit (bit mask of legs).
    StrokeLimitExceeded {
        /// Bit i = leg i+1.
        legs: u8,
    },
    /// FK from home did not converge at a workspace corner (detail: corner in the low
    /// byte, low byte of the FK error code in the high byte).
    FkFailed {
        /// Corner index 0..64 (bit k set = axis k at +half-range).
        corner: u8,
        /// [`crate::kinematics::FkError::code`].
        fk_code: u16,
    },
    /// FK converged at a corner but not to the corner.
    FkInaccurate {
        /// Corner index 0..64.
        corner: u8,
    },
    /// The validation configuration itself is out of range (grid points).
    BadConfig,
    /// The thermal model is out of range (detail: [`crate::thermal::ThermalModelError::code`],
    /// 1 reference, 2 expansion, 3 column length, 4 sensor index).
    Thermal {
        /// The refused field.
        field: u8,
    },
}

impl ValidationError {
    /// Stable numeric code for telemetry.
    pub const fn code(&self) -> u16 {
        match self {
            ValidationError::ProvenanceNotAscii { .. } => 0x0410,
            ValidationError::NonFinite { .. } => 0x0411,
            ValidationError::CoordinateOffNominal { .. } => 0x0412,
            ValidationError::RodLengthImplausible { .. } => 0x0413,
            ValidationError::Geometry(_) => 0x0414,
            ValidationError::StrokeLimitBeyondCap { .. } => 0x0415,
            ValidationError::WorkspaceBeyondCap { .. } => 0x0416,
            ValidationError::Supervision { .. } => 0x0417,
            ValidationError::Unreachable { .. } => 0x0418,
            ValidationError::StrokeLimitExceeded { .. } => 0x0419,
            ValidationError::FkFailed { .. } => 0x041a,
            ValidationError::FkInaccurate { .. } => 0x041b,
            ValidationError::BadConfig => 0x041c,
            ValidationError::Thermal { .. } => 0x041d,
        }
    }

    /// Detail word for telemetry (index, leg mask, or nested code; see each variant).
    pub const fn detail(&self) -> u16 {
        match *self {
            ValidationError::ProvenanceNotAscii { index } => index as u16,
            ValidationError::NonFinite { field } => field,
            ValidationError::CoordinateOffNominal { index } => index as u16,
            ValidationError::RodLengthImplausible { leg } => leg as u16,
            ValidationError::Geometry(g) => g.code(),
            ValidationError::StrokeLimitBeyondCap { leg } => leg as u16,
            ValidationError::WorkspaceBeyondCap { axis } => axis as u16,
            ValidationError::Supervision { field } => field as u16,
            ValidationError::Unreachable { legs } => legs as u16,
            ValidationError::StrokeLimitExceeded { legs } => legs as u16,
            ValidationError::FkFailed { corner, fk_code } => {
                ((fk_code & 0xff) << 8) | corner as u16
            }
            ValidationError::FkInaccurate { corner } => corner as u16,
            ValidationError::BadConfig => 0,
            ValidationError::Thermal { field } => field as u16,
        }
    }
}

/// Field indices reported by [`ValidationError::NonFinite`]: 0..36 joint coordinates,
/// 36..39 p0, 39..45 stroke min, 45..51 stroke max, 51..54 workspace translation,
/// 54..57 workspace rotation, 57..61 the four `f32` supervision thresholds.
pub mod field_index {
    use super::{JOINT_COORDS, LEGS};
    /// First p0 component.
    pub const P0: u16 = JOINT_COORDS as u16;
    /// First stroke lower limit.
    pub const STROKE_MIN: u16 = P0 + 3;
    /// First stroke upper limit.
    pub const STROKE_MAX: u16 = STROKE_MIN + LEGS as u16;
    /// First workspace translation half-range.
    pub const WORKSPACE_TRANSLATION: u16 = STROKE_MAX + LEGS as u16;
    /// First workspace rotation half-range.
    pub const WORKSPACE_ROTATION: u16 = WORKSPACE_TRANSLATION + 3;
    /// First supervision threshold.
    pub const SUPERVISION: u16 = WORKSPACE_ROTATION + 3;
}

/// `a <= b`; false if either is NaN, so a NaN never passes a check written with it.
fn le(a: f64, b: f64) -> bool {
    a <= b
}

/// `a < b`; false if either is NaN.
fn lt(a: f64, b: f64) -> bool {
    a < b
}

/// `|a - b| <= tol`; false if any is NaN.
fn close(a: f64, b: f64, tol: f64) -> bool {
    le(libm::fabs(a - b), tol)
}

/// Index of the first non-finite value in `v`, offset by `base`.
fn first_non_finite(v: &[f64], base: u16) -> Option<u16> {
    v.iter()
        .position(|x| !x.is_finite())
        .map(|i| base.saturating_add(u16::try_from(i).unwrap_or(u16::MAX)))
}

/// Joint coordinates per leg in table order (`a.xyz` then `b.xyz`).
const COORDS_PER_LEG: usize = JOINT_COORDS / LEGS;

fn check_finite(t: &Table) -> Result<(), ValidationError> {
    // The joint coordinates first (fields 0 to JOINT_COORDS - 1, leg-major; per leg
    // `a.xyz` then `b.xyz`: `Table::joint_coord_mm`'s order), read in place.
    for (l, leg) in t.legs.iter().enumerate() {
        let base = u16::try_from(l * COORDS_PER_LEG).unwrap_or(u16::MAX);
        let b_base = base.saturating_add(leg.a_mm.len() as u16);
        if let Some(field) =
            first_non_finite(&leg.a_mm, base).or_else(|| first_non_finite(&leg.b_mm, b_base))
        {
            return Err(ValidationError::NonFinite { field });
        }
    }
    let s = &t.supervision;
    let sup = [
        f64::from(s.following_error_warning_mm),
        f64::from(s.following_error_fault_mm),
        f64::from(s.encoder_jump_mm_per_cycle),
        f64::from(s.stuck_min_progress_mm),
    ];
    let groups: [(&[f64], u16); 6] = [
        (&t.p0_mm, field_index::P0),
        (&t.stroke_limits.min_mm, field_index::STROKE_MIN),
        (&t.stroke_limits.max_mm, field_index::STROKE_MAX),
        (
            &t.workspace.translation_mm,
            field_index::WORKSPACE_TRANSLATION,
        ),
        (&t.workspace.rotation_rad, field_index::WORKSPACE_ROTATION),
        (&sup, field_index::SUPERVISION),
    ];
    for (values, base) in groups {
        if let Some(field) = first_non_finite(values, base) {
            return Err(ValidationError::NonFinite { field });
        }
    }
    Ok(())
}

/// Index (`base` + position) of the first value of `v` farther than `tol` from its
/// reference in `r` (mm), as a coordinate index of event `CoordinateOffNominal`.
fn first_off(v: &[f64], r: &[f64], tol: f64, base: usize) -> Option<u8> {
    v.iter()
        .zip(r.iter())
        .position(|(v, r)| !close(*v, *r, tol))
        .map(|k| (base + k) as u8)
}

fn check_near_reference(t: &Table, cfg: &ValidationConfig) -> Result<(), ValidationError> {
    let tol = cfg.max_coordinate_deviation_mm;
    // The joint coordinates in table order (leg-major; per leg `a.xyz` then `b.xyz`:
    // `Table::joint_coord_mm`'s), then p0, read in place.
    for (l, (leg, ref_leg)) in t.legs.iter().zip(cfg.reference.legs.iter()).enumerate() {
        let base = l * COORDS_PER_LEG;
        if let Some(index) = first_off(&leg.a_mm, &ref_leg.a_mm, tol, base)
            .or_else(|| first_off(&leg.b_mm, &ref_leg.b_mm, tol, base + leg.a_mm.len()))
        {
            return Err(ValidationError::CoordinateOffNominal { index });
        }
    }
    if let Some(index) = first_off(&t.p0_mm, &cfg.reference.p0_mm, tol, JOINT_COORDS) {
        return Err(ValidationError::CoordinateOffNominal { index });
    }
    for (i, (leg, ref_leg)) in t.legs.iter().zip(cfg.reference.legs.iter()).enumerate() {
        let l = norm3(home_rod_mm(leg, &t.p0_mm));
        let l_ref = norm3(home_rod_mm(ref_leg, &cfg.reference.p0_mm));
        if !close(l, l_ref, cfg.max_rod_deviation_mm) {
            return Err(ValidationError::RodLengthImplausible { leg: i as u8 });
        }
    }
    Ok(())
}

fn check_caps(t: &Table, cfg: &ValidationConfig) -> Result<(), ValidationError> {
    let cap = cfg.max_abs_stroke_limit_mm;
    let lims = t
        .stroke_limits
        .min_mm
        .iter()
        .zip(t.stroke_limits.max_mm.iter());
    for (i, (lo, hi)) in lims.enumerate() {
        if !(le(-cap, *lo) && le(*hi, cap)) {
            return Err(ValidationError::StrokeLimitBeyondCap { leg: i as u8 });
        }
    }
    let w = &t.workspace;
    let m = &cfg.max_workspace;
    let half = w.translation_mm.iter().chain(w.rotation_rad.iter());
    let caps = m.translation_mm.iter().chain(m.rotation_rad.iter());
    for (k, (v, c)) in half.zip(caps).enumerate() {
        if !le(*v, *c) {
            return Err(ValidationError::WorkspaceBeyondCap { axis: k as u8 });
        }
    }
    Ok(())
}

fn check_supervision(s: &SupervisionThresholds) -> Result<(), ValidationError> {
    let positive = [
        s.following_error_warning_mm,
        s.following_error_fault_mm,
        s.encoder_jump_mm_per_cycle,
        s.stuck_min_progress_mm,
    ];
    if let Some(k) = positive.iter().position(|v| !lt(0.0, f64::from(*v))) {
        return Err(ValidationError::Supervision { field: k as u8 });
    }
    if !lt(
        f64::from(s.following_error_warning_mm),
        f64::from(s.following_error_fault_mm),
    ) {
        return Err(ValidationError::Supervision { field: 1 });
    }
    let counts = [
        s.stuck_detection_cycles,
        s.warning_debounce_cycles,
        s.fault_debounce_cycles,
    ];
    if let Some(k) = counts.iter().position(|c| *c == 0) {
        return Err(ValidationError::Supervision {
            field: (positive.len() + k) as u8,
        });
    }
    Ok(())
}

/// Analytic part of the reachability check for one leg: the interpolation margin (mm)
/// of the grid (module docs), or `None` if its rod might turn horizontal in the box.
/// `intervals` is the grid's intervals per axis, `rot_sum` the sum of the rotation
/// half-ranges, `t_max` the norm of the translation half-ranges.
fn grid_margin_mm(
    w: &WorkspaceLimits,
    leg: &LegParams,
    p0: &[f64; 3],
    intervals: f64,
    rot_sum: f64,
    t_max: f64,
) -> Option<f64> {
    let d0 = home_rod_mm(leg, p0);
    let l = norm3(d0);
    let h0 = crate::kinematics::real::sqrt_f64(d0[0] * d0[0] + d0[1] * d0[1]);
    let b = norm3(leg.b_mm);
    let h_max = h0 + b * rot_sum + t_max;
    let q2 = l * l - h_max * h_max;
    if !lt(0.0, q2) {
        return None;
    }
    let q_min = crate::kinematics::real::sqrt_f64(q2);
    let hess = l * l / (q_min * q_min * q_min);
    let m_trans = hess;
    let m_rot = b * (1.0 + h_max / q_min) + b * b * hess;
    let mut sum = 0.0;
    for (half, curv) in w
        .translation_mm
        .iter()
        .map(|h| (h, m_trans))
        .chain(w.rotation_rad.iter().map(|h| (h, m_rot)))
    {
        let spacing = 2.0 * half / intervals;
        sum += spacing * spacing * curv;
    }
    Some(sum / 8.0 + F32_STROKE_ROUNDING_MM)
}

/// Grid pose number `index` (mixed radix, axis 0 fastest) on `n` points per axis, into
/// `v`. With `changed_only`, only the axes whose grid point differs from that of pose
/// `index - 1` are written (all of them for pose 0), so `v` must hold pose `index - 1`.
fn set_grid_pose(v: &mut [f32; 6], w: &WorkspaceLimits, n: u8, mut index: u32, changed_only: bool) {
    let n32 = u32::from(n.max(MIN_GRID_POINTS_PER_AXIS));
    let intervals = f64::from(n32 - 1);
    let halves = [
        w.translation_mm[0],
        w.translation_mm[1],
        w.translation_mm[2],
        w.rotation_rad[0],
        w.rotation_rad[1],
        w.rotation_rad[2],
    ];
    for (o, half) in v.iter_mut().zip(halves.iter()) {
        let j = index % n32;
        index /= n32;
        *o = (-half + 2.0 * half * f64::from(j) / intervals) as f32;
        // Axis k+1 differs from pose `index - 1` only if axis k wrapped round to 0.
        if changed_only && j != 0 {
            break;
        }
    }
}

/// Legs whose grid margins are derived per [`ValidationState::step`].
pub const MARGIN_LEGS_PER_STEP: u32 = 3;
/// Grid poses of the reachability check evaluated per [`ValidationState::step`].
pub const GRID_POSES_PER_STEP: u32 = 24;

/// Steps of the checks before the margins (1 to 4 of the module docs; 5 to 7 and the
/// configuration).
const CHECK_STEPS: u32 = 2;
/// Steps of the grid margins.
const MARGIN_STEPS: u32 = (LEGS as u32).div_ceil(MARGIN_LEGS_PER_STEP);

/// Steps a validation takes when every check passes, with `grid_points_per_axis`
/// points per axis (in range): the checks before the grid, its margins, the grid in
/// slices of [`GRID_POSES_PER_STEP`], one per workspace corner. A refused table takes
/// fewer: the step that finds the first failure returns it.
pub const fn validation_steps(grid_points_per_axis: u8) -> u32 {
    CHECK_STEPS
        + MARGIN_STEPS
        + (grid_points_per_axis as u32)
            .pow(6)
            .div_ceil(GRID_POSES_PER_STEP)
        + WORKSPACE_CORNERS as u32
}

/// Most steps any validation takes (the largest grid; a configuration out of range is
/// refused before the grid).
pub const MAX_VALIDATION_STEPS: u32 = validation_steps(MAX_GRID_POINTS_PER_AXIS);

/// Where a validation stands: the work of its next step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    /// Checks 1 to 4 of the module docs (provenance to rod lengths).
    Checks,
    /// Checks 5 to 7 (the working geometry, caps, supervision) and the configuration.
    Geometry,
    /// The grid margins from leg `next`, [`MARGIN_LEGS_PER_STEP`] legs per step.
    Margins,
    /// The reachability grid from pose `next`, [`GRID_POSES_PER_STEP`] poses per step.
    Grid,
    /// FK at workspace corner `next`, one per step.
    Corners,
    /// Finished; every further step returns the result again.
    Done(Result<(), ValidationError>),
}

/// A validation that runs in bounded steps: [`validate`]'s state between them.
///
/// Holds no reference, so a caller can keep it next to the table it validates (the
/// background worker: one [`step`](Self::step) per worker step); every step must be
/// given the same table and configuration ([`Validation`] borrows them for a caller
/// that can). Stepped to completion the result is [`validate`]'s, which is this in a
/// loop. A step does one of: checks 1 to 4 of the module docs; checks 5 to 7 and the
/// configuration; [`MARGIN_LEGS_PER_STEP`] legs' grid margins; [`GRID_POSES_PER_STEP`]
/// grid poses; the FK of one workspace corner. [`validation_steps`] gives their number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValidationState {
    stage: Stage,
    /// Grid points per axis (from the configuration, checked in range).
    points: u8,
    /// Legs refused so far as unreachable: rod possibly horizontal in the box
    /// (margins), radicand not positive at some grid pose (grid).
    unreachable: u8,
    /// Legs beyond (or within the margin of) a stroke limit at some grid pose so far.
    beyond: u8,
    /// The next leg (margins), grid pose (grid) or corner (corners).
    next: u32,
    /// Grid pose `next` (grid).
    pose: [f32; 6],
    /// Per leg, the interpolation margin (mm) of [`grid_margin_mm`] (grid).
    margins: [f64; LEGS],
    /// The table's working geometry, from the geometry step on (an error before).
    geom: Result<Geometry<f32>, GeometryError>,
}

impl Default for ValidationState {
    fn default() -> Self {
        Self::new()
    }
}

impl ValidationState {
    /// A validation not started. Out of line: inlined at its flight call sites (the
    /// worker's three, the boot's validation), 84 bytes of flash more.
    #[inline(never)]
    pub const fn new() -> Self {
        Self {
            stage: Stage::Checks,
            points: 0,
            unreachable: 0,
            beyond: 0,
            next: 0,
            pose: [0.0; 6],
            margins: [0.0; LEGS],
            geom: Err(GeometryError::NonFinite),
        }
    }

    /// The result once finished, `None` before.
    pub const fn result(&self) -> Option<Result<(), ValidationError>> {
        match self.stage {
            Stage::Done(r) => Some(r),
            _ => None,
        }
    }

    /// One bounded step of validating `t` against `cfg` (the same at every step):
    /// `None` while work remains, then the result (again at every later step). Never
    /// panics, whatever the table holds. (Out of line, as is each stage's work: one
    /// copy for every caller, and only one stage's frame on the stack.)
    #[inline(never)]
    pub fn step(
        &mut self,
        t: &Table,
        cfg: &ValidationConfig,
    ) -> Option<Result<(), ValidationError>> {
        let next = match self.stage {
            Stage::Checks => checks(t, cfg),
            Stage::Geometry => self.geometry(t, cfg),
            Stage::Margins => self.margins(t),
            Stage::Grid => self.grid(t),
            Stage::Corners => self.corner(t),
            Stage::Done(r) => return Some(r),
        };
        self.stage = next.unwrap_or_else(|e| Stage::Done(Err(e)));
        self.result()
    }

    /// A stage past the geometry step without the geometry (cannot happen): start over,
    /// at the checks (every later stage starts from its first leg, pose or corner).
    fn restart(&mut self) -> Stage {
        self.next = 0;
        self.unreachable = 0;
        self.beyond = 0;
        Stage::Checks
    }

    /// Checks 5 to 7 and the configuration; the working geometry kept.
    fn geometry(&mut self, t: &Table, cfg: &ValidationConfig) -> Result<Stage, ValidationError> {
        self.geom = working_geometry(t);
        if let Err(e) = self.geom {
            return Err(ValidationError::Geometry(e));
        }
        check_caps(t, cfg)?;
        check_supervision(&t.supervision)?;
        t.thermal
            .validate()
            .map_err(|e| ValidationError::Thermal { field: e.code() })?;
        let points = cfg.grid_points_per_axis;
        if !(MIN_GRID_POINTS_PER_AXIS..=MAX_GRID_POINTS_PER_AXIS).contains(&points) {
            return Err(ValidationError::BadConfig);
        }
        self.points = points;
        Ok(Stage::Margins)
    }

    /// The next [`MARGIN_LEGS_PER_STEP`] legs' grid margins.
    fn margins(&mut self, t: &Table) -> Result<Stage, ValidationError> {
        let w = &t.workspace;
        let intervals = f64::from(self.points.saturating_sub(1).max(1));
        let rot_sum: f64 = w.rotation_rad.iter().sum();
        let t_max = norm3(w.translation_mm);
        let end = self.next.saturating_add(MARGIN_LEGS_PER_STEP);
        while self.next < end {
            let i = self.next as usize;
            let (Some(leg), Some(m)) = (t.legs.get(i), self.margins.get_mut(i)) else {
                break;
            };
            match grid_margin_mm(w, leg, &t.p0_mm, intervals, rot_sum, t_max) {
                Some(v) => *m = v,
                None => self.unreachable |= 1 << i,
            }
            self.next += 1;
        }
        if (self.next as usize) < LEGS {
            return Ok(Stage::Margins);
        }
        if self.unreachable != 0 {
            return Err(ValidationError::Unreachable {
                legs: self.unreachable,
            });
        }
        self.next = 0;
        set_grid_pose(&mut self.pose, w, self.points, 0, false);
        Ok(Stage::Grid)
    }

    /// The next [`GRID_POSES_PER_STEP`] grid poses.
    fn grid(&mut self, t: &Table) -> Result<Stage, ValidationError> {
        let Ok(geom) = &self.geom else {
            return Ok(self.restart());
        };
        // The window a grid stroke must lie in, per leg (the same sums at every step).
        let mut lo = [0.0; LEGS];
        let mut hi = [0.0; LEGS];
        let lims = t
            .stroke_limits
            .min_mm
            .iter()
            .zip(t.stroke_limits.max_mm.iter());
        for ((l, h), ((min, max), m)) in lo
            .iter_mut()
            .zip(hi.iter_mut())
            .zip(lims.zip(self.margins.iter()))
        {
            *l = min + m;
            *h = max - m;
        }
        let total = u32::from(self.points).pow(6);
        let end = total.min(self.next.saturating_add(GRID_POSES_PER_STEP));
        while self.next < end {
            let (strokes, bad) = strokes_unchecked(geom, &Pose::from_array(self.pose));
            self.unreachable |= bad;
            for (i, (s, (l, h))) in strokes.iter().zip(lo.iter().zip(hi.iter())).enumerate() {
                let s = f64::from(*s);
                if !(le(*l, s) && le(s, *h)) {
                    self.beyond |= 1 << i;
                }
            }
            self.next += 1;
            set_grid_pose(&mut self.pose, &t.workspace, self.points, self.next, true);
        }
        if self.next < total {
            return Ok(Stage::Grid);
        }
        if self.unreachable != 0 {
            return Err(ValidationError::Unreachable {
                legs: self.unreachable,
            });
        }
        // Unreachable legs keep stroke 0 and are reported above, so `beyond` is
        // meaningful.
        if self.beyond != 0 {
            return Err(ValidationError::StrokeLimitExceeded { legs: self.beyond });
        }
        self.next = 0;
        Ok(Stage::Corners)
    }

    /// Check 9 at workspace corner `next`.
    fn corner(&mut self, t: &Table) -> Result<Stage, ValidationError> {
        let Ok(geom) = &self.geom else {
            return Ok(self.restart());
        };
        let corner = self.next as u8;
        let cfg = FkConfig::<f32>::default();
        let home = Pose::<f32>::home();
        // On a 2-point grid the pose index bits are exactly the corner signs.
        let mut want = [0.0f32; 6];
        set_grid_pose(
            &mut want,
            &t.workspace,
            MIN_GRID_POINTS_PER_AXIS,
            self.next,
            false,
        );
        let (strokes, bad) = strokes_unchecked(geom, &Pose::from_array(want));
        if bad != 0 {
            return Err(ValidationError::Unreachable { legs: bad });
        }
        let sol = fk(geom, &strokes, &home, &cfg).map_err(|e| ValidationError::FkFailed {
            corner,
            fk_code: e.code(),
        })?;
        let got = sol.pose.to_array();
        for (k, (g, w)) in got.iter().zip(want.iter()).enumerate() {
            let tol = if k < 3 {
                FK_CORNER_TOL_MM
            } else {
                FK_CORNER_TOL_RAD
            };
            if !close(f64::from(*g), f64::from(*w), tol) {
                return Err(ValidationError::FkInaccurate { corner });
            }
        }
        self.next += 1;
        if (self.next as usize) < WORKSPACE_CORNERS {
            Ok(Stage::Corners)
        } else {
            Ok(Stage::Done(Ok(())))
        }
    }
}

/// Checks 1 to 4 of the module docs.
fn checks(t: &Table, cfg: &ValidationConfig) -> Result<Stage, ValidationError> {
    if let Some(i) = t
        .provenance
        .tag
        .iter()
        .position(|b| *b != 0 && !ASCII_PRINTABLE.contains(b))
    {
        return Err(ValidationError::ProvenanceNotAscii { index: i as u8 });
    }
    check_finite(t)?;
    check_near_reference(t, cfg)?;
    Ok(Stage::Geometry)
}

/// A [`ValidationState`] with the table and configuration it validates.
#[derive(Clone, Copy, Debug)]
pub struct Validation<'a> {
    table: &'a Table,
    cfg: &'a ValidationConfig,
    state: ValidationState,
}

impl<'a> Validation<'a> {
    /// A validation of `table` against `cfg`, not started.
    pub const fn new(table: &'a Table, cfg: &'a ValidationConfig) -> Self {
        Self {
            table,
            cfg,
            state: ValidationState::new(),
        }
    }

    /// One bounded step ([`ValidationState::step`]): `None` while work remains, then
    /// the result.
    pub fn step(&mut self) -> Option<Result<(), ValidationError>> {
        self.state.step(self.table, self.cfg)
    }
}

/// The working geometry of `t` (not inlined: its f64 parameters are not on the stack
/// during the other checks). The one derivation of a table's geometry in the flight
/// code outside the controller's start (the worker's and the scrub's use it too: one
/// copy of the f64 parameters' assembly).
#[inline(never)]
pub fn working_geometry(t: &Table) -> Result<Geometry<f32>, GeometryError> {
    Geometry::<f32>::new(&t.geometry_params())
}

/// Validates a candidate table (see the module docs for the checks and their order):
/// a [`ValidationState`] stepped to completion. Never panics, whatever the table holds.
/// Out of line: inlined into the boot selection (its one flight caller), 64 bytes of
/// flash more.
#[inline(never)]
pub fn validate(t: &Table, cfg: &ValidationConfig) -> Result<(), ValidationError> {
    let mut v = ValidationState::new();
    loop {
        if let Some(r) = v.step(t, cfg) {
            return r;
        }
    }
}

#[cfg(all(test, feature = "host"))]
mod reference;
#[cfg(all(test, feature = "host"))]
mod tests;
