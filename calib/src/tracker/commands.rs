//! The tracker-path commands of `m2ground` as functions returning text: `calibrate` from
//! a point export, a stroke file and a target file, and `simulate-tracker-campaign`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::Point3;

use super::campaign::{simulate_with_truth, CampaignSeeds, TrackerSetup};
use super::exports::{read_export, ExportOptions};
use super::files::{
    format_export, format_strokes, format_targets, parse_strokes, parse_targets, PointPose, Which,
};
use super::plots::{per_pose, Band, Panel, Series};
use super::study::{rms3, TruthModel};
use crate::calib::adjust::{adjust, AdjustConfig, Adjustment, PriorSetting};
use crate::calib::bundle::{self, BundleFit};
use crate::calib::registration::{pose_from_balls, rotation_angles};
use crate::calib::{param_name, to_vec, N_PARAMS};
use crate::eval::{accuracy, pose_error, random_poses, Accuracy, AXES};
use crate::eval::{DEFAULT_EVAL_POSES, DEFAULT_EVAL_ROTATION_ARCSEC, DEFAULT_EVAL_TRANSLATION_MM};
use crate::files::{format_geometry, read_geometry, GeometryFile};
use crate::report::DEFAULT_EVAL_SEED;
use m2ctl::kinematics::{fk, FkConfig, Geometry, GeometryParams, Pose};
use m2ctl::sim::tracker::TrackerNoise;
use m2ctl::units::{ARCSEC_PER_RAD, MM_PER_M, UM_PER_MM};

/// Weakest directions listed in the report.
pub const REPORTED_DIRECTIONS: usize = 6;
/// Quantiles of the noise-floor band: where a pure-noise per-pose maximum lands 90 % of
/// the time.
pub const BAND_QUANTILES: (f64, f64) = (0.05, 0.95);
/// Draws of the noise-floor band's Monte Carlo.
const BAND_DRAWS: usize = 4000;

/// Options of `calibrate` on tracker points.
#[derive(Clone, Debug)]
pub struct PointCalibrateArgs {
    /// Tracker point export.
    pub points: PathBuf,
    /// Stroke file.
    pub strokes: PathBuf,
    /// Target file.
    pub targets: PathBuf,
    /// Nominal geometry file.
    pub nominal: PathBuf,
    /// How to read the point export (format, unit, frame).
    pub export: ExportOptions,
    /// The tracker's noise model (weights of points without their own sigma): the
    /// a-priori model that the variance components scale.
    pub noise: TrackerNoise,
    /// Adjustment settings (priors, noise estimation, outlier test).
    pub adjust: AdjustConfig,
    /// Print the pose errors at the measured poses (and, with `truth`, held out).
    pub report: bool,
    /// True geometry of a simulated campaign.
    pub truth: Option<PathBuf>,
    /// Per-pose error plot (with `report`).
    pub plot: Option<PathBuf>,
    /// Picture of the standardised residuals per pose and ball.
    pub residual_plot: Option<PathBuf>,
}

fn read(path: &Path) -> Result<String, String> {
    std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))
}

/// The lower and upper band edges (um or arcsec) of per-pose maxima of pure pose noise
/// with per-axis sigmas `s` (three axes), by Monte Carlo.
pub fn noise_band(s: &[f64]) -> Band {
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let mut v: Vec<f64> = (0..BAND_DRAWS)
        .map(|_| {
            s.iter().fold(0.0f64, |m, si| {
                let z: f64 = StandardNormal.sample(&mut rng);
                m.max((z * si).abs())
            })
        })
        .collect();
    v.sort_by(|a, b| a.total_cmp(b));
    let q = |f: f64| v[((v.len() - 1) as f64 * f) as usize];
    Band {
        lo: q(BAND_QUANTILES.0),
        hi: q(BAND_QUANTILES.1),
    }
}

/// The two panels of a per-pose error plot of the accuracies `series` (label, accuracy):
/// the largest |translation error| of each pose (um) and the largest |rotation error|
/// (arcsec), each with the [`noise_band`] of `floor`, the 1-sigma noise of one pose
/// measurement per axis (um x3, arcsec x3), if given; `log` for log-scale axes.
pub fn pose_error_panels(
    series: &[(&str, &Accuracy)],
    floor: Option<&[f64; 6]>,
    log: bool,
) -> [Panel; 2] {
    let scale = if log { ", log scale" } else { "" };
    let panel = |what: &str, unit: &str, rot: bool| Panel {
        caption: format!("largest |{what} error| of each pose ({unit}{scale})"),
        y_label: unit.to_string(),
        series: series
            .iter()
            .map(|(l, a)| Series {
                label: l.to_string(),
                values: a
                    .per_pose_max()
                    .iter()
                    .map(|(t, r)| if rot { *r } else { *t })
                    .collect(),
            })
            .collect(),
        band: floor.map(|f| noise_band(if rot { &f[3..] } else { &f[..3] })),
        log,
    };
    [
        panel("translation", "um", false),
        panel("rotation", "arcsec", true),
    ]
}

/// The tracker's 1-sigma noise of one pose measurement at home (um x3, arcsec x3).
pub fn pose_noise(fit: &BundleFit, p0_mm: &[f64; 3], noise: &TrackerNoise) -> Option<[f64; 6]> {
    bundle::pose_measurement_sigma(
        &fit.balls_m,
        &fit.registration,
        p0_mm,
        &Pose::home(),
        &|y| noise.covariance_mm2(y),
    )
}

fn line(out: &mut String, label: &str, a: &Accuracy) {
    let _ = writeln!(out, "  {label:<26} max/RMS: {}", a.max_rms_cells(3));
}

/// The a-priori noise model with the estimated variance factors applied (range and
/// transverse sigmas times the square roots of their factors).
pub fn scaled_noise(noise: &TrackerNoise, adj: &Adjustment) -> TrackerNoise {
    let f = adj.factors();
    let (r, t) = (f[0].sqrt(), f[1].sqrt());
    TrackerNoise {
        range_um: noise.range_um * r,
        range_um_per_m: noise.range_um_per_m * r,
        transverse_um: noise.transverse_um * t,
        transverse_um_per_m: noise.transverse_um_per_m * t,
    }
}

/// Mean tracker-to-ball range of the data (mm).
fn data_ranges_mm(data: &crate::calib::bundle::BundleData) -> f64 {
    let r: Vec<f64> = data
        .poses
        .iter()
        .flat_map(|p| p.balls.iter())
        .map(|b| nalgebra::Vector3::from(b.obs.y_mm).norm())
        .collect();
    r.iter().sum::<f64>() / r.len().max(1) as f64
}

/// The statistics of the adjustment: variance components, the global test, the outlier
/// test and what it removed.
pub fn format_statistics(adj: &Adjustment, noise: &TrackerNoise, range_mm: f64) -> String {
    use crate::calib::adjust::{GLOBAL_TEST_ALPHA, OUTLIER_POWER, SPREAD_RANGE_MM};
    let mut s = String::new();
    let (sr, st) = noise.sigmas_mm(range_mm);
    let _ = writeln!(
        s,
        "noise model and priors from the data (variance components, Foerstner's iterative estimator = type-II maximum likelihood; 95 % intervals):"
    );
    for (k, c) in adj.components.iter().enumerate() {
        if c.rows == 0 {
            continue;
        }
        let what = match k {
            0 => format!(
                "sigma {:.2} um at {:.2} m (model {:.2} um)",
                sr * UM_PER_MM * c.factor.sqrt(),
                range_mm / MM_PER_M,
                sr * UM_PER_MM
            ),
            1 => format!(
                "sigma {:.2} um at {:.2} m (model {:.2} um)",
                st * UM_PER_MM * c.factor.sqrt(),
                range_mm / MM_PER_M,
                st * UM_PER_MM
            ),
            2 => "sigma x the export's".to_string(),
            3 => format!(
                "spread {} mm (type-II ML)",
                adj.joint_prior_mm.map_or("-".into(), |v| format!("{v:.4}"))
            ),
            _ => format!(
                "spread {} mm",
                adj.ball_prior_mm.map_or("-".into(), |v| format!("{v:.4}"))
            ),
        };
        let _ = writeln!(
            s,
            "  {:<30} variance factor {:.3} ({:.3} .. {:.3}), sigma factor {:.3}; {}; redundancy {:.1} of {} rows{}",
            c.name,
            c.factor,
            c.factor_ci.0,
            c.factor_ci.1,
            c.factor.sqrt(),
            what,
            c.redundancy,
            c.rows,
            if c.estimated { "" } else { " (not estimated: fixed or redundancy too small)" }
        );
    }
    if let Some(p) = &adj.spread_posterior {
        let _ = writeln!(
            s,
            "  joints' spread, posterior (marginal likelihood x log-uniform hyperprior over {} .. {} mm): median {:.4} mm, 68 % {:.4} .. {:.4} mm; the calibration is the average of {} fits over the spread, weighted by it",
            SPREAD_RANGE_MM.0,
            SPREAD_RANGE_MM.1,
            p.median_mm,
            p.interval_mm.0,
            p.interval_mm.1,
            p.grid_mm.len()
        );
    }
    let g = |t: &crate::calib::adjust::GlobalTest| {
        format!(
            "sigma0^2 = {:.3} (95 % {:.3} .. {:.3}), {:.1} degrees of freedom, accepted region {:.3} .. {:.3} at alpha {}: {}",
            t.sigma0_sq,
            t.sigma0_sq_ci.0,
            t.sigma0_sq_ci.1,
            t.redundancy,
            t.accept.0,
            t.accept.1,
            GLOBAL_TEST_ALPHA,
            if t.passed { "accepted" } else { "rejected" }
        )
    };
    let _ = writeln!(
        s,
        "global test of the a-priori noise model (chi-square of the data residuals with the model's variances):
  all points: {}
  after the outliers: {}
  {}",
        g(&adj.global_before),
        g(&adj.global_after),
        if adj.global_after.passed {
            "the model fits; the estimated factors are consistent with 1"
        } else {
            "the model does not fit this tracker: the fit's weights and covariances use the estimated variance factors instead (nothing is refused for it)"
        }
    );
    let mdb: Vec<f64> = {
        let mut v: Vec<f64> = adj
            .tests
            .iter()
            .map(|t| t.mdb_mm)
            .filter(|v| v.is_finite())
            .collect();
        v.sort_by(|a, b| a.total_cmp(b));
        v
    };
    let worst = adj
        .tests
        .iter()
        .filter(|t| t.t.is_finite())
        .max_by(|a, b| a.t.total_cmp(&b.t));
    let untestable = adj.tests.iter().filter(|t| !t.t.is_finite()).count();
    let _ = writeln!(
        s,
        "outlier test (data snooping: each point's 3 standardised residuals together, T = v^T Q_vv^-1 v ~ chi-square(3)): critical T {:.2} (family alpha {}, Bonferroni over {} points: {:.2e} per point); minimal detectable bias ({:.0} % power, lambda0 {:.1}, worst direction) {:.3} .. {:.3} mm, median {:.3} mm{}",
        adj.critical,
        adj.alpha_per_test * adj.tests.len() as f64,
        adj.tests.len(),
        adj.alpha_per_test,
        OUTLIER_POWER * 100.0,
        adj.lambda0,
        mdb.first().copied().unwrap_or(f64::NAN),
        mdb.last().copied().unwrap_or(f64::NAN),
        mdb.get(mdb.len() / 2).copied().unwrap_or(f64::NAN),
        if untestable > 0 { format!("; {untestable} points not testable") } else { String::new() }
    );
    if adj.removed.is_empty() {
        let _ = writeln!(s, "  outliers: none");
    }
    for o in &adj.removed {
        let e = o.test.error_mm;
        let _ = writeln!(
            s,
            "  removed: line {}: {}, T = {:.1} > {:.1} (max |w| {:.1}), estimated error {:.0} um ({:+.0} / {:+.0} / {:+.0} um, tracker frame)",
            o.test.line,
            o.test.what,
            o.test.t,
            o.critical,
            o.test.w_max,
            (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt() * UM_PER_MM,
            e[0] * UM_PER_MM,
            e[1] * UM_PER_MM,
            e[2] * UM_PER_MM
        );
    }
    if let Some(w) = worst {
        let _ = writeln!(
            s,
            "  largest remaining: line {}: {}, T = {:.2} (max |w| {:.2}, mean redundancy number {:.3})",
            w.line, w.what, w.t, w.w_max, w.redundancy
        );
    }
    s
}

/// The standardised residuals `sqrt(T)` of every ball at every pose (one series per
/// ball), the fiducials' (one series, drawn at x = 1, 2, ... in file order) and the
/// removed outliers' at their removal, with the critical value as the accepted band.
pub fn plot_residuals(path: &Path, adj: &Adjustment) -> Result<(), String> {
    use crate::calib::adjust::PointId;
    let n = adj
        .data
        .poses
        .iter()
        .map(|p| p.pose as usize)
        .chain(
            adj.removed
                .iter()
                .filter_map(|o| o.test.pose.map(|p| p as usize)),
        )
        .max()
        .unwrap_or(1);
    let mut series: Vec<Series> = adj
        .data
        .ball_names
        .iter()
        .map(|b| Series {
            label: format!("ball {b}"),
            values: vec![f64::NAN; n],
        })
        .collect();
    let mut fid = Series {
        label: "fiducials (at poses 1..)".into(),
        values: vec![f64::NAN; n],
    };
    let mut k_fid = 0;
    for t in &adj.tests {
        match t.id {
            PointId::Ball { pose, ball } => {
                let p = adj.data.poses[pose].pose as usize;
                series[ball].values[p - 1] = t.t.sqrt();
            }
            PointId::Fiducial(_) => {
                if k_fid < n {
                    fid.values[k_fid] = t.t.sqrt();
                }
                k_fid += 1;
            }
        }
    }
    let mut removed = Series {
        label: "removed outliers".into(),
        values: vec![f64::NAN; n],
    };
    for o in &adj.removed {
        let p = o.test.pose.unwrap_or(1) as usize;
        removed.values[p - 1] = o.test.t.sqrt();
    }
    series.push(fid);
    series.push(removed);
    per_pose(
        path,
        &format!(
            "Standardised residuals sqrt(T), T = v' Q_vv^-1 v (chi-square, 3 dof, when good); critical sqrt(T) {:.2}",
            adj.critical.sqrt()
        ),
        "pose (number in the files)",
        &[Panel {
            caption: "sqrt(T) per pose and ball".into(),
            y_label: "sqrt(T)".into(),
            series,
            band: Some(Band {
                lo: 0.0,
                hi: adj.critical.sqrt(),
            }),
            log: false,
        }],
        Some("accepted: sqrt(T) below the critical value"),
    )
}

/// Runs `calibrate` on tracker points: the geometry file text and the printed report.
/// Nothing is returned (so nothing written) unless the flight validation accepts the
/// result.
pub fn run_point_calibrate(a: &PointCalibrateArgs) -> Result<(String, String), String> {
    let name = |p: &Path, e: &dyn std::fmt::Display| format!("{}: {e}", p.display());
    let targets = parse_targets(&read(&a.targets)?).map_err(|e| name(&a.targets, &e))?;
    let points = read_export(&read(&a.points)?, &a.export).map_err(|e| name(&a.points, &e))?;
    let strokes = parse_strokes(&read(&a.strokes)?).map_err(|e| name(&a.strokes, &e))?;
    let nominal = read_geometry(&a.nominal)?;
    let data = super::bundle_data(&targets, &points, &strokes, &nominal.params, &a.noise).map_err(
        |e| {
            let p = match e.which {
                Which::Points => &a.points,
                Which::Strokes => &a.strokes,
            };
            name(p, &e)
        },
    )?;
    let adj = adjust(&data, &a.adjust).map_err(|e| match e {
        bundle::BundleError::Outlier { .. } => name(&a.points, &e),
        bundle::BundleError::Data(ref m) if m.contains("outlier test") => name(&a.points, &e),
        e => format!("calibration: {e}"),
    })?;
    let fit = &adj.fit;
    let data = &adj.data;
    let estimated_noise = scaled_noise(&a.noise, &adj);
    crate::files::validate_for_flight(&fit.params)
        .map_err(|e| format!("calibration result: {e}"))?;
    let p0 = nominal.params.p0_mm;
    let mut s = String::new();
    let prior = |v: Option<f64>, setting: &PriorSetting| match (v, setting) {
        (None, _) => "none".to_string(),
        (Some(x), PriorSetting::Estimate { .. }) => format!("{x:.4} mm (estimated)"),
        (Some(x), _) => format!("{x} mm (given)"),
    };
    let _ = writeln!(
        s,
        "calibrated {N_PARAMS} joint coordinates from {} poses ({} ball points, {} fiducials) by a bundle fit in ball coordinates; priors: joints {}, balls {}; a-priori tracker noise model: {}",
        data.poses.len(),
        data.poses.iter().map(|p| p.balls.len()).sum::<usize>(),
        data.fiducials.len(),
        match &adj.spread_posterior {
            Some(p) => format!("{:.4} mm (posterior median; fits averaged over the spread)", p.median_mm),
            None => prior(adj.joint_prior_mm, &a.adjust.joint_prior),
        },
        prior(adj.ball_prior_mm, &a.adjust.ball_prior),
        a.noise.describe()
    );
    s.push_str(&format_statistics(&adj, &a.noise, data_ranges_mm(data)));
    // Registration.
    let reg_angles = |iso: &nalgebra::Isometry3<f64>| {
        rotation_angles(iso.rotation.to_rotation_matrix().matrix()).map(|v| v.to_degrees())
    };
    let t = fit.registration.translation.vector;
    let ang = reg_angles(&fit.registration);
    let d = fit.registration_fiducials.inverse() * fit.registration;
    let dang =
        rotation_angles(d.rotation.to_rotation_matrix().matrix()).map(|v| v * ARCSEC_PER_RAD);
    let fres: Vec<f64> = fit
        .fiducial_residuals_um
        .iter()
        .map(|r| (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt())
        .collect();
    let _ = writeln!(
        s,
        "registration base -> tracker: rotation (alpha, beta, gamma) {:.5} / {:.5} / {:.5} deg, translation {:.4} / {:.4} / {:.4} mm; the fit moved it from the fiducials-only Kabsch fit by {:.2} / {:.2} / {:.2}\" and {:.1} / {:.1} / {:.1} um; fiducial residuals {} um",
        ang[0], ang[1], ang[2], t.x, t.y, t.z,
        dang[0], dang[1], dang[2],
        d.translation.vector.x * UM_PER_MM, d.translation.vector.y * UM_PER_MM, d.translation.vector.z * UM_PER_MM,
        fres.iter().map(|v| format!("{v:.1}")).collect::<Vec<_>>().join(", ")
    );
    let balls: Vec<String> = data
        .ball_names
        .iter()
        .zip(fit.balls_m.iter().zip(data.balls_nominal_m.iter()))
        .map(|(n, (f, c))| {
            format!(
                "{n} {:+.1}/{:+.1}/{:+.1}",
                (f[0] - c[0]) * UM_PER_MM,
                (f[1] - c[1]) * UM_PER_MM,
                (f[2] - c[2]) * UM_PER_MM
            )
        })
        .collect();
    let _ = writeln!(
        s,
        "ball centres, fitted - nominal (frame M, um): {}",
        balls.join(", ")
    );
    let nom = to_vec(&nominal.params);
    let cal = to_vec(&fit.params);
    let (kmax, dmax) = (0..N_PARAMS)
        .map(|k| (k, (cal[k] - nom[k]).abs()))
        .fold((0, 0.0), |m, v| if v.1 > m.1 { v } else { m });
    let sig: Vec<f64> = (0..N_PARAMS)
        .map(|k| fit.covariance[(k, k)].max(0.0).sqrt() * UM_PER_MM)
        .collect();
    let _ = writeln!(
        s,
        "joints: largest change from nominal {:.1} um ({}); posterior 1 sigma {:.1} .. {:.1} um",
        dmax * UM_PER_MM,
        param_name(kmax),
        sig.iter().fold(f64::INFINITY, |m, v| m.min(*v)),
        sig.iter().fold(0.0f64, |m, v| m.max(*v))
    );
    let _ = writeln!(
        s,
        "fit: normalised residual RMS {:.3} (1 when the noise model is right; {:.3} at nominal), ball residual RMS {:.2} um per coordinate, worst point {:.2} sigma ({}, line {}), {} evaluations, {:.0} ms, {}{}",
        fit.normalised_rms(),
        fit.start_rms,
        fit.ball_residual_rms_um,
        fit.worst_point.0,
        fit.worst_point.2,
        fit.worst_point.1,
        fit.evaluations,
        fit.elapsed.as_secs_f64() * 1e3,
        fit.note,
        if fit.covariance_pseudo_inverse { "; covariance by pseudo-inverse (information singular)" } else { "" }
    );
    // Observability.
    let scale = adj
        .spread_posterior
        .as_ref()
        .map(|p| (p.median_mm * 1e4).round() / 1e4)
        .or(adj.joint_prior_mm)
        .unwrap_or(bundle::DEFAULT_JOINT_PRIOR_SIGMA_MM);
    let obs = bundle::observability(data, &fit.x, scale, REPORTED_DIRECTIONS)
        .map_err(|e| e.to_string())?;
    let below = |v: &[f64]| v.iter().filter(|x| **x < 1.0).count();
    let tail = |v: &[f64]| {
        v.iter()
            .rev()
            .take(REPORTED_DIRECTIONS)
            .map(|x| format!("{x:.3}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let _ = writeln!(
        s,
        "observability of the joints from the data alone (singular values of the whitened Jacobian, joints in units of {scale} mm: 1 = the data know a direction as well as a {scale} mm prior):\n  balls and registration known: {:.3} .. {:.4}, {} below 1 (smallest: {})\n  balls and registration free:  {:.3} .. {:.4}, {} below 1 (smallest: {})",
        obs.singular_known.first().copied().unwrap_or(0.0),
        obs.singular_known.last().copied().unwrap_or(0.0),
        below(&obs.singular_known),
        tail(&obs.singular_known),
        obs.singular_free.first().copied().unwrap_or(0.0),
        obs.singular_free.last().copied().unwrap_or(0.0),
        below(&obs.singular_free),
        tail(&obs.singular_free),
    );
    let _ = writeln!(
        s,
        "  weakest directions with the balls and registration free (free / known singular value):"
    );
    for d in &obs.weakest {
        let _ = writeln!(
            s,
            "    {:.4} / {:.4}: {}",
            d.singular_free, d.singular_known, d.description
        );
    }
    let _ = writeln!(
        s,
        "  directions that freeing the balls and registration hides most (information kept):"
    );
    for (kept, d) in &obs.hidden {
        let _ = writeln!(
            s,
            "    {:.2e} kept, {:.4} / {:.4}: {}",
            kept, d.singular_free, d.singular_known, d.description
        );
    }
    // Predicted accuracy.
    let held_out = random_poses(
        DEFAULT_EVAL_POSES,
        DEFAULT_EVAL_TRANSLATION_MM,
        DEFAULT_EVAL_ROTATION_ARCSEC,
        DEFAULT_EVAL_SEED,
    );
    let pred = bundle::predict_accuracy(
        &fit.params,
        &fit.joint_covariance(),
        &held_out,
        bundle::DEFAULT_MC_DRAWS,
        1,
    )?;
    let fmt6 = |v: &[f64; 6]| {
        v.iter()
            .enumerate()
            .map(|(k, x)| format!("{} {x:.3}{}", AXES[k], if k < 3 { "um" } else { "\"" }))
            .collect::<Vec<_>>()
            .join("  ")
    };
    let pred_unscaled = bundle::predict_accuracy(
        &fit.params,
        &adj.joint_covariance_unscaled(),
        &held_out,
        bundle::DEFAULT_MC_DRAWS,
        1,
    )?;
    let _ = writeln!(
        s,
        "predicted accuracy of the calibrated mechanism over {} poses (+-{} mm, +-{}\"), with the estimated noise scaling (the covariance of the fit):\n  RMS (1 sigma)  {}\n  largest sigma  {}\n  expected max   {}\nwithout it (the a-priori tracker model, same fit and priors):\n  RMS (1 sigma)  {}\n  expected max   {}",
        held_out.len(),
        DEFAULT_EVAL_TRANSLATION_MM,
        DEFAULT_EVAL_ROTATION_ARCSEC,
        fmt6(&pred.rms_sigma),
        fmt6(&pred.max_sigma),
        fmt6(&pred.expected_max),
        fmt6(&pred_unscaled.rms_sigma),
        fmt6(&pred_unscaled.expected_max)
    );
    if let Some(p) = &a.residual_plot {
        plot_residuals(p, &adj)?;
        let _ = writeln!(s, "standardised residuals: {}", p.display());
    }
    if a.report {
        // Pose errors at the measured poses: FK(strokes) - pose from the balls.
        let inv = fit.registration.inverse();
        let g_nom = Geometry::<f64>::new(&nominal.params)
            .map_err(|e| crate::files::describe_geometry_error(&e))?;
        let g_cal = Geometry::<f64>::new(&fit.params)
            .map_err(|e| crate::files::describe_geometry_error(&e))?;
        let fk_cfg = FkConfig {
            max_iterations: bundle::BUNDLE_FK_ITERATIONS,
            ..FkConfig::default()
        };
        let (mut before, mut after) = (Vec::new(), Vec::new());
        for p in &data.poses {
            let (mut m, mut b) = (Vec::new(), Vec::new());
            for pt in points.iter().filter(|q| q.pose == PointPose::Pose(p.pose)) {
                if let Some(i) = data.ball_names.iter().position(|n| *n == pt.name) {
                    let x = inv * Point3::from(pt.y_mm);
                    m.push(fit.balls_m[i]);
                    b.push([x.x, x.y, x.z]);
                }
            }
            let measured =
                pose_from_balls(&m, &b, None, &p0).map_err(|e| format!("pose {}: {e}", p.pose))?;
            for (g, out) in [(&g_nom, &mut before), (&g_cal, &mut after)] {
                let q = fk(g, &p.strokes_mm, &measured, &fk_cfg).map_err(|e| {
                    format!("pose {}: {}", p.pose, crate::ikfk::describe_fk_error(&e))
                })?;
                out.push(pose_error(&q.pose, &measured));
            }
        }
        let before = Accuracy::from_errors(before);
        let after = Accuracy::from_errors(after);
        let noise_sigma = pose_noise(fit, &p0, &estimated_noise).ok_or("pose noise singular")?;
        let _ = writeln!(
            s,
            "pose error at the measured poses, FK(strokes) - pose from the balls (fitted centres and registration), um and arcsec; one tracker pose measurement is 1 sigma {:.2}/{:.2}/{:.2} um, {:.2}/{:.2}/{:.2}\":",
            noise_sigma[0], noise_sigma[1], noise_sigma[2], noise_sigma[3], noise_sigma[4], noise_sigma[5]
        );
        line(&mut s, "nominal", &before);
        line(&mut s, "calibrated", &after);
        let mut plot_series = vec![
            ("nominal table".to_string(), before),
            ("calibrated table".to_string(), after),
        ];
        let mut band_label = Some("tracker noise floor (90 % of pure-noise poses)");
        let mut title = format!("Pose error at the {} measured poses: FK(encoder strokes) - pose from the tracker's balls", data.poses.len());
        let mut x_label = "measured pose (number in the files)";
        if let Some(tp) = &a.truth {
            let truth = read_geometry(tp)?;
            let b =
                accuracy(&nominal.params, &truth.params, &held_out).map_err(|e| e.to_string())?;
            let c = accuracy(&fit.params, &truth.params, &held_out).map_err(|e| e.to_string())?;
            let _ = writeln!(
                s,
                "held-out accuracy vs truth ({} random poses), commanding with (RMS of translation / rotation axes {:.3} um / {:.3}\" calibrated):",
                held_out.len(),
                rms3(&c.rms[..3]),
                rms3(&c.rms[3..])
            );
            line(&mut s, "nominal", &b);
            line(&mut s, "calibrated", &c);
            line(
                &mut s,
                "predicted (exp. max/1 sigma)",
                &Accuracy {
                    errors: vec![],
                    max_abs: pred.expected_max,
                    rms: pred.rms_sigma,
                },
            );
            plot_series = vec![
                ("nominal table (held-out)".into(), b),
                ("calibrated table (held-out)".into(), c),
            ];
            band_label = None;
            title = format!(
                "Held-out pose error vs the true mechanism, {} random poses",
                held_out.len()
            );
            x_label = "held-out pose";
        }
        if let Some(p) = &a.plot {
            let series: Vec<(&str, &Accuracy)> = plot_series
                .iter()
                .map(|(l, acc)| (l.as_str(), acc))
                .collect();
            let floor = band_label.map(|_| &noise_sigma);
            per_pose(
                p,
                &title,
                x_label,
                &pose_error_panels(&series, floor, false),
                band_label,
            )?;
            let _ = writeln!(s, "plot: {}", p.display());
        }
    }
    let id = format!(
        "cal-bundle-{}poses-nrms{:.0}m",
        data.poses.len(),
        fit.normalised_rms() * 1e3
    );
    let provenance = vec![
        ("calibration_id".to_string(), id),
        ("solver".to_string(), "bundle".to_string()),
        ("points".to_string(), a.points.display().to_string()),
        ("strokes".to_string(), a.strokes.display().to_string()),
        ("targets".to_string(), a.targets.display().to_string()),
        ("poses".to_string(), data.poses.len().to_string()),
        (
            "normalised_residual_rms".to_string(),
            format!("{:.6}", fit.normalised_rms()),
        ),
        (
            "predicted_rms_um".to_string(),
            format!("{:.4}", rms3(&pred.rms_sigma[..3])),
        ),
        (
            "predicted_rms_arcsec".to_string(),
            format!("{:.4}", rms3(&pred.rms_sigma[3..])),
        ),
        (
            "noise_factor_range".to_string(),
            format!("{:.4}", adj.components[0].factor.sqrt()),
        ),
        (
            "noise_factor_transverse".to_string(),
            format!("{:.4}", adj.components[1].factor.sqrt()),
        ),
        (
            "joint_spread_mm".to_string(),
            adj.spread_posterior
                .as_ref()
                .map(|p| p.median_mm)
                .or(adj.joint_prior_mm)
                .map_or("none".into(), |v| format!("{v:.5}")),
        ),
        (
            "outliers_removed".to_string(),
            if adj.removed.is_empty() {
                "none".to_string()
            } else {
                adj.removed
                    .iter()
                    .map(|o| format!("line {}", o.test.line))
                    .collect::<Vec<_>>()
                    .join(" ")
            },
        ),
    ];
    let text = format_geometry(
        &GeometryFile {
            params: fit.params,
            provenance,
        },
        &format!(
            "Calibrated by m2ground calibrate (bundle fit) from {}",
            a.points.display()
        ),
    );
    Ok((text, s))
}

/// Options of `simulate-tracker-campaign`.
#[derive(Clone, Debug)]
pub struct SimulateArgs {
    /// Nominal geometry.
    pub nominal: GeometryParams,
    /// True joints' spread.
    pub truth: TruthModel,
    /// Tracker setup.
    pub setup: TrackerSetup,
    /// Plan poses.
    pub plan: Vec<Pose<f64>>,
    /// Campaign number (seeds).
    pub campaign: u64,
}

/// The four files of a simulated campaign: (targets.toml, points.csv, strokes.csv,
/// truth.toml) texts.
pub fn run_simulate(a: &SimulateArgs) -> Result<[String; 4], String> {
    let seeds = CampaignSeeds::from_one(a.campaign);
    let truth = a.truth.draw(&a.nominal, seeds.geometry);
    let c = simulate_with_truth(&a.nominal, &truth, &a.setup, &a.plan, seeds)?;
    let what = format!(
        "Simulated tracker campaign {} (m2ground simulate-tracker-campaign): {} poses, tracker {:.2} m away, {}; true joints {}",
        a.campaign,
        a.plan.len(),
        a.setup.placement.distance_mm / MM_PER_M,
        a.setup.noise.describe(),
        a.truth.describe()
    );
    let truth_text = format_geometry(
        &GeometryFile {
            params: truth,
            provenance: vec![
                ("kind".into(), "simulated true geometry".into()),
                ("campaign".into(), a.campaign.to_string()),
            ],
        },
        "True geometry of a simulated tracker campaign",
    );
    Ok([
        format_targets(&a.setup.targets, "Target balls and fiducials"),
        format_export(
            &c.points,
            &format!("{what}\nTracker point export, tracker frame (mm)"),
        ),
        format_strokes(
            &c.strokes,
            &format!("{what}\nEncoder strokes per pose (mm)"),
        ),
        truth_text,
    ])
}

/// File names written by `simulate-tracker-campaign` into its output directory.
pub const SIMULATED_FILES: [&str; 4] = ["targets.toml", "points.csv", "strokes.csv", "truth.toml"];
