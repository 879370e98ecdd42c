//! The mission story, end to end on the simulated plant (`m2ground mission`):
//!
//! 1. a mechanism with manufacturing errors (the "true" geometry) and the controller,
//!    running its real code, booted on the nominal table;
//! 2. the operator moves the mirror to a set of targets by telecommand; a simulated
//!    laser tracker measures its target balls and the ground derives where it really
//!    went (pose error before calibration; ball centres from a survey at home);
//! 3. a calibration campaign: the paper's sampling plan, each pose commanded by
//!    telecommand, the tracker's ball points and the encoder strokes (from housekeeping
//!    telemetry) recorded as a tracker point export and a stroke file;
//! 4. ground calibration from the export: the bundle fit in ball coordinates
//!    (`ground::tracker`);
//! 5. the calibrated table uploaded by telecommands (chunks, commit with CRC-32),
//!    validated on board and activated;
//! 6. the same targets again: pose error after calibration;
//! 7. thermal: the parts at +5 K, then -5 K (uniform), the mirror held at the last
//!    target; the held pose error against the pose held at the reference temperature,
//!    with the thermal compensation off, then on (TC[20,3] parameter 0x0060; the
//!    calibrated table carries the materials' nominal thermal model, the plant's truth);
//! 8. a summary table and a plot.
//!
//! Everything the controller sees arrives as framed PUS telecommands and everything the
//! ground learns comes from telemetry or the tracker, as in operations.

use std::path::PathBuf;

use indicatif::{ProgressBar, ProgressStyle};

use super::tc::{activate_command, upload_commands};
use m2calib::calib::bundle::{BundleConfig, BundleFit};
use m2calib::eval::{pose_error, random_poses, Accuracy};
use m2calib::plan::{plan_poses, PlanConfig};
use m2calib::tracker::campaign::TrackerSetup;
use m2calib::tracker::session::TrackerSession;
use m2ctl::controller::State;
use m2ctl::kinematics::{Pose, LEGS};
use m2ctl::link::tm::Verification;
use m2ctl::link::{Command, WirePose};
use m2ctl::motion::CYCLE_S;
use m2ctl::sim::drive_train::DriveTrainConfig;
use m2ctl::sim::manufacturing::perturbed;
use m2ctl::sim::thermal::{Coefficients, Profile, SensorConfig, ThermalConfig, ThermalField};
use m2ctl::sim::{Bench, Plant, PlantConfig};
use m2ctl::table::{Provenance, Table, DEFAULT_SUPERVISION};
use m2ctl::units::NM_PER_MM;

/// Most cycles one telecommand may take to complete (a move across the workspace at
/// the default 0.2 mm/s is well under this).
const MAX_CYCLES_PER_COMMAND: u32 = 200_000;
/// Times a move that ended not in position is sent again ([`Mission::command`]).
const MOVE_RETRIES: usize = 2;
/// How [`Mission::command_once`] names a move that ended not in position (0x070F).
const NOT_IN_POSITION: &str = "code 0x070f";
/// Cycles to wait after arrival before a measurement (drives settled, encoders fresh).
const SETTLE_CYCLES: u32 = 20;
/// Table ID of the uploaded calibrated table.
const CALIBRATED_TABLE_ID: u32 = 1;
/// The thermal phase's uniform swing (K): issue 22's +-5 K.
const THERMAL_SWING_K: [f64; 2] = [5.0, -5.0];
/// Cycles the sensors take to give their first means (16 readings at 10 Hz), with margin.
const SENSOR_MEAN_CYCLES: u32 = 3_000;
/// Cycles the compensation is given to follow, and to ramp back when disabled: about
/// 4 um of offset at +-5 K in steps of 0.5 um, each step followed by its fine
/// positioning on the realistic drive train (up to 1.2 s to be in position: a step
/// comes every one or two seconds), with a wide margin: two minutes.
const COMPENSATION_CYCLES: u32 = 120_000;
/// Provenance tag of the calibrated table (16 ASCII bytes).
const PROVENANCE_TAG: [u8; 16] = *b"MISSION-DEMO-IMP";

/// Settings of the mission demo.
#[derive(Clone, Debug)]
pub struct MissionConfig {
    /// Seed of the manufacturing errors, the tracker noise, the targets and the solver.
    pub seed: u64,
    /// Standard deviation of each joint coordinate's manufacturing error (mm).
    pub manufacturing_sigma_mm: f64,
    /// The laser tracker, its target balls and the base fiducials.
    pub tracker: TrackerSetup,
    /// Number of operator targets.
    pub n_targets: usize,
    /// Targets are drawn uniformly within +- this translation (mm)...
    pub target_translation_mm: f64,
    /// ...and +- this rotation (arcsec).
    pub target_rotation_arcsec: f64,
    /// The calibration sampling plan.
    pub plan: PlanConfig,
    /// Bundle-fit settings.
    pub bundle: BundleConfig,
    /// Show progress bars.
    pub progress: bool,
    /// Write the per-target error plot here (SVG).
    pub plot: Option<PathBuf>,
    /// Between the drives and the sliders: by default the realistic drive train
    /// (`m2ctl::sim::drive_train`: microsteps, backlash, lead error, stiction,
    /// settling), which the controller's fine positioning corrects;
    /// [`DriveTrainConfig::ideal`] for sliders exactly where their drives are.
    pub drive_train: DriveTrainConfig,
}

/// Default number of operator targets.
pub const DEFAULT_TARGETS: usize = 20;
/// Default target range in translation (mm): the paper's +-1 mm stroke.
pub const DEFAULT_TARGET_TRANSLATION_MM: f64 = 1.0;
/// Default target range in rotation (arcsec): the paper's +-1 arcmin.
pub const DEFAULT_TARGET_ROTATION_ARCSEC: f64 = 60.0;
/// Default manufacturing error (mm).
pub const DEFAULT_MANUFACTURING_SIGMA_MM: f64 = m2ctl::sim::manufacturing::DEFAULT_JOINT_SIGMA_MM;

impl Default for MissionConfig {
    fn default() -> Self {
        Self {
            seed: 1,
            manufacturing_sigma_mm: DEFAULT_MANUFACTURING_SIGMA_MM,
            tracker: TrackerSetup {
                noise: m2ctl::sim::tracker::TrackerNoise::PAPER,
                ..TrackerSetup::default()
            },
            n_targets: DEFAULT_TARGETS,
            target_translation_mm: DEFAULT_TARGET_TRANSLATION_MM,
            target_rotation_arcsec: DEFAULT_TARGET_ROTATION_ARCSEC,
            plan: PlanConfig::default(),
            bundle: BundleConfig::with_priors(
                m2calib::calib::bundle::DEFAULT_JOINT_PRIOR_SIGMA_MM,
                m2calib::tracker::files::DEFAULT_BALL_SIGMA_MM,
            ),
            progress: true,
            plot: None,
            drive_train: DriveTrainConfig::realistic(),
        }
    }
}

/// What the mission measured.
#[derive(Clone, Debug)]
pub struct MissionReport {
    /// Tracker-measured pose error at the targets with the nominal table.
    pub before: Accuracy,
    /// The same targets with the calibrated table.
    pub after: Accuracy,
    /// The calibration run.
    pub calib: BundleFit,
    /// Calibration measurements taken.
    pub n_measurements: usize,
    /// Telecommands sent and telemetry packets received.
    pub tc_sent: usize,
    /// Telemetry packets received.
    pub tm_received: usize,
    /// Simulated time (s).
    pub sim_time_s: f64,
    /// CRC-32 of the table that became active.
    pub table_crc32: u32,
    /// The thermal phase's largest held pose error with the compensation off:
    /// translation (um) and rotation (arcsec) norms.
    pub thermal_off: HeldError,
    /// ... and on.
    pub thermal_on: HeldError,
}

/// A held pose error: translation norm (um) and rotation norm (arcsec).
pub type HeldError = (f64, f64);

/// Translation (um) and rotation (arcsec) norms of `a - b` (`pose_error`'s axes).
fn held_error(a: &Pose<f64>, b: &Pose<f64>) -> HeldError {
    let e = pose_error(a, b);
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    (norm(&e[..3]), norm(&e[3..]))
}

/// The larger of two (um, arcsec) pairs, component by component.
fn worse(a: HeldError, b: HeldError) -> HeldError {
    (a.0.max(b.0), a.1.max(b.1))
}

/// The bench with the mission's helpers.
struct Mission {
    bench: Bench,
}

impl Mission {
    /// Sends a telecommand and runs until its completion report (success or failure).
    /// A move that ends not in position (0x070F) is sent again, up to
    /// [`MOVE_RETRIES`] times: the operator's procedure (docs/icd.md section 3: the next
    /// move to the same target corrects what is left).
    fn command(&mut self, cmd: &Command) -> Result<(), String> {
        let mut result = self.command_once(cmd);
        let mut retries = 0;
        while matches!(&result, Err(e) if e.contains(NOT_IN_POSITION)) && retries < MOVE_RETRIES {
            retries += 1;
            result = self.command_once(cmd);
        }
        result
    }

    fn command_once(&mut self, cmd: &Command) -> Result<(), String> {
        let reps = self.bench.command(cmd, MAX_CYCLES_PER_COMMAND);
        for v in &reps {
            match v {
                Verification::CompletionSuccess => return Ok(()),
                Verification::AcceptanceFailure { code, data }
                | Verification::StartFailure { code, data }
                | Verification::CompletionFailure { code, data } => {
                    return Err(format!("{cmd:?} failed: code {code:#06x} data {data:#x}"))
                }
                _ => {}
            }
        }
        Err(format!(
            "{cmd:?}: no completion after {MAX_CYCLES_PER_COMMAND} cycles"
        ))
    }

    fn settle(&mut self) {
        self.bench.run(SETTLE_CYCLES);
    }

    fn move_to(&mut self, target: &Pose<f64>) -> Result<(), String> {
        self.command(&Command::MoveAbsolute(WirePose::from_pose(target)))?;
        self.settle();
        if self.bench.ctl.state() != State::Idle {
            return Err(format!(
                "not idle after a move: {:?}",
                self.bench.ctl.state()
            ));
        }
        Ok(())
    }

    /// Strokes from a housekeeping report (what the ground knows of the encoders).
    fn strokes_from_hk(&mut self) -> Result<[f64; LEGS], String> {
        self.command(&Command::HousekeepingOneShot)?;
        let hk = self.bench.st.last_hk().ok_or("no housekeeping received")?;
        Ok(hk.encoders_nm.map(|v| f64::from(v) / NM_PER_MM))
    }

    /// Step 7: the parts at each of [`THERMAL_SWING_K`] in turn; the largest held pose
    /// error with the compensation off and on, against the pose held now (at the
    /// reference temperature). The compensation is enabled and disabled by TC[20,3],
    /// and ramps back to zero before the next swing.
    fn thermal_swing(
        &mut self,
        truth: &m2ctl::kinematics::geometry::GeometryParams,
        seed: u64,
    ) -> Result<(HeldError, HeldError), String> {
        let reference = self.true_pose()?;
        let (mut off, mut on) = ((0.0, 0.0), (0.0, 0.0));
        for dt_k in THERMAL_SWING_K {
            let cfg = ThermalConfig {
                profile: Profile {
                    mean_c: m2ctl::sim::thermal::REFERENCE_C + dt_k,
                    ..Profile::REFERENCE
                },
                truth: Coefficients::NOMINAL,
                sensors: SensorConfig::drawn(seed),
            };
            let field = ThermalField::new(cfg, truth).map_err(|e| format!("thermal: {e:?}"))?;
            self.bench.plant.with(|p| *p.thermal_mut() = field);
            self.bench.run(SENSOR_MEAN_CYCLES);
            off = worse(off, held_error(&self.true_pose()?, &reference));
            self.set_compensation(true)?;
            self.bench.run(COMPENSATION_CYCLES);
            on = worse(on, held_error(&self.true_pose()?, &reference));
            self.set_compensation(false)?;
            self.bench.run(COMPENSATION_CYCLES);
        }
        Ok((off, on))
    }

    /// TC[20,3]: the thermal compensation on or off (parameter 0x0060).
    fn set_compensation(&mut self, on: bool) -> Result<(), String> {
        use m2ctl::controller::params::{index, PARAMETERS};
        let id = PARAMETERS[index::THERMAL_ENABLE].id;
        let values = m2ctl::link::ParameterValues::new(&[(id, i32::from(on))])
            .map_err(|e| format!("{e:?}"))?;
        self.command(&Command::SetParameters(values))
    }

    fn true_pose(&mut self) -> Result<Pose<f64>, String> {
        self.bench
            .plant
            .with(|p| p.true_pose())
            .map_err(|e| format!("true pose: {e:?}"))
    }
}

fn bar(show: bool, len: u64, msg: &'static str) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template("{msg:<34} [{bar:30}] {pos}/{len} {elapsed}") {
        pb.set_style(style.progress_chars("=> "));
    }
    pb.set_message(msg);
    pb
}

/// Moves to each target and returns the tracker-measured errors.
fn visit_targets(
    m: &mut Mission,
    targets: &[Pose<f64>],
    tracker: &mut TrackerSession,
    pb: &ProgressBar,
) -> Result<Accuracy, String> {
    let mut errors = Vec::with_capacity(targets.len());
    for t in targets {
        m.move_to(t)?;
        let truth = m.true_pose()?;
        errors.push(pose_error(&tracker.measure_pose(&truth)?, t));
        pb.inc(1);
    }
    pb.finish();
    Ok(Accuracy::from_errors(errors))
}

/// Runs the whole story; `log` receives the narrative lines.
pub fn run_mission(
    cfg: &MissionConfig,
    log: &mut dyn FnMut(&str),
) -> Result<MissionReport, String> {
    let nominal = Table::nominal();
    let nominal_params = nominal.geometry_params();
    let truth = perturbed(&nominal_params, cfg.manufacturing_sigma_mm, cfg.seed);
    log(&format!(
        "1. mechanism: nominal prototype with manufacturing errors (sigma {} mm, seed {}), {} drive train; controller booted on the nominal table",
        cfg.manufacturing_sigma_mm,
        cfg.seed,
        if cfg.drive_train == DriveTrainConfig::ideal() { "ideal" } else { "realistic" }
    ));
    let plant = Plant::new(
        &truth,
        PlantConfig {
            seed: cfg.seed,
            ..PlantConfig::default()
        },
    )
    .map_err(|e| format!("true geometry: {e:?}"))?
    .with_drive_train(cfg.drive_train)
    .map_err(|e| format!("drive train: {e:?}"))?;
    let mut m = Mission {
        bench: Bench::with_plant(plant),
    };
    m.bench.tick();
    let mut tracker = TrackerSession::new(&cfg.tracker, &nominal_params.p0_mm, cfg.seed);
    let home = m.true_pose()?;
    tracker.survey_home(&home)?;
    let targets = random_poses(
        cfg.n_targets,
        cfg.target_translation_mm,
        cfg.target_rotation_arcsec,
        cfg.seed.wrapping_add(1),
    );

    let pb = bar(
        cfg.progress,
        targets.len() as u64,
        "2. targets, nominal table",
    );
    let before = visit_targets(&mut m, &targets, &mut tracker, &pb)?;
    log(&format!(
        "2. {} targets with the nominal table: max error {:.3} um, {:.3} arcsec (tracker: {})",
        targets.len(),
        before.max_um(),
        before.max_arcsec(),
        cfg.tracker.noise.describe()
    ));

    let plan = plan_poses(&cfg.plan);
    let pb = bar(cfg.progress, plan.len() as u64, "3. calibration campaign");
    for p in &plan {
        m.move_to(p)?;
        let strokes_mm = m.strokes_from_hk()?;
        let truth_pose = m.true_pose()?;
        tracker.record(&truth_pose, strokes_mm);
        pb.inc(1);
    }
    pb.finish();
    log(&format!(
        "3. campaign: {} poses of the paper's sampling plan, tracker ball points + encoder strokes from housekeeping",
        tracker.poses()
    ));

    let calib = tracker.calibrate(&nominal_params, &cfg.bundle)?.clone();
    log(&format!(
        "4. calibration from the tracker export: {}",
        tracker.summary()
    ));

    let mut table = Table::from_geometry(
        &calib.params,
        CALIBRATED_TABLE_ID,
        Provenance {
            calibration_id: u32::try_from(cfg.seed & u64::from(u32::MAX)).unwrap_or(0),
            tag: PROVENANCE_TAG,
        },
        DEFAULT_SUPERVISION,
    )
    .map_err(|e| format!("table: {e:?}"))?;
    // The materials' nominal thermal model (the plant's truth here; the thermal
    // calibration, `m2calib::thermal`, fits a mechanism's own).
    table.thermal = Coefficients::NOMINAL.model();
    let upload = upload_commands(&table)?;
    for cmd in &upload {
        m.command(cmd)?;
    }
    m.command(&activate_command(&table))?;
    let hk_table = {
        m.command(&Command::HousekeepingOneShot)?;
        m.bench
            .st
            .last_hk()
            .map(|h| (h.active_table_id, h.active_table_crc32))
    };
    if hk_table != Some((CALIBRATED_TABLE_ID, table.crc32())) {
        return Err(format!("the calibrated table is not active: {hk_table:?}"));
    }
    log(&format!(
        "5. table {} uploaded in {} chunks, committed (CRC-32 {:#010x}), validated on board, activated",
        CALIBRATED_TABLE_ID,
        upload.len() - 1,
        table.crc32()
    ));

    let pb = bar(
        cfg.progress,
        targets.len() as u64,
        "6. targets, calibrated table",
    );
    let after = visit_targets(&mut m, &targets, &mut tracker, &pb)?;
    log(&format!(
        "6. the same targets with the calibrated table: max error {:.3} um, {:.3} arcsec",
        after.max_um(),
        after.max_arcsec()
    ));
    log(&format!("   {}", tracker.verification_note(&targets)));
    let (thermal_off, thermal_on) = m.thermal_swing(&truth, cfg.seed)?;
    log(&format!(
        "7. thermal, +-5 K uniform, held at the last target: compensation off {:.3} um / {:.3} arcsec, on {:.3} um / {:.3} arcsec",
        thermal_off.0, thermal_off.1, thermal_on.0, thermal_on.1
    ));
    if m.bench.st.bad_frames != 0 {
        return Err(format!(
            "{} telemetry frames did not parse",
            m.bench.st.bad_frames
        ));
    }
    if let Some(path) = &cfg.plot {
        m2calib::report::plot_per_pose_with_floor(
            path,
            &[("nominal table", &before), ("calibrated table", &after)],
            tracker.pose_noise_sigma(),
        )?;
        log(&format!("8. plot: {}", path.display()));
    }
    Ok(MissionReport {
        before,
        after,
        calib,
        n_measurements: tracker.poses(),
        tc_sent: m.bench.st.tc_sent,
        tm_received: m.bench.st.log.len(),
        sim_time_s: m.bench.cycles as f64 * f64::from(CYCLE_S),
        table_crc32: table.crc32(),
        thermal_off,
        thermal_on,
    })
}

/// The summary table: max and RMS error per axis before and after.
pub fn format_summary(r: &MissionReport) -> String {
    let mut s = String::new();
    s.push_str("| table | | x um | y um | z um | alpha arcsec | beta arcsec | gamma arcsec |\n");
    s.push_str("|---|---|---|---|---|---|---|---|\n");
    for (name, a) in [("nominal", &r.before), ("calibrated", &r.after)] {
        for (what, v) in [("max", &a.max_abs), ("RMS", &a.rms)] {
            s.push_str(&format!(
                "| {name} | {what} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} |\n",
                v[0], v[1], v[2], v[3], v[4], v[5]
            ));
        }
    }
    s.push_str(&format!(
        "\nThermal, +-5 K uniform, held pose error: compensation off {:.3} um / {:.3} arcsec, on {:.3} um / {:.3} arcsec\n",
        r.thermal_off.0, r.thermal_off.1, r.thermal_on.0, r.thermal_on.1
    ));
    s.push_str(&format!(
        "\n{} calibration poses, {} telecommands, {} telemetry packets, {:.1} s of simulated time\n",
        r.n_measurements, r.tc_sent, r.tm_received, r.sim_time_s
    ));
    s
}
