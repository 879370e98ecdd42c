//! `m2ground`: the ground tool of the M2 mechanism controller (host only).
//!
//! One command line ([`Cmd`]); the arguments and actions of its subcommands live in
//! [`ops`] (operations) and [`research`] (the calibration study).

mod ops;
mod research;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use m2calib::ikfk::IkFk;
use ops::{
    CalibrateCli, CampaignCli, GatewayCli, IcdTablesCli, IoArgs, MissionCli, PlanCli,
    SimulateTrackerCli, TcCli,
};
use research::{
    BenchCli, CompareCli, PaperExperimentCli, StudyCli, TableCli, TrackerDefaultsCli,
    TrackerPlanCli, TrackerStatsCli,
};

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

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.cmd {
        Cmd::Ik(a) => ops::ik_fk_cmd(IkFk::Ik, a),
        Cmd::Fk(a) => ops::ik_fk_cmd(IkFk::Fk, a),
        Cmd::Calibrate(a) => ops::calibrate_cmd(a),
        Cmd::Plan(a) => ops::plan_cmd(a),
        Cmd::SimulateCampaign(a) => ops::campaign_cmd(a),
        Cmd::Table3(a) => research::table3_cmd(a),
        Cmd::CompareCuckoo(a) => research::compare_cuckoo_cmd(a),
        Cmd::SimulateTrackerCampaign(a) => ops::simulate_tracker_cmd(a),
        Cmd::TrackerTable(a) => research::tracker_table_cmd(a),
        Cmd::TrackerStats(a) => research::tracker_stats_cmd(a),
        Cmd::TrackerPlan(a) => research::tracker_plan_cmd(a),
        Cmd::PaperExperiment(a) => research::paper_experiment_cmd(a),
        Cmd::TrackerDefaults(a) => research::tracker_defaults_cmd(a),
        Cmd::Tc(a) => ops::tc_cmd(a),
        Cmd::Mission(a) => ops::mission_cmd(a),
        Cmd::Gateway(a) => ops::gateway_cmd(a),
        Cmd::MdbJson { out } => ops::mdb_json_cmd(out.as_ref()),
        Cmd::IcdTables(a) => match ops::icd_tables_cmd(a) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::FAILURE,
            Err(e) => Err(e),
        },
        Cmd::Bench(a) => research::bench_cmd(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("m2ground: {e}");
            ExitCode::FAILURE
        }
    }
}
