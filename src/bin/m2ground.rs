//! `m2ground`: the ground tool of the M2 mechanism controller (host only).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use m2ctl::ground::ikfk::{run_file, IkFk};

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
        };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("m2ground: {e}");
            ExitCode::FAILURE
        }
    }
}
