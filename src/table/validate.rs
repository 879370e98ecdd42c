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

use crate::kinematics::geometry::LegParams;
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
            reference: nominal::PROTOTYPE,
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

fn norm3(v: [f64; 3]) -> f64 {
    crate::kinematics::real::sqrt_f64(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
}

fn home_rod_mm(leg: &LegParams, p0: &[f64; 3]) -> [f64; 3] {
    [
        leg.b_mm[0] + p0[0] - leg.a_mm[0],
        leg.b_mm[1] + p0[1] - leg.a_mm[1],
        leg.b_mm[2] + p0[2] - leg.a_mm[2],
    ]
}

fn check_finite(t: &Table) -> Result<(), ValidationError> {
    let mut coords = [0.0; JOINT_COORDS];
    for (i, c) in coords.iter_mut().enumerate() {
        *c = t.joint_coord_mm(i).unwrap_or(f64::NAN);
    }
    let s = &t.supervision;
    let sup = [
        f64::from(s.following_error_warning_mm),
        f64::from(s.following_error_fault_mm),
        f64::from(s.encoder_jump_mm_per_cycle),
        f64::from(s.stuck_min_progress_mm),
    ];
    let groups: [(&[f64], u16); 7] = [
        (&coords, 0),
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

fn check_near_reference(t: &Table, cfg: &ValidationConfig) -> Result<(), ValidationError> {
    let tol = cfg.max_coordinate_deviation_mm;
    let reference = Table {
        legs: cfg.reference.legs,
        p0_mm: cfg.reference.p0_mm,
        ..*t
    };
    for i in 0..JOINT_COORDS {
        let (Some(v), Some(r)) = (t.joint_coord_mm(i), reference.joint_coord_mm(i)) else {
            return Err(ValidationError::CoordinateOffNominal { index: i as u8 });
        };
        if !close(v, r, tol) {
            return Err(ValidationError::CoordinateOffNominal { index: i as u8 });
        }
    }
    for (k, (v, r)) in t.p0_mm.iter().zip(cfg.reference.p0_mm.iter()).enumerate() {
        if !close(*v, *r, tol) {
            return Err(ValidationError::CoordinateOffNominal {
                index: (JOINT_COORDS + k) as u8,
            });
        }
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

/// Analytic part of the reachability check: per leg, the interpolation margin (mm) of
/// the grid (module docs), or the legs whose rod might turn horizontal in the box.
fn grid_margins_mm(t: &Table, points_per_axis: u8) -> Result<[f64; LEGS], ValidationError> {
    let w = &t.workspace;
    let intervals = f64::from(points_per_axis.saturating_sub(1).max(1));
    let rot_sum: f64 = w.rotation_rad.iter().sum();
    let t_max = norm3(w.translation_mm);
    let mut margins = [0.0; LEGS];
    let mut bad = 0u8;
    for (i, (m, leg)) in margins.iter_mut().zip(t.legs.iter()).enumerate() {
        let d0 = home_rod_mm(leg, &t.p0_mm);
        let l = norm3(d0);
        let h0 = crate::kinematics::real::sqrt_f64(d0[0] * d0[0] + d0[1] * d0[1]);
        let b = norm3(leg.b_mm);
        let h_max = h0 + b * rot_sum + t_max;
        let q2 = l * l - h_max * h_max;
        if !lt(0.0, q2) {
            bad |= 1 << i;
            continue;
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
        *m = sum / 8.0 + F32_STROKE_ROUNDING_MM;
    }
    if bad != 0 {
        return Err(ValidationError::Unreachable { legs: bad });
    }
    Ok(margins)
}

/// Grid pose number `index` (mixed radix, axis 0 fastest) on `n` points per axis.
fn grid_pose(w: &WorkspaceLimits, n: u8, mut index: u32) -> Pose<f32> {
    let n32 = u32::from(n.max(MIN_GRID_POINTS_PER_AXIS));
    let intervals = f64::from(n32 - 1);
    let mut v = [0.0f32; 6];
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
    }
    Pose::from_array(v)
}

fn check_grid(
    t: &Table,
    geom: &Geometry<f32>,
    cfg: &ValidationConfig,
) -> Result<(), ValidationError> {
    let n = cfg.grid_points_per_axis;
    if !(MIN_GRID_POINTS_PER_AXIS..=MAX_GRID_POINTS_PER_AXIS).contains(&n) {
        return Err(ValidationError::BadConfig);
    }
    let margins = grid_margins_mm(t, n)?;
    let total = u32::from(n).pow(6);
    let mut unreachable = 0u8;
    let mut beyond = 0u8;
    for index in 0..total {
        let pose = grid_pose(&t.workspace, n, index);
        let (strokes, bad) = strokes_unchecked(geom, &pose);
        unreachable |= bad;
        let lims = t
            .stroke_limits
            .min_mm
            .iter()
            .zip(t.stroke_limits.max_mm.iter());
        for (i, ((s, (lo, hi)), m)) in strokes.iter().zip(lims).zip(margins.iter()).enumerate() {
            let s = f64::from(*s);
            if !(le(lo + m, s) && le(s, hi - m)) {
                beyond |= 1 << i;
            }
        }
    }
    if unreachable != 0 {
        return Err(ValidationError::Unreachable { legs: unreachable });
    }
    // Unreachable legs keep stroke 0 and are reported above, so `beyond` is meaningful.
    if beyond != 0 {
        return Err(ValidationError::StrokeLimitExceeded { legs: beyond });
    }
    Ok(())
}

fn check_fk_corners(t: &Table, geom: &Geometry<f32>) -> Result<(), ValidationError> {
    let cfg = FkConfig::<f32>::default();
    let home = Pose::<f32>::home();
    for corner in 0..WORKSPACE_CORNERS {
        // On a 2-point grid the pose index bits are exactly the corner signs.
        let pose = grid_pose(&t.workspace, MIN_GRID_POINTS_PER_AXIS, corner as u32);
        let c = corner as u8;
        let (strokes, bad) = strokes_unchecked(geom, &pose);
        if bad != 0 {
            return Err(ValidationError::Unreachable { legs: bad });
        }
        let sol = fk(geom, &strokes, &home, &cfg).map_err(|e| ValidationError::FkFailed {
            corner: c,
            fk_code: e.code(),
        })?;
        let got = sol.pose.to_array();
        let want = pose.to_array();
        for (k, (g, w)) in got.iter().zip(want.iter()).enumerate() {
            let tol = if k < 3 {
                FK_CORNER_TOL_MM
            } else {
                FK_CORNER_TOL_RAD
            };
            if !close(f64::from(*g), f64::from(*w), tol) {
                return Err(ValidationError::FkInaccurate { corner: c });
            }
        }
    }
    Ok(())
}

/// The working geometry of `t` (not inlined: its f64 parameters are not on the stack
/// during the grid and corner checks).
#[inline(never)]
fn working_geometry(t: &Table) -> Result<Geometry<f32>, ValidationError> {
    Geometry::<f32>::new(&t.geometry_params()).map_err(ValidationError::Geometry)
}

/// Validates a candidate table (see the module docs for the checks and their order).
/// Never panics, whatever the table holds.
pub fn validate(t: &Table, cfg: &ValidationConfig) -> Result<(), ValidationError> {
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
    let geom = working_geometry(t)?;
    check_caps(t, cfg)?;
    check_supervision(&t.supervision)?;
    check_grid(t, &geom, cfg)?;
    check_fk_corners(t, &geom)?;
    Ok(())
}
