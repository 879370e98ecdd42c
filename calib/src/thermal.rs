//! Thermal calibration in simulation (issue 22): the mechanism measured at several
//! temperatures, the expansion coefficients fitted with their covariance, and which of
//! them the campaign can tell apart (docs/calibration.md, "Thermal calibration").
//!
//! Campaign ([`ThermalCampaign`]): every target pose is commanded with the ground's
//! geometry (the calibrated table, valid at the reference temperature) and measured by
//! the idealised [`PoseTracker`] once with every part at the reference temperature and
//! once in each thermal *state* (the parts' temperatures: a uniform soak, the platform
//! heated alone, ...), the strokes held. The simulated mechanism is the plant
//! ([`m2ctl::sim::Plant`] with its thermal side): the pose it reaches is that of its
//! expanded true geometry ([`m2ctl::sim::thermal`]).
//!
//! Fit ([`fit`]): the observation is each pose's change from the reference to the state
//! (in um and arcsec): errors of the ground's geometry cancel to first order. The model
//! is the thermal physics of [`m2ctl::thermal`] evaluated on the ground's geometry
//! (exactly: the expanded mechanism's FK, [`m2ctl::sim::thermal::expanded`]); weighted
//! Gauss-Newton from the nominal coefficients, the covariance `(J^T W J)^-1` from the
//! tracker's stated noise, and `chi^2 / dof` as the check that the noise is as stated.
//!
//! Observability: in the model the column's coefficient and its length appear only as
//! their product (the joint rises by `alpha_column * column_length * dT`), so the fit's
//! parameters are [`PARAMS`]: the rods', base plate's and platform's coefficients and the
//! column growth (mm/K); [`observability`] shows the rank defect of the five-parameter
//! set and the correlations of the four. The firmware's model takes the column growth
//! with the nominal length ([`ThermalFit::coefficients`]).
//!
//! Part temperatures are taken as known (the chamber's reference sensors): the flight
//! sensors' class 1/10 DIN offsets (0.04 K) over a campaign of +-10 K bias the
//! coefficients by up to 0.4 %, not modelled here.

use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_pcg::Pcg64;

use crate::campaign::CampaignError;
use m2ctl::kinematics::{fk, ik, FkConfig, Geometry, GeometryParams, Pose, LEGS};
use m2ctl::sim::thermal::{expanded, Coefficients, PartTemperatures, PART_CLASSES, REFERENCE_C};
use m2ctl::sim::tracker::PoseTracker;
use m2ctl::sim::{pose_error, Plant};
use m2ctl::thermal::PARTS;

/// Number of fitted parameters.
pub const PARAMS: usize = 4;
/// The fitted parameters, in order: expansion coefficients of the rods, the base plate
/// and the platform (1/K), and the column growth `alpha_column * column_length` (mm/K).
pub const PARAM_NAMES: [&str; PARAMS] = [
    "alpha_rod_per_k",
    "alpha_base_per_k",
    "alpha_platform_per_k",
    "column_growth_mm_per_k",
];

/// A thermal campaign's design.
#[derive(Clone, Debug, PartialEq)]
pub struct ThermalCampaign {
    /// The targets (poses), commanded with the ground's geometry.
    pub targets: Vec<Pose<f64>>,
    /// The thermal states every target is measured in (besides the reference).
    pub states: Vec<PartTemperatures>,
    /// The instrument.
    pub tracker: PoseTracker,
}

/// One target measured at the reference and in one state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThermalMeasurement {
    /// The parts' temperatures of the state (deg C).
    pub temps: PartTemperatures,
    /// The strokes held (mm).
    pub strokes_mm: [f64; LEGS],
    /// The pose measured at the reference temperature.
    pub at_reference: Pose<f64>,
    /// The pose measured in the state.
    pub in_state: Pose<f64>,
}

/// The largest uniform soak of the default design, from the reference (K): the
/// coefficients are measured over `reference +- LARGEST_SOAK_K` (the ground alarms on a
/// sensor further away: the mission database's `temperature_deviation_max`).
pub const LARGEST_SOAK_K: f64 = 10.0;

/// The targets of the default design: home, the translation corners (+-1.5 mm) and the
/// rotation corners (+-500 arcsec), each measured in every state.
pub fn default_targets() -> Vec<Pose<f64>> {
    let mut t = vec![Pose::home()];
    for s in crate::plan::sign_patterns() {
        t.push(Pose::from_mm_arcsec(s.map(|v| 1.5 * v), [0.0; 3]));
        t.push(Pose::from_mm_arcsec([0.0; 3], s.map(|v| 500.0 * v)));
    }
    t
}

/// The states of the default design: uniform soaks at `reference +- 5` and `+- 10` K,
/// the platform alone at `+- 5` K (its heaters; the base side at the reference), the
/// base side (rods, columns, plate) at `+ 5` K, and the base interface heated (columns
/// and plate at `+- 5` K, rods and platform at the reference: the transient of a
/// conductive interface, before the rods follow). Without the last, the rods' and the
/// columns' growth both lift the mirror almost uniformly and are 0.998 correlated.
pub fn default_states() -> Vec<PartTemperatures> {
    let mut s: Vec<PartTemperatures> = [-LARGEST_SOAK_K, -5.0, 5.0, LARGEST_SOAK_K]
        .iter()
        .map(|d| PartTemperatures::uniform(REFERENCE_C + d))
        .collect();
    for d in [-5.0, 5.0] {
        let mut t = PartTemperatures::uniform(REFERENCE_C);
        t.platform_c += d;
        s.push(t);
    }
    let mut t = PartTemperatures::uniform(REFERENCE_C + 5.0);
    t.platform_c = REFERENCE_C;
    s.push(t);
    for d in [-5.0, 5.0] {
        let mut t = PartTemperatures::uniform(REFERENCE_C + d);
        t.rod_c = [REFERENCE_C; LEGS];
        t.platform_c = REFERENCE_C;
        t.base_centre_c = REFERENCE_C + d;
        s.push(t);
    }
    s
}

/// Simulates the campaign on `plant` (its true geometry and coefficients are what the
/// fit should find); `ground` is the geometry the targets are commanded with; the
/// tracker's noise is drawn from `noise_seed`.
pub fn simulate(
    plant: &mut Plant,
    ground: &GeometryParams,
    campaign: &ThermalCampaign,
    noise_seed: u64,
) -> Result<Vec<ThermalMeasurement>, CampaignError> {
    let geom = Geometry::<f64>::new(ground)
        .map_err(|e| CampaignError(crate::files::describe_geometry_error(&e)))?;
    let mut rng = Pcg64::seed_from_u64(noise_seed);
    let mut out = Vec::new();
    let reach = |plant: &mut Plant, t: PartTemperatures, rng: &mut Pcg64| {
        plant.thermal_mut().set_temperatures(t);
        plant
            .true_pose()
            .map(|p| campaign.tracker.measure(&p, rng))
            .map_err(|e| CampaignError(crate::ikfk::describe_fk_error(&e)))
    };
    for (k, target) in campaign.targets.iter().enumerate() {
        let strokes = ik(&geom, target).map_err(|e| {
            CampaignError(format!(
                "target {}: {}",
                k + 1,
                crate::ikfk::describe_ik_error(&e)
            ))
        })?;
        plant.set_strokes_mm(&strokes);
        for temps in &campaign.states {
            let at_reference = reach(plant, PartTemperatures::uniform(REFERENCE_C), &mut rng)?;
            let in_state = reach(plant, *temps, &mut rng)?;
            out.push(ThermalMeasurement {
                temps: *temps,
                strokes_mm: strokes,
                at_reference,
                in_state,
            });
        }
    }
    Ok(out)
}

/// The coefficients of the parameters `p` ([`PARAMS`] order) with columns of
/// `column_length_mm`.
fn coefficients_of(p: &[f64; PARAMS], column_length_mm: f64) -> Coefficients {
    let [rod, base, platform, growth] = *p;
    Coefficients {
        expansion_per_k: [rod, growth / column_length_mm, base, platform],
        column_length_mm,
    }
}

/// The model's change of the pose (um, arcsec: [`pose_error`]) of `m` from the
/// reference to its state, with `coef`, on the geometry `ground`.
fn model_change(
    ground: &GeometryParams,
    geom: &Geometry<f64>,
    coef: &Coefficients,
    m: &ThermalMeasurement,
) -> Result<[f64; 6], CampaignError> {
    let cfg = FkConfig::<f64> {
        max_iterations: 20,
        ..FkConfig::default()
    };
    let e: [[f64; PARTS]; LEGS] = core::array::from_fn(|leg| {
        core::array::from_fn(|p| {
            coef.expansion_per_k[p] * (m.temps.of(leg, PART_CLASSES[p]) - REFERENCE_C)
        })
    });
    let fk_err = |e| CampaignError(crate::ikfk::describe_fk_error(&e));
    let x = expanded(ground, &e, coef.column_length_mm)
        .map_err(|e| CampaignError(crate::files::describe_geometry_error(&e)))?;
    let hot = Geometry::<f64>::new(&x.params)
        .map_err(|e| CampaignError(crate::files::describe_geometry_error(&e)))?;
    let mut s = m.strokes_mm;
    for (s, c) in s.iter_mut().zip(x.stroke_origin_mm.iter()) {
        *s -= c;
    }
    let cold = fk(geom, &m.strokes_mm, &m.at_reference, &cfg).map_err(fk_err)?;
    let warm = fk(&hot, &s, &cold.pose, &cfg).map_err(fk_err)?;
    Ok(pose_error(&warm.pose, &cold.pose))
}

/// The weighted residuals (observed minus model change, over the per-component
/// standard deviation of a difference of two measurements).
fn residuals(
    ground: &GeometryParams,
    geom: &Geometry<f64>,
    coef: &Coefficients,
    meas: &[ThermalMeasurement],
    sigma: &[f64; 6],
) -> Result<DVector<f64>, CampaignError> {
    let mut r = DVector::zeros(6 * meas.len());
    for (k, m) in meas.iter().enumerate() {
        let model = model_change(ground, geom, coef, m)?;
        let observed = pose_error(&m.in_state, &m.at_reference);
        for c in 0..6 {
            r[6 * k + c] = (observed[c] - model[c]) / sigma[c];
        }
    }
    Ok(r)
}

/// Per-component standard deviation of a measured change (um, arcsec): two
/// independent measurements.
fn change_sigma(tracker: &PoseTracker) -> [f64; 6] {
    let (u, a) = (
        tracker.noise_um * core::f64::consts::SQRT_2,
        tracker.noise_arcsec * core::f64::consts::SQRT_2,
    );
    [u, u, u, a, a, a]
}

/// Finite-difference steps of the parameters (1 % of the nominal values: the model is
/// linear in them to second order in the expansions, ppm).
fn fd_steps(p: &[f64]) -> Vec<f64> {
    p.iter().map(|v| 0.01 * v.abs().max(1e-9)).collect()
}

/// The Jacobian of the weighted residuals' model part (`d model / d p / sigma`) for the
/// parameters `p` mapped to coefficients by `coef_of`.
fn jacobian(
    ground: &GeometryParams,
    geom: &Geometry<f64>,
    meas: &[ThermalMeasurement],
    sigma: &[f64; 6],
    p: &[f64],
    coef_of: &dyn Fn(&[f64]) -> Coefficients,
) -> Result<DMatrix<f64>, CampaignError> {
    let h = fd_steps(p);
    let mut j = DMatrix::zeros(6 * meas.len(), p.len());
    for i in 0..p.len() {
        let (mut hi, mut lo) = (p.to_vec(), p.to_vec());
        hi[i] += h[i];
        lo[i] -= h[i];
        // Residuals are observed - model: the model's derivative is minus theirs.
        let rh = residuals(ground, geom, &coef_of(&hi), meas, sigma)?;
        let rl = residuals(ground, geom, &coef_of(&lo), meas, sigma)?;
        let col = (rl - rh) / (2.0 * h[i]);
        j.set_column(i, &col);
    }
    Ok(j)
}

/// A thermal fit's result.
#[derive(Clone, Debug, PartialEq)]
pub struct ThermalFit {
    /// The parameters ([`PARAM_NAMES`]).
    pub estimate: [f64; PARAMS],
    /// Their covariance (from the tracker's stated noise).
    pub covariance: [[f64; PARAMS]; PARAMS],
    /// Their standard deviations.
    pub sigma: [f64; PARAMS],
    /// Their correlation matrix.
    pub correlation: [[f64; PARAMS]; PARAMS],
    /// `chi^2 / dof` of the weighted residuals: about 1 when the noise is as stated.
    pub chi2_per_dof: f64,
    /// The column length the coefficients are given with (mm).
    pub column_length_mm: f64,
}

impl ThermalFit {
    /// The coefficients for the thermal model: the column's coefficient is the fitted
    /// growth over [`ThermalFit::column_length_mm`].
    pub fn coefficients(&self) -> Coefficients {
        coefficients_of(&self.estimate, self.column_length_mm)
    }
}

/// The parameters of `c` ([`PARAMS`] order).
pub fn params_of(c: &Coefficients) -> [f64; PARAMS] {
    let [rod, col, base, platform] = c.expansion_per_k;
    [rod, base, platform, col * c.column_length_mm]
}

/// Fits the parameters to the measurements (module documentation): Gauss-Newton from
/// the nominal coefficients on the `ground` geometry, the column length
/// `column_length_mm` (the nominal one: only the growth is observable).
pub fn fit(
    ground: &GeometryParams,
    meas: &[ThermalMeasurement],
    tracker: &PoseTracker,
    column_length_mm: f64,
) -> Result<ThermalFit, CampaignError> {
    let geom = Geometry::<f64>::new(ground)
        .map_err(|e| CampaignError(crate::files::describe_geometry_error(&e)))?;
    let sigma = change_sigma(tracker);
    if meas.len() * 6 <= PARAMS || sigma.iter().any(|s| !(*s > 0.0)) {
        return Err(CampaignError(
            "thermal fit: too few measurements or a noise-free tracker".into(),
        ));
    }
    let coef_of = |p: &[f64]| {
        let a: [f64; PARAMS] = [p[0], p[1], p[2], p[3]];
        coefficients_of(&a, column_length_mm)
    };
    let mut p: Vec<f64> = params_of(&Coefficients {
        column_length_mm,
        ..Coefficients::NOMINAL
    })
    .to_vec();
    let mut jtj = DMatrix::zeros(PARAMS, PARAMS);
    let mut r = DVector::zeros(0);
    // The model is linear to ppm: two steps converge.
    for _ in 0..3 {
        let j = jacobian(ground, &geom, meas, &sigma, &p, &coef_of)?;
        r = residuals(ground, &geom, &coef_of(&p), meas, &sigma)?;
        jtj = j.transpose() * &j;
        let step = jtj
            .clone()
            .cholesky()
            .ok_or_else(|| CampaignError("thermal fit: parameters not observable".into()))?
            .solve(&(j.transpose() * &r));
        for (v, d) in p.iter_mut().zip(step.iter()) {
            *v += d;
        }
    }
    r = residuals(ground, &geom, &coef_of(&p), meas, &sigma).unwrap_or(r);
    let cov = jtj
        .try_inverse()
        .ok_or_else(|| CampaignError("thermal fit: singular normal matrix".into()))?;
    let mut covariance = [[0.0; PARAMS]; PARAMS];
    let mut correlation = [[0.0; PARAMS]; PARAMS];
    let sd: [f64; PARAMS] = core::array::from_fn(|i| cov[(i, i)].sqrt());
    for i in 0..PARAMS {
        for k in 0..PARAMS {
            covariance[i][k] = cov[(i, k)];
            correlation[i][k] = cov[(i, k)] / (sd[i] * sd[k]);
        }
    }
    let dof = (r.len() - PARAMS) as f64;
    Ok(ThermalFit {
        estimate: [p[0], p[1], p[2], p[3]],
        covariance,
        sigma: sd,
        correlation,
        chi2_per_dof: r.norm_squared() / dof,
        column_length_mm,
    })
}

/// Observability of the five physical parameters (the four coefficients and the column
/// length) by the campaign: the singular values of the Jacobian with each column scaled
/// by its parameter's nominal value (relative sensitivities), largest first. The
/// smallest is 0 to rounding: the column's coefficient and length enter as a product.
pub fn observability(
    ground: &GeometryParams,
    meas: &[ThermalMeasurement],
    tracker: &PoseTracker,
) -> Result<Vec<f64>, CampaignError> {
    let geom = Geometry::<f64>::new(ground)
        .map_err(|e| CampaignError(crate::files::describe_geometry_error(&e)))?;
    let sigma = change_sigma(tracker);
    let n = Coefficients::NOMINAL;
    let p: Vec<f64> = n
        .expansion_per_k
        .iter()
        .copied()
        .chain([n.column_length_mm])
        .collect();
    let coef_of = |p: &[f64]| Coefficients {
        expansion_per_k: [p[0], p[1], p[2], p[3]],
        column_length_mm: p[4],
    };
    let mut j = jacobian(ground, &geom, meas, &sigma, &p, &coef_of)?;
    for (i, v) in p.iter().enumerate() {
        let c = j.column(i) * *v;
        j.set_column(i, &c);
    }
    let mut sv: Vec<f64> = j.singular_values().iter().copied().collect();
    sv.sort_by(|a, b| b.total_cmp(a));
    Ok(sv)
}
