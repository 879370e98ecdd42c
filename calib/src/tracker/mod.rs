//! Calibration from what a laser tracker really measures (host): target balls on the
//! moving platform and fiducial nests on the base, measured in the tracker's own frame,
//! with the encoder strokes from housekeeping.
//!
//! * [`files`]: the input formats (target file, tracker point export, strokes).
//! * [`data`](bundle_data): the files checked against each other and turned into the
//!   bundle fit's observations ([`crate::calib::bundle`]), with the covariance of
//!   every point from the tracker's noise model; gross errors (a swapped point name, a
//!   moved nest, wrong strokes) refused with the line before the fit.
//! * [`campaign`]: a simulated campaign with the realistic tracker
//!   ([`m2ctl::sim::tracker`]), written as the same files.
//! * [`session`]: the tracker at work in the mission demo (measure, export, fit, verify).
//! * [`study`]: the figures of docs/calibration.md (campaign table, predicted vs measured over
//!   many campaigns, optimal plan, the paper's experiment) and [`plots`].

pub mod campaign;
pub mod commands;
pub mod exports;
pub mod files;
pub mod plots;
pub mod robust;
pub mod session;
pub mod study;

use nalgebra::{Point3, Vector3};

use self::files::{check_export, PointPose, PointRecord, StrokeRecord, TargetFile, Which};
use crate::calib::bundle::{BallObs, BundleData, FiducialObs, PointObs, PoseObs};
use crate::calib::registration::kabsch;
use crate::files::FileError;
use m2ctl::kinematics::{fk, FkConfig, Geometry, GeometryParams, Pose};
use m2ctl::sim::tracker::{rotation_matrix, TrackerNoise};

/// Largest plausible distance of a fiducial from where the others register it (mm): the
/// drawing tolerance is tens of um; a larger gap is a wrong nest or a moved tracker.
pub const MAX_FIDUCIAL_MISMATCH_MM: f64 = 1.0;
/// Largest plausible distance of a measured ball from where the nominal geometry, the
/// nominal ball centres and the fiducial registration put it (mm): joint and ball errors
/// of a few tenths of a mm move a ball by well under 1 mm; a larger gap is a swapped
/// name, a wrong pose number or wrong strokes.
pub const MAX_PREFIT_MISMATCH_MM: f64 = 2.0;

/// A tracker-data problem with the file it concerns.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackerDataError {
    /// Which file.
    pub which: Which,
    /// The problem and line.
    pub error: FileError,
}

impl std::fmt::Display for TrackerDataError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.error)
    }
}

fn data_err(which: Which, line: usize, message: String) -> TrackerDataError {
    TrackerDataError {
        which,
        error: FileError { line, message },
    }
}

/// The observation of a point: isotropic from the export's `sigma_mm` if given, else
/// the tracker class's model (range along the line of sight, transverse across it),
/// plus a fixed isotropic `fixed_var_mm2` (a fiducial's drawing tolerance).
fn point_obs(p: &PointRecord, noise: &TrackerNoise, fixed_var_mm2: f64) -> Option<PointObs> {
    match p.sigma_mm {
        Some(s) => PointObs::isotropic(p.line, p.y_mm, s, fixed_var_mm2),
        None => PointObs::tracker(p.line, p.y_mm, noise, fixed_var_mm2),
    }
}

/// Checks the three inputs against each other and builds the bundle's observations.
/// Strokes must lie within the slider range (`nominal`'s limits, else the flight
/// limits); fiducials must agree with their registration within
/// [`MAX_FIDUCIAL_MISMATCH_MM`], balls with the nominal prediction within
/// [`MAX_PREFIT_MISMATCH_MM`].
pub fn bundle_data(
    targets: &TargetFile,
    points: &[PointRecord],
    strokes: &[StrokeRecord],
    nominal: &GeometryParams,
    noise: &TrackerNoise,
) -> Result<BundleData, TrackerDataError> {
    let poses = check_export(targets, points, strokes)
        .map_err(|(which, error)| TrackerDataError { which, error })?;
    let cov_ok = |p: &PointRecord, fixed: f64| {
        point_obs(p, noise, fixed).ok_or_else(|| {
            data_err(
                Which::Points,
                p.line,
                format!(
                    "point {}: its covariance is not positive definite (noise model all zero?)",
                    p.name
                ),
            )
        })
    };
    let fid_var = targets.fiducial_sigma_mm * targets.fiducial_sigma_mm;
    let mut fiducials = Vec::new();
    for p in points.iter().filter(|p| p.pose == PointPose::Base) {
        let Some(def) = targets.fiducials.iter().find(|f| f.name == p.name) else {
            continue;
        };
        fiducials.push(FiducialObs {
            name: p.name.clone(),
            drawing_b_mm: def.mm,
            obs: cov_ok(p, fid_var)?,
        });
    }
    // Registration and its residuals: a fiducial far from the others' fit is refused.
    let from: Vec<[f64; 3]> = fiducials.iter().map(|f| f.drawing_b_mm).collect();
    let to: Vec<[f64; 3]> = fiducials.iter().map(|f| f.obs.y_mm).collect();
    let reg = kabsch(&from, &to, None)
        .map_err(|e| data_err(Which::Points, 0, format!("fiducial registration: {e}")))?;
    let worst = fiducials
        .iter()
        .map(|f| {
            let y = reg * Point3::from(f.drawing_b_mm);
            (f, (Vector3::from(f.obs.y_mm) - y.coords).norm())
        })
        .max_by(|a, b| a.1.total_cmp(&b.1));
    if let Some((f, d)) = worst {
        if d > MAX_FIDUCIAL_MISMATCH_MM {
            return Err(data_err(
                Which::Points,
                f.obs.line,
                format!(
                    "fiducial {} is {d:.3} mm from where the fiducials' registration puts it (limit {MAX_FIDUCIAL_MISMATCH_MM} mm): a wrong nest, name or a moved tracker?",
                    f.name
                ),
            ));
        }
    }
    let flight = m2ctl::nominal::prototype_with_flight_limits();
    let limits = nominal
        .stroke_limits
        .or(flight.stroke_limits)
        .ok_or_else(|| data_err(Which::Strokes, 0, "no stroke limits".into()))?;
    let geom = Geometry::<f64>::new(&GeometryParams::new(nominal.legs, nominal.p0_mm))
        .map_err(|e| data_err(Which::Strokes, 0, crate::files::describe_geometry_error(&e)))?;
    let fk_cfg = FkConfig {
        max_iterations: crate::calib::bundle::BUNDLE_FK_ITERATIONS,
        ..FkConfig::default()
    };
    let inv = reg.inverse();
    let mut out_poses = Vec::with_capacity(poses.len());
    for k in poses {
        let Some(s) = strokes.iter().find(|s| s.pose == k) else {
            continue;
        };
        for (i, v) in s.strokes_mm.iter().enumerate() {
            if *v < limits.min_mm[i] || *v > limits.max_mm[i] {
                return Err(data_err(
                    Which::Strokes,
                    s.line,
                    format!(
                        "stroke s{}_mm = {v} mm is outside the slider range [{}, {}] mm",
                        i + 1,
                        limits.min_mm[i],
                        limits.max_mm[i]
                    ),
                ));
            }
        }
        let pose = fk(&geom, &s.strokes_mm, &Pose::home(), &fk_cfg).map_err(|e| {
            data_err(
                Which::Strokes,
                s.line,
                format!(
                    "pose {k}: the strokes have no pose under the nominal geometry: {}",
                    crate::ikfk::describe_fk_error(&e)
                ),
            )
        })?;
        let r = rotation_matrix(&pose.pose.rotation_rad);
        let predicted_of = |b: usize| {
            Vector3::from(nominal.p0_mm)
                + Vector3::from(pose.pose.translation_mm)
                + r * Vector3::from(targets.balls[b].mm)
        };
        let in_pose: Vec<(&PointRecord, usize)> = points
            .iter()
            .filter(|p| p.pose == PointPose::Pose(k))
            .filter_map(|p| Some((p, targets.balls.iter().position(|b| b.name == p.name)?)))
            .collect();
        let gap = |p: &PointRecord, b: usize| {
            ((inv * Point3::from(p.y_mm)).coords - predicted_of(b)).norm()
        };
        let mut balls = Vec::new();
        for &(p, b) in &in_pose {
            let d = gap(p, b);
            if d > MAX_PREFIT_MISMATCH_MM {
                // Two names exchanged: each point is where the other's name should be.
                if let Some((q, _)) = in_pose.iter().find(|(q, c)| {
                    q.line != p.line
                        && gap(p, *c) <= MAX_PREFIT_MISMATCH_MM
                        && gap(q, b) <= MAX_PREFIT_MISMATCH_MM
                }) {
                    return Err(data_err(
                        Which::Points,
                        p.line,
                        format!(
                            "balls {} (line {}) and {} (line {}) of pose {k} are swapped: each is where the other's name should be ({d:.3} mm from its own, within {MAX_PREFIT_MISMATCH_MM} mm of the other's); correct the names in the export",
                            p.name, p.line, q.name, q.line
                        ),
                    ));
                }
                return Err(data_err(
                    Which::Points,
                    p.line,
                    format!(
                        "ball {} of pose {k} is {d:.3} mm from where the strokes (line {} of the stroke file) and the nominal geometry put it (limit {MAX_PREFIT_MISMATCH_MM} mm): a swapped name, a wrong pose number or wrong strokes?",
                        p.name, s.line
                    ),
                ));
            }
            balls.push(BallObs {
                ball: b,
                obs: cov_ok(p, 0.0)?,
            });
        }
        out_poses.push(PoseObs {
            pose: k,
            stroke_line: s.line,
            strokes_mm: s.strokes_mm,
            balls,
        });
    }
    Ok(BundleData {
        nominal: *nominal,
        ball_names: targets.balls.iter().map(|b| b.name.clone()).collect(),
        balls_nominal_m: targets.balls.iter().map(|b| b.mm).collect(),
        fiducials,
        poses: out_poses,
    })
}
