//! Where the defaults of `calibrate --points` lose against the fit given the truth
//! (docs/calibration.md, table E, "The defaults on unknown spreads and noise"): on the
//! campaigns of one cell of `m2ground tracker-defaults` (same numbering), the held-out
//! max of the defaults and of variants that each change one ingredient, as the ratio to
//! the plain fit given the true spread and noise model (ratio of the means over the
//! campaigns, with its standard error).
//!
//! `cargo run --release --features host --example spread_weighting -- SPREAD_MM SCALE CAMPAIGNS`
//!
//! Variants (all from the same adjustment unless stated):
//! * `defaults`: the averaged fit over the spread grid (log-uniform hyperprior).
//! * `true spread`: the defaults' noise factors and ball prior, the joint prior at the
//!   true spread (what knowing the spread alone would give).
//! * `posterior median`, `posterior geometric mean`, `posterior mode`: one MAP fit at
//!   that spread instead of the average.
//! * `type-II ML spread`: the fit at the variance-component estimate of the spread.
//! * `hyperprior uniform in s`, `hyperprior 1/s in log s`, `hyperprior up to 0.5 mm`:
//!   the grid's fits re-averaged with another hyperprior.
//! * `ball prior fixed`: a second adjustment with the ball prior at the target file's
//!   value.
//! * `true noise model`: a second adjustment weighted with the simulated tracker's true
//!   model, noise not estimated, ball prior fixed (only the spread unknown).

use m2calib::calib::adjust::{adjust, Adjustment, PriorSetting};
use m2calib::calib::bundle::{self, Bundle, BundleConfig, Priors};
use m2calib::calib::from_vec;
use m2calib::eval::accuracy;
use m2calib::tracker::bundle_data;
use m2calib::tracker::robust::{cell_first_campaign, max2, Cell, RobustConfig};
use m2calib::tracker::study::StudyConfig;
use m2ctl::kinematics::GeometryParams;

/// The variants in output order.
const VARIANTS: [&str; 11] = [
    "defaults",
    "true spread",
    "posterior median",
    "posterior geometric mean",
    "posterior mode",
    "type-II ML spread",
    "hyperprior uniform in s",
    "hyperprior 1/s in log s",
    "hyperprior up to 0.5 mm",
    "ball prior fixed",
    "true noise model",
];

/// The MAP fit of the defaults' data, noise factors and ball prior at joint spread `s`.
fn fit_at(d: &Adjustment, s: f64) -> Result<GeometryParams, String> {
    let mut b = Bundle::new(
        &d.data,
        Priors {
            joint_sigma_mm: Some(s),
            ball_sigma_mm: d.ball_prior_mm,
        },
    )
    .map_err(|e| e.to_string())?;
    b.set_variance_factors(&d.factors());
    let (x, _, _) = bundle::solve(&b, d.fit.x.clone(), &BundleConfig::unbounded())
        .map_err(|e| e.to_string())?;
    Ok(from_vec(&b.joints(&x), &d.data.nominal))
}

/// The grid's fits averaged with the posterior times `hyper(s)` (relative to the
/// log-uniform hyperprior).
fn reweighted(d: &Adjustment, hyper: &dyn Fn(f64) -> f64) -> Result<GeometryParams, String> {
    let post = d.spread_posterior.as_ref().ok_or("no spread posterior")?;
    let w: Vec<f64> = post
        .weights
        .iter()
        .zip(&post.grid_mm)
        .map(|(w, s)| w * hyper(*s))
        .collect();
    let sum: f64 = w.iter().sum();
    let mut x = vec![0.0; post.grid_x[0].len()];
    for (wi, xi) in w.iter().zip(&post.grid_x) {
        for (a, v) in x.iter_mut().zip(xi) {
            *a += wi / sum * v;
        }
    }
    let b = Bundle::new(
        &d.data,
        Priors {
            joint_sigma_mm: Some(post.median_mm),
            ball_sigma_mm: d.ball_prior_mm,
        },
    )
    .map_err(|e| e.to_string())?;
    Ok(from_vec(&b.joints(&x), &d.data.nominal))
}

fn main() -> Result<(), String> {
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .map(|a| a.parse::<f64>().map_err(|e| format!("{a}: {e}")))
        .collect::<Result<_, _>>()?;
    let [spread, scale, campaigns] = args[..] else {
        return Err("usage: spread_weighting SPREAD_MM SCALE CAMPAIGNS".into());
    };
    let cfg = RobustConfig::new(StudyConfig::default());
    let ball_mm = cfg.base.setup.targets.ball_sigma_mm;
    let first = cell_first_campaign(spread, scale);
    let mut cells: Vec<Cell> = VARIANTS.iter().map(|_| Cell::default()).collect();
    for k in first..first + campaigns as u64 {
        let c = cfg.campaign(k, spread, scale)?;
        let score = |g: &GeometryParams| -> Result<[f64; 2], String> {
            Ok(max2(
                &accuracy(g, &c.truth, &cfg.base.targets).map_err(|e| e.to_string())?,
            ))
        };
        let reference = score(&cfg.run_reference(&c, spread, scale)?.params)?;
        let d = cfg.run_defaults(&c, &c.points)?;
        let post = d.spread_posterior.as_ref().ok_or("no spread posterior")?;
        let log_mean: f64 = post
            .weights
            .iter()
            .zip(&post.grid_mm)
            .map(|(w, s)| w * s.ln())
            .sum();
        let mode = post
            .weights
            .iter()
            .zip(&post.grid_mm)
            .max_by(|a, b| a.0.total_cmp(b.0))
            .map(|(_, s)| *s)
            .ok_or("empty grid")?;
        let data = |noise| {
            bundle_data(
                &cfg.base.setup.targets,
                &c.points,
                &c.strokes,
                &cfg.base.nominal,
                noise,
            )
            .map_err(|e| e.to_string())
        };
        let mut ball_fixed = cfg.adjust;
        ball_fixed.ball_prior = PriorSetting::Fixed(ball_mm);
        let mut true_noise = ball_fixed;
        true_noise.estimate_noise = false;
        let params = [
            d.fit.params,
            fit_at(&d, spread)?,
            fit_at(&d, post.median_mm)?,
            fit_at(&d, log_mean.exp())?,
            fit_at(&d, mode)?,
            fit_at(&d, d.joint_prior_mm.ok_or("no joint prior")?)?,
            reweighted(&d, &|s| s)?,
            reweighted(&d, &|s| 1.0 / s)?,
            reweighted(&d, &|s| if s <= 0.5 { 1.0 } else { 0.0 })?,
            adjust(&data(&cfg.model)?, &ball_fixed)
                .map_err(|e| e.to_string())?
                .fit
                .params,
            adjust(&data(&cfg.model.scaled(scale))?, &true_noise)
                .map_err(|e| e.to_string())?
                .fit
                .params,
        ];
        for (cell, p) in cells.iter_mut().zip(&params) {
            cell.pairs.push((score(p)?, reference));
        }
        eprintln!("campaign {k} done");
    }
    println!(
        "Cell: true spread {spread} mm, noise x{scale}; campaigns {first}..{} (as `m2ground tracker-defaults`). Ratio of the mean held-out max to the fit given the truth, um / arcsec, +- 1 standard error.\n",
        first + campaigns as u64 - 1
    );
    println!("| variant | ratio um / \" | standard error |\n|---|---|---|");
    for (name, cell) in VARIANTS.iter().zip(cells.iter_mut()) {
        let n = cell.pairs.len() as f64;
        for a in 0..2 {
            cell.defaults[a] = cell.pairs.iter().map(|p| p.0[a]).sum::<f64>() / n;
            cell.reference[a] = cell.pairs.iter().map(|p| p.1[a]).sum::<f64>() / n;
        }
        let (r, se) = (cell.ratio(), cell.ratio_se());
        println!(
            "| {name} | {:.3} / {:.3} | {:.3} / {:.3} |",
            r[0], r[1], se[0], se[1]
        );
    }
    Ok(())
}
