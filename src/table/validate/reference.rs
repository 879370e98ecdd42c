//! The validation as it was before it ran in steps (commit 749c65e, `validate` in one
//! call), kept verbatim as the reference the stepped one is tested against
//! (`super::tests`). Test code only.

use crate::kinematics::geometry::LegParams;
use crate::kinematics::ik::strokes_unchecked;
use crate::kinematics::{fk, FkConfig, Geometry, Pose, WorkspaceLimits, LEGS};

use super::super::layout::{SupervisionThresholds, Table, JOINT_COORDS};
use super::{
    field_index, ValidationConfig, ValidationError, ASCII_PRINTABLE, F32_STROKE_ROUNDING_MM,
    FK_CORNER_TOL_MM, FK_CORNER_TOL_RAD, MAX_GRID_POINTS_PER_AXIS, MIN_GRID_POINTS_PER_AXIS,
    WORKSPACE_CORNERS,
};

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
    // Added with table format 2 (issue 22), after the reference was frozen.
    t.thermal
        .validate()
        .map_err(|e| ValidationError::Thermal { field: e.code() })?;
    check_grid(t, &geom, cfg)?;
    check_fk_corners(t, &geom)?;
    Ok(())
}
