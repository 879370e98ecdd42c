//! The paper's sampling plan for the calibration measurements.
//!
//! Translation stroke points (centre, the corners of a cube of half-side
//! [`DEFAULT_CUBE_HALF_MM`], the six axis points at [`DEFAULT_AXIS_MM`]), each combined with
//! all 8 sign combinations of `(+-r, +-r, +-r)` rotations, `r` = [`DEFAULT_ROTATION_ARCSEC`].
//! The defaults give 15 x 8 = 120 poses.

use m2ctl::kinematics::Pose;

/// Default half-side of the translation cube whose corners are sampled (mm).
pub const DEFAULT_CUBE_HALF_MM: f64 = 0.5;
/// Default distance of the axis points from the centre (mm): the paper's stroke, 1 mm.
pub const DEFAULT_AXIS_MM: f64 = 1.0;
/// Default rotation magnitude about each axis (arcsec): the paper's 0.5'.
pub const DEFAULT_ROTATION_ARCSEC: f64 = 30.0;

/// Sampling-plan settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanConfig {
    /// Include the centre translation point.
    pub centre: bool,
    /// Half-side of the cube whose 8 corners are sampled (mm); `None` leaves them out.
    pub cube_half_mm: Option<f64>,
    /// Distance of the 6 axis points (mm); `None` leaves them out.
    pub axis_mm: Option<f64>,
    /// Rotation magnitude (arcsec), combined with all 8 sign patterns.
    pub rotation_arcsec: f64,
}

impl Default for PlanConfig {
    fn default() -> Self {
        Self {
            centre: true,
            cube_half_mm: Some(DEFAULT_CUBE_HALF_MM),
            axis_mm: Some(DEFAULT_AXIS_MM),
            rotation_arcsec: DEFAULT_ROTATION_ARCSEC,
        }
    }
}

/// The 8 sign patterns of three components, in binary order (`-,-,-` first).
pub fn sign_patterns() -> [[f64; 3]; 8] {
    let mut out = [[0.0; 3]; 8];
    for (k, o) in out.iter_mut().enumerate() {
        for (axis, v) in o.iter_mut().enumerate() {
            *v = if k & (4 >> axis) != 0 { 1.0 } else { -1.0 };
        }
    }
    out
}

/// The translation stroke points of the plan (mm).
pub fn translation_points(cfg: &PlanConfig) -> Vec<[f64; 3]> {
    let mut pts = Vec::new();
    if cfg.centre {
        pts.push([0.0; 3]);
    }
    if let Some(h) = cfg.cube_half_mm {
        pts.extend(sign_patterns().iter().map(|s| s.map(|v| v * h)));
    }
    if let Some(d) = cfg.axis_mm {
        for axis in 0..3 {
            for sign in [1.0, -1.0] {
                let mut p = [0.0; 3];
                p[axis] = sign * d;
                pts.push(p);
            }
        }
    }
    pts
}

/// The plan's poses: every translation point with every rotation sign pattern.
pub fn plan_poses(cfg: &PlanConfig) -> Vec<Pose<f64>> {
    let rots = sign_patterns().map(|s| s.map(|v| v * cfg.rotation_arcsec));
    translation_points(cfg)
        .into_iter()
        .flat_map(|t| rots.iter().map(move |r| Pose::from_mm_arcsec(t, *r)))
        .collect()
}

/// The plan as a 6-column pose CSV (header `x_mm,...,rz_arcsec`), input of `m2ground ik`.
pub fn format_plan(poses: &[Pose<f64>], header_comment: &str) -> String {
    let mut s = String::new();
    for l in header_comment.lines() {
        s.push_str(&format!("# {l}\n"));
    }
    s.push_str(&crate::files::CSV_COLUMNS[crate::files::POSE_COLUMNS].join(","));
    s.push('\n');
    for p in poses {
        let v = super::calib::pose_mm_arcsec(p);
        let f: Vec<String> = v.iter().map(|x| format!("{x:.15}")).collect();
        s.push_str(&f.join(","));
        s.push('\n');
    }
    s
}
