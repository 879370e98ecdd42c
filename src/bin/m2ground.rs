//! `m2ground`: the ground tool of the M2 mechanism controller (host only).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use m2ctl::ground::calib::{cuckoo::CuckooConfig, CalibConfig, SolverKind};
use m2ctl::ground::calib_cmd::{
    run_calibrate, run_campaign, run_plan, CalibrateArgs, CampaignArgs,
};
use m2ctl::ground::campaign::{Tracker, DEFAULT_MANUFACTURING_SIGMA_MM};
use m2ctl::ground::ikfk::{run_file, IkFk};
use m2ctl::ground::plan::{
    PlanConfig, DEFAULT_AXIS_MM, DEFAULT_CUBE_HALF_MM, DEFAULT_ROTATION_ARCSEC,
};
use m2ctl::ground::report::{bench, compare_cuckoo, table3, TableConfig};
use m2ctl::ground::tc::{run_tc, TcOutput, TcRequest, TcSequencer};
use m2ctl::link::AckFlags;

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
    Calibrate(CalibrateCli),
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
    /// Tracker noise: "paper" (0.1 um, 0.1 arcsec) or "realistic" (5 um, 1 arcsec).
    #[arg(long, default_value = "paper")]
    tracker: String,
    /// Calibration solver: lm, smcs, improved, improved+lm.
    #[arg(long, default_value = "improved+lm")]
    solver: String,
    /// Write the per-target error plot (SVG) here.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// No progress bars.
    #[arg(long)]
    quiet: bool,
}

fn mission_cmd(a: &MissionCli) -> Result<(), String> {
    use m2ctl::ground::calib::SolverKind;
    use m2ctl::ground::campaign::Tracker;
    use m2ctl::ground::mission::{format_summary, run_mission, MissionConfig};
    let tracker = match a.tracker.as_str() {
        "paper" => Tracker::PAPER,
        "realistic" => Tracker::REALISTIC,
        other => {
            return Err(format!(
                "--tracker: '{other}' is neither 'paper' nor 'realistic'"
            ))
        }
    };
    let solver = SolverKind::parse(&a.solver)
        .ok_or_else(|| format!("--solver: unknown solver '{}'", a.solver))?;
    let mut cfg = MissionConfig {
        seed: a.seed,
        n_targets: a.targets,
        manufacturing_sigma_mm: a.sigma_mm,
        tracker,
        plot: a.plot.clone(),
        progress: !a.quiet,
        ..MissionConfig::default()
    };
    cfg.calib.solver = solver;
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
    /// Sequence count of the first telecommand (14 bits); later ones count up.
    #[arg(long, default_value_t = 0, global = true)]
    seq: u16,
    /// Source ID in the PUS secondary header.
    #[arg(long, default_value_t = 0, global = true)]
    source_id: u16,
    /// Acknowledgement flags (4 bits: acceptance, start, progress, completion).
    #[arg(long, default_value_t = 0b1111, global = true)]
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
    #[command(flatten)]
    Now(PlainTc),
    /// TC[11,4]: the telecommand of the subcommand (numbered first), released on board
    /// at on-board time --at-s.
    Schedule {
        /// Release time: on-board time in seconds since the controller's boot (the clock
        /// of the TM time stamps), to 1/65536 s.
        #[arg(long, allow_negative_numbers = true)]
        at_s: f64,
        #[command(subcommand)]
        what: PlainTc,
    },
    /// TC[11,1] enable the release of scheduled activities.
    ScheduleEnable,
    /// TC[11,2] disable the release of scheduled activities.
    ScheduleDisable,
    /// TC[11,3] reset the schedule (delete all; release disabled afterwards).
    ScheduleReset,
    /// TC[11,5] delete the activities whose telecommands were sent with these sequence
    /// counts.
    ScheduleDelete {
        /// Sequence count of a scheduled telecommand (repeat for several).
        #[arg(long = "seq-count", required = true)]
        seq_counts: Vec<u16>,
    },
    /// TC[11,15] move every release time by an offset.
    ScheduleShift {
        /// Offset (s, signed), to 1/65536 s.
        #[arg(long, allow_negative_numbers = true)]
        by_s: f64,
    },
    /// TC[11,17] summary report of the schedule (TM[11,13]).
    ScheduleReport,
    /// TC[9,1] time reports TM[9,2] every 2^N s (--exponent N), or --off.
    TimeReports {
        /// N of the period 2^N s (0..8).
        #[arg(long, required_unless_present = "off", conflicts_with = "off")]
        exponent: Option<u8>,
        /// Stop the time reports.
        #[arg(long)]
        off: bool,
    },
}

/// The telecommands that run at once (and that `schedule` can release later).
#[derive(Subcommand)]
enum PlainTc {
    /// TC[17,1] are-you-alive.
    Ping,
    /// TC[3,27] one-shot housekeeping report.
    Hk,
    /// TC[8,1] move to a pose (absolute unless --relative).
    Move {
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        x_um: f64,
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        y_um: f64,
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        z_um: f64,
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        rx_arcsec: f64,
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        ry_arcsec: f64,
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        rz_arcsec: f64,
        /// Increment from the commanded pose.
        #[arg(long)]
        relative: bool,
    },
    /// TC[8,1] move one slider by an increment (recovery).
    DirectStroke {
        /// Leg 1..6.
        #[arg(long)]
        leg: u8,
        /// Stroke increment (um).
        #[arg(long, allow_negative_numbers = true)]
        delta_um: f64,
    },
    /// TC[8,1] stop.
    Stop,
    /// TC[8,1] clear latched faults.
    ClearFault,
    /// TC[8,1] activate the pending table, named by its table ID and CRC-32.
    Activate {
        /// Table ID of the pending table.
        #[arg(long)]
        table_id: u32,
        /// CRC-32 of the pending table (decimal or 0x hex).
        #[arg(long, value_parser = parse_u32)]
        crc32: u32,
    },
    /// TC[8,1] switch to the other bank's table.
    SwitchBank,
    /// TC[8,1] revert to the nominal table.
    RevertNominal,
    /// TC[6,2] chunks of the table built from a geometry file, then TC[8,1] commit.
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
    /// TC[6,5] dump of the active table (or --upload-buffer).
    Dump {
        #[arg(long)]
        upload_buffer: bool,
    },
}

impl TcWhat {
    fn request(&self) -> TcRequest {
        match self {
            TcWhat::Now(t) => t.request(),
            TcWhat::Schedule { at_s, what } => TcRequest::Schedule {
                release_s: *at_s,
                what: Box::new(what.request()),
            },
            TcWhat::ScheduleEnable => TcRequest::ScheduleEnable,
            TcWhat::ScheduleDisable => TcRequest::ScheduleDisable,
            TcWhat::ScheduleReset => TcRequest::ScheduleReset,
            TcWhat::ScheduleDelete { seq_counts } => TcRequest::ScheduleDelete {
                seq_counts: seq_counts.clone(),
            },
            TcWhat::ScheduleShift { by_s } => TcRequest::ScheduleShift { by_s: *by_s },
            TcWhat::ScheduleReport => TcRequest::ScheduleReport,
            TcWhat::TimeReports { exponent, off } => TcRequest::TimeReportRate {
                exponent: if *off { None } else { *exponent },
            },
        }
    }
}

impl PlainTc {
    fn request(&self) -> TcRequest {
        match self {
            PlainTc::Ping => TcRequest::Ping,
            PlainTc::Hk => TcRequest::Housekeeping,
            PlainTc::Move {
                x_um,
                y_um,
                z_um,
                rx_arcsec,
                ry_arcsec,
                rz_arcsec,
                relative,
            } => TcRequest::Move {
                translation_um: [*x_um, *y_um, *z_um],
                rotation_arcsec: [*rx_arcsec, *ry_arcsec, *rz_arcsec],
                relative: *relative,
            },
            PlainTc::DirectStroke { leg, delta_um } => TcRequest::DirectStroke {
                leg: *leg,
                delta_um: *delta_um,
            },
            PlainTc::Stop => TcRequest::Stop,
            PlainTc::ClearFault => TcRequest::ClearFault,
            PlainTc::Activate { table_id, crc32 } => TcRequest::Activate {
                table_id: *table_id,
                crc32: *crc32,
            },
            PlainTc::SwitchBank => TcRequest::SwitchBank,
            PlainTc::RevertNominal => TcRequest::RevertToNominal,
            PlainTc::Upload {
                geometry,
                table_id,
                calibration_id,
                activate,
            } => TcRequest::Upload {
                geometry: geometry.clone(),
                table_id: *table_id,
                calibration_id: *calibration_id,
                activate: *activate,
            },
            PlainTc::Dump { upload_buffer } => TcRequest::Dump {
                upload_buffer: *upload_buffer,
            },
        }
    }
}

/// A u32 in decimal or `0x` hexadecimal.
fn parse_u32(s: &str) -> Result<u32, String> {
    match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(h) => u32::from_str_radix(h, 16).map_err(|e| format!("{s}: {e}")),
        None => s.parse().map_err(|e| format!("{s}: {e}")),
    }
}

fn tc_cmd(a: &TcCli) -> Result<(), String> {
    let mut seq = TcSequencer::new(a.seq);
    seq.source_id = a.source_id;
    seq.ack = AckFlags(a.ack & 0b1111);
    let output = if a.out.is_some() && !a.hex {
        TcOutput::Binary
    } else {
        TcOutput::HexLines
    };
    let bytes = run_tc(&a.what.request(), &mut seq, output, a.unframed)?;
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

#[derive(clap::Args)]
struct CalibrateCli {
    /// Measurement CSV (12 columns: pose mm/arcsec, strokes mm).
    #[arg(long)]
    data: PathBuf,
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
    #[arg(long, default_value_t = Tracker::PAPER.noise_um)]
    noise_um: f64,
    /// Tracker noise on the rotation (arcsec, per axis).
    #[arg(long, default_value_t = Tracker::PAPER.noise_arcsec)]
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

fn calibrate_cmd(a: &CalibrateCli) -> Result<(), String> {
    let solver = SolverKind::parse(&a.solver).ok_or_else(|| {
        format!(
            "unknown solver '{}' (lm, lm-unbounded, smcs, improved, improved+lm)",
            a.solver
        )
    })?;
    let args = CalibrateArgs {
        data: a.data.clone(),
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

fn campaign_cmd(a: &CampaignCli) -> Result<(), String> {
    let nominal = match &a.nominal {
        Some(p) => m2ctl::ground::files::read_geometry(p)?.params,
        None => m2ctl::nominal::PROTOTYPE,
    };
    let (csv, truth) = run_campaign(&CampaignArgs {
        nominal,
        sigma_mm: a.sigma_mm,
        geometry_seed: a.geometry_seed,
        tracker: Tracker {
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
            Cmd::Tc(a) => tc_cmd(a),
            Cmd::Mission(a) => mission_cmd(a),
            Cmd::Gateway(a) => gateway_cmd(a),
            Cmd::MdbJson { out } => write_out(out.as_ref(), &m2ctl::ground::mdb::mdb().to_json()),
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
