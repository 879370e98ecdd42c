//! Research: the calibration study's subcommands (the paper's Table 3, solver
//! comparison and bench, the tracker-path studies and the paper's experiment). They
//! build on the operations' argument groups, never the other way round.

use std::path::PathBuf;

use m2calib::calib::SolverKind;
use m2calib::report::{bench, compare_cuckoo, table3, TableConfig};

use crate::ops::{SolverCli, TrackerCli};

#[derive(clap::Args)]
pub(crate) struct CompareCli {
    #[command(flatten)]
    solver_cli: SolverCli,
    /// Solver seeds 1..=N.
    #[arg(long, default_value_t = 5)]
    seeds: u64,
}

/// Settings of the tracker-path studies.
#[derive(clap::Args, Clone)]
pub(crate) struct StudyCli {
    #[command(flatten)]
    tracker: TrackerCli,
    /// True joints: gauss:SIGMA_MM (truncated at 3 sigma) or uniform:HALF_MM.
    #[arg(long, default_value = "gauss:0.1")]
    truth: String,
    /// Prior spread of the joints in the bundle fit (mm); default: the truth's sigma.
    #[arg(long)]
    joint_prior_mm: Option<f64>,
    /// Number of simulated campaigns.
    #[arg(long, default_value_t = m2calib::tracker::study::DEFAULT_TABLE_CAMPAIGNS)]
    campaigns: usize,
    /// Number of the first campaign (seeds).
    #[arg(long, default_value_t = 1)]
    first_campaign: u64,
}

impl StudyCli {
    fn config(&self) -> Result<m2calib::tracker::study::StudyConfig, String> {
        use m2calib::tracker::study::{StudyConfig, TruthModel};
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
pub(crate) struct TrackerStatsCli {
    #[command(flatten)]
    study: StudyCli,
    /// Tracker noise scales (the --tracker preset times each).
    #[arg(long, value_delimiter = ',', default_values_t = m2calib::tracker::study::DEFAULT_SWEEP_SCALES)]
    scales: Vec<f64>,
    /// Write the predicted-vs-measured plot (SVG).
    #[arg(long)]
    plot: Option<PathBuf>,
}

#[derive(clap::Args)]
pub(crate) struct TrackerPlanCli {
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
pub(crate) struct TrackerDefaultsCli {
    #[command(flatten)]
    tracker: TrackerCli,
    /// True joint spreads (mm, Gaussian, truncated at 3 sigma).
    #[arg(long, value_delimiter = ',', default_values_t = m2calib::tracker::robust::DEFAULT_SPREADS)]
    spreads: Vec<f64>,
    /// Tracker noise scales (the --tracker preset times each).
    #[arg(long, value_delimiter = ',', default_values_t = m2calib::tracker::robust::DEFAULT_SCALES)]
    scales: Vec<f64>,
    /// Campaigns per (spread, scale) cell.
    #[arg(long, default_value_t = m2calib::tracker::robust::DEFAULT_CELL_CAMPAIGNS)]
    campaigns: usize,
    /// Campaigns per planted gross error (0: none).
    #[arg(long, default_value_t = m2calib::tracker::robust::DEFAULT_GROSS_CAMPAIGNS)]
    gross_campaigns: usize,
    /// Clean campaigns that must not be refused (0: none).
    #[arg(long, default_value_t = m2calib::tracker::robust::DEFAULT_CLEAN_DRAWS)]
    clean_draws: usize,
}

#[derive(clap::Args)]
pub(crate) struct PaperExperimentCli {
    #[command(flatten)]
    study: StudyCli,
    /// Write the per-pose error plot (SVG).
    #[arg(long)]
    plot: Option<PathBuf>,
}

#[derive(clap::Args)]
pub(crate) struct TableCli {
    #[command(flatten)]
    solver_cli: SolverCli,
    /// Write the per-pose error plot (SVG).
    #[arg(long)]
    plot: Option<PathBuf>,
}

#[derive(clap::Args)]
pub(crate) struct BenchCli {
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

pub(crate) fn tracker_defaults_cmd(a: &TrackerDefaultsCli) -> Result<(), String> {
    use m2calib::tracker::robust::{robust_study, RobustConfig};
    if a.spreads
        .iter()
        .chain(a.scales.iter())
        .any(|v| !(v.is_finite() && *v > 0.0))
    {
        return Err("--spreads and --scales must be positive numbers".into());
    }
    let base = m2calib::tracker::study::StudyConfig {
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

pub(crate) fn tracker_stats_cmd(a: &TrackerStatsCli) -> Result<(), String> {
    use m2calib::tracker::plots::PredictionGroup;
    use m2calib::tracker::study::{format_prediction_sweep, prediction_sweep, rms3};
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
        m2calib::tracker::plots::predicted_vs_measured(
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

pub(crate) fn tracker_plan_cmd(a: &TrackerPlanCli) -> Result<(), String> {
    use m2calib::calib::design::Criterion;
    use m2calib::tracker::study::plan_study;
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
        let csv = m2calib::plan::format_plan(
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
        m2calib::tracker::plots::plan_map(
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

pub(crate) fn paper_experiment_cmd(a: &PaperExperimentCli) -> Result<(), String> {
    use m2calib::tracker::commands::noise_band;
    use m2calib::tracker::plots::{per_pose, Panel, Series};
    use m2calib::tracker::study::{format_paper_experiment, paper_experiment};
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

/// `m2ground table3`.
pub(crate) fn table3_cmd(a: &TableCli) -> Result<(), String> {
    table3(&table_config(&a.solver_cli, a.plot.clone())).map(|t| print!("{t}"))
}

/// `m2ground compare-cuckoo`.
pub(crate) fn compare_cuckoo_cmd(a: &CompareCli) -> Result<(), String> {
    compare_cuckoo(&table_config(&a.solver_cli, None), a.seeds).map(|t| print!("{t}"))
}

/// `m2ground tracker-table`.
pub(crate) fn tracker_table_cmd(a: &StudyCli) -> Result<(), String> {
    a.config()
        .and_then(|c| m2calib::tracker::study::campaign_table(&c))
        .map(|t| print!("{t}"))
}

/// `m2ground bench`.
pub(crate) fn bench_cmd(a: &BenchCli) -> Result<(), String> {
    bench(&table_config(&a.solver_cli, None), a.repeats).map(|t| print!("{t}"))
}
