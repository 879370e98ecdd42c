//! `calibrate --points` with its defaults on campaigns it was not tuned for
//! (docs/calibration.md, table E, "The defaults on unknown spreads and noise"): true
//! joint spreads and tracker noise levels the defaults do not know, planted gross
//! errors, and clean campaigns that must never be refused.
//!
//! * **Accuracy grid**: for each true joint spread `s` (Gaussian, truncated at 3 sigma)
//!   and tracker noise scale `k` (the class preset times `k`), `n` campaigns from
//!   [`cell_first_campaign`] on are calibrated twice: with the defaults (noise model:
//!   the unscaled preset; variance factors, joint and ball priors estimated; outliers
//!   removed by data snooping), and by the reference, the plain bundle fit given the
//!   truth (joint prior `s`, ball prior the scene's, noise model the tracker's true
//!   one). Ratio = mean held-out max (defaults) / mean held-out max (reference), per
//!   translation (um) and rotation (arcsec), with its standard error
//!   ([`Cell::ratio_se`]).
//! * **Gross errors** planted in the point export of a clean campaign (spread 0.1 mm,
//!   the preset tracker): one ball moved by 0.1-0.5 mm in a random direction, two balls'
//!   names swapped in one pose, one fiducial moved by 0.1-0.5 mm; found = the removed
//!   (or refused) point is the planted one, named by its line.
//! * **Clean draws**: campaigns cycling through the grid's cells, calibrated with the
//!   defaults; refused = the command would have refused the campaign.

use std::fmt::Write as _;
use std::time::Instant;

use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64;

use super::bundle_data;
use super::campaign::{simulate_with_truth, CampaignSeeds, SimulatedCampaign, TrackerSetup};
use super::files::{format_export, parse_export, PointPose, PointRecord};
use super::study::{StudyConfig, TruthModel};
use crate::calib::adjust::{adjust, AdjustConfig, Adjustment};
use crate::calib::bundle::{self, BundleConfig};
use crate::eval::{accuracy, Accuracy};
use m2ctl::sim::tracker::TrackerNoise;

/// Default true joint spreads of the grid (mm).
pub const DEFAULT_SPREADS: [f64; 4] = [0.05, 0.1, 0.2, 0.5];
/// Default tracker noise scales of the grid (times the class preset).
pub const DEFAULT_SCALES: [f64; 4] = [0.3, 1.0, 2.0, 3.0];
/// Default campaigns per grid cell.
pub const DEFAULT_CELL_CAMPAIGNS: usize = 10;
/// Default clean draws.
pub const DEFAULT_CLEAN_DRAWS: usize = 200;
/// Default campaigns per planted gross error.
pub const DEFAULT_GROSS_CAMPAIGNS: usize = 10;
/// Planted single-ball errors (mm).
pub const BALL_ERRORS_MM: [f64; 4] = [0.1, 0.2, 0.3, 0.5];
/// Planted fiducial moves (mm).
pub const FIDUCIAL_MOVES_MM: [f64; 3] = [0.1, 0.3, 0.5];
/// First campaign number of the gross-error campaigns (apart from the grid's).
pub const GROSS_FIRST_CAMPAIGN: u64 = 5001;
/// First campaign number of the clean draws.
pub const CLEAN_FIRST_CAMPAIGN: u64 = 9001;

/// Settings of the study.
#[derive(Clone, Debug)]
pub struct RobustConfig {
    /// Plan, held-out poses, targets, tracker placement (its noise is replaced per cell).
    pub base: StudyConfig,
    /// The noise model the defaults assume (the preset of `--tracker`).
    pub model: TrackerNoise,
    /// True joint spreads (mm).
    pub spreads: Vec<f64>,
    /// Tracker noise scales.
    pub scales: Vec<f64>,
    /// Campaigns per cell.
    pub campaigns: usize,
    /// Campaigns per planted gross error (0: none).
    pub gross_campaigns: usize,
    /// Clean draws (0: none).
    pub clean_draws: usize,
    /// The defaults' settings (ball prior start: the target file's).
    pub adjust: AdjustConfig,
}

impl RobustConfig {
    /// The study of docs/calibration.md (table E) with `base`'s setup.
    pub fn new(base: StudyConfig) -> Self {
        let ball = base.setup.targets.ball_sigma_mm;
        Self {
            model: base.setup.noise,
            base,
            spreads: DEFAULT_SPREADS.to_vec(),
            scales: DEFAULT_SCALES.to_vec(),
            campaigns: DEFAULT_CELL_CAMPAIGNS,
            gross_campaigns: DEFAULT_GROSS_CAMPAIGNS,
            clean_draws: DEFAULT_CLEAN_DRAWS,
            adjust: AdjustConfig::estimated(ball),
        }
    }

    fn setup(&self, scale: f64) -> TrackerSetup {
        TrackerSetup {
            noise: self.model.scaled(scale),
            ..self.base.setup.clone()
        }
    }

    /// Campaign `k` with true spread `spread` and noise scale `scale`, its point export
    /// numbered as the file `format_export` writes (so that lines are real).
    pub fn campaign(&self, k: u64, spread: f64, scale: f64) -> Result<SimulatedCampaign, String> {
        let seeds = CampaignSeeds::from_one(k);
        let truth =
            TruthModel::Gaussian { sigma_mm: spread }.draw(&self.base.nominal, seeds.geometry);
        let mut c = simulate_with_truth(
            &self.base.nominal,
            &truth,
            &self.setup(scale),
            &self.base.plan,
            seeds,
        )?;
        c.points = numbered(&c.points)?;
        Ok(c)
    }

    /// The defaults on a point list.
    pub fn run_defaults(
        &self,
        c: &SimulatedCampaign,
        points: &[PointRecord],
    ) -> Result<Adjustment, String> {
        let data = bundle_data(
            &self.base.setup.targets,
            points,
            &c.strokes,
            &self.base.nominal,
            &self.model,
        )
        .map_err(|e| format!("line {}: {}", e.error.line, e.error.message))?;
        adjust(&data, &self.adjust).map_err(|e| e.to_string())
    }

    /// The reference: the plain bundle fit given the true spread and noise model.
    pub fn run_reference(
        &self,
        c: &SimulatedCampaign,
        spread: f64,
        scale: f64,
    ) -> Result<bundle::BundleFit, String> {
        let data = bundle_data(
            &self.base.setup.targets,
            &c.points,
            &c.strokes,
            &self.base.nominal,
            &self.model.scaled(scale),
        )
        .map_err(|e| e.to_string())?;
        bundle::fit_plain(
            &data,
            &BundleConfig::with_priors(spread, self.base.setup.targets.ball_sigma_mm),
        )
        .map_err(|e| e.to_string())
    }
}

/// The records as the export file numbers them (written, then parsed).
pub fn numbered(points: &[PointRecord]) -> Result<Vec<PointRecord>, String> {
    parse_export(&format_export(points, "simulated")).map_err(|e| e.to_string())
}

/// Largest |error| over the translation axes (um) and the rotation axes (arcsec).
pub fn max2(a: &Accuracy) -> [f64; 2] {
    [
        a.max_abs[..3].iter().fold(0.0f64, |m, v| m.max(*v)),
        a.max_abs[3..].iter().fold(0.0f64, |m, v| m.max(*v)),
    ]
}

/// One grid cell.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Cell {
    /// True spread (mm).
    pub spread: f64,
    /// Noise scale.
    pub scale: f64,
    /// Campaigns.
    pub n: usize,
    /// Mean held-out max with the defaults (um, arcsec).
    pub defaults: [f64; 2],
    /// ... with the reference.
    pub reference: [f64; 2],
    /// Largest per-campaign ratio defaults / reference (um, arcsec).
    pub worst_ratio: [f64; 2],
    /// Mean estimated joint spread (mm).
    pub joint_prior_mm: f64,
    /// Mean estimated range and transverse sigma factors (sqrt of the variance factors).
    pub noise_factor: [f64; 2],
    /// Campaigns whose a-priori model failed the global test.
    pub global_rejected: usize,
    /// Points removed in all campaigns.
    pub removed: usize,
    /// Refused campaigns.
    pub refused: usize,
    /// Mean wall time of the defaults (s) and of the reference (s).
    pub seconds: [f64; 2],
    /// Per campaign: held-out max with the defaults and with the reference (um, arcsec).
    pub pairs: Vec<([f64; 2], [f64; 2])>,
}

impl Cell {
    /// Ratio of the means (um, arcsec).
    pub fn ratio(&self) -> [f64; 2] {
        [
            self.defaults[0] / self.reference[0],
            self.defaults[1] / self.reference[1],
        ]
    }

    /// Standard error of [`Cell::ratio`] over the campaigns (um, arcsec): the delta
    /// method for a ratio of paired means, `sd(a_k - R b_k) / (mean(b) sqrt(n))`; NaN
    /// with fewer than two campaigns.
    pub fn ratio_se(&self) -> [f64; 2] {
        let n = self.pairs.len();
        let r = self.ratio();
        [0, 1].map(|a| {
            if n < 2 {
                return f64::NAN;
            }
            let d: Vec<f64> = self.pairs.iter().map(|(x, y)| x[a] - r[a] * y[a]).collect();
            let m = d.iter().sum::<f64>() / n as f64;
            let var = d.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1) as f64;
            (var / n as f64).sqrt() / self.reference[a]
        })
    }
}

/// First campaign number of a grid cell: a function of its spread and noise scale only,
/// so that a cell run alone (`--spreads`, `--scales`) draws the same campaigns as in the
/// whole table. The default grid's cells are numbered in table order (`1 + 1000 i`);
/// any other cell from its values.
pub fn cell_first_campaign(spread: f64, scale: f64) -> u64 {
    let default_index = DEFAULT_SPREADS
        .iter()
        .position(|s| *s == spread)
        .zip(DEFAULT_SCALES.iter().position(|k| *k == scale))
        .map(|(i, j)| (i * DEFAULT_SCALES.len() + j) as u64);
    let index = default_index.unwrap_or_else(|| {
        // Outside the default grid: 100 + the values in um and per mille, so distinct
        // cells get distinct campaigns.
        100 + (spread * 1e3).round() as u64 * 10_000 + (scale * 1e3).round() as u64
    });
    1 + 1000 * index
}

/// Runs one grid cell.
pub fn run_cell(cfg: &RobustConfig, spread: f64, scale: f64, first: u64) -> Result<Cell, String> {
    let mut cell = Cell {
        spread,
        scale,
        ..Cell::default()
    };
    for k in first..first + cfg.campaigns as u64 {
        let c = cfg.campaign(k, spread, scale)?;
        let t0 = Instant::now();
        let d = match cfg.run_defaults(&c, &c.points) {
            Ok(d) => d,
            Err(_) => {
                cell.refused += 1;
                continue;
            }
        };
        let t1 = Instant::now();
        let r = cfg.run_reference(&c, spread, scale)?;
        let t2 = Instant::now();
        let score = |p| accuracy(p, &c.truth, &cfg.base.targets).map_err(|e| e.to_string());
        let (ad, ar) = (max2(&score(&d.fit.params)?), max2(&score(&r.params)?));
        cell.n += 1;
        cell.pairs.push((ad, ar));
        for a in 0..2 {
            cell.defaults[a] += ad[a];
            cell.reference[a] += ar[a];
            cell.worst_ratio[a] = cell.worst_ratio[a].max(ad[a] / ar[a]);
        }
        cell.joint_prior_mm += d
            .spread_posterior
            .as_ref()
            .map(|p| p.median_mm)
            .or(d.joint_prior_mm)
            .unwrap_or(f64::NAN);
        cell.noise_factor[0] += d.components[0].factor.sqrt();
        cell.noise_factor[1] += d.components[1].factor.sqrt();
        cell.global_rejected += usize::from(!d.global_before.passed);
        cell.removed += d.removed.len();
        cell.seconds[0] += (t1 - t0).as_secs_f64();
        cell.seconds[1] += (t2 - t1).as_secs_f64();
    }
    let n = cell.n.max(1) as f64;
    for a in 0..2 {
        cell.defaults[a] /= n;
        cell.reference[a] /= n;
        cell.noise_factor[a] /= n;
        cell.seconds[a] /= n;
    }
    cell.joint_prior_mm /= n;
    Ok(cell)
}

/// Outcome of one planted gross error.
#[derive(Clone, Debug, PartialEq)]
pub struct Planted {
    /// What was planted.
    pub kind: String,
    /// Its size (mm; 0 for a swap).
    pub size_mm: f64,
    /// Campaigns.
    pub n: usize,
    /// Found and named (removed first, or refused naming its line).
    pub found: usize,
    /// Good points removed besides it (all campaigns).
    pub extra_removed: usize,
    /// Refused campaigns (the swap's expected outcome).
    pub refused: usize,
    /// Its minimal detectable bias (mean over the campaigns, mm; NaN if unknown).
    pub mdb_mm: f64,
    /// One example message.
    pub example: String,
}

fn random_unit(rng: &mut Pcg64) -> [f64; 3] {
    loop {
        let v: [f64; 3] = [0, 1, 2].map(|_| StandardNormal.sample(&mut *rng));
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if n > 1e-6 {
            return v.map(|x| x / n);
        }
    }
}

/// Plants a moved point (`pick` chooses its index) and checks that the defaults name it.
fn plant_move(
    cfg: &RobustConfig,
    kind: &str,
    size_mm: f64,
    fiducial: bool,
) -> Result<Planted, String> {
    let mut out = Planted {
        kind: kind.into(),
        size_mm,
        n: 0,
        found: 0,
        extra_removed: 0,
        refused: 0,
        mdb_mm: 0.0,
        example: String::new(),
    };
    let mut mdb_n = 0usize;
    for k in GROSS_FIRST_CAMPAIGN..GROSS_FIRST_CAMPAIGN + cfg.gross_campaigns as u64 {
        let c = cfg.campaign(k, 0.1, 1.0)?;
        let mut rng = Pcg64::seed_from_u64(k ^ 0x6055);
        let candidates: Vec<usize> = c
            .points
            .iter()
            .enumerate()
            .filter(|(_, p)| (p.pose == PointPose::Base) == fiducial)
            .map(|(i, _)| i)
            .collect();
        let i = candidates[rng.random_range(0..candidates.len())];
        let u = random_unit(&mut rng);
        let mut pts = c.points.clone();
        for (y, u) in pts[i].y_mm.iter_mut().zip(u.iter()) {
            *y += size_mm * u;
        }
        let line = pts[i].line;
        out.n += 1;
        match cfg.run_defaults(&c, &pts) {
            Ok(d) => {
                let hit = d.removed.first().is_some_and(|o| o.test.line == line);
                out.found += usize::from(hit);
                out.extra_removed += d.removed.iter().filter(|o| o.test.line != line).count();
                if let Some(o) = d.removed.iter().find(|o| o.test.line == line) {
                    if out.example.is_empty() {
                        out.example = format!(
                            "line {}: {} removed, T = {:.1} > {:.1}, estimated error {:.0} um (planted {:.0} um)",
                            o.test.line,
                            o.test.what,
                            o.test.t,
                            o.critical,
                            (o.test.error_mm.iter().map(|v| v * v).sum::<f64>()).sqrt() * 1e3,
                            size_mm * 1e3
                        );
                    }
                    if o.test.mdb_mm.is_finite() {
                        out.mdb_mm += o.test.mdb_mm;
                        mdb_n += 1;
                    }
                } else if let Some(t) = d.tests.iter().find(|t| t.line == line) {
                    if t.mdb_mm.is_finite() {
                        out.mdb_mm += t.mdb_mm;
                        mdb_n += 1;
                    }
                }
            }
            Err(e) => {
                out.refused += 1;
                if e.contains(&format!("line {line}")) {
                    out.found += 1;
                }
                if out.example.is_empty() {
                    out.example = e;
                }
            }
        }
    }
    out.mdb_mm = if mdb_n > 0 {
        out.mdb_mm / mdb_n as f64
    } else {
        f64::NAN
    };
    Ok(out)
}

/// Swaps the names of two balls of one pose: refused before the fit, both lines named.
fn plant_swap(cfg: &RobustConfig) -> Result<Planted, String> {
    let mut out = Planted {
        kind: "two balls' names swapped in one pose".into(),
        size_mm: 0.0,
        n: 0,
        found: 0,
        extra_removed: 0,
        refused: 0,
        mdb_mm: f64::NAN,
        example: String::new(),
    };
    for k in GROSS_FIRST_CAMPAIGN..GROSS_FIRST_CAMPAIGN + cfg.gross_campaigns as u64 {
        let c = cfg.campaign(k, 0.1, 1.0)?;
        let mut rng = Pcg64::seed_from_u64(k ^ 0x5a5a);
        let pose = rng.random_range(1..=c.strokes.len() as u32);
        let idx: Vec<usize> = c
            .points
            .iter()
            .enumerate()
            .filter(|(_, p)| p.pose == PointPose::Pose(pose))
            .map(|(i, _)| i)
            .collect();
        let a = idx[rng.random_range(0..idx.len())];
        let b = loop {
            let b = idx[rng.random_range(0..idx.len())];
            if b != a {
                break b;
            }
        };
        let mut pts = c.points.clone();
        let na = pts[a].name.clone();
        pts[a].name = pts[b].name.clone();
        pts[b].name = na;
        let (la, lb) = (pts[a].line, pts[b].line);
        out.n += 1;
        match cfg.run_defaults(&c, &pts) {
            Ok(d) => {
                let named = d
                    .removed
                    .iter()
                    .filter(|o| o.test.line == la || o.test.line == lb)
                    .count();
                out.found += usize::from(named == 2);
                out.extra_removed += d.removed.len() - named;
            }
            Err(e) => {
                out.refused += 1;
                let named = e.contains(&format!("line {la}")) && e.contains(&format!("line {lb}"));
                out.found += usize::from(named && e.contains("swapped"));
                if out.example.is_empty() {
                    out.example = e;
                }
            }
        }
    }
    Ok(out)
}

/// Runs the planted gross errors.
pub fn run_gross(cfg: &RobustConfig) -> Result<Vec<Planted>, String> {
    let mut out = Vec::new();
    for m in BALL_ERRORS_MM {
        out.push(plant_move(cfg, "one ball moved", m, false)?);
    }
    out.push(plant_swap(cfg)?);
    for m in FIDUCIAL_MOVES_MM {
        out.push(plant_move(cfg, "one fiducial moved", m, true)?);
    }
    Ok(out)
}

/// Clean draws: (draws, refused, campaigns with a removal, points removed, failures of
/// the a-priori global test, mean seconds).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CleanDraws {
    /// Draws.
    pub n: usize,
    /// Refused campaigns (with the message of the first).
    pub refused: usize,
    /// The first refusal's message.
    pub first_refusal: Option<String>,
    /// Campaigns that lost at least one (good) point.
    pub with_removal: usize,
    /// Good points removed.
    pub removed: usize,
    /// Mean wall time (s).
    pub seconds: f64,
    /// Largest wall time (s).
    pub max_seconds: f64,
}

/// Runs `cfg.clean_draws` clean campaigns, cycling through the grid's cells.
pub fn run_clean(cfg: &RobustConfig) -> Result<CleanDraws, String> {
    let mut out = CleanDraws::default();
    let cells: Vec<(f64, f64)> = cfg
        .spreads
        .iter()
        .flat_map(|s| cfg.scales.iter().map(move |k| (*s, *k)))
        .collect();
    for i in 0..cfg.clean_draws {
        let (s, k) = cells[i % cells.len()];
        let c = cfg.campaign(CLEAN_FIRST_CAMPAIGN + i as u64, s, k)?;
        let t0 = Instant::now();
        let r = cfg.run_defaults(&c, &c.points);
        let dt = t0.elapsed().as_secs_f64();
        out.seconds += dt;
        out.max_seconds = out.max_seconds.max(dt);
        out.n += 1;
        match r {
            Ok(d) => {
                out.with_removal += usize::from(!d.removed.is_empty());
                out.removed += d.removed.len();
            }
            Err(e) => {
                out.refused += 1;
                if out.first_refusal.is_none() {
                    out.first_refusal = Some(format!(
                        "campaign {} (spread {s} mm, noise x{k}): {e}",
                        CLEAN_FIRST_CAMPAIGN + i as u64
                    ));
                }
            }
        }
    }
    out.seconds /= out.n.max(1) as f64;
    Ok(out)
}

/// The whole study as Markdown.
pub fn robust_study(cfg: &RobustConfig, progress: &mut dyn FnMut(&str)) -> Result<String, String> {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Defaults of `calibrate --points` (noise model: {}; variance factors, joint and ball priors estimated; outliers removed at family alpha {}) against the bundle fit given the truth (joint prior = the true spread, the tracker's true noise model). {} campaigns per cell, {} plan poses, {} held-out poses; mean held-out max (um / arcsec).\n",
        cfg.model.describe(),
        cfg.adjust.alpha,
        cfg.campaigns,
        cfg.base.plan.len(),
        cfg.base.targets.len()
    );
    if cfg.campaigns > 0 {
        let _ = writeln!(s, "| true spread mm | noise x preset | defaults max um / \" | given the truth | ratio um / \" (mean) | its standard error | worst campaign ratio | estimated spread mm (posterior median) | estimated range / transverse noise x model | a-priori model rejected | removed | refused | s per fit (defaults / reference) |");
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|---|");
        let mut worst = [0.0f64; 2];
        for sp in &cfg.spreads {
            for k in &cfg.scales {
                let c = run_cell(cfg, *sp, *k, cell_first_campaign(*sp, *k))?;
                let r = c.ratio();
                let se = c.ratio_se();
                worst[0] = worst[0].max(r[0]);
                worst[1] = worst[1].max(r[1]);
                let row = format!(
                    "| {sp} | {k} | {:.2} / {:.2} | {:.2} / {:.2} | {:.3} / {:.3} | {:.3} / {:.3} | {:.2} / {:.2} | {:.3} | {:.2} / {:.2} | {}/{} | {} | {} | {:.2} / {:.2} |",
                    c.defaults[0], c.defaults[1], c.reference[0], c.reference[1], r[0], r[1], se[0], se[1],
                    c.worst_ratio[0], c.worst_ratio[1], c.joint_prior_mm,
                    c.noise_factor[0], c.noise_factor[1], c.global_rejected, c.n, c.removed, c.refused,
                    c.seconds[0], c.seconds[1]
                );
                progress(&row);
                let _ = writeln!(s, "{row}");
            }
        }
        let _ = writeln!(
            s,
            "\nLargest cell ratio: {:.3} (um) / {:.3} (arcsec); goal 1.1.\n",
            worst[0], worst[1]
        );
    }
    if cfg.gross_campaigns > 0 {
        let _ = writeln!(
            s,
            "Planted gross errors ({} campaigns each, true spread 0.1 mm, the preset tracker):\n",
            cfg.gross_campaigns
        );
        let _ = writeln!(s, "| planted | size mm | found and named | refused | good points also removed | its MDB mm (80 %) | example |");
        let _ = writeln!(s, "|---|---|---|---|---|---|---|");
        for p in run_gross(cfg)? {
            let row = format!(
                "| {} | {} | {}/{} | {} | {} | {} | {} |",
                p.kind,
                if p.size_mm > 0.0 {
                    format!("{}", p.size_mm)
                } else {
                    "-".into()
                },
                p.found,
                p.n,
                p.refused,
                p.extra_removed,
                if p.mdb_mm.is_finite() {
                    format!("{:.3}", p.mdb_mm)
                } else {
                    "-".into()
                },
                p.example.replace('|', "/")
            );
            progress(&row);
            let _ = writeln!(s, "{row}");
        }
        s.push('\n');
    }
    if cfg.clean_draws > 0 {
        let c = run_clean(cfg)?;
        let _ = writeln!(
            s,
            "Clean draws: {} campaigns (campaigns {}.., cycling through the {} cells): **{} refused**; {} lost a good point to the outlier test ({} points in all); {:.2} s per calibration (max {:.2} s).{}",
            c.n,
            CLEAN_FIRST_CAMPAIGN,
            cfg.spreads.len() * cfg.scales.len(),
            c.refused,
            c.with_removal,
            c.removed,
            c.seconds,
            c.max_seconds,
            c.first_refusal.map(|m| format!(" First refusal: {m}")).unwrap_or_default()
        );
    }
    Ok(s)
}
