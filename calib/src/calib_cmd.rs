//! The calibration commands of `m2ground` (`calibrate`, `plan`, `simulate-campaign`,
//! `table3`, `bench`) as functions returning text; the binary only parses arguments
//! and writes files.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::calib::{
    calibrate, parse_measurements, CalibConfig, CalibError, CalibResult, Measurement,
};
use super::campaign::{perturbed, reached, simulate};
use super::eval::{accuracy, max_param_error_mm, random_poses, Accuracy};
use super::eval::{DEFAULT_EVAL_POSES, DEFAULT_EVAL_ROTATION_ARCSEC, DEFAULT_EVAL_TRANSLATION_MM};
use super::files::{format_geometry, read_geometry, GeometryFile};
use super::plan::{format_plan, plan_poses, PlanConfig};
use super::report::{plot_per_pose, DEFAULT_EVAL_SEED};
use m2ctl::kinematics::{Geometry, GeometryParams};
use m2ctl::sim::tracker::PoseTracker;
use m2ctl::units::{NM_PER_MM, UM_PER_MM};

/// Reads and parses a measurement file; errors are prefixed with the path.
pub fn read_measurements(path: &Path) -> Result<Vec<Measurement>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    parse_measurements(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// Pose errors at the measured poses: `FK(measured strokes, params) - measured pose`
/// (the paper's experiment scores the sampling poses this way).
pub fn measured_pose_errors(
    params: &GeometryParams,
    meas: &[Measurement],
) -> Result<Accuracy, String> {
    let g = Geometry::<f64>::new(params).map_err(|e| super::files::describe_geometry_error(&e))?;
    let mut errors = Vec::with_capacity(meas.len());
    for m in meas {
        let p = reached(&g, &m.strokes_mm, &m.pose).map_err(|e| format!("line {}: {e}", m.line))?;
        errors.push(super::eval::pose_error(&p, &m.pose));
    }
    Ok(Accuracy::from_errors(errors))
}

fn accuracy_lines(out: &mut String, label: &str, a: &Accuracy) {
    let _ = writeln!(out, "  {label:<10} max/RMS: {}", a.max_rms_cells(4));
}

/// Options of `m2ground calibrate`.
#[derive(Clone, Debug)]
pub struct CalibrateArgs {
    /// Measurement CSV.
    pub data: PathBuf,
    /// Nominal geometry file.
    pub nominal: PathBuf,
    /// Calibration settings.
    pub cfg: CalibConfig,
    /// Print the evaluation.
    pub report: bool,
    /// True geometry (simulated campaigns): adds the held-out evaluation to the report.
    pub truth: Option<PathBuf>,
    /// SVG plot of the per-pose errors before/after (with the report).
    pub plot: Option<PathBuf>,
}

/// Runs `calibrate`: returns the calibrated geometry file text and the printed summary.
pub fn run_calibrate(a: &CalibrateArgs) -> Result<(String, String), String> {
    let meas = read_measurements(&a.data)?;
    let nominal = read_geometry(&a.nominal)?;
    let r: CalibResult = calibrate(&nominal.params, &meas, &a.cfg).map_err(|e| match e {
        CalibError::Implausible(fe) => format!("{}: {fe}", a.data.display()),
        e => format!("calibration: {e}"),
    })?;
    // Nothing is written (file or plot) unless the table would pass on board.
    super::files::validate_for_flight(&r.params)
        .map_err(|e| format!("calibration result ({} solver): {e}", a.cfg.solver))?;
    let mut summary = format!(
        "calibrated {} joint coordinates from {} poses ({}), solver {}, seed {}\n{}\n",
        super::calib::N_PARAMS,
        meas.len(),
        a.data.display(),
        a.cfg.solver,
        a.cfg.seed,
        r.summary()
    );
    let id = format!(
        "cal-{}-seed{}-{}poses-rms{:.0}nm",
        a.cfg.solver,
        a.cfg.seed,
        meas.len(),
        r.rms_after_mm * NM_PER_MM
    );
    let mut provenance = vec![
        ("calibration_id".to_string(), id),
        ("solver".to_string(), a.cfg.solver.to_string()),
        ("seed".to_string(), a.cfg.seed.to_string()),
        ("data".to_string(), a.data.display().to_string()),
        ("poses".to_string(), meas.len().to_string()),
        (
            "residual_rms_um".to_string(),
            format!("{:.6}", r.rms_after_mm * UM_PER_MM),
        ),
        ("condition".to_string(), format!("{:.6e}", r.condition())),
        (
            "omega_half_width_mm".to_string(),
            a.cfg.omega_half_width_mm.to_string(),
        ),
    ];
    provenance.extend(
        nominal
            .provenance
            .iter()
            .map(|(k, v)| (format!("nominal_{k}"), v.clone())),
    );
    let text = format_geometry(
        &GeometryFile {
            params: r.params,
            provenance,
        },
        &format!(
            "Calibrated by m2ground calibrate ({} solver) from {}",
            a.cfg.solver,
            a.data.display()
        ),
    );
    if a.report {
        let before = measured_pose_errors(&nominal.params, &meas)?;
        let after = measured_pose_errors(&r.params, &meas)?;
        summary
            .push_str("pose error at the measured poses, FK(strokes) - measured (um, arcsec):\n");
        accuracy_lines(&mut summary, "nominal", &before);
        accuracy_lines(&mut summary, "calibrated", &after);
        let mut series = vec![("nominal", before), ("calibrated", after)];
        if let Some(tp) = &a.truth {
            let truth = read_geometry(tp)?;
            let targets = random_poses(
                DEFAULT_EVAL_POSES,
                DEFAULT_EVAL_TRANSLATION_MM,
                DEFAULT_EVAL_ROTATION_ARCSEC,
                DEFAULT_EVAL_SEED,
            );
            let b =
                accuracy(&nominal.params, &truth.params, &targets).map_err(|e| e.to_string())?;
            let c = accuracy(&r.params, &truth.params, &targets).map_err(|e| e.to_string())?;
            let _ = writeln!(
                summary,
                "held-out accuracy vs truth ({} random poses, +-{} mm, +-{}\"), commanding with:",
                targets.len(),
                DEFAULT_EVAL_TRANSLATION_MM,
                DEFAULT_EVAL_ROTATION_ARCSEC
            );
            accuracy_lines(&mut summary, "nominal", &b);
            accuracy_lines(&mut summary, "calibrated", &c);
            let _ = writeln!(
                summary,
                "  largest joint-coordinate error vs truth: {:.4} mm (nominal {:.4} mm)",
                max_param_error_mm(&r.params, &truth.params),
                max_param_error_mm(&nominal.params, &truth.params)
            );
            series = vec![("nominal (held-out)", b), ("calibrated (held-out)", c)];
        }
        if let Some(p) = &a.plot {
            let refs: Vec<(&str, &Accuracy)> = series.iter().map(|(l, a)| (*l, a)).collect();
            plot_per_pose(p, &refs)?;
            let _ = writeln!(summary, "plot: {}", p.display());
        }
    }
    Ok((text, summary))
}

/// Runs `plan`: the sampling plan's poses as a 6-column CSV.
pub fn run_plan(cfg: &PlanConfig) -> String {
    let poses = plan_poses(cfg);
    format_plan(
        &poses,
        &format!(
            "Calibration sampling plan: {} poses (centre: {}, cube corners: {:?} mm, axis points: {:?} mm, rotations +-{} arcsec, 8 sign patterns)",
            poses.len(),
            cfg.centre,
            cfg.cube_half_mm,
            cfg.axis_mm,
            cfg.rotation_arcsec
        ),
    )
}

/// Options of `m2ground simulate-campaign`.
#[derive(Clone, Debug)]
pub struct CampaignArgs {
    /// Nominal geometry (commands are computed with it).
    pub nominal: GeometryParams,
    /// Manufacturing error sigma (mm).
    pub sigma_mm: f64,
    /// Seed of the true geometry.
    pub geometry_seed: u64,
    /// Tracker model.
    pub tracker: PoseTracker,
    /// Seed of the tracker noise.
    pub noise_seed: u64,
    /// Sampling plan.
    pub plan: PlanConfig,
}

/// Runs `simulate-campaign`: returns (measurement CSV, true geometry file text).
pub fn run_campaign(a: &CampaignArgs) -> Result<(String, String), String> {
    let truth = perturbed(&a.nominal, a.sigma_mm, a.geometry_seed);
    let meas = simulate(
        &a.nominal,
        &truth,
        &plan_poses(&a.plan),
        &a.tracker,
        a.noise_seed,
    )
    .map_err(|e| e.to_string())?;
    let desc = format!(
        "Simulated calibration campaign: {} poses, true geometry = nominal + N(0, {} mm) (seed {}), tracker noise {} um / {} arcsec (seed {}), encoders exact",
        meas.len(),
        a.sigma_mm,
        a.geometry_seed,
        a.tracker.noise_um,
        a.tracker.noise_arcsec,
        a.noise_seed
    );
    let csv = super::calib::format_measurements(&meas, &desc);
    let truth_text = format_geometry(
        &GeometryFile {
            params: truth,
            provenance: vec![
                ("kind".into(), "simulated true geometry".into()),
                ("sigma_mm".into(), a.sigma_mm.to_string()),
                ("geometry_seed".into(), a.geometry_seed.to_string()),
            ],
        },
        "True geometry of a simulated campaign (m2ground simulate-campaign)",
    );
    Ok((csv, truth_text))
}
