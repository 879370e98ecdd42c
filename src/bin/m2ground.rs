//! `m2ground`: the ground tool of the M2 mechanism controller (host only).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use m2ctl::ground::calib::{cuckoo::CuckooConfig, CalibConfig, SolverKind};
use m2ctl::ground::calib_cmd::{
    run_calibrate, run_campaign, run_plan, CalibrateArgs, CampaignArgs,
};
use m2ctl::ground::campaign::DEFAULT_MANUFACTURING_SIGMA_MM;
use m2ctl::ground::ikfk::{run_file, IkFk};
use m2ctl::ground::plan::{
    PlanConfig, DEFAULT_AXIS_MM, DEFAULT_CUBE_HALF_MM, DEFAULT_ROTATION_ARCSEC,
};
use m2ctl::ground::report::{bench, compare_cuckoo, table3, TableConfig};
use m2ctl::ground::tc::{
    command_from_args, run_tc, schedule_from_args, telecommand_list, upload_procedure, TcOutput,
    TcSequencer,
};
use m2ctl::link::tc::SEQ_COUNT_MASK;
use m2ctl::link::AckFlags;
use m2ctl::sim::tracker::PoseTracker;

#[derive(Parser)]
#[command(
    name = "m2ground",
    version,
    about = "Ground tool of the M2 mechanism controller"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Inverse kinematics: pose columns of a CSV -> 12-column CSV with strokes (f64).
    Ik(IoArgs),
    /// Forward kinematics: stroke columns of a CSV -> 12-column CSV with poses (f64).
    Fk(IoArgs),
    /// Calibrate the 36 joint coordinates from a measurement CSV.
    Calibrate(Box<CalibrateCli>),
    /// Write the calibration sampling plan's poses (6-column CSV).
    Plan(PlanCli),
    /// Write a measurement CSV from a simulated campaign (true mechanism + tracker noise).
    SimulateCampaign(CampaignCli),
    /// Print the paper's Table 3 comparison on a simulated campaign (and write the plot).
    Table3(TableCli),
    /// Print the wall time of each solver on the simulated campaign.
    Bench(BenchCli),
    /// Compare SMCS and the improved algorithm over several solver seeds.
    CompareCuckoo(CompareCli),
    /// Write a simulated laser-tracker campaign: targets.toml, points.csv, strokes.csv,
    /// truth.toml (input of `calibrate --points`).
    SimulateTrackerCampaign(SimulateTrackerCli),
    /// Tracker path: before / two-step / bundle without and with prior, three tracker
    /// classes, over many simulated campaigns.
    TrackerTable(StudyCli),
    /// Tracker path: predicted vs measured held-out accuracy over many campaigns.
    TrackerStats(TrackerStatsCli),
    /// Tracker path: optimal measurement plan vs the paper's 120 poses.
    TrackerPlan(TrackerPlanCli),
    /// Tracker path: the paper's prototype experiment reproduced and explained.
    PaperExperiment(PaperExperimentCli),
    /// Tracker path: calibrate's defaults on unknown spreads and noise, planted gross
    /// errors, clean draws never refused.
    TrackerDefaults(TrackerDefaultsCli),
    /// Encode telecommands (framed PUS-C packets, docs/icd.md) as hex lines or binary.
    Tc(TcCli),
    /// The whole mission story on the simulated plant: move, calibrate, upload, move again.
    Mission(MissionCli),
    /// Join Yamcs' TCP link and the controller's COBS byte stream (docs/ground-segment.md).
    Gateway(GatewayCli),
    /// Write the mission database (every TC, TM packet, enumeration, event) as JSON, the
    /// input of yamcs/tools/gen_xtce.py (docs/ground-segment.md).
    MdbJson {
        /// Output file (default: stdout).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// The tables of docs/icd.md that restate the code (codes, IDs, offsets, units,
    /// ranges), generated from the mission database: printed, checked against the
    /// document's marked blocks, or written into them (nothing outside the markers
    /// changes).
    IcdTables(IcdTablesCli),
}

#[derive(clap::Args)]
#[group(multiple = false)]
struct IcdTablesCli {
    /// Exit 1 with a diff if this document's generated blocks differ from the code.
    #[arg(long, value_name = "ICD")]
    check: Option<PathBuf>,
    /// Rewrite this document's generated blocks from the code.
    #[arg(long, value_name = "ICD")]
    write: Option<PathBuf>,
}

/// `m2ground icd-tables`: Ok(true) when the document is (now) as generated.
fn icd_tables_cmd(a: &IcdTablesCli) -> Result<bool, String> {
    use m2ctl::ground::icd;
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
struct MissionCli {
    /// Seed of the manufacturing errors, tracker noise, targets and solver.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Number of operator targets.
    #[arg(long, default_value_t = m2ctl::ground::mission::DEFAULT_TARGETS)]
    targets: usize,
    /// Manufacturing error of each joint coordinate (mm, standard deviation).
    #[arg(long, default_value_t = m2ctl::ground::mission::DEFAULT_MANUFACTURING_SIGMA_MM)]
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
}

fn mission_cmd(a: &MissionCli) -> Result<(), String> {
    use m2ctl::ground::mission::{format_summary, run_mission, MissionConfig};
    use m2ctl::ground::tracker::campaign::{noise_preset, TrackerSetup};
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
        ..MissionConfig::default()
    };
    let report = run_mission(&cfg, &mut |line: &str| println!("{line}"))?;
    println!();
    print!("{}", format_summary(&report));
    Ok(())
}

#[derive(clap::Args)]
struct GatewayCli {
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
    /// Seconds to wait for the controller's stream to appear.
    #[arg(long, default_value_t = 30)]
    wait_s: u64,
    /// Print the counters every N seconds (0: only at the end).
    #[arg(long, default_value_t = 10)]
    stats_s: u64,
}

fn gateway_cmd(a: &GatewayCli) -> Result<(), String> {
    use m2ctl::ground::gateway::{run, Options, Stats, Uart, DEFAULT_BACKLOG_PACKETS};
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
            .map(|u| format!(", time correlation -> {u}"))
            .unwrap_or_default()
    );
    let options = Options {
        tco_url: a.tco_url.clone(),
        backlog: DEFAULT_BACKLOG_PACKETS,
        stats_every: (a.stats_s > 0).then(|| Duration::from_secs(a.stats_s)),
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
struct TcCli {
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

fn tc_cmd(a: &TcCli) -> Result<(), String> {
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
struct CompareCli {
    #[command(flatten)]
    solver_cli: SolverCli,
    /// Solver seeds 1..=N.
    #[arg(long, default_value_t = 5)]
    seeds: u64,
}

#[derive(clap::Args)]
struct SolverCli {
    /// Half-width of the feasible box Omega around nominal (mm).
    #[arg(long, default_value_t = m2ctl::ground::calib::DEFAULT_OMEGA_HALF_WIDTH_MM)]
    omega_mm: f64,
    /// Seed of the stochastic solvers.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Cuckoo search: number of nests.
    #[arg(long, default_value_t = m2ctl::ground::calib::cuckoo::DEFAULT_NESTS)]
    nests: usize,
    /// Cuckoo search: generation budget T_max.
    #[arg(long, default_value_t = m2ctl::ground::calib::cuckoo::DEFAULT_MAX_GENERATIONS)]
    generations: usize,
    /// Cuckoo search: Nelder-Mead iterations per refined nest per generation.
    #[arg(long, default_value_t = m2ctl::ground::calib::cuckoo::DEFAULT_NM_ITERATIONS)]
    nm_iterations: usize,
    /// LM: assumed spread of the true joints about nominal (mm).
    #[arg(long, default_value_t = m2ctl::ground::calib::lm::DEFAULT_PRIOR_SIGMA_MM)]
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
    fn config(&self, solver: SolverKind) -> CalibConfig {
        let mut c = CalibConfig {
            solver,
            omega_half_width_mm: self.omega_mm,
            seed: self.seed,
            cuckoo: CuckooConfig {
                nests: self.nests,
                max_generations: self.generations,
                nm_iterations: self.nm_iterations,
                coordinates: match self.coordinates {
                    CoordArg::Original => m2ctl::ground::calib::cuckoo::Coordinates::Original,
                    CoordArg::Whitened => m2ctl::ground::calib::cuckoo::Coordinates::Whitened,
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
struct TrackerCli {
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
    #[arg(long, default_value_t = m2ctl::ground::tracker::files::DEFAULT_BALL_RADIUS_MM)]
    ball_radius_mm: f64,
}

impl TrackerCli {
    fn noise(&self) -> Result<m2ctl::sim::tracker::TrackerNoise, String> {
        use m2ctl::ground::tracker::campaign::{noise_preset, NOISE_PRESETS};
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

    fn setup(&self) -> Result<m2ctl::ground::tracker::campaign::TrackerSetup, String> {
        if !(self.distance_m > 0.5 && self.distance_m < 40.0) {
            return Err("--distance-m must be between 0.5 and 40 m".into());
        }
        if !(self.ball_radius_mm >= 20.0 && self.ball_radius_mm <= 1000.0) {
            return Err("--ball-radius-mm must be between 20 and 1000 mm".into());
        }
        let mut s = m2ctl::ground::tracker::campaign::TrackerSetup {
            noise: self.noise()?,
            targets: m2ctl::ground::tracker::files::TargetFile::with_ball_radius(
                self.ball_radius_mm,
            ),
            ..Default::default()
        };
        s.placement.distance_mm = self.distance_m * m2ctl::units::MM_PER_M;
        Ok(s)
    }
}

/// Settings of the tracker-path studies.
#[derive(clap::Args, Clone)]
struct StudyCli {
    #[command(flatten)]
    tracker: TrackerCli,
    /// True joints: gauss:SIGMA_MM (truncated at 3 sigma) or uniform:HALF_MM.
    #[arg(long, default_value = "gauss:0.1")]
    truth: String,
    /// Prior spread of the joints in the bundle fit (mm); default: the truth's sigma.
    #[arg(long)]
    joint_prior_mm: Option<f64>,
    /// Number of simulated campaigns.
    #[arg(long, default_value_t = m2ctl::ground::tracker::study::DEFAULT_TABLE_CAMPAIGNS)]
    campaigns: usize,
    /// Number of the first campaign (seeds).
    #[arg(long, default_value_t = 1)]
    first_campaign: u64,
}

impl StudyCli {
    fn config(&self) -> Result<m2ctl::ground::tracker::study::StudyConfig, String> {
        use m2ctl::ground::tracker::study::{StudyConfig, TruthModel};
        let truth = TruthModel::parse(&self.truth).ok_or_else(|| {
            format!(
                "--truth: '{}' is neither gauss:SIGMA nor uniform:HALF",
                self.truth
            )
        })?;
        if let Some(p) = self.joint_prior_mm {
            if !(p.is_finite() && p > 0.0) {
                return Err("--joint-prior-mm must be a positive number".into());
            }
        }
        Ok(StudyConfig {
            truth,
            setup: self.tracker.setup()?,
            joint_prior_sigma_mm: self.joint_prior_mm,
            campaigns: self.campaigns.max(1),
            first_campaign: self.first_campaign,
            ..StudyConfig::default()
        })
    }
}

#[derive(clap::Args)]
struct SimulateTrackerCli {
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
struct TrackerStatsCli {
    #[command(flatten)]
    study: StudyCli,
    /// Tracker noise scales (the --tracker preset times each).
    #[arg(long, value_delimiter = ',', default_values_t = m2ctl::ground::tracker::study::DEFAULT_SWEEP_SCALES)]
    scales: Vec<f64>,
    /// Write the predicted-vs-measured plot (SVG).
    #[arg(long)]
    plot: Option<PathBuf>,
}

#[derive(clap::Args)]
struct TrackerPlanCli {
    #[command(flatten)]
    study: StudyCli,
    /// Plan sizes to compare with the paper's plan.
    #[arg(long, value_delimiter = ',', default_value = "20,30,40,60,120")]
    sizes: Vec<usize>,
    /// Design criterion: i-optimal or d-optimal.
    #[arg(long, default_value = "i-optimal")]
    criterion: String,
    /// Write the plan of this size (from --sizes) as a pose CSV to --out.
    #[arg(long, default_value_t = 40)]
    poses: usize,
    /// Output pose CSV of the --poses plan.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write the plan map (SVG): the --poses plan against the paper's.
    #[arg(long)]
    plot: Option<PathBuf>,
}

#[derive(clap::Args)]
struct TrackerDefaultsCli {
    #[command(flatten)]
    tracker: TrackerCli,
    /// True joint spreads (mm, Gaussian, truncated at 3 sigma).
    #[arg(long, value_delimiter = ',', default_values_t = m2ctl::ground::tracker::robust::DEFAULT_SPREADS)]
    spreads: Vec<f64>,
    /// Tracker noise scales (the --tracker preset times each).
    #[arg(long, value_delimiter = ',', default_values_t = m2ctl::ground::tracker::robust::DEFAULT_SCALES)]
    scales: Vec<f64>,
    /// Campaigns per (spread, scale) cell.
    #[arg(long, default_value_t = m2ctl::ground::tracker::robust::DEFAULT_CELL_CAMPAIGNS)]
    campaigns: usize,
    /// Campaigns per planted gross error (0: none).
    #[arg(long, default_value_t = m2ctl::ground::tracker::robust::DEFAULT_GROSS_CAMPAIGNS)]
    gross_campaigns: usize,
    /// Clean campaigns that must not be refused (0: none).
    #[arg(long, default_value_t = m2ctl::ground::tracker::robust::DEFAULT_CLEAN_DRAWS)]
    clean_draws: usize,
}

#[derive(clap::Args)]
struct PaperExperimentCli {
    #[command(flatten)]
    study: StudyCli,
    /// Write the per-pose error plot (SVG).
    #[arg(long)]
    plot: Option<PathBuf>,
}

#[derive(clap::Args)]
struct CalibrateCli {
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
    #[arg(long, default_value_t = m2ctl::ground::calib::adjust::DEFAULT_ALPHA)]
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
struct PlanCli {
    #[command(flatten)]
    plan: PlanArgsCli,
    /// Output file (default: stdout).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(clap::Args)]
struct CampaignCli {
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

#[derive(clap::Args)]
struct TableCli {
    #[command(flatten)]
    solver_cli: SolverCli,
    /// Write the per-pose error plot (SVG).
    #[arg(long)]
    plot: Option<PathBuf>,
}

#[derive(clap::Args)]
struct BenchCli {
    #[command(flatten)]
    solver_cli: SolverCli,
    /// Runs per solver.
    #[arg(long, default_value_t = 3)]
    repeats: usize,
}

fn table_config(s: &SolverCli, plot: Option<PathBuf>) -> TableConfig {
    TableConfig {
        calib: SolverCli::config(s, SolverKind::Lm),
        plot,
        ..TableConfig::default()
    }
}

/// How `calibrate --points` reads the export.
fn point_export_options(
    a: &CalibrateCli,
) -> Result<m2ctl::ground::tracker::exports::ExportOptions, String> {
    use m2ctl::ground::tracker::exports::{ExportFormat, GenericColumns, LengthUnit};
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
    Ok(m2ctl::ground::tracker::exports::ExportOptions {
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
) -> Result<m2ctl::ground::calib::adjust::AdjustConfig, String> {
    use m2ctl::ground::calib::adjust::{AdjustConfig, OutlierRule, PriorSetting};
    let ball_sigma = m2ctl::ground::tracker::files::parse_targets(
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

fn calibrate_cmd(a: &CalibrateCli) -> Result<(), String> {
    let solver = SolverKind::parse(&a.solver).ok_or_else(|| {
        format!(
            "unknown solver '{}' (lm, lm-unbounded, smcs, improved, improved+lm)",
            a.solver
        )
    })?;
    if let (Some(points), Some(strokes), Some(targets)) = (&a.points, &a.strokes, &a.targets) {
        use m2ctl::ground::tracker::commands::{run_point_calibrate, PointCalibrateArgs};
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

fn tracker_defaults_cmd(a: &TrackerDefaultsCli) -> Result<(), String> {
    use m2ctl::ground::tracker::robust::{robust_study, RobustConfig};
    if a.spreads
        .iter()
        .chain(a.scales.iter())
        .any(|v| !(v.is_finite() && *v > 0.0))
    {
        return Err("--spreads and --scales must be positive numbers".into());
    }
    let base = m2ctl::ground::tracker::study::StudyConfig {
        setup: a.tracker.setup()?,
        ..Default::default()
    };
    let cfg = RobustConfig {
        spreads: a.spreads.clone(),
        scales: a.scales.clone(),
        campaigns: a.campaigns,
        gross_campaigns: a.gross_campaigns,
        clean_draws: a.clean_draws,
        ..RobustConfig::new(base)
    };
    let text = robust_study(&cfg, &mut |row| eprintln!("{row}"))?;
    print!("{text}");
    Ok(())
}

fn simulate_tracker_cmd(a: &SimulateTrackerCli) -> Result<(), String> {
    use m2ctl::ground::tracker::commands::{run_simulate, SimulateArgs, SIMULATED_FILES};
    use m2ctl::ground::tracker::study::TruthModel;
    let truth = TruthModel::parse(&a.truth).ok_or_else(|| {
        format!(
            "--truth: '{}' is neither gauss:SIGMA nor uniform:HALF",
            a.truth
        )
    })?;
    let plan = match &a.plan {
        Some(p) => {
            let text = std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()))?;
            m2ctl::ground::files::parse_csv(&text, m2ctl::ground::files::POSE_COLUMNS)
                .map_err(|e| format!("{}: {e}", p.display()))?
                .iter()
                .map(|r| {
                    let v = &r.values;
                    m2ctl::kinematics::Pose::from_mm_arcsec([v[0], v[1], v[2]], [v[3], v[4], v[5]])
                })
                .collect()
        }
        None => m2ctl::ground::plan::plan_poses(&PlanConfig::default()),
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

fn tracker_stats_cmd(a: &TrackerStatsCli) -> Result<(), String> {
    use m2ctl::ground::tracker::plots::PredictionGroup;
    use m2ctl::ground::tracker::study::{format_prediction_sweep, prediction_sweep, rms3};
    let cfg = a.study.config()?;
    if a.scales.iter().any(|k| !(k.is_finite() && *k > 0.0)) {
        return Err("--scales: every scale must be a positive number".into());
    }
    let rows = prediction_sweep(&cfg, &a.scales)?;
    print!("{}", format_prediction_sweep(&cfg, &rows));
    if let Some(p) = &a.plot {
        let groups = |rot: bool| -> Vec<PredictionGroup> {
            let range = if rot { 3..6 } else { 0..3 };
            rows.iter()
                .map(|(k, r)| PredictionGroup {
                    label: format!("noise x{k}"),
                    points: r
                        .points
                        .iter()
                        .map(|q| {
                            (
                                rms3(&q.predicted_rms[range.clone()]),
                                rms3(&q.measured_rms[range.clone()]),
                            )
                        })
                        .collect(),
                })
                .collect()
        };
        m2ctl::ground::tracker::plots::predicted_vs_measured(
            p,
            &format!(
                "Predicted vs measured held-out RMS, bundle fit with prior, {} campaigns per tracker noise scale",
                cfg.campaigns
            ),
            &[
                ("translation (x, y, z combined)".into(), "um".into(), groups(false)),
                ("rotation (alpha, beta, gamma combined)".into(), "arcsec".into(), groups(true)),
            ],
        )?;
        println!("\nplot: {}", p.display());
    }
    Ok(())
}

fn tracker_plan_cmd(a: &TrackerPlanCli) -> Result<(), String> {
    use m2ctl::ground::calib::design::Criterion;
    use m2ctl::ground::tracker::study::plan_study;
    let cfg = a.study.config()?;
    let criterion = Criterion::parse(&a.criterion).ok_or_else(|| {
        format!(
            "--criterion: '{}' is neither i-optimal nor d-optimal",
            a.criterion
        )
    })?;
    let mut sizes = a.sizes.clone();
    if !sizes.contains(&a.poses) {
        sizes.push(a.poses);
    }
    let (text, plans) = plan_study(&cfg, criterion, &sizes)?;
    print!("{text}");
    let chosen = plans
        .iter()
        .skip(1)
        .find(|(_, p)| p.len() == a.poses)
        .ok_or("no plan of that size")?;
    if let Some(out) = &a.out {
        let csv = m2ctl::ground::plan::format_plan(
            &chosen.1,
            &format!(
                "Optimal calibration plan ({}), m2ground tracker-plan",
                chosen.0
            ),
        );
        std::fs::write(out, csv).map_err(|e| format!("{}: {e}", out.display()))?;
        println!("\nwrote {}", out.display());
    }
    if let Some(p) = &a.plot {
        m2ctl::ground::tracker::plots::plan_map(
            p,
            &format!(
                "Plan map: {} against the paper's {} poses",
                chosen.0,
                cfg.plan.len()
            ),
            &[plans[0].clone(), chosen.clone()],
        )?;
        println!("plot: {}", p.display());
    }
    Ok(())
}

fn paper_experiment_cmd(a: &PaperExperimentCli) -> Result<(), String> {
    use m2ctl::ground::tracker::commands::noise_band;
    use m2ctl::ground::tracker::plots::{per_pose, Panel, Series};
    use m2ctl::ground::tracker::study::{format_paper_experiment, paper_experiment};
    let cfg = a.study.config()?;
    let r = paper_experiment(&cfg)?;
    print!("{}", format_paper_experiment(&cfg, &r));
    if let Some(p) = &a.plot {
        let s = &r.pose_noise_sigma;
        let series = |rot: bool| {
            [
                (
                    "before (poses from nominal ball centres)",
                    &r.sampling_before_naive,
                ),
                (
                    "before (poses from fitted ball centres)",
                    &r.sampling_before,
                ),
                ("after calibration", &r.sampling_after),
            ]
            .iter()
            .map(|(l, acc)| Series {
                label: l.to_string(),
                values: acc
                    .per_pose_max()
                    .iter()
                    .map(|(t, q)| if rot { *q } else { *t })
                    .collect(),
            })
            .collect::<Vec<_>>()
        };
        per_pose(
            p,
            &format!("The paper's experiment, simulated: pose error at the {} sampling poses, FK(strokes) - tracker-measured pose", cfg.plan.len()),
            "sampling pose",
            &[
                Panel {
                    caption: "largest |translation error| of each pose (um, log scale)".into(),
                    y_label: "um".into(),
                    series: series(false),
                    band: Some(noise_band(&s[..3])),
                    log: true,
                },
                Panel {
                    caption: "largest |rotation error| of each pose (arcsec, log scale)".into(),
                    y_label: "arcsec".into(),
                    series: series(true),
                    band: Some(noise_band(&s[3..])),
                    log: true,
                },
            ],
            Some("tracker noise floor (90 % of pure-noise poses)"),
        )?;
        println!("\nplot: {}", p.display());
    }
    Ok(())
}

fn campaign_cmd(a: &CampaignCli) -> Result<(), String> {
    let nominal = match &a.nominal {
        Some(p) => m2ctl::ground::files::read_geometry(p)?.params,
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
struct IoArgs {
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

fn write_out(out: Option<&PathBuf>, text: &str) -> Result<(), String> {
    match out {
        Some(p) => std::fs::write(p, text).map_err(|e| format!("{}: {e}", p.display())),
        None => {
            print!("{text}");
            Ok(())
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result =
        match &cli.cmd {
            Cmd::Ik(a) => run_file(IkFk::Ik, &a.geometry, &a.input)
                .and_then(|t| write_out(a.output.as_ref(), &t)),
            Cmd::Fk(a) => run_file(IkFk::Fk, &a.geometry, &a.input)
                .and_then(|t| write_out(a.output.as_ref(), &t)),
            Cmd::Calibrate(a) => calibrate_cmd(a),
            Cmd::Plan(a) => write_out(a.out.as_ref(), &run_plan(&a.plan.config())),
            Cmd::SimulateCampaign(a) => campaign_cmd(a),
            Cmd::Table3(a) => {
                table3(&table_config(&a.solver_cli, a.plot.clone())).map(|t| print!("{t}"))
            }
            Cmd::CompareCuckoo(a) => {
                compare_cuckoo(&table_config(&a.solver_cli, None), a.seeds).map(|t| print!("{t}"))
            }
            Cmd::SimulateTrackerCampaign(a) => simulate_tracker_cmd(a),
            Cmd::TrackerTable(a) => a
                .config()
                .and_then(|c| m2ctl::ground::tracker::study::campaign_table(&c))
                .map(|t| print!("{t}")),
            Cmd::TrackerStats(a) => tracker_stats_cmd(a),
            Cmd::TrackerPlan(a) => tracker_plan_cmd(a),
            Cmd::PaperExperiment(a) => paper_experiment_cmd(a),
            Cmd::TrackerDefaults(a) => tracker_defaults_cmd(a),
            Cmd::Tc(a) => tc_cmd(a),
            Cmd::Mission(a) => mission_cmd(a),
            Cmd::Gateway(a) => gateway_cmd(a),
            Cmd::MdbJson { out } => write_out(out.as_ref(), &m2ctl::ground::mdb::mdb().to_json()),
            Cmd::IcdTables(a) => match icd_tables_cmd(a) {
                Ok(true) => Ok(()),
                Ok(false) => return ExitCode::FAILURE,
                Err(e) => Err(e),
            },
            Cmd::Bench(a) => {
                bench(&table_config(&a.solver_cli, None), a.repeats).map(|t| print!("{t}"))
            }
        };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("m2ground: {e}");
            ExitCode::FAILURE
        }
    }
}
