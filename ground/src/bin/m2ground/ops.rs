//! Operations: the subcommands an operator runs on the real mechanism or to rehearse
//! on the simulated one (kinematics, the sampling plan, simulated campaigns as input of
//! `calibrate`, calibration, telecommands, the mission story, the Yamcs gateway, the
//! mission database and the ICD's generated tables), and the argument groups they
//! share with the study ([`SolverCli`], [`TrackerCli`]).

use std::path::PathBuf;

use clap::Subcommand;
use m2calib::calib::{cuckoo::CuckooConfig, CalibConfig, SolverKind};
use m2calib::calib_cmd::{run_calibrate, run_campaign, run_plan, CalibrateArgs, CampaignArgs};
use m2calib::campaign::DEFAULT_MANUFACTURING_SIGMA_MM;
use m2calib::ikfk::{run_file, IkFk};
use m2calib::plan::{PlanConfig, DEFAULT_AXIS_MM, DEFAULT_CUBE_HALF_MM, DEFAULT_ROTATION_ARCSEC};
use m2ctl::link::tc::SEQ_COUNT_MASK;
use m2ctl::link::AckFlags;
use m2ctl::sim::tracker::PoseTracker;
use m2ground::tc::{
    command_from_args, run_tc, schedule_from_args, telecommand_list, upload_procedure, TcOutput,
    TcSequencer,
};

#[derive(clap::Args)]
#[group(multiple = false)]
pub(crate) struct IcdTablesCli {
    /// Exit 1 with a diff if this document's generated blocks differ from the code.
    #[arg(long, value_name = "ICD")]
    check: Option<PathBuf>,
    /// Rewrite this document's generated blocks from the code.
    #[arg(long, value_name = "ICD")]
    write: Option<PathBuf>,
}

/// `m2ground icd-tables`: Ok(true) when the document is (now) as generated.
pub(crate) fn icd_tables_cmd(a: &IcdTablesCli) -> Result<bool, String> {
    use m2ground::icd;
    let read =
        |p: &PathBuf| std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()));
    match (&a.check, &a.write) {
        (Some(p), _) => {
            let drift = icd::drift(&read(p)?).map_err(|e| format!("{}: {e}", p.display()))?;
            if drift.is_empty() {
                return Ok(true);
            }
            eprint!("{}", icd::drift_report(&p.display().to_string(), &drift));
            Ok(false)
        }
        (None, Some(p)) => {
            let doc = read(p)?;
            let new = icd::regenerate(&doc).map_err(|e| format!("{}: {e}", p.display()))?;
            if new != doc {
                std::fs::write(p, &new).map_err(|e| format!("{}: {e}", p.display()))?;
                eprintln!("{}: generated tables rewritten", p.display());
            }
            Ok(true)
        }
        (None, None) => {
            for b in icd::blocks()? {
                println!(
                    "{}\n{}{}\n",
                    icd::begin_marker(b.name),
                    b.text,
                    icd::end_marker(b.name)
                );
            }
            Ok(true)
        }
    }
}

#[derive(clap::Args)]
pub(crate) struct MissionCli {
    /// Seed of the manufacturing errors, tracker noise, targets and solver.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Number of operator targets.
    #[arg(long, default_value_t = m2ground::mission::DEFAULT_TARGETS)]
    targets: usize,
    /// Manufacturing error of each joint coordinate (mm, standard deviation).
    #[arg(long, default_value_t = m2ground::mission::DEFAULT_MANUFACTURING_SIGMA_MM)]
    sigma_mm: f64,
    /// Laser tracker measuring the target balls: "paper" (0.07 um per point, the
    /// paper's ~0.1" per pose) or "realistic" (the +-(15 um + 6 um/m) class, 2.5 m away).
    #[arg(long, default_value = "paper")]
    tracker: String,
    /// Write the per-target error plot (SVG) here.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// No progress bars.
    #[arg(long)]
    quiet: bool,
    /// Sliders exactly where their drives are (the default is the realistic drive
    /// train: microsteps, backlash, lead error, stiction, settling).
    #[arg(long)]
    ideal_plant: bool,
}

pub(crate) fn mission_cmd(a: &MissionCli) -> Result<(), String> {
    use m2calib::tracker::campaign::{noise_preset, TrackerSetup};
    use m2ground::mission::{format_summary, run_mission, MissionConfig};
    let noise = match a.tracker.as_str() {
        "paper" => noise_preset("paper"),
        "realistic" => noise_preset("class15+6"),
        _ => None,
    }
    .ok_or_else(|| {
        format!(
            "--tracker: '{}' is neither 'paper' nor 'realistic'",
            a.tracker
        )
    })?;
    let cfg = MissionConfig {
        seed: a.seed,
        n_targets: a.targets,
        manufacturing_sigma_mm: a.sigma_mm,
        tracker: TrackerSetup {
            noise,
            ..TrackerSetup::default()
        },
        plot: a.plot.clone(),
        progress: !a.quiet,
        drive_train: if a.ideal_plant {
            m2ctl::sim::drive_train::DriveTrainConfig::ideal()
        } else {
            m2ctl::sim::drive_train::DriveTrainConfig::realistic()
        },
        ..MissionConfig::default()
    };
    let report = run_mission(&cfg, &mut |line: &str| println!("{line}"))?;
    println!();
    print!("{}", format_summary(&report));
    Ok(())
}

#[derive(clap::Args)]
pub(crate) struct GatewayCli {
    /// The controller's byte stream: unix:PATH (QEMU UART socket), tcp:HOST:PORT, or a
    /// serial device path (configured first: stty -F DEV 115200 raw -echo).
    #[arg(long)]
    uart: String,
    /// Address Yamcs' TcpTcTmDataLink connects to.
    #[arg(long, default_value = "127.0.0.1:10015")]
    listen: String,
    /// Yamcs' time-correlation URL (http://127.0.0.1:8090/api/tco/m2/tco0/coefficients);
    /// without it Yamcs stamps packets with their reception time.
    #[arg(long)]
    tco_url: Option<String>,
    /// Yamcs' event URL (http://127.0.0.1:8090/api/archive/m2/events): every TM[5,x] is
    /// posted there as a Yamcs event, its text named by the mission database.
    #[arg(long)]
    events_url: Option<String>,
    /// Yamcs' parameter URL
    /// (http://127.0.0.1:8090/api/processors/m2/realtime/parameters:batchSet): the
    /// link-health parameters (counters, time-correlation residual) are set there.
    #[arg(long)]
    parameters_url: Option<String>,
    /// Publish the link-health parameters every N seconds.
    #[arg(long, default_value_t = 2)]
    health_s: u64,
    /// Seconds to wait for the controller's stream to appear.
    #[arg(long, default_value_t = 30)]
    wait_s: u64,
    /// Print the counters every N seconds (0: only at the end).
    #[arg(long, default_value_t = 10)]
    stats_s: u64,
}

pub(crate) fn gateway_cmd(a: &GatewayCli) -> Result<(), String> {
    use m2ground::gateway::{run, Options, Stats, Uart, DEFAULT_BACKLOG_PACKETS};
    use std::sync::{atomic::AtomicBool, Arc};
    use std::time::Duration;
    let listener =
        std::net::TcpListener::bind(&a.listen).map_err(|e| format!("{}: {e}", a.listen))?;
    let uart = Uart::parse(&a.uart);
    let (rx, tx) = uart.open(Duration::from_secs(a.wait_s))?;
    eprintln!(
        "gateway: controller {uart:?} <-> Yamcs on {}{}",
        a.listen,
        a.tco_url
            .as_ref()
            .map(|u| format!(
                ", time correlation -> {}",
                m2ground::gateway::without_user(u)
            ))
            .unwrap_or_default()
    );
    let options = Options {
        tco_url: a.tco_url.clone(),
        events_url: a.events_url.clone(),
        backlog: DEFAULT_BACKLOG_PACKETS,
        stats_every: (a.stats_s > 0).then(|| Duration::from_secs(a.stats_s)),
        parameters_url: a.parameters_url.clone(),
        health_every: Duration::from_secs(a.health_s),
    };
    run(
        listener,
        rx,
        tx,
        &options,
        Arc::new(Stats::default()),
        Arc::new(AtomicBool::new(false)),
    )
}

#[derive(clap::Args)]
pub(crate) struct TcCli {
    /// Sequence count of the first telecommand (14 bits: 0..=16383); later ones count up.
    #[arg(long, default_value_t = 0, global = true,
          value_parser = clap::value_parser!(u16).range(0..=i64::from(SEQ_COUNT_MASK)))]
    seq: u16,
    /// Source ID in the PUS secondary header.
    #[arg(long, default_value_t = 0, global = true)]
    source_id: u16,
    /// Acknowledgement flags (4 bits, 0..=15: acceptance, start, progress, completion).
    #[arg(long, default_value_t = 0b1111, global = true,
          value_parser = clap::value_parser!(u8).range(0..=i64::from(AckFlags::ALL.0)))]
    ack: u8,
    /// Write raw frames back to back to this file instead of hex lines on stdout.
    #[arg(long, global = true)]
    out: Option<PathBuf>,
    /// Hex lines into --out instead of binary.
    #[arg(long, global = true)]
    hex: bool,
    /// Bare PUS packets, without the COBS framing.
    #[arg(long, global = true)]
    unframed: bool,
    #[command(subcommand)]
    what: TcWhat,
}

#[derive(Subcommand)]
enum TcWhat {
    /// The telecommands of the mission database with their arguments, units and ranges.
    List,
    /// The upload procedure: TC[6,2] chunks of the table built from a geometry file
    /// (validated first), then TC[8,1] commit (and activate).
    Upload {
        /// Calibrated geometry file (with [limits]).
        geometry: PathBuf,
        /// Table ID.
        #[arg(long, default_value_t = 1)]
        table_id: u32,
        /// Calibration ID (default: CRC-32 of [provenance] calibration_id).
        #[arg(long)]
        calibration_id: Option<u32>,
        /// Also activate it (TC[8,1] activate with its ID and CRC) after the commit.
        #[arg(long)]
        activate: bool,
    },
    /// Any telecommand of the mission database by name, arguments as name=value in
    /// engineering units (`move-absolute x=1.5 rx=-2`; `m2ground tc list`), each checked
    /// against the controller's range; or `schedule at=SECONDS NAME [arg=value ...]`
    /// (SCHEDULE_INSERT_ACTIVITY, TC[11,4]: the named telecommand, numbered first,
    /// released at that on-board time).
    #[command(external_subcommand)]
    Named(Vec<String>),
}

impl TcWhat {
    /// The telecommands to send; a schedule insert numbers its embedded telecommand
    /// with `seq` first.
    fn commands(&self, seq: &mut TcSequencer) -> Result<Vec<m2ctl::link::Command>, String> {
        match self {
            TcWhat::List => Ok(Vec::new()),
            TcWhat::Upload {
                geometry,
                table_id,
                calibration_id,
                activate,
            } => upload_procedure(geometry, *table_id, *calibration_id, *activate),
            TcWhat::Named(words) => {
                let (name, args) = words.split_first().ok_or("no telecommand named")?;
                if name == "schedule" {
                    let (insert, id) = schedule_from_args(args, seq)?;
                    eprintln!(
                        "scheduled telecommand: request ID {:04x}{:04x} (sequence count {})",
                        id.packet_id,
                        id.sequence_control,
                        id.seq_count()
                    );
                    return Ok(vec![insert]);
                }
                Ok(vec![command_from_args(name, args)?])
            }
        }
    }
}

pub(crate) fn tc_cmd(a: &TcCli) -> Result<(), String> {
    let mut seq = TcSequencer::new(a.seq);
    seq.source_id = a.source_id;
    seq.ack = AckFlags(a.ack);
    let output = if a.out.is_some() && !a.hex {
        TcOutput::Binary
    } else {
        TcOutput::HexLines
    };
    if matches!(a.what, TcWhat::List) {
        print!("{}", telecommand_list());
        return Ok(());
    }
    let commands = a.what.commands(&mut seq)?;
    let bytes = run_tc(&commands, &mut seq, output, a.unframed)?;
    match &a.out {
        Some(p) => std::fs::write(p, bytes).map_err(|e| format!("{}: {e}", p.display())),
        None => {
            print!("{}", String::from_utf8_lossy(&bytes));
            Ok(())
        }
    }
}

#[derive(clap::Args)]
pub(crate) struct SolverCli {
    /// Half-width of the feasible box Omega around nominal (mm).
    #[arg(long, default_value_t = m2calib::calib::DEFAULT_OMEGA_HALF_WIDTH_MM)]
    omega_mm: f64,
    /// Seed of the stochastic solvers.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Cuckoo search: number of nests.
    #[arg(long, default_value_t = m2calib::calib::cuckoo::DEFAULT_NESTS)]
    nests: usize,
    /// Cuckoo search: generation budget T_max.
    #[arg(long, default_value_t = m2calib::calib::cuckoo::DEFAULT_MAX_GENERATIONS)]
    generations: usize,
    /// Cuckoo search: Nelder-Mead iterations per refined nest per generation.
    #[arg(long, default_value_t = m2calib::calib::cuckoo::DEFAULT_NM_ITERATIONS)]
    nm_iterations: usize,
    /// LM: assumed spread of the true joints about nominal (mm).
    #[arg(long, default_value_t = m2calib::calib::lm::DEFAULT_PRIOR_SIGMA_MM)]
    prior_sigma_mm: f64,
    /// Cuckoo search coordinates: "whitened" (default, our preconditioning) or
    /// "original" (the paper's joint coordinates, exactly as the seed notes describe).
    #[arg(long, value_enum, default_value_t = CoordArg::Whitened)]
    coordinates: CoordArg,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// Search coordinates of the cuckoo-search solvers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum CoordArg {
    /// Jacobian-whitened coordinates (our preconditioning; the default).
    Whitened,
    /// The paper's joint coordinates.
    Original,
}

impl SolverCli {
    pub(crate) fn config(&self, solver: SolverKind) -> CalibConfig {
        let mut c = CalibConfig {
            solver,
            omega_half_width_mm: self.omega_mm,
            seed: self.seed,
            cuckoo: CuckooConfig {
                nests: self.nests,
                max_generations: self.generations,
                nm_iterations: self.nm_iterations,
                coordinates: match self.coordinates {
                    CoordArg::Original => m2calib::calib::cuckoo::Coordinates::Original,
                    CoordArg::Whitened => m2calib::calib::cuckoo::Coordinates::Whitened,
                },
                ..CuckooConfig::default()
            },
            progress: !self.quiet,
            ..CalibConfig::default()
        };
        c.lm.prior_sigma_mm = self.prior_sigma_mm;
        c
    }
}

/// The laser tracker of the tracker path.
#[derive(clap::Args, Clone)]
pub(crate) struct TrackerCli {
    /// Tracker noise preset: class15+6 (the +-(15 um + 6 um/m) class), iso15 (isotropic
    /// 15 um), paper (0.07 um, the paper's ~0.1" per pose), perfect.
    #[arg(long, default_value = "class15+6")]
    tracker: String,
    /// Multiply every sigma of the preset (0.1: a tracker ten times better).
    #[arg(long, default_value_t = 1.0)]
    tracker_scale: f64,
    /// Tracker distance from the mechanism (m; simulation only).
    #[arg(long, default_value_t = m2ctl::sim::tracker::DEFAULT_TRACKER_DISTANCE_MM / m2ctl::units::MM_PER_M)]
    distance_m: f64,
    /// Distance of the target balls from the platform axis (mm; simulation only).
    #[arg(long, default_value_t = m2calib::tracker::files::DEFAULT_BALL_RADIUS_MM)]
    ball_radius_mm: f64,
}

impl TrackerCli {
    fn noise(&self) -> Result<m2ctl::sim::tracker::TrackerNoise, String> {
        use m2calib::tracker::campaign::{noise_preset, NOISE_PRESETS};
        let n = noise_preset(&self.tracker).ok_or_else(|| {
            format!(
                "--tracker: '{}' is not one of {}",
                self.tracker,
                NOISE_PRESETS.join(", ")
            )
        })?;
        if !(self.tracker_scale.is_finite() && self.tracker_scale >= 0.0) {
            return Err("--tracker-scale must be a non-negative number".into());
        }
        Ok(n.scaled(self.tracker_scale))
    }

    pub(crate) fn setup(&self) -> Result<m2calib::tracker::campaign::TrackerSetup, String> {
        if !(self.distance_m > 0.5 && self.distance_m < 40.0) {
            return Err("--distance-m must be between 0.5 and 40 m".into());
        }
        if !(self.ball_radius_mm >= 20.0 && self.ball_radius_mm <= 1000.0) {
            return Err("--ball-radius-mm must be between 20 and 1000 mm".into());
        }
        let mut s = m2calib::tracker::campaign::TrackerSetup {
            noise: self.noise()?,
            targets: m2calib::tracker::files::TargetFile::with_ball_radius(self.ball_radius_mm),
            ..Default::default()
        };
        s.placement.distance_mm = self.distance_m * m2ctl::units::MM_PER_M;
        Ok(s)
    }
}

#[derive(clap::Args)]
pub(crate) struct SimulateTrackerCli {
    #[command(flatten)]
    tracker: TrackerCli,
    /// Output directory (created).
    #[arg(long)]
    out_dir: PathBuf,
    /// Campaign number (seeds of the truth, the scene and the noise).
    #[arg(long, default_value_t = 1)]
    campaign: u64,
    /// True joints: gauss:SIGMA_MM or uniform:HALF_MM.
    #[arg(long, default_value = "gauss:0.1")]
    truth: String,
    /// Plan poses (6-column pose CSV, e.g. from `plan` or `tracker-plan --out`); default:
    /// the paper's 120 poses.
    #[arg(long)]
    plan: Option<PathBuf>,
}

#[derive(clap::Args)]
pub(crate) struct CalibrateCli {
    /// Measurement CSV (12 columns: pose mm/arcsec, strokes mm): the idealised pose path.
    #[arg(long, required_unless_present = "points", conflicts_with = "points")]
    data: Option<PathBuf>,
    /// Tracker point export (the tracker path; with --strokes and --targets).
    #[arg(long, requires_all = ["strokes", "targets"])]
    points: Option<PathBuf>,
    /// Encoder strokes per pose (tracker path).
    #[arg(long)]
    strokes: Option<PathBuf>,
    /// Target balls and fiducials (tracker path).
    #[arg(long)]
    targets: Option<PathBuf>,
    #[command(flatten)]
    tracker: TrackerCli,
    /// Tracker path: prior spread of the joints (mm); default: estimated from the data.
    #[arg(long)]
    joint_prior_mm: Option<f64>,
    /// Tracker path: prior spread of the balls (mm); default: estimated from the data,
    /// starting at the target file's ball_sigma_mm.
    #[arg(long)]
    ball_prior_mm: Option<f64>,
    /// Tracker path: no priors (the plain maximum-likelihood bundle fit).
    #[arg(long, conflicts_with_all = ["joint_prior_mm", "ball_prior_mm"])]
    no_prior: bool,
    /// Tracker path: weight with the --tracker model as given (no variance components).
    #[arg(long)]
    fixed_noise: bool,
    /// Tracker path: family-wise significance of the outlier test (Bonferroni over the
    /// points).
    #[arg(long, default_value_t = m2calib::calib::adjust::DEFAULT_ALPHA)]
    alpha: f64,
    /// Tracker path: a point failing the outlier test is removed (and reported) or
    /// refuses the campaign: remove | refuse.
    #[arg(long, default_value = "remove")]
    outliers: String,
    /// Tracker path: format of the point export: auto | native | sa | csv.
    #[arg(long, default_value = "auto")]
    points_format: String,
    /// Tracker path, csv format: pose=COL,point=COL,x=COL,y=COL,z=COL[,sigma=COL].
    #[arg(long)]
    columns: Option<String>,
    /// Tracker path: unit of the export's coordinates: mm | m | in (must agree with the
    /// file's own declaration, if any).
    #[arg(long)]
    units: Option<String>,
    /// Tracker path: the tracker head's position X,Y,Z in the export's frame and unit
    /// (default: the export is in the tracker's own frame).
    #[arg(long, value_delimiter = ',', num_args = 3, allow_hyphen_values = true)]
    tracker_at: Option<Vec<f64>>,
    /// Tracker path: the group (pose column value) of the base fiducials.
    #[arg(long, default_value = "base")]
    base_group: String,
    /// Tracker path: picture of the standardised residuals per pose and ball (SVG).
    #[arg(long)]
    residual_plot: Option<PathBuf>,
    /// Nominal geometry file.
    #[arg(long)]
    nominal: PathBuf,
    /// Output calibrated geometry file.
    #[arg(long)]
    out: PathBuf,
    /// Solver: lm | lm-unbounded | smcs | improved | improved+lm.
    #[arg(long, default_value = "lm")]
    solver: String,
    #[command(flatten)]
    solver_cli: SolverCli,
    /// Print the evaluation (pose errors before/after).
    #[arg(long)]
    report: bool,
    /// True geometry of a simulated campaign: adds the held-out evaluation.
    #[arg(long)]
    truth: Option<PathBuf>,
    /// Write an SVG plot of the per-pose errors (with --report).
    #[arg(long)]
    plot: Option<PathBuf>,
}

#[derive(clap::Args)]
struct PlanArgsCli {
    /// Half-side of the translation cube whose corners are sampled (mm); 0 leaves them out.
    #[arg(long, default_value_t = DEFAULT_CUBE_HALF_MM)]
    cube_half_mm: f64,
    /// Distance of the axis points (mm); 0 leaves them out.
    #[arg(long, default_value_t = DEFAULT_AXIS_MM)]
    axis_mm: f64,
    /// Rotation magnitude combined with all 8 sign patterns (arcsec).
    #[arg(long, default_value_t = DEFAULT_ROTATION_ARCSEC)]
    rotation_arcsec: f64,
    /// Leave out the centre point.
    #[arg(long)]
    no_centre: bool,
}

impl PlanArgsCli {
    fn config(&self) -> PlanConfig {
        PlanConfig {
            centre: !self.no_centre,
            cube_half_mm: (self.cube_half_mm > 0.0).then_some(self.cube_half_mm),
            axis_mm: (self.axis_mm > 0.0).then_some(self.axis_mm),
            rotation_arcsec: self.rotation_arcsec,
        }
    }
}

#[derive(clap::Args)]
pub(crate) struct PlanCli {
    #[command(flatten)]
    plan: PlanArgsCli,
    /// Output file (default: stdout).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(clap::Args)]
pub(crate) struct CampaignCli {
    /// Nominal geometry file (default: the compiled-in prototype).
    #[arg(long)]
    nominal: Option<PathBuf>,
    /// Output measurement CSV (default: stdout).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also write the simulated true geometry here.
    #[arg(long)]
    truth_out: Option<PathBuf>,
    /// Manufacturing error sigma per joint coordinate (mm).
    #[arg(long, default_value_t = DEFAULT_MANUFACTURING_SIGMA_MM)]
    sigma_mm: f64,
    /// Seed of the true geometry.
    #[arg(long, default_value_t = 1)]
    geometry_seed: u64,
    /// Tracker noise on the translation (um, per axis).
    #[arg(long, default_value_t = PoseTracker::PAPER.noise_um)]
    noise_um: f64,
    /// Tracker noise on the rotation (arcsec, per axis).
    #[arg(long, default_value_t = PoseTracker::PAPER.noise_arcsec)]
    noise_arcsec: f64,
    /// Seed of the tracker noise.
    #[arg(long, default_value_t = 2)]
    noise_seed: u64,
    #[command(flatten)]
    plan: PlanArgsCli,
}

/// How `calibrate --points` reads the export.
fn point_export_options(
    a: &CalibrateCli,
) -> Result<m2calib::tracker::exports::ExportOptions, String> {
    use m2calib::tracker::exports::{ExportFormat, GenericColumns, LengthUnit};
    let format = match (a.points_format.as_str(), &a.columns) {
        ("csv", Some(c)) => ExportFormat::Generic(GenericColumns::parse(c)?),
        ("csv", None) => return Err("--points-format csv needs --columns".into()),
        (_, Some(_)) => return Err("--columns needs --points-format csv".into()),
        ("auto", None) => ExportFormat::Auto,
        ("native", None) => ExportFormat::Native,
        ("sa", None) => ExportFormat::SpatialAnalyzer,
        (f, _) => {
            return Err(format!(
                "--points-format: '{f}' is not auto, native, sa or csv"
            ))
        }
    };
    let units = match &a.units {
        Some(u) => {
            Some(LengthUnit::parse(u).ok_or_else(|| format!("--units: '{u}' is not mm, m or in"))?)
        }
        None => None,
    };
    let tracker_at = match &a.tracker_at {
        Some(v) if v.len() == 3 && v.iter().all(|x| x.is_finite()) => Some([v[0], v[1], v[2]]),
        Some(_) => return Err("--tracker-at needs three finite numbers X,Y,Z".into()),
        None => None,
    };
    Ok(m2calib::tracker::exports::ExportOptions {
        format,
        units,
        tracker_at,
        base_group: a.base_group.clone(),
    })
}

/// The adjustment settings of `calibrate --points`.
fn point_adjust_config(
    a: &CalibrateCli,
    targets: &std::path::Path,
) -> Result<m2calib::calib::adjust::AdjustConfig, String> {
    use m2calib::calib::adjust::{AdjustConfig, OutlierRule, PriorSetting};
    let ball_sigma = m2calib::tracker::files::parse_targets(
        &std::fs::read_to_string(targets).map_err(|e| format!("{}: {e}", targets.display()))?,
    )
    .map_err(|e| format!("{}: {e}", targets.display()))?
    .ball_sigma_mm;
    let positive = |v: Option<f64>, what: &str| match v {
        Some(x) if !(x.is_finite() && x > 0.0) => Err(format!("{what} must be a positive number")),
        _ => Ok(v),
    };
    let mut c = AdjustConfig::estimated(ball_sigma);
    if let Some(j) = positive(a.joint_prior_mm, "--joint-prior-mm")? {
        c.joint_prior = PriorSetting::Fixed(j);
    }
    if let Some(b) = positive(a.ball_prior_mm, "--ball-prior-mm")? {
        c.ball_prior = PriorSetting::Fixed(b);
    }
    if a.no_prior {
        c.joint_prior = PriorSetting::Free;
        c.ball_prior = PriorSetting::Free;
    }
    c.estimate_noise = !a.fixed_noise;
    if !(a.alpha > 0.0 && a.alpha < 1.0) {
        return Err("--alpha must be between 0 and 1".into());
    }
    c.alpha = a.alpha;
    c.rule = match a.outliers.as_str() {
        "remove" => OutlierRule::Remove,
        "refuse" => OutlierRule::Refuse,
        o => return Err(format!("--outliers: '{o}' is neither remove nor refuse")),
    };
    Ok(c)
}

pub(crate) fn calibrate_cmd(a: &CalibrateCli) -> Result<(), String> {
    let solver = SolverKind::parse(&a.solver).ok_or_else(|| {
        format!(
            "unknown solver '{}' (lm, lm-unbounded, smcs, improved, improved+lm)",
            a.solver
        )
    })?;
    if let (Some(points), Some(strokes), Some(targets)) = (&a.points, &a.strokes, &a.targets) {
        use m2calib::tracker::commands::{run_point_calibrate, PointCalibrateArgs};
        let (text, summary) = run_point_calibrate(&PointCalibrateArgs {
            points: points.clone(),
            strokes: strokes.clone(),
            targets: targets.clone(),
            nominal: a.nominal.clone(),
            export: point_export_options(a)?,
            noise: a.tracker.noise()?,
            adjust: point_adjust_config(a, targets)?,
            report: a.report,
            truth: a.truth.clone(),
            plot: a.plot.clone(),
            residual_plot: a.residual_plot.clone(),
        })?;
        std::fs::write(&a.out, text).map_err(|e| format!("{}: {e}", a.out.display()))?;
        print!("{summary}");
        println!("wrote {}", a.out.display());
        return Ok(());
    }
    let data = a.data.clone().ok_or("--data or --points is required")?;
    let args = CalibrateArgs {
        data,
        nominal: a.nominal.clone(),
        cfg: a.solver_cli.config(solver),
        report: a.report,
        truth: a.truth.clone(),
        plot: a.plot.clone(),
    };
    let (text, summary) = run_calibrate(&args)?;
    std::fs::write(&a.out, text).map_err(|e| format!("{}: {e}", a.out.display()))?;
    print!("{summary}");
    println!("wrote {}", a.out.display());
    Ok(())
}

pub(crate) fn simulate_tracker_cmd(a: &SimulateTrackerCli) -> Result<(), String> {
    use m2calib::tracker::commands::{run_simulate, SimulateArgs, SIMULATED_FILES};
    use m2calib::tracker::study::TruthModel;
    let truth = TruthModel::parse(&a.truth).ok_or_else(|| {
        format!(
            "--truth: '{}' is neither gauss:SIGMA nor uniform:HALF",
            a.truth
        )
    })?;
    let plan = match &a.plan {
        Some(p) => {
            let text = std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()))?;
            m2calib::files::parse_csv(&text, m2calib::files::POSE_COLUMNS)
                .map_err(|e| format!("{}: {e}", p.display()))?
                .iter()
                .map(|r| {
                    let v = &r.values;
                    m2ctl::kinematics::Pose::from_mm_arcsec([v[0], v[1], v[2]], [v[3], v[4], v[5]])
                })
                .collect()
        }
        None => m2calib::plan::plan_poses(&PlanConfig::default()),
    };
    let files = run_simulate(&SimulateArgs {
        nominal: m2ctl::nominal::PROTOTYPE,
        truth,
        setup: a.tracker.setup()?,
        plan,
        campaign: a.campaign,
    })?;
    std::fs::create_dir_all(&a.out_dir).map_err(|e| format!("{}: {e}", a.out_dir.display()))?;
    for (name, text) in SIMULATED_FILES.iter().zip(files.iter()) {
        let p = a.out_dir.join(name);
        std::fs::write(&p, text).map_err(|e| format!("{}: {e}", p.display()))?;
        println!("wrote {}", p.display());
    }
    Ok(())
}

pub(crate) fn campaign_cmd(a: &CampaignCli) -> Result<(), String> {
    let nominal = match &a.nominal {
        Some(p) => m2calib::files::read_geometry(p)?.params,
        None => m2ctl::nominal::PROTOTYPE,
    };
    let (csv, truth) = run_campaign(&CampaignArgs {
        nominal,
        sigma_mm: a.sigma_mm,
        geometry_seed: a.geometry_seed,
        tracker: PoseTracker {
            noise_um: a.noise_um,
            noise_arcsec: a.noise_arcsec,
        },
        noise_seed: a.noise_seed,
        plan: a.plan.config(),
    })?;
    if let Some(p) = &a.truth_out {
        std::fs::write(p, truth).map_err(|e| format!("{}: {e}", p.display()))?;
    }
    write_out(a.out.as_ref(), &csv)
}

#[derive(clap::Args)]
pub(crate) struct IoArgs {
    /// Geometry file (geometry.toml format, optional [limits]).
    #[arg(long)]
    geometry: PathBuf,
    /// Input CSV (ik_golden.csv column format).
    #[arg(long)]
    input: PathBuf,
    /// Output file (default: stdout).
    #[arg(long)]
    output: Option<PathBuf>,
}

/// `m2ground ik` / `fk`.
pub(crate) fn ik_fk_cmd(which: IkFk, a: &IoArgs) -> Result<(), String> {
    run_file(which, &a.geometry, &a.input).and_then(|t| write_out(a.output.as_ref(), &t))
}

/// `m2ground plan`.
pub(crate) fn plan_cmd(a: &PlanCli) -> Result<(), String> {
    write_out(a.out.as_ref(), &run_plan(&a.plan.config()))
}

/// `m2ground mdb-json`.
pub(crate) fn mdb_json_cmd(out: Option<&PathBuf>) -> Result<(), String> {
    write_out(out, &m2ground::mdb::mdb().to_json())
}

fn write_out(out: Option<&PathBuf>, text: &str) -> Result<(), String> {
    match out {
        Some(p) => std::fs::write(p, text).map_err(|e| format!("{}: {e}", p.display())),
        None => {
            print!("{text}");
            Ok(())
        }
    }
}
