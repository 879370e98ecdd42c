//! The paper's simulation comparison (its Table 3), the solver benchmark and the
//! per-pose error plot, on one simulated campaign.
//!
//! Campaign: true geometry = nominal + manufacturing errors ([`Experiment::sigma_mm`],
//! seed [`Experiment::geometry_seed`]), the sampling plan's poses commanded with nominal
//! parameters, the tracker noise of each table part. Score: held-out random poses in the
//! stroke, commanded with the calibrated parameters on the true mechanism.

use std::fmt::Write as _;
use std::path::Path;

use super::calib::cuckoo::Coordinates;
use super::calib::{calibrate, CalibConfig, CalibResult, Measurement, SolverKind};
use super::campaign::{perturbed, simulate, CampaignError, DEFAULT_MANUFACTURING_SIGMA_MM};
use super::eval::{
    accuracy, max_param_error_mm, random_poses, Accuracy, DEFAULT_EVAL_POSES,
    DEFAULT_EVAL_ROTATION_ARCSEC, DEFAULT_EVAL_TRANSLATION_MM,
};
use super::plan::{plan_poses, PlanConfig};
use m2ctl::kinematics::{GeometryParams, Pose};
use m2ctl::nominal::PROTOTYPE;
use m2ctl::sim::tracker::PoseTracker;
use m2ctl::units::UM_PER_MM;

/// Default seed of the true geometry of the table campaign.
pub const DEFAULT_GEOMETRY_SEED: u64 = 2018;
/// Default seed of the tracker noise of the table campaign.
pub const DEFAULT_NOISE_SEED: u64 = 47;
/// Default seed of the held-out evaluation poses.
pub const DEFAULT_EVAL_SEED: u64 = 518_002;
/// Default seed of the cuckoo-search solvers.
pub const DEFAULT_SOLVER_SEED: u64 = 1;

/// One simulated experiment (campaign + evaluation).
#[derive(Clone, Debug)]
pub struct Experiment {
    /// Nominal geometry (what the controller flies before calibration).
    pub nominal: GeometryParams,
    /// Manufacturing error sigma (mm).
    pub sigma_mm: f64,
    /// Seed of the true geometry.
    pub geometry_seed: u64,
    /// Seed of the tracker noise.
    pub noise_seed: u64,
    /// Sampling plan.
    pub plan: PlanConfig,
    /// Held-out poses.
    pub eval_poses: usize,
    /// Seed of the held-out poses.
    pub eval_seed: u64,
}

impl Default for Experiment {
    fn default() -> Self {
        Self {
            nominal: PROTOTYPE,
            sigma_mm: DEFAULT_MANUFACTURING_SIGMA_MM,
            geometry_seed: DEFAULT_GEOMETRY_SEED,
            noise_seed: DEFAULT_NOISE_SEED,
            plan: PlanConfig::default(),
            eval_poses: DEFAULT_EVAL_POSES,
            eval_seed: DEFAULT_EVAL_SEED,
        }
    }
}

/// A prepared experiment: truth, measurements, held-out targets.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// The true geometry.
    pub truth: GeometryParams,
    /// The campaign's measurements.
    pub meas: Vec<Measurement>,
    /// Held-out targets.
    pub targets: Vec<Pose<f64>>,
}

impl Experiment {
    /// Builds the truth, simulates the campaign with `tracker`, draws the targets.
    pub fn prepare(&self, tracker: &PoseTracker) -> Result<Prepared, CampaignError> {
        let truth = perturbed(&self.nominal, self.sigma_mm, self.geometry_seed);
        let meas = simulate(
            &self.nominal,
            &truth,
            &plan_poses(&self.plan),
            tracker,
            self.noise_seed,
        )?;
        let targets = random_poses(
            self.eval_poses,
            DEFAULT_EVAL_TRANSLATION_MM,
            DEFAULT_EVAL_ROTATION_ARCSEC,
            self.eval_seed,
        );
        Ok(Prepared {
            truth,
            meas,
            targets,
        })
    }
}

/// One table row.
#[derive(Clone, Debug)]
pub struct Row {
    /// Label.
    pub label: String,
    /// Held-out accuracy.
    pub acc: Accuracy,
    /// The calibration (None for "before").
    pub calib: Option<CalibResult>,
    /// Largest joint-coordinate error vs truth (mm).
    pub param_error_mm: f64,
}

/// Runs one solver on a prepared experiment and scores it.
pub fn run_solver(exp: &Experiment, prep: &Prepared, cfg: &CalibConfig) -> Result<Row, String> {
    let r = calibrate(&exp.nominal, &prep.meas, cfg).map_err(|e| e.to_string())?;
    let acc = accuracy(&r.params, &prep.truth, &prep.targets).map_err(|e| e.to_string())?;
    Ok(Row {
        label: cfg.solver.name().to_string(),
        param_error_mm: max_param_error_mm(&r.params, &prep.truth),
        acc,
        calib: Some(r),
    })
}

/// The "before calibration" row (commanding with nominal parameters).
pub fn before_row(exp: &Experiment, prep: &Prepared) -> Result<Row, String> {
    Ok(Row {
        label: "before".into(),
        acc: accuracy(&exp.nominal, &prep.truth, &prep.targets).map_err(|e| e.to_string())?,
        calib: None,
        param_error_mm: max_param_error_mm(&exp.nominal, &prep.truth),
    })
}

/// Formats rows as a Markdown table: max |error| per axis, RMS, residual, time.
pub fn format_rows(rows: &[Row]) -> String {
    let mut s = String::new();
    s.push_str("| solver | max x um | max y um | max z um | max alpha \" | max beta \" | max gamma \" | RMS xyz um | RMS rot \" | fit RMS um | max param err mm | time ms |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let m = &r.acc.max_abs;
        let rms_t = (r.acc.rms[..3].iter().map(|v| v * v).sum::<f64>() / 3.0).sqrt();
        let rms_r = (r.acc.rms[3..].iter().map(|v| v * v).sum::<f64>() / 3.0).sqrt();
        let (fit, time) = match &r.calib {
            Some(c) => (
                format!("{:.4}", c.rms_after_mm * UM_PER_MM),
                format!("{:.1}", c.elapsed.as_secs_f64() * 1e3),
            ),
            None => ("-".into(), "-".into()),
        };
        let _ = writeln!(
            s,
            "| {} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {} | {:.4} | {} |",
            r.label, m[0], m[1], m[2], m[3], m[4], m[5], rms_t, rms_r, fit, r.param_error_mm, time
        );
    }
    s
}

/// Settings of the table command.
#[derive(Clone, Debug)]
pub struct TableConfig {
    /// The experiment.
    pub exp: Experiment,
    /// Base calibration settings (solver replaced per row).
    pub calib: CalibConfig,
    /// Where to write the per-pose error plot (SVG), if anywhere.
    pub plot: Option<std::path::PathBuf>,
}

impl Default for TableConfig {
    fn default() -> Self {
        Self {
            exp: Experiment::default(),
            calib: CalibConfig {
                seed: DEFAULT_SOLVER_SEED,
                ..CalibConfig::default()
            },
            plot: None,
        }
    }
}

fn with_solver(base: &CalibConfig, solver: SolverKind) -> CalibConfig {
    CalibConfig {
        solver,
        ..base.clone()
    }
}

/// The rows of one tracker-noise case of the comparison: the campaign measured with
/// `tracker`, its uncalibrated row, then one row per solver of `solvers` (settings of
/// `calib` otherwise).
fn solver_rows(
    exp: &Experiment,
    tracker: &PoseTracker,
    calib: &CalibConfig,
    solvers: &[SolverKind],
) -> Result<Vec<Row>, String> {
    let prep = exp.prepare(tracker).map_err(|e| e.to_string())?;
    let mut rows = vec![before_row(exp, &prep)?];
    for &solver in solvers {
        rows.push(run_solver(exp, &prep, &with_solver(calib, solver))?);
    }
    Ok(rows)
}

/// Runs the whole comparison and returns the report text (Markdown).
pub fn table3(cfg: &TableConfig) -> Result<String, String> {
    let exp = &cfg.exp;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Campaign: {} plan poses, manufacturing sigma {} mm (seed {}), held-out {} poses within +-{} mm / +-{}\" (seed {}), Omega +-{} mm, solver seed {}, cuckoo: {} nests x {} generations, NM {} iterations on the worst {:.0} %, {} coordinates.\n",
        plan_poses(&exp.plan).len(),
        exp.sigma_mm,
        exp.geometry_seed,
        exp.eval_poses,
        DEFAULT_EVAL_TRANSLATION_MM,
        DEFAULT_EVAL_ROTATION_ARCSEC,
        exp.eval_seed,
        cfg.calib.omega_half_width_mm,
        cfg.calib.seed,
        cfg.calib.cuckoo.nests,
        cfg.calib.cuckoo.max_generations,
        cfg.calib.cuckoo.nm_iterations,
        cfg.calib.cuckoo.nm_fraction * 100.0,
        coordinates_name(cfg.calib.cuckoo.coordinates)
    );
    // Part 1: the paper's noise.
    let rows = solver_rows(
        exp,
        &PoseTracker::PAPER,
        &cfg.calib,
        &[
            SolverKind::Smcs,
            SolverKind::Improved,
            SolverKind::Lm,
            SolverKind::ImprovedLm,
        ],
    )?;
    let _ = writeln!(
        out,
        "### Tracker noise {} um / {} arcsec (the paper's Table 3)\n",
        PoseTracker::PAPER.noise_um,
        PoseTracker::PAPER.noise_arcsec
    );
    out.push_str(&format_rows(&rows));
    if let Some(path) = &cfg.plot {
        let series: Vec<(&str, &Accuracy)> = rows
            .iter()
            .filter(|r| r.label != "improved+lm")
            .map(|r| (r.label.as_str(), &r.acc))
            .collect();
        plot_per_pose(path, &series)?;
        let _ = writeln!(out, "\nPer-pose error plot: {}", path.display());
    }
    // Part 2: realistic noise, bounded vs unbounded.
    let rows = solver_rows(
        exp,
        &PoseTracker::REALISTIC,
        &cfg.calib,
        &[
            SolverKind::LmUnbounded,
            SolverKind::Lm,
            SolverKind::Improved,
        ],
    )?;
    let _ = writeln!(
        out,
        "\n### Tracker noise {} um / {} arcsec: bounded vs unbounded\n",
        PoseTracker::REALISTIC.noise_um,
        PoseTracker::REALISTIC.noise_arcsec
    );
    out.push_str(&format_rows(&rows));
    for r in rows.iter().filter_map(|r| r.calib.as_ref()) {
        let _ = writeln!(
            out,
            "- {}: condition {:.3e}, {} parameters on or outside a bound, {}",
            r.note.split(':').next().unwrap_or(""),
            r.condition(),
            r.active_bounds,
            r.note
        );
    }
    Ok(out)
}

/// Wall time of each solver on the paper-noise campaign, `repeats` runs each (the
/// minimum and mean are reported).
pub fn bench(cfg: &TableConfig, repeats: usize) -> Result<String, String> {
    let exp = &cfg.exp;
    let prep = exp
        .prepare(&PoseTracker::PAPER)
        .map_err(|e| e.to_string())?;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "| solver | poses | runs | min ms | mean ms | iterations | evaluations | held-out max um | held-out max arcsec |\n|---|---|---|---|---|---|---|---|---|"
    );
    for solver in [
        SolverKind::Lm,
        SolverKind::LmUnbounded,
        SolverKind::Smcs,
        SolverKind::Improved,
        SolverKind::ImprovedLm,
    ] {
        let c = with_solver(&cfg.calib, solver);
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..repeats.max(1) {
            let row = run_solver(exp, &prep, &c)?;
            if let Some(r) = &row.calib {
                times.push(r.elapsed.as_secs_f64() * 1e3);
            }
            last = Some(row);
        }
        let Some(row) = last else { continue };
        let Some(r) = &row.calib else { continue };
        let min = times.iter().fold(f64::INFINITY, |m, v| m.min(*v));
        let mean = times.iter().sum::<f64>() / times.len().max(1) as f64;
        let _ = writeln!(
            out,
            "| {} | {} | {} | {:.1} | {:.1} | {} | {} | {:.4} | {:.4} |",
            solver,
            prep.meas.len(),
            times.len(),
            min,
            mean,
            r.iterations,
            r.evaluations,
            row.acc.max_um(),
            row.acc.max_arcsec()
        );
    }
    Ok(out)
}

/// Writes an SVG with two panels (largest translation error um, largest rotation error
/// arcsec, per pose, log scale), one marker shape per series (no lines joining unrelated
/// poses), the legend in a strip of its own.
pub fn plot_per_pose(path: &Path, series: &[(&str, &Accuracy)]) -> Result<(), String> {
    plot_per_pose_with_floor(path, series, None)
}

/// [`plot_per_pose`] with the measurement's noise floor drawn as a band: `floor` = the
/// 1-sigma noise of one pose measurement per axis (um x3, arcsec x3); the band is where
/// the largest |error| of a pose of pure noise lands 90 % of the time.
pub fn plot_per_pose_with_floor(
    path: &Path,
    series: &[(&str, &Accuracy)],
    floor: Option<[f64; 6]>,
) -> Result<(), String> {
    use super::tracker::commands::pose_error_panels;
    use super::tracker::plots::per_pose;
    let n = series
        .iter()
        .map(|(_, a)| a.errors.len())
        .max()
        .unwrap_or(0);
    per_pose(
        path,
        &format!("Pose error per pose, {n} poses"),
        "pose",
        &pose_error_panels(series, floor.as_ref(), true),
        floor.map(|_| "measurement noise floor (90 % of pure-noise poses)"),
    )
}

/// SMCS vs the improved algorithm over solver seeds `1..=seeds` on the paper-noise
/// campaign: held-out max errors per seed and their means (a single seed is a noisy
/// comparison of two stochastic searches), in the configured search coordinates and,
/// for comparison, in the other ones (whitened vs the paper's original coordinates).
pub fn compare_cuckoo(cfg: &TableConfig, seeds: u64) -> Result<String, String> {
    let exp = &cfg.exp;
    let prep = exp
        .prepare(&PoseTracker::PAPER)
        .map_err(|e| e.to_string())?;
    let mut out = String::from(
        "| coordinates | seed | smcs max um | smcs max arcsec | smcs fit RMS um | improved max um | improved max arcsec | improved fit RMS um | improved time ms |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    let configured = cfg.calib.cuckoo.coordinates;
    let other = match configured {
        Coordinates::Whitened => Coordinates::Original,
        Coordinates::Original => Coordinates::Whitened,
    };
    for coordinates in [configured, other] {
        let name = coordinates_name(coordinates);
        let mut sums = [0.0f64; 7];
        for seed in 1..=seeds.max(1) {
            let mut cells = Vec::new();
            for solver in [SolverKind::Smcs, SolverKind::Improved] {
                let mut c = CalibConfig {
                    seed,
                    ..with_solver(&cfg.calib, solver)
                };
                c.cuckoo.coordinates = coordinates;
                let row = run_solver(exp, &prep, &c)?;
                let (fit, ms) = row
                    .calib
                    .as_ref()
                    .map(|r| (r.rms_after_mm * UM_PER_MM, r.elapsed.as_secs_f64() * 1e3))
                    .unwrap_or((0.0, 0.0));
                cells.extend([row.acc.max_um(), row.acc.max_arcsec(), fit]);
                if solver == SolverKind::Improved {
                    cells.push(ms);
                }
            }
            for (s, c) in sums.iter_mut().zip(cells.iter()) {
                *s += c;
            }
            let _ = writeln!(out, "| {name} | {seed} | {} |", compare_cells(&cells));
        }
        let n = seeds.max(1) as f64;
        let means = sums.map(|v| v / n);
        let _ = writeln!(out, "| {name} | mean | {} |", compare_cells(&means));
    }
    Ok(out)
}

/// Cells of a `compare_cuckoo` row: errors and fit RMS to 4 decimals, the time (last)
/// in whole ms.
fn compare_cells(cells: &[f64]) -> String {
    let last = cells.len().saturating_sub(1);
    let f: Vec<String> = cells
        .iter()
        .enumerate()
        .map(|(k, v)| {
            if k == last {
                format!("{v:.0}")
            } else {
                format!("{v:.4}")
            }
        })
        .collect();
    f.join(" | ")
}

/// Report name of the search coordinates.
pub fn coordinates_name(c: Coordinates) -> &'static str {
    match c {
        Coordinates::Whitened => "whitened",
        Coordinates::Original => "original",
    }
}
