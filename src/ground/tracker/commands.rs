//! The tracker-path commands of `m2ground` as functions returning text: `calibrate` from
//! a point export, a stroke file and a target file, and `simulate-tracker-campaign`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::Point3;

use super::campaign::{simulate_with_truth, CampaignSeeds, TrackerSetup};
use super::files::{
    format_export, format_strokes, format_targets, parse_export, parse_strokes, parse_targets,
    PointPose, Which,
};
use super::plots::{per_pose, Band, Panel, Series};
use super::study::{rms3, TruthModel};
use crate::ground::calib::bundle::{self, BundleConfig, BundleFit};
use crate::ground::calib::registration::{pose_from_balls, rotation_angles};
use crate::ground::calib::{param_name, to_vec, N_PARAMS};
use crate::ground::eval::{accuracy, pose_error, random_poses, Accuracy, AXES};
use crate::ground::eval::{
    DEFAULT_EVAL_POSES, DEFAULT_EVAL_ROTATION_ARCSEC, DEFAULT_EVAL_TRANSLATION_MM,
};
use crate::ground::files::{format_geometry, read_geometry, GeometryFile};
use crate::ground::report::DEFAULT_EVAL_SEED;
use crate::kinematics::{fk, FkConfig, Geometry, GeometryParams, Pose};
use crate::sim::tracker::TrackerNoise;
use crate::units::{ARCSEC_PER_RAD, MM_PER_M, UM_PER_MM};

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
    /// The tracker's noise model (weights of points without their own sigma).
    pub noise: TrackerNoise,
    /// Bundle settings.
    pub cfg: BundleConfig,
    /// Print the pose errors at the measured poses (and, with `truth`, held out).
    pub report: bool,
    /// True geometry of a simulated campaign.
    pub truth: Option<PathBuf>,
    /// Per-pose error plot (with `report`).
    pub plot: Option<PathBuf>,
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

/// Runs `calibrate` on tracker points: the geometry file text and the printed report.
/// Nothing is returned (so nothing written) unless the flight validation accepts the
/// result.
pub fn run_point_calibrate(a: &PointCalibrateArgs) -> Result<(String, String), String> {
    let name = |p: &Path, e: &dyn std::fmt::Display| format!("{}: {e}", p.display());
    let targets = parse_targets(&read(&a.targets)?).map_err(|e| name(&a.targets, &e))?;
    let points = parse_export(&read(&a.points)?).map_err(|e| name(&a.points, &e))?;
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
    let fit = bundle::fit(&data, &a.cfg).map_err(|e| match e {
        bundle::BundleError::Outlier { .. } => name(&a.points, &e),
        e => format!("calibration: {e}"),
    })?;
    crate::ground::files::validate_for_flight(&fit.params)
        .map_err(|e| format!("calibration result: {e}"))?;
    let p0 = nominal.params.p0_mm;
    let mut s = String::new();
    let prior = |v: Option<f64>| v.map_or("none".to_string(), |x| format!("{x} mm"));
    let _ = writeln!(
        s,
        "calibrated {N_PARAMS} joint coordinates from {} poses ({} ball points, {} fiducials) by a bundle fit in ball coordinates; priors: joints {}, balls {}; tracker noise model: {}",
        data.poses.len(),
        data.poses.iter().map(|p| p.balls.len()).sum::<usize>(),
        data.fiducials.len(),
        prior(a.cfg.priors.joint_sigma_mm),
        prior(a.cfg.priors.ball_sigma_mm),
        a.noise.describe()
    );
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
    let scale = a
        .cfg
        .priors
        .joint_sigma_mm
        .unwrap_or(bundle::DEFAULT_JOINT_PRIOR_SIGMA_MM);
    let obs = bundle::observability(&data, &fit.x, scale, REPORTED_DIRECTIONS)
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
    let _ = writeln!(
        s,
        "predicted accuracy of the calibrated mechanism over {} poses (+-{} mm, +-{}\"):\n  RMS (1 sigma)  {}\n  largest sigma  {}\n  expected max   {}",
        held_out.len(),
        DEFAULT_EVAL_TRANSLATION_MM,
        DEFAULT_EVAL_ROTATION_ARCSEC,
        fmt6(&pred.rms_sigma),
        fmt6(&pred.max_sigma),
        fmt6(&pred.expected_max)
    );
    if a.report {
        // Pose errors at the measured poses: FK(strokes) - pose from the balls.
        let inv = fit.registration.inverse();
        let g_nom = Geometry::<f64>::new(&nominal.params)
            .map_err(|e| crate::ground::files::describe_geometry_error(&e))?;
        let g_cal = Geometry::<f64>::new(&fit.params)
            .map_err(|e| crate::ground::files::describe_geometry_error(&e))?;
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
                    format!(
                        "pose {}: {}",
                        p.pose,
                        crate::ground::ikfk::describe_fk_error(&e)
                    )
                })?;
                out.push(pose_error(&q.pose, &measured));
            }
        }
        let before = Accuracy::from_errors(before);
        let after = Accuracy::from_errors(after);
        let noise_sigma = pose_noise(&fit, &p0, &a.noise).ok_or("pose noise singular")?;
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
            let band_t = band_label.map(|_| noise_band(&noise_sigma[..3]));
            let band_r = band_label.map(|_| noise_band(&noise_sigma[3..]));
            let panel = |what: &str, unit: &str, rot: bool, band: Option<Band>| Panel {
                caption: format!("largest |{what} error| of each pose ({unit})"),
                y_label: unit.to_string(),
                series: plot_series
                    .iter()
                    .map(|(l, acc)| Series {
                        label: l.clone(),
                        values: acc
                            .per_pose_max()
                            .iter()
                            .map(|(t, r)| if rot { *r } else { *t })
                            .collect(),
                    })
                    .collect(),
                band,
                log: false,
            };
            per_pose(
                p,
                &title,
                x_label,
                &[
                    panel("translation", "um", false, band_t),
                    panel("rotation", "arcsec", true, band_r),
                ],
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
