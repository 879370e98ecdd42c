//! The figures of the tracker path (docs/calibration.md, "Calibration from laser-tracker
//! points"), each a function returning Markdown: the campaign table ([`campaign_table`]),
//! predicted vs measured accuracy over many campaigns ([`prediction_check`]), the
//! optimal plan ([`plan_study`]) and the paper's experiment ([`paper_experiment`]).
//!
//! Every campaign `k` draws its true joints, its scene (balls, fiducials) and its tracker
//! noise from seeds derived from `k` ([`CampaignSeeds::from_one`]); held-out poses are
//! the idealised path's (200 uniform in +-1 mm, +-60", seed 518002), commanded with the
//! calibrated parameters on the true mechanism.

use std::fmt::Write as _;

use nalgebra::Point3;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64;

use super::campaign::{
    nominal_data, simulate_with_truth, CampaignSeeds, SimulatedCampaign, TrackerSetup,
};
use super::files::PointPose;
use crate::calib::bundle::{self, BundleConfig, BundleFit, PredictedAccuracy};
use crate::calib::design::{self, Criterion};
use crate::calib::registration::pose_from_balls;
use crate::calib::{calibrate, CalibConfig, Measurement};
use crate::eval::{accuracy, pose_error, random_poses, Accuracy};
use crate::eval::{DEFAULT_EVAL_POSES, DEFAULT_EVAL_ROTATION_ARCSEC, DEFAULT_EVAL_TRANSLATION_MM};
use crate::plan::{plan_poses, PlanConfig};
use crate::report::DEFAULT_EVAL_SEED;
use m2ctl::kinematics::{fk, FkConfig, Geometry, GeometryParams, Pose};
use m2ctl::nominal::PROTOTYPE;
use m2ctl::sim::manufacturing::{perturbed, DEFAULT_JOINT_SIGMA_MM};
use m2ctl::sim::tracker::{true_motion, TrackerNoise};
use m2ctl::units::MM_PER_M;

/// How the true joints scatter about nominal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TruthModel {
    /// Gaussian, `sigma_mm` per coordinate, truncated at 3 sigma (the simulated plant's).
    Gaussian {
        /// Standard deviation (mm).
        sigma_mm: f64,
    },
    /// Uniform in `+-half_mm` per coordinate (the "within +-0.3 mm").
    Uniform {
        /// Half-width (mm).
        half_mm: f64,
    },
}

impl TruthModel {
    /// Standard deviation of a coordinate (mm): the matched prior.
    pub fn sigma_mm(&self) -> f64 {
        match self {
            TruthModel::Gaussian { sigma_mm } => *sigma_mm,
            TruthModel::Uniform { half_mm } => half_mm / 3f64.sqrt(),
        }
    }

    /// A true geometry from `seed`.
    pub fn draw(&self, nominal: &GeometryParams, seed: u64) -> GeometryParams {
        match self {
            TruthModel::Gaussian { sigma_mm } => perturbed(nominal, *sigma_mm, seed),
            TruthModel::Uniform { half_mm } => {
                let mut rng = Pcg64::seed_from_u64(seed);
                let mut out = *nominal;
                for leg in out.legs.iter_mut() {
                    for v in leg.a_mm.iter_mut().chain(leg.b_mm.iter_mut()) {
                        *v += rng.random_range(-1.0..=1.0) * half_mm;
                    }
                }
                out
            }
        }
    }

    /// Parses `gauss:SIGMA` or `uniform:HALF` (mm).
    pub fn parse(s: &str) -> Option<Self> {
        let (kind, v) = s.split_once(':')?;
        let v: f64 = v
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite() && *v >= 0.0)?;
        match kind {
            "gauss" => Some(TruthModel::Gaussian { sigma_mm: v }),
            "uniform" => Some(TruthModel::Uniform { half_mm: v }),
            _ => None,
        }
    }

    /// Description for reports.
    pub fn describe(&self) -> String {
        match self {
            TruthModel::Gaussian { sigma_mm } => {
                format!("Gaussian sigma {sigma_mm} mm (truncated at 3 sigma)")
            }
            TruthModel::Uniform { half_mm } => format!("uniform +-{half_mm} mm"),
        }
    }
}

/// Settings of a study.
#[derive(Clone, Debug)]
pub struct StudyConfig {
    /// Nominal geometry.
    pub nominal: GeometryParams,
    /// The true joints' spread.
    pub truth: TruthModel,
    /// Balls, fiducials, tracker.
    pub setup: TrackerSetup,
    /// Prior spread of the joints in the bundle fit (mm); `None`: the truth's sigma.
    pub joint_prior_sigma_mm: Option<f64>,
    /// Calibration plan (default: the paper's 120 poses).
    pub plan: Vec<Pose<f64>>,
    /// Held-out poses.
    pub targets: Vec<Pose<f64>>,
    /// Number of campaigns.
    pub campaigns: usize,
    /// Campaign number of the first campaign.
    pub first_campaign: u64,
    /// Monte-Carlo draws of the predicted maximum.
    pub mc_draws: usize,
}

/// Default campaigns of the table.
pub const DEFAULT_TABLE_CAMPAIGNS: usize = 20;

impl Default for StudyConfig {
    fn default() -> Self {
        Self {
            nominal: PROTOTYPE,
            truth: TruthModel::Gaussian {
                sigma_mm: DEFAULT_JOINT_SIGMA_MM,
            },
            setup: TrackerSetup::default(),
            joint_prior_sigma_mm: None,
            plan: plan_poses(&PlanConfig::default()),
            targets: random_poses(
                DEFAULT_EVAL_POSES,
                DEFAULT_EVAL_TRANSLATION_MM,
                DEFAULT_EVAL_ROTATION_ARCSEC,
                DEFAULT_EVAL_SEED,
            ),
            campaigns: DEFAULT_TABLE_CAMPAIGNS,
            first_campaign: 1,
            mc_draws: bundle::DEFAULT_MC_DRAWS,
        }
    }
}

impl StudyConfig {
    /// The joint prior used (mm).
    pub fn prior_mm(&self) -> f64 {
        self.joint_prior_sigma_mm.unwrap_or(self.truth.sigma_mm())
    }

    /// Bundle settings with the priors (joints: [`StudyConfig::prior_mm`], balls: the
    /// target file's tolerance).
    pub fn bundle_config(&self) -> BundleConfig {
        BundleConfig::with_priors(self.prior_mm(), self.setup.targets.ball_sigma_mm)
    }

    /// Simulates campaign `k` with `plan`.
    pub fn campaign(&self, k: u64, plan: &[Pose<f64>]) -> Result<SimulatedCampaign, String> {
        let seeds = CampaignSeeds::from_one(k);
        let truth = self.truth.draw(&self.nominal, seeds.geometry);
        simulate_with_truth(&self.nominal, &truth, &self.setup, plan, seeds)
    }

    fn describe(&self) -> String {
        format!(
            "true joints {}; balls {} at {} mm (tolerance {} mm), fiducials {} (drawing tolerance {} mm); tracker {:.2} m away, {}; bundle prior: joints {} mm, balls {} mm; {} held-out poses (+-{} mm, +-{}\"); {} plan poses",
            self.truth.describe(),
            self.setup.targets.balls.len(),
            self.setup.targets.ball_radius_mm(),
            self.setup.targets.ball_sigma_mm,
            self.setup.targets.fiducials.len(),
            self.setup.targets.fiducial_sigma_mm,
            self.setup.placement.distance_mm / MM_PER_M,
            self.setup.noise.describe(),
            self.prior_mm(),
            self.setup.targets.ball_sigma_mm,
            self.targets.len(),
            DEFAULT_EVAL_TRANSLATION_MM,
            DEFAULT_EVAL_ROTATION_ARCSEC,
            self.plan.len()
        )
    }
}

/// The combined RMS of the three translation (or rotation) axes.
pub fn rms3(a: &[f64]) -> f64 {
    (a.iter().map(|v| v * v).sum::<f64>() / a.len().max(1) as f64).sqrt()
}

/// Poses measured from the balls: each pose's balls mapped to B with `registration`
/// inverse and fitted to `balls_m` (weights: inverse mean variance of each point).
pub fn measured_poses(
    c: &SimulatedCampaign,
    balls_m: &[[f64; 3]],
    ball_names: &[String],
    registration: &nalgebra::Isometry3<f64>,
    p0_mm: &[f64; 3],
    noise: &TrackerNoise,
) -> Result<Vec<Pose<f64>>, String> {
    let inv = registration.inverse();
    (1..=c.strokes.len() as u32)
        .map(|k| {
            let mut m = Vec::new();
            let mut b = Vec::new();
            let mut w = Vec::new();
            for p in c.points.iter().filter(|p| p.pose == PointPose::Pose(k)) {
                let Some(i) = ball_names.iter().position(|n| *n == p.name) else {
                    continue;
                };
                let x = inv * Point3::from(p.y_mm);
                m.push(balls_m[i]);
                b.push([x.x, x.y, x.z]);
                w.push(3.0 / noise.covariance_mm2(&p.y_mm).trace().max(f64::MIN_POSITIVE));
            }
            pose_from_balls(&m, &b, Some(&w), p0_mm).map_err(|e| format!("pose {k}: {e}"))
        })
        .collect()
}

/// The naive two-step: poses from the balls with their nominal centres and the fiducial
/// registration, then the idealised pose-based LM calibration.
pub fn naive_two_step(cfg: &StudyConfig, c: &SimulatedCampaign) -> Result<GeometryParams, String> {
    let data = c
        .data(&cfg.nominal, &cfg.setup)
        .map_err(|e| e.to_string())?;
    let reg = bundle::Bundle::new(&data, bundle::Priors::NONE)
        .map_err(|e| e.to_string())?
        .registration(&vec![
            0.0;
            bundle::Layout {
                n_balls: data.ball_names.len()
            }
            .n()
        ]);
    let poses = measured_poses(
        c,
        &data.balls_nominal_m,
        &data.ball_names,
        &reg,
        &cfg.nominal.p0_mm,
        &cfg.setup.noise,
    )?;
    let meas: Vec<Measurement> = poses
        .iter()
        .zip(c.strokes.iter())
        .map(|(p, s)| Measurement {
            line: 0,
            pose: *p,
            strokes_mm: s.strokes_mm,
        })
        .collect();
    calibrate(&cfg.nominal, &meas, &CalibConfig::default())
        .map(|r| r.params)
        .map_err(|e| format!("two-step: {e}"))
}

/// One method's result on one campaign.
#[derive(Clone, Debug)]
pub struct MethodResult {
    /// Held-out accuracy.
    pub acc: Accuracy,
    /// Predicted accuracy (bundle fits).
    pub predicted: Option<PredictedAccuracy>,
}

/// The calibration methods compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Commanding with the nominal parameters.
    Before,
    /// Poses from nominal ball centres, then the pose-based LM.
    NaiveTwoStep,
    /// Bundle fit without priors.
    BundleUnbounded,
    /// Bundle fit with priors toward nominal.
    BundlePrior,
}

impl Method {
    /// Report label.
    pub fn label(&self) -> &'static str {
        match self {
            Method::Before => "before calibration",
            Method::NaiveTwoStep => "two-step, nominal ball centres",
            Method::BundleUnbounded => "bundle, no prior",
            Method::BundlePrior => "bundle with prior",
        }
    }
}

/// Runs `method` on campaign `c`.
pub fn run_method(
    cfg: &StudyConfig,
    c: &SimulatedCampaign,
    method: Method,
) -> Result<(MethodResult, Option<BundleFit>), String> {
    let score = |p: &GeometryParams| accuracy(p, &c.truth, &cfg.targets).map_err(|e| e.to_string());
    match method {
        Method::Before => Ok((
            MethodResult {
                acc: score(&cfg.nominal)?,
                predicted: None,
            },
            None,
        )),
        Method::NaiveTwoStep => Ok((
            MethodResult {
                acc: score(&naive_two_step(cfg, c)?)?,
                predicted: None,
            },
            None,
        )),
        Method::BundleUnbounded | Method::BundlePrior => {
            let bc = if method == Method::BundlePrior {
                cfg.bundle_config()
            } else {
                BundleConfig::unbounded()
            };
            let data = c
                .data(&cfg.nominal, &cfg.setup)
                .map_err(|e| e.to_string())?;
            let fit = bundle::fit(&data, &bc).map_err(|e| e.to_string())?;
            let predicted = bundle::predict_accuracy(
                &fit.params,
                &fit.joint_covariance(),
                &cfg.targets,
                cfg.mc_draws,
                1,
            )?;
            Ok((
                MethodResult {
                    acc: score(&fit.params)?,
                    predicted: Some(predicted),
                },
                Some(fit),
            ))
        }
    }
}

/// Mean over campaigns of one method's figures.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Summary {
    /// Mean held-out max (um, arcsec).
    pub max: [f64; 2],
    /// Mean held-out RMS (um, arcsec; three axes combined).
    pub rms: [f64; 2],
    /// Mean predicted RMS (um, arcsec), if any.
    pub predicted_rms: Option<[f64; 2]>,
    /// Mean predicted expected max (um, arcsec), if any.
    pub predicted_max: Option<[f64; 2]>,
    /// Campaign `first`'s held-out max (um, arcsec).
    pub first_max: [f64; 2],
    /// Campaign `first`'s held-out RMS (um, arcsec).
    pub first_rms: [f64; 2],
}

/// Runs `methods` over the configured campaigns.
pub fn summarise(cfg: &StudyConfig, methods: &[Method]) -> Result<Vec<Summary>, String> {
    let mut out = vec![Summary::default(); methods.len()];
    let mut pred = vec![([0.0; 2], [0.0; 2], 0usize); methods.len()];
    let n = cfg.campaigns.max(1);
    for i in 0..n {
        let k = cfg.first_campaign + i as u64;
        let c = cfg.campaign(k, &cfg.plan)?;
        for (m, method) in methods.iter().enumerate() {
            let (r, _) = run_method(cfg, &c, *method)?;
            let a = &r.acc;
            let s = &mut out[m];
            let mx = [a.max_um(), a.max_arcsec()];
            let rm = [rms3(&a.rms[..3]), rms3(&a.rms[3..])];
            for q in 0..2 {
                s.max[q] += mx[q] / n as f64;
                s.rms[q] += rm[q] / n as f64;
            }
            if i == 0 {
                s.first_max = mx;
                s.first_rms = rm;
            }
            if let Some(p) = &r.predicted {
                let e = &mut pred[m];
                e.0[0] += rms3(&p.rms_sigma[..3]);
                e.0[1] += rms3(&p.rms_sigma[3..]);
                e.1[0] += p.expected_max_combined[0];
                e.1[1] += p.expected_max_combined[1];
                e.2 += 1;
            }
        }
    }
    for (s, (r, m, cnt)) in out.iter_mut().zip(pred) {
        if cnt > 0 {
            s.predicted_rms = Some(r.map(|v| v / cnt as f64));
            s.predicted_max = Some(m.map(|v| v / cnt as f64));
        }
    }
    Ok(out)
}

/// The tracker classes of the campaign table: name, noise.
pub fn table_trackers() -> Vec<(&'static str, TrackerNoise)> {
    vec![
        ("+-(15 um + 6 um/m) class", TrackerNoise::CLASS_15_6),
        (
            "isotropic 15 um",
            TrackerNoise::isotropic(m2ctl::sim::tracker::ISOTROPIC_15_UM),
        ),
        (
            "10x better (class / 10)",
            TrackerNoise::CLASS_15_6.scaled(0.1),
        ),
    ]
}

/// The campaign table: every method, every tracker class of [`table_trackers`].
pub fn campaign_table(cfg: &StudyConfig) -> Result<String, String> {
    let methods = [
        Method::Before,
        Method::NaiveTwoStep,
        Method::BundleUnbounded,
        Method::BundlePrior,
    ];
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Campaigns {}..{} ({} each row); {}.\n",
        cfg.first_campaign,
        cfg.first_campaign + cfg.campaigns.max(1) as u64 - 1,
        cfg.campaigns.max(1),
        cfg.describe()
    );
    let _ = writeln!(out, "| tracker | method | held-out max um / \" (mean) | held-out RMS um / \" (mean) | campaign {} max um / \" | predicted RMS (1 sigma) um / \" | predicted max um / \" |", cfg.first_campaign);
    let _ = writeln!(out, "|---|---|---|---|---|---|---|");
    for (name, noise) in table_trackers() {
        let mut c = cfg.clone();
        c.setup.noise = noise;
        let rows = summarise(&c, &methods)?;
        for (m, s) in methods.iter().zip(rows.iter()) {
            let pr = s
                .predicted_rms
                .map_or("-".into(), |p| format!("{:.2} / {:.2}", p[0], p[1]));
            let pm = s
                .predicted_max
                .map_or("-".into(), |p| format!("{:.2} / {:.2}", p[0], p[1]));
            let _ = writeln!(
                out,
                "| {name} | {} | {:.2} / {:.2} | {:.2} / {:.2} | {:.2} / {:.2} | {pr} | {pm} |",
                m.label(),
                s.max[0],
                s.max[1],
                s.rms[0],
                s.rms[1],
                s.first_max[0],
                s.first_max[1]
            );
        }
    }
    Ok(out)
}

/// One campaign of the prediction check: measured and predicted RMS per axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PredictionPoint {
    /// Campaign number.
    pub campaign: u64,
    /// Measured held-out RMS per axis (um x3, arcsec x3).
    pub measured_rms: [f64; 6],
    /// Predicted RMS (1 sigma) per axis.
    pub predicted_rms: [f64; 6],
    /// Measured held-out max per axis.
    pub measured_max: [f64; 6],
    /// Predicted expected max per axis.
    pub predicted_max: [f64; 6],
}

/// Result of the prediction check.
#[derive(Clone, Debug, PartialEq)]
pub struct PredictionCheck {
    /// Per campaign.
    pub points: Vec<PredictionPoint>,
    /// `sqrt(sum measured MS / sum predicted MS)` per axis over the campaigns.
    pub rms_ratio: [f64; 6],
    /// Mean measured max / mean predicted max per axis.
    pub max_ratio: [f64; 6],
}

/// Fits every campaign with the prior and compares the predicted accuracy with the
/// measured held-out errors.
pub fn prediction_check(cfg: &StudyConfig) -> Result<PredictionCheck, String> {
    let mut points = Vec::new();
    for i in 0..cfg.campaigns.max(1) {
        let k = cfg.first_campaign + i as u64;
        let c = cfg.campaign(k, &cfg.plan)?;
        let (r, _) = run_method(cfg, &c, Method::BundlePrior)?;
        let p = r.predicted.ok_or("no prediction")?;
        points.push(PredictionPoint {
            campaign: k,
            measured_rms: r.acc.rms,
            predicted_rms: p.rms_sigma,
            measured_max: r.acc.max_abs,
            predicted_max: p.expected_max,
        });
    }
    let mut rms_ratio = [0.0; 6];
    let mut max_ratio = [0.0; 6];
    for a in 0..6 {
        let mm: f64 = points.iter().map(|p| p.measured_rms[a].powi(2)).sum();
        let pm: f64 = points.iter().map(|p| p.predicted_rms[a].powi(2)).sum();
        rms_ratio[a] = (mm / pm).sqrt();
        let mx: f64 = points.iter().map(|p| p.measured_max[a]).sum();
        let px: f64 = points.iter().map(|p| p.predicted_max[a]).sum();
        max_ratio[a] = mx / px;
    }
    Ok(PredictionCheck {
        points,
        rms_ratio,
        max_ratio,
    })
}

/// Default tracker-noise scales of the prediction sweep.
pub const DEFAULT_SWEEP_SCALES: [f64; 4] = [0.1, 0.3, 1.0, 2.0];

/// [`prediction_check`] for each tracker-noise scale (`cfg.setup.noise` times the scale).
pub fn prediction_sweep(
    cfg: &StudyConfig,
    scales: &[f64],
) -> Result<Vec<(f64, PredictionCheck)>, String> {
    scales
        .iter()
        .map(|k| {
            let mut c = cfg.clone();
            c.setup.noise = cfg.setup.noise.scaled(*k);
            prediction_check(&c).map(|r| (*k, r))
        })
        .collect()
}

/// The sweep as Markdown: one row per scale, measured / predicted RMS and max per axis.
pub fn format_prediction_sweep(cfg: &StudyConfig, rows: &[(f64, PredictionCheck)]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{} campaigns per row ({}..); {}; tracker noise = the model above times the scale.\n",
        cfg.campaigns.max(1),
        cfg.first_campaign,
        cfg.describe()
    );
    let _ = writeln!(s, "| noise scale | measured RMS um / \" (mean) | predicted 1 sigma um / \" (mean) | measured / predicted RMS, x y z alpha beta gamma | measured / predicted max, x y z alpha beta gamma |\n|---|---|---|---|---|");
    for (k, r) in rows {
        let n = r.points.len().max(1) as f64;
        let mean = |f: &dyn Fn(&PredictionPoint) -> f64| r.points.iter().map(f).sum::<f64>() / n;
        let list = |v: &[f64; 6]| {
            v.iter()
                .map(|x| format!("{x:.2}"))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let _ = writeln!(
            s,
            "| {k} | {:.3} / {:.3} | {:.3} / {:.3} | {} | {} |",
            mean(&|p| rms3(&p.measured_rms[..3])),
            mean(&|p| rms3(&p.measured_rms[3..])),
            mean(&|p| rms3(&p.predicted_rms[..3])),
            mean(&|p| rms3(&p.predicted_rms[3..])),
            list(&r.rms_ratio),
            list(&r.max_ratio)
        );
    }
    s
}

/// The prediction check as Markdown.
pub fn format_prediction_check(cfg: &StudyConfig, r: &PredictionCheck) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{} campaigns ({}..), {}.\n",
        r.points.len(),
        cfg.first_campaign,
        cfg.describe()
    );
    let _ = writeln!(
        s,
        "| | x | y | z | alpha | beta | gamma |\n|---|---|---|---|---|---|---|"
    );
    let row = |name: &str, v: &[f64; 6]| {
        format!(
            "| {name} | {} |\n",
            v.iter()
                .map(|x| format!("{x:.3}"))
                .collect::<Vec<_>>()
                .join(" | ")
        )
    };
    let mean = |f: &dyn Fn(&PredictionPoint) -> [f64; 6]| {
        let mut m = [0.0; 6];
        for p in &r.points {
            let v = f(p);
            for a in 0..6 {
                m[a] += v[a] / r.points.len() as f64;
            }
        }
        m
    };
    s.push_str(&row(
        "measured RMS (mean, um / \")",
        &mean(&|p| p.measured_rms),
    ));
    s.push_str(&row(
        "predicted 1 sigma (mean)",
        &mean(&|p| p.predicted_rms),
    ));
    s.push_str(&row("**measured / predicted RMS**", &r.rms_ratio));
    s.push_str(&row("measured max (mean)", &mean(&|p| p.measured_max)));
    s.push_str(&row("predicted max (mean)", &mean(&|p| p.predicted_max)));
    s.push_str(&row("**measured / predicted max**", &r.max_ratio));
    s
}

/// Plans compared by [`plan_study`]: label and poses.
pub type NamedPlan = (String, Vec<Pose<f64>>);

/// The optimal plan study: the paper's plan against plans of `sizes` poses chosen by
/// `criterion` from the 729-pose grid, predicted (mean sigma over the evaluation poses)
/// and measured (held-out over the campaigns). Returns the report and the plans.
pub fn plan_study(
    cfg: &StudyConfig,
    criterion: Criterion,
    sizes: &[usize],
) -> Result<(String, Vec<NamedPlan>), String> {
    let candidates =
        design::grid_candidates(DEFAULT_EVAL_TRANSLATION_MM, DEFAULT_EVAL_ROTATION_ARCSEC);
    // The design sees its own evaluation poses, not the held-out ones.
    let eval = random_poses(
        DEFAULT_EVAL_POSES,
        DEFAULT_EVAL_TRANSLATION_MM,
        DEFAULT_EVAL_ROTATION_ARCSEC,
        DESIGN_EVAL_SEED,
    );
    let priors = cfg.bundle_config().priors;
    let data = nominal_data(&cfg.nominal, &cfg.setup, &candidates)?;
    let problem = design::problem(&data, priors, &eval).map_err(|e| e.to_string())?;
    let paper_data = nominal_data(&cfg.nominal, &cfg.setup, &cfg.plan)?;
    let paper_problem = design::problem(&paper_data, priors, &eval).map_err(|e| e.to_string())?;
    let all: Vec<usize> = (0..cfg.plan.len()).collect();
    let mut plans: Vec<(String, Vec<Pose<f64>>, f64)> = vec![(
        format!("paper, {} poses", cfg.plan.len()),
        cfg.plan.clone(),
        paper_problem.mean_variance(&all).ok_or("singular")?,
    )];
    for &n in sizes {
        let sel = problem.select(criterion, n);
        plans.push((
            format!("{}, {} poses", criterion.name(), sel.len()),
            sel.iter().map(|k| candidates[*k]).collect(),
            problem.mean_variance(&sel).ok_or("singular")?,
        ));
    }
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Candidates: the {}-pose grid {{-1, 0, 1}} x (1 mm, 60\") per axis; criterion {}; design evaluation poses: 200 uniform, seed {DESIGN_EVAL_SEED}; measured over campaigns {}..{}; {}.\n",
        candidates.len(),
        criterion.name(),
        cfg.first_campaign,
        cfg.first_campaign + cfg.campaigns.max(1) as u64 - 1,
        cfg.describe()
    );
    let _ = writeln!(out, "| plan | predicted mean sigma (um, \" combined) | held-out max um / \" (mean) | held-out RMS um / \" (mean) |\n|---|---|---|---|");
    let mut named = Vec::new();
    for (label, plan, var) in plans {
        let mut c = cfg.clone();
        c.plan = plan.clone();
        let s = summarise(&c, &[Method::BundlePrior])?;
        let s = s.first().ok_or("no result")?;
        let _ = writeln!(
            out,
            "| {label} | {:.3} | {:.2} / {:.2} | {:.2} / {:.2} |",
            (var / 6.0).sqrt(),
            s.max[0],
            s.max[1],
            s.rms[0],
            s.rms[1]
        );
        named.push((label, plan));
    }
    Ok((out, named))
}

/// Seed of the design's own evaluation poses.
pub const DESIGN_EVAL_SEED: u64 = 4242;
/// The paper's prototype experiment (seed notes): max displacement / angle error at the
/// sampling poses before and after calibration, and at ~40 other poses after.
pub const PAPER_SAMPLING_BEFORE: [f64; 2] = [19.97, 123.84];
/// After, at the sampling poses (um, arcsec).
pub const PAPER_SAMPLING_AFTER: [f64; 2] = [9.68, 8.86];
/// After, at the ~40 other poses (um, arcsec).
pub const PAPER_OTHER_AFTER: [f64; 2] = [9.85, 11.41];
/// Other poses of the experiment.
pub const PAPER_OTHER_POSES: usize = 40;
/// Seed of the 40 other poses.
pub const OTHER_POSES_SEED: u64 = 40;
/// Monte-Carlo draws of the expected maximum of pure noise.
const NOISE_MC_DRAWS: usize = 2000;

/// The paper's experiment, reproduced on simulated campaign `cfg.first_campaign`.
#[derive(Clone, Debug)]
pub struct PaperExperiment {
    /// Sampling poses, `FK(strokes, nominal) - measured` with the poses from the nominal
    /// ball centres (the naive measurement).
    pub sampling_before_naive: Accuracy,
    /// Sampling poses, `FK(strokes, nominal) - measured` (poses from the fitted balls).
    pub sampling_before: Accuracy,
    /// Sampling poses, `FK(strokes, calibrated) - measured`.
    pub sampling_after: Accuracy,
    /// Sampling poses, the tracker's part: `true - measured`.
    pub sampling_noise: Accuracy,
    /// Sampling poses, the calibrated model's part: `FK(strokes, calibrated) - true`.
    pub sampling_model: Accuracy,
    /// Other poses commanded with the calibrated table, tracker-measured error.
    pub other_measured: Accuracy,
    /// Other poses, true error.
    pub other_true: Accuracy,
    /// Other poses, tracker part (measured - true).
    pub other_noise: Accuracy,
    /// 1-sigma pose noise of one tracker measurement at home (um x3, arcsec x3).
    pub pose_noise_sigma: [f64; 6],
    /// Expected max over 120 poses x 3 axes of pure noise, in sigmas.
    pub expected_max_sigmas_sampling: f64,
    /// Expected max over 40 poses x 3 axes of pure noise, in sigmas.
    pub expected_max_sigmas_other: f64,
    /// The fit.
    pub fit: BundleFit,
}

/// Expected max of `n` independent |N(0, 1)| (Monte Carlo, seeded).
fn expected_max_abs_normal(n: usize) -> f64 {
    let mut rng = Pcg64::seed_from_u64(7);
    let mut sum = 0.0;
    for _ in 0..NOISE_MC_DRAWS {
        let mut m = 0.0f64;
        for _ in 0..n {
            let z: f64 = StandardNormal.sample(&mut rng);
            m = m.max(z.abs());
        }
        sum += m;
    }
    sum / NOISE_MC_DRAWS as f64
}

/// Runs the paper's experiment.
pub fn paper_experiment(cfg: &StudyConfig) -> Result<PaperExperiment, String> {
    let c = cfg.campaign(cfg.first_campaign, &cfg.plan)?;
    let data = c
        .data(&cfg.nominal, &cfg.setup)
        .map_err(|e| e.to_string())?;
    let fit = bundle::fit(&data, &cfg.bundle_config()).map_err(|e| e.to_string())?;
    let p0 = cfg.nominal.p0_mm;
    let noise = cfg.setup.noise;
    let meas = measured_poses(
        &c,
        &fit.balls_m,
        &data.ball_names,
        &fit.registration,
        &p0,
        &noise,
    )?;
    let naive = measured_poses(
        &c,
        &data.balls_nominal_m,
        &data.ball_names,
        &fit.registration_fiducials,
        &p0,
        &noise,
    )?;
    let fk_errors =
        |params: &GeometryParams, reference: &[Pose<f64>]| -> Result<Accuracy, String> {
            let g = Geometry::<f64>::new(params)
                .map_err(|e| crate::files::describe_geometry_error(&e))?;
            let cfg_fk = FkConfig {
                max_iterations: bundle::BUNDLE_FK_ITERATIONS,
                ..FkConfig::default()
            };
            let mut e = Vec::new();
            for (s, r) in c.strokes.iter().zip(reference) {
                let p = fk(&g, &s.strokes_mm, r, &cfg_fk)
                    .map_err(|e| crate::ikfk::describe_fk_error(&e))?;
                e.push(pose_error(&p.pose, r));
            }
            Ok(Accuracy::from_errors(e))
        };
    let sampling_before_naive = fk_errors(&cfg.nominal, &naive)?;
    let sampling_before = fk_errors(&cfg.nominal, &meas)?;
    let sampling_after = fk_errors(&fit.params, &meas)?;
    let sampling_model = fk_errors(&fit.params, &c.true_poses)?;
    let sampling_noise = Accuracy::from_errors(
        c.true_poses
            .iter()
            .zip(&meas)
            .map(|(t, m)| pose_error(t, m))
            .collect(),
    );
    // The other poses: commanded with the calibrated table, measured again.
    let others = random_poses(
        PAPER_OTHER_POSES,
        DEFAULT_EVAL_TRANSLATION_MM,
        DEFAULT_EVAL_ROTATION_ARCSEC,
        OTHER_POSES_SEED,
    );
    let cal =
        Geometry::<f64>::new(&fit.params).map_err(|e| crate::files::describe_geometry_error(&e))?;
    let tru =
        Geometry::<f64>::new(&c.truth).map_err(|e| crate::files::describe_geometry_error(&e))?;
    let mut reached = Vec::new();
    for t in &others {
        let s = m2ctl::kinematics::ik(&cal, t).map_err(|e| crate::ikfk::describe_ik_error(&e))?;
        reached.push(true_motion(&tru, &s, t).map_err(|e| crate::ikfk::describe_fk_error(&e))?);
    }
    let mut rng =
        Pcg64::seed_from_u64(CampaignSeeds::from_one(cfg.first_campaign).noise ^ OTHER_POSES_SEED);
    let inv = fit.registration.inverse();
    let mut other_meas = Vec::new();
    for p in &reached {
        let pts = c.scene.measure_balls(&p0, p, &mut rng);
        let b: Vec<[f64; 3]> = pts
            .iter()
            .map(|(_, y)| {
                let x = inv * Point3::from(*y);
                [x.x, x.y, x.z]
            })
            .collect();
        let w: Vec<f64> = pts
            .iter()
            .map(|(_, y)| 3.0 / noise.covariance_mm2(y).trace())
            .collect();
        other_meas
            .push(pose_from_balls(&fit.balls_m, &b, Some(&w), &p0).map_err(|e| e.to_string())?);
    }
    let pose_noise_sigma =
        bundle::pose_measurement_sigma(&fit.balls_m, &fit.registration, &p0, &Pose::home(), &|y| {
            noise.covariance_mm2(y)
        })
        .ok_or("pose noise singular")?;
    Ok(PaperExperiment {
        sampling_before_naive,
        sampling_before,
        sampling_after,
        sampling_noise,
        sampling_model,
        other_measured: Accuracy::from_errors(
            other_meas
                .iter()
                .zip(&others)
                .map(|(m, t)| pose_error(m, t))
                .collect(),
        ),
        other_true: Accuracy::from_errors(
            reached
                .iter()
                .zip(&others)
                .map(|(r, t)| pose_error(r, t))
                .collect(),
        ),
        other_noise: Accuracy::from_errors(
            other_meas
                .iter()
                .zip(&reached)
                .map(|(m, r)| pose_error(m, r))
                .collect(),
        ),
        pose_noise_sigma,
        expected_max_sigmas_sampling: expected_max_abs_normal(3 * cfg.plan.len()),
        expected_max_sigmas_other: expected_max_abs_normal(3 * PAPER_OTHER_POSES),
        fit,
    })
}

/// Share of the tracker's error in the mean square error, `MS(noise) / (MS(noise) +
/// MS(model))`, translation and rotation: the tracker's error and the calibrated model's
/// own error are independent, so their mean squares add.
pub fn noise_share(noise: &Accuracy, model: &Accuracy) -> [f64; 2] {
    let ms = |a: &Accuracy, r: std::ops::Range<usize>| a.rms[r].iter().map(|v| v * v).sum::<f64>();
    [
        ms(noise, 0..3) / (ms(noise, 0..3) + ms(model, 0..3)),
        ms(noise, 3..6) / (ms(noise, 3..6) + ms(model, 3..6)),
    ]
}

/// The paper's experiment as Markdown.
pub fn format_paper_experiment(cfg: &StudyConfig, r: &PaperExperiment) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "Campaign {}: {}.\n", cfg.first_campaign, cfg.describe());
    let _ = writeln!(s, "| where | what | paper max um / \" | simulated max um / \" | simulated RMS um / \" | tracker's share of the mean square, MS(tracker) / (MS(tracker) + MS(model)), translation / rotation |\n|---|---|---|---|---|---|");
    let f = |a: &Accuracy| format!("{:.2} / {:.2}", a.max_um(), a.max_arcsec());
    let g = |a: &Accuracy| format!("{:.2} / {:.2}", rms3(&a.rms[..3]), rms3(&a.rms[3..]));
    let share = |n: &Accuracy, m: &Accuracy| {
        let v = noise_share(n, m);
        format!("{:.0} % / {:.0} %", 100.0 * v[0], 100.0 * v[1])
    };
    let p = |v: [f64; 2]| format!("{:.2} / {:.2}", v[0], v[1]);
    let _ = writeln!(
        s,
        "| {} sampling poses | before, poses from nominal ball centres | {} | {} | {} | - |",
        cfg.plan.len(),
        p(PAPER_SAMPLING_BEFORE),
        f(&r.sampling_before_naive),
        g(&r.sampling_before_naive)
    );
    let _ = writeln!(
        s,
        "| | before, poses from the fitted ball centres | | {} | {} | - |",
        f(&r.sampling_before),
        g(&r.sampling_before)
    );
    let _ = writeln!(
        s,
        "| | after (bundle with prior) | {} | {} | {} | {} |",
        p(PAPER_SAMPLING_AFTER),
        f(&r.sampling_after),
        g(&r.sampling_after),
        share(&r.sampling_noise, &r.sampling_model)
    );
    let _ = writeln!(s, "| | after, the calibrated model's own error, FK(strokes, calibrated) - true (simulation only) | | {} | {} | |", f(&r.sampling_model), g(&r.sampling_model));
    let _ = writeln!(
        s,
        "| {PAPER_OTHER_POSES} other poses | after, measured by the tracker | {} | {} | {} | {} |",
        p(PAPER_OTHER_AFTER),
        f(&r.other_measured),
        g(&r.other_measured),
        share(&r.other_noise, &r.other_true)
    );
    let _ = writeln!(
        s,
        "| | after, true error (simulation only) | | {} | {} | |",
        f(&r.other_true),
        g(&r.other_true)
    );
    let _ = writeln!(
        s,
        "| | the tracker's own error (measured - true) | | {} | {} | |",
        f(&r.other_noise),
        g(&r.other_noise)
    );
    let sig = &r.pose_noise_sigma;
    let _ = writeln!(
        s,
        "\nOne tracker pose measurement (4 balls): 1 sigma {:.2} / {:.2} / {:.2} um, {:.2} / {:.2} / {:.2}\" (x, y, z, alpha, beta, gamma). Pure noise of that size gives a max over {} x 3 axis values of {:.2} sigma, over {} x 3 of {:.2} sigma on average; the paper's after figures would be pure tracker noise of 1 sigma {:.2} um / {:.2}\" (sampling) and {:.2} um / {:.2}\" (other poses).",
        sig[0], sig[1], sig[2], sig[3], sig[4], sig[5],
        cfg.plan.len(),
        r.expected_max_sigmas_sampling,
        PAPER_OTHER_POSES,
        r.expected_max_sigmas_other,
        PAPER_SAMPLING_AFTER[0] / r.expected_max_sigmas_sampling,
        PAPER_SAMPLING_AFTER[1] / r.expected_max_sigmas_sampling,
        PAPER_OTHER_AFTER[0] / r.expected_max_sigmas_other,
        PAPER_OTHER_AFTER[1] / r.expected_max_sigmas_other,
    );
    s
}
