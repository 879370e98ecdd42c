//! The bundle fit as a geodetic adjustment: variance components estimated from the
//! data, a global test of the noise model, outliers found by data snooping.
//!
//! The bundle ([`super::bundle`]) is a Gauss-Markov model with pseudo-observations: every
//! measured point gives three whitened rows (in the basis of its covariance: for a
//! tracker point the line of sight, [`super::bundle::Component::Range`], and two transverse directions,
//! [`super::bundle::Component::Transverse`]; a point with its own sigma from the export,
//! [`super::bundle::Component::Export`]); the priors give one row per joint coordinate
//! (`(theta - theta_nominal) / sigma_joint`) and per ball coordinate
//! (`(c - c_nominal) / sigma_ball`). With `J` the whitened Jacobian at the solution
//! (rows scaled by the current variance factors), `N = J^T J` the normal matrix and
//! `Q_xx = N^-1`:
//!
//! * **Redundancy numbers** `r_i = (Q_vv P)_ii = 1 - j_i^T Q_xx j_i` (whitened rows:
//!   `P = I`); their sum over all rows is `n - u`.
//! * **Variance component estimation** (Foerstner's iterative estimator, equivalent to
//!   maximising the marginal likelihood, type-II ML, for these components): for every
//!   component `c`, `k_c <- k_c * Omega_c / r_c` with `Omega_c = sum v_i^2` and
//!   `r_c = sum r_i` over its rows. For the priors this is
//!   `sigma^2 <- |x - x_nominal|^2 / r_prior`, the evidence (MacKay) fixed point: the
//!   spread of the joints (and of the balls) is estimated from the data, not assumed.
//!   Each iteration takes one Gauss-Newton step of the unknowns with the factors in force,
//!   then updates the factors; a component whose redundancy is below
//!   [`MIN_COMPONENT_REDUNDANCY`] keeps its a-priori value (not estimable).
//!   Fiducial rows (12 of ~1,450) are weighted with the estimated tracker factors but
//!   left out of the estimation (their variance includes the drawing tolerance).
//! * **Global test** of the a-priori noise model: `Omega_0 = sum v_i^2` of the data rows
//!   with the model's own variances, against chi-square with `r_data = sum r_i`
//!   degrees of freedom (two-sided, [`GLOBAL_TEST_ALPHA`]); `sigma0^2 = Omega_0 /
//!   r_data` with its confidence interval. The estimated factors are the same test per
//!   component. The test is reported, never a reason to refuse: a tracker noisier or
//!   quieter than its data sheet is what the estimation is for.
//! * **Data snooping** (Baarda), one point at a time: each point's three rows are tested
//!   together, `T_p = v_p^T Q_vv,pp^-1 v_p` (the 3-D extension of the w-test,
//!   `w_i = v_i / sqrt(q_vv,ii)` for one row), which is chi-square with 3 degrees of
//!   freedom when the point is good (the variance factors estimated: sigma0 = 1).
//!   Critical value: `chi2_3(1 - alpha / n_points)` (Bonferroni over the points, family
//!   significance `alpha`, [`DEFAULT_ALPHA`]). The largest `T_p` above it is removed
//!   ([`OutlierRule::Remove`], the default) or refused ([`OutlierRule::Refuse`]); the
//!   fit, the variance components and the tests are then redone, until no point exceeds
//!   it. The campaign is refused only if more than [`MAX_REMOVED_FRACTION`] of its
//!   points (at least [`MIN_REMOVED_LIMIT`]) would have to go, or a removal would leave
//!   fewer than 3 fiducials. Each removal is reported with its file line, its test
//!   value and the estimated error vector `Q_vv,pp^-1 v_p` (tracker frame, um).
//! * **Minimal detectable bias** (Baarda's B-method): the smallest error of a point
//!   detected with probability [`OUTLIER_POWER`] by the same test, in its worst
//!   direction: `sqrt(lambda_0 / mu_min)`, `mu_min` the smallest eigenvalue of
//!   `W^T Q_vv,pp W` (`W` the point's whitening) and `lambda_0` the non-centrality of
//!   that power.

use std::time::Instant;

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use super::bundle::{
    self, Bundle, BundleConfig, BundleData, BundleError, BundleFit, Priors, N_COMPONENTS,
};
use super::stats::{chi2_quantile, chi2_sf, noncentrality_for_power};
use super::N_PARAMS;

/// Default family-wise significance of the outlier tests (the chance that a campaign
/// within its noise model loses one good point), Bonferroni over the points.
pub const DEFAULT_ALPHA: f64 = 0.01;
/// Power of the minimal detectable bias (Baarda's B-method: 80 %).
pub const OUTLIER_POWER: f64 = 0.8;
/// Significance of the global test and level of the confidence intervals (two-sided).
pub const GLOBAL_TEST_ALPHA: f64 = 0.05;
/// Most variance-component iterations.
pub const MAX_VCE_ITERATIONS: usize = 300;
/// Convergence: every factor's relative change below this.
pub const VCE_TOLERANCE: f64 = 1e-3;
/// Smallest redundancy of a component for its factor to be estimated.
pub const MIN_COMPONENT_REDUNDANCY: f64 = 1.0;
/// Largest fraction of the points that may be removed as outliers before the campaign
/// is refused as not within any noise model.
pub const MAX_REMOVED_FRACTION: f64 = 0.05;
/// The limit on removals is at least this many points.
pub const MIN_REMOVED_LIMIT: usize = 3;
/// A point whose smallest redundancy is below this is not testable (its own
/// measurement alone determines what it measures).
pub const MIN_TESTABLE_REDUNDANCY: f64 = 1e-3;
/// Range of the joints' spread over which the hyperprior is spread (log-uniform, mm):
/// from a hundredth of a mm, finer than any machining of such a mechanism, to 1 mm, the
/// flight validation's limit on a joint's distance from nominal.
pub const SPREAD_RANGE_MM: (f64, f64) = (0.01, 1.0);
/// Points of the log grid over [`SPREAD_RANGE_MM`] on which the marginal likelihood is
/// evaluated and the fits averaged.
pub const SPREAD_GRID: usize = 17;
/// Fewest fiducials a removal may leave.
pub const MIN_FIDUCIALS_LEFT: usize = 3;

/// How a prior's spread is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PriorSetting {
    /// Estimated from the data (variance components), starting at `start_mm`.
    Estimate {
        /// Start value (mm).
        start_mm: f64,
    },
    /// Given by the user (mm).
    Fixed(f64),
    /// No prior (the group is free).
    Free,
}

impl PriorSetting {
    fn start(&self) -> Option<f64> {
        match self {
            PriorSetting::Estimate { start_mm } => Some(*start_mm),
            PriorSetting::Fixed(v) => Some(*v),
            PriorSetting::Free => None,
        }
    }
    fn estimated(&self) -> bool {
        matches!(self, PriorSetting::Estimate { .. })
    }
}

/// What to do with a point the outlier test rejects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutlierRule {
    /// Remove it, report it and fit again (default).
    Remove,
    /// Refuse the campaign, naming it.
    Refuse,
}

/// Settings of the adjustment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdjustConfig {
    /// The joints' prior.
    pub joint_prior: PriorSetting,
    /// The balls' prior.
    pub ball_prior: PriorSetting,
    /// Estimate the tracker's variance factors (else the model as given).
    pub estimate_noise: bool,
    /// Family-wise significance of the outlier tests.
    pub alpha: f64,
    /// Outlier rule.
    pub rule: OutlierRule,
    /// With an estimated joint prior: average the fits over the joints' spread, weighted
    /// by its posterior (marginal likelihood times a log-uniform hyperprior over
    /// [`SPREAD_RANGE_MM`]), instead of fitting with the single most likely spread.
    pub marginalise_spread: bool,
    /// LM budget and tolerances (its priors are not used).
    pub solver: BundleConfig,
}

impl AdjustConfig {
    /// The defaults: both priors and the noise estimated (joints from
    /// [`bundle::DEFAULT_JOINT_PRIOR_SIGMA_MM`], balls from `ball_sigma_mm`), outliers
    /// removed at [`DEFAULT_ALPHA`].
    pub fn estimated(ball_sigma_mm: f64) -> Self {
        Self {
            joint_prior: PriorSetting::Estimate {
                start_mm: bundle::DEFAULT_JOINT_PRIOR_SIGMA_MM,
            },
            ball_prior: PriorSetting::Estimate {
                start_mm: ball_sigma_mm,
            },
            estimate_noise: true,
            alpha: DEFAULT_ALPHA,
            rule: OutlierRule::Remove,
            marginalise_spread: true,
            solver: BundleConfig::unbounded(),
        }
    }

    /// Nothing estimated: the given priors and noise model (outliers still tested).
    pub fn fixed(joint_sigma_mm: f64, ball_sigma_mm: f64) -> Self {
        Self {
            joint_prior: PriorSetting::Fixed(joint_sigma_mm),
            ball_prior: PriorSetting::Fixed(ball_sigma_mm),
            estimate_noise: false,
            ..Self::estimated(ball_sigma_mm)
        }
    }
}

/// One estimated variance component.
#[derive(Clone, Debug, PartialEq)]
pub struct ComponentEstimate {
    /// Name.
    pub name: String,
    /// Variance factor against the a-priori value (1: as assumed). For a prior, the
    /// estimated spread squared over the start value squared.
    pub factor: f64,
    /// 95 % confidence interval of the factor (chi-square with the redundancy).
    pub factor_ci: (f64, f64),
    /// Sum of squared whitened residuals of its rows (with the estimated factor).
    pub omega: f64,
    /// Its redundancy (sum of the redundancy numbers of its rows).
    pub redundancy: f64,
    /// Number of rows.
    pub rows: usize,
    /// Whether it was estimated (else fixed: not asked for, no rows, or redundancy below
    /// [`MIN_COMPONENT_REDUNDANCY`]).
    pub estimated: bool,
}

/// The global test of a noise model.
#[derive(Clone, Debug, PartialEq)]
pub struct GlobalTest {
    /// Sum of squared whitened data residuals with the model's variances.
    pub omega: f64,
    /// Its degrees of freedom (redundancy of the data rows).
    pub redundancy: f64,
    /// Variance of unit weight `omega / redundancy`.
    pub sigma0_sq: f64,
    /// Its 95 % confidence interval.
    pub sigma0_sq_ci: (f64, f64),
    /// Acceptance region of `sigma0_sq` at [`GLOBAL_TEST_ALPHA`].
    pub accept: (f64, f64),
    /// Whether the model passes.
    pub passed: bool,
}

impl GlobalTest {
    fn new(omega: f64, redundancy: f64) -> Self {
        let r = redundancy.max(1e-9);
        let a = GLOBAL_TEST_ALPHA;
        let lo = chi2_quantile(a / 2.0, r) / r;
        let hi = chi2_quantile(1.0 - a / 2.0, r) / r;
        let s = omega / r;
        Self {
            omega,
            redundancy,
            sigma0_sq: s,
            sigma0_sq_ci: (s / hi, s / lo),
            accept: (lo, hi),
            passed: s >= lo && s <= hi,
        }
    }
}

/// The posterior of the joints' spread on the grid.
#[derive(Clone, Debug, PartialEq)]
pub struct SpreadPosterior {
    /// Grid (mm).
    pub grid_mm: Vec<f64>,
    /// Log marginal likelihood (Laplace) at each grid point.
    pub log_evidence: Vec<f64>,
    /// Posterior weights (sum 1).
    pub weights: Vec<f64>,
    /// Posterior median (mm).
    pub median_mm: f64,
    /// 68 % interval (16 %, 84 % quantiles, mm).
    pub interval_mm: (f64, f64),
    /// The MAP unknowns at each grid point.
    pub grid_x: Vec<Vec<f64>>,
}

impl SpreadPosterior {
    fn quantile(&self, q: f64) -> f64 {
        // Piecewise-linear CDF in log s between grid points.
        let mut cum = 0.0;
        for (i, w) in self.weights.iter().enumerate() {
            if cum + w >= q {
                let f = if *w > 0.0 { (q - cum) / w } else { 0.0 };
                let (a, b) = (
                    if i == 0 {
                        self.grid_mm[0]
                    } else {
                        (self.grid_mm[i - 1] * self.grid_mm[i]).sqrt()
                    },
                    if i + 1 == self.grid_mm.len() {
                        self.grid_mm[i]
                    } else {
                        (self.grid_mm[i] * self.grid_mm[i + 1]).sqrt()
                    },
                );
                return (a.ln() + f * (b.ln() - a.ln())).exp();
            }
            cum += w;
        }
        *self.grid_mm.last().unwrap_or(&f64::NAN)
    }
}

/// Where a point is in the data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointId {
    /// Fiducial index.
    Fiducial(usize),
    /// A ball at a pose: (index into the poses, ball index).
    Ball {
        /// Index of the pose in [`BundleData::poses`].
        pose: usize,
        /// Ball index ([`BundleData::ball_names`]).
        ball: usize,
    },
}

/// The outlier test of one point.
#[derive(Clone, Debug, PartialEq)]
pub struct PointTest {
    /// Where.
    pub id: PointId,
    /// Line in the point export.
    pub line: usize,
    /// Pose number of the files (None: a fiducial).
    pub pose: Option<u32>,
    /// Description ("ball B3 of pose 17", "fiducial F2").
    pub what: String,
    /// Test statistic `v^T Q_vv^-1 v` (chi-square, 3 degrees of freedom, if good);
    /// NaN if untestable.
    pub t: f64,
    /// Largest |w| of its three rows (`v_i / sqrt(q_vv,ii)`).
    pub w_max: f64,
    /// Mean redundancy number of its rows.
    pub redundancy: f64,
    /// Minimal detectable bias, worst direction (mm).
    pub mdb_mm: f64,
    /// Estimated error of the point (tracker frame, mm): `W^-1 Q_vv^-1 v`.
    pub error_mm: [f64; 3],
}

/// A removed (or refused) outlier.
#[derive(Clone, Debug, PartialEq)]
pub struct Outlier {
    /// Its test when it was removed.
    pub test: PointTest,
    /// The critical value in force.
    pub critical: f64,
}

/// Result of the adjustment.
#[derive(Clone, Debug)]
pub struct Adjustment {
    /// The fit (covariance scaled by the estimated variance components).
    pub fit: BundleFit,
    /// The data after the removals.
    pub data: BundleData,
    /// Tracker components (range, transverse, export sigmas), then the joint and the
    /// ball prior.
    pub components: Vec<ComponentEstimate>,
    /// The joints' prior spread used (mm; None: free): the variance-component (type-II
    /// maximum-likelihood) estimate if estimated.
    pub joint_prior_mm: Option<f64>,
    /// The posterior of the joints' spread, if marginalised.
    pub spread_posterior: Option<SpreadPosterior>,
    /// The balls' prior spread used (mm).
    pub ball_prior_mm: Option<f64>,
    /// The a-priori noise model's global test on all the data (before any removal,
    /// priors as finally estimated).
    pub global_before: GlobalTest,
    /// ... and after the removals.
    pub global_after: GlobalTest,
    /// The tests of every point (final fit).
    pub tests: Vec<PointTest>,
    /// Critical value of `T` (final).
    pub critical: f64,
    /// Significance per point test.
    pub alpha_per_test: f64,
    /// Non-centrality of the minimal detectable bias.
    pub lambda0: f64,
    /// Removed outliers in removal order.
    pub removed: Vec<Outlier>,
    /// Covariance of the unknowns with the a-priori noise model (variance factors 1) at
    /// the same solution and priors: the prediction "without the estimated scaling".
    pub covariance_unscaled: DMatrix<f64>,
    /// Variance-component iterations (all fits).
    pub vce_iterations: usize,
}

impl Adjustment {
    /// The 36 x 36 joint block of the unscaled covariance (mm^2).
    pub fn joint_covariance_unscaled(&self) -> DMatrix<f64> {
        self.covariance_unscaled
            .view((0, 0), (N_PARAMS, N_PARAMS))
            .into_owned()
    }

    /// The tracker variance factors `[range, transverse, export]`.
    pub fn factors(&self) -> [f64; N_COMPONENTS] {
        [0, 1, 2].map(|c| self.components[c].factor)
    }
}

/// The point identities in row order.
fn point_ids(data: &BundleData) -> Vec<(PointId, usize, Option<u32>, String)> {
    let mut out: Vec<(PointId, usize, Option<u32>, String)> = data
        .fiducials
        .iter()
        .enumerate()
        .map(|(k, f)| {
            (
                PointId::Fiducial(k),
                f.obs.line,
                None,
                format!("fiducial {}", f.name),
            )
        })
        .collect();
    for (pi, p) in data.poses.iter().enumerate() {
        for b in &p.balls {
            out.push((
                PointId::Ball {
                    pose: pi,
                    ball: b.ball,
                },
                b.obs.line,
                Some(p.pose),
                format!("ball {} of pose {}", data.ball_names[b.ball], p.pose),
            ));
        }
    }
    out
}

/// Row bookkeeping of one linearisation.
struct Linear {
    /// Residuals (all rows).
    res: Vec<f64>,
    /// Jacobian.
    j: DMatrix<f64>,
    /// `Q_xx`.
    q: DMatrix<f64>,
    /// Redundancy numbers (all rows).
    red: Vec<f64>,
}

/// The redundancy numbers `r_i = 1 - j_i^T Q_xx j_i` of every row (data, then priors)
/// of `bundle` at `x`, with its variance factors and priors in force.
pub fn redundancy_numbers(bundle: &Bundle, x: &[f64]) -> Result<Vec<f64>, BundleError> {
    Ok(linearise(bundle, x)?.red)
}

fn linearise(bundle: &Bundle, x: &[f64]) -> Result<Linear, BundleError> {
    let j = bundle.jacobian(x);
    let res = bundle.evaluate(x, None);
    let n = j.transpose() * &j;
    let q = n
        .cholesky()
        .ok_or_else(|| {
            BundleError::Data(
                "the normal matrix is singular: the data and priors do not determine the unknowns"
                    .into(),
            )
        })?
        .inverse();
    let jq = &j * &q;
    let red = (0..j.nrows())
        .map(|i| 1.0 - jq.row(i).dot(&j.row(i)))
        .collect();
    Ok(Linear { res, j, q, red })
}

/// Current variance factors and prior spreads.
#[derive(Clone, Copy, Debug)]
struct State {
    k: [f64; N_COMPONENTS],
    joint: Option<f64>,
    ball: Option<f64>,
}

impl State {
    fn apply(&self, bundle: &mut Bundle) {
        bundle.set_variance_factors(&self.k);
        bundle.set_priors(Priors {
            joint_sigma_mm: self.joint,
            ball_sigma_mm: self.ball,
        });
    }
}

/// Sums of squared residuals and redundancies per group: tracker components (ball rows
/// only), joint prior, ball prior; and their row counts.
fn group_sums(bundle: &Bundle, lin: &Linear) -> ([f64; 5], [f64; 5], [usize; 5]) {
    let mut om = [0.0; 5];
    let mut rd = [0.0; 5];
    let mut count = [0usize; 5];
    let n_fid_rows = 3 * bundle.data().fiducials.len();
    let mut row = 0;
    for o in bundle.observations() {
        for (a, c) in o.components.iter().enumerate() {
            let i = row + a;
            if row >= n_fid_rows {
                let g = *c as usize;
                om[g] += lin.res[i] * lin.res[i];
                rd[g] += lin.red[i];
                count[g] += 1;
            }
        }
        row += 3;
    }
    let nd = bundle.n_data_rows();
    let priors = bundle.priors();
    let mut r = nd;
    if priors.joint_sigma_mm.is_some() {
        for i in r..r + N_PARAMS {
            om[3] += lin.res[i] * lin.res[i];
            rd[3] += lin.red[i];
            count[3] += 1;
        }
        r += N_PARAMS;
    }
    if priors.ball_sigma_mm.is_some() {
        for i in r..lin.res.len() {
            om[4] += lin.res[i] * lin.res[i];
            rd[4] += lin.red[i];
            count[4] += 1;
        }
    }
    (om, rd, count)
}

/// Variance component estimation from `x`: returns the solution, the final state and
/// the iterations.
fn estimate(
    bundle: &mut Bundle,
    x0: Vec<f64>,
    mut st: State,
    cfg: &AdjustConfig,
) -> Result<(Vec<f64>, State, usize), BundleError> {
    st.apply(bundle);
    let (mut x, _, _) = bundle::solve(bundle, x0, &cfg.solver)?;
    let anything = cfg.estimate_noise || cfg.joint_prior.estimated() || cfg.ball_prior.estimated();
    if !anything {
        return Ok((x, st, 0));
    }
    let objective = |b: &Bundle, x: &[f64]| b.evaluate(x, None).iter().map(|v| v * v).sum::<f64>();
    for it in 1..=MAX_VCE_ITERATIONS {
        st.apply(bundle);
        let lin = linearise(bundle, &x)?;
        // One Gauss-Newton step with the factors in force (halved if it does not help).
        let g = lin.j.transpose() * DVector::from_column_slice(&lin.res);
        let dx = -(&lin.q * g);
        let f0 = lin.res.iter().map(|v| v * v).sum::<f64>();
        let mut step = 1.0;
        let mut moved = false;
        for _ in 0..12 {
            let xt: Vec<f64> = x.iter().zip(dx.iter()).map(|(a, d)| a + step * d).collect();
            if objective(bundle, &xt) <= f0 * (1.0 + 1e-12) {
                x = xt;
                moved = true;
                break;
            }
            step *= 0.5;
        }
        if !moved {
            x = bundle::solve(bundle, x, &cfg.solver)?.0;
        }
        // New factors.
        let (om, rd, count) = group_sums(bundle, &lin);
        let mut change = 0.0f64;
        if cfg.estimate_noise {
            for c in 0..N_COMPONENTS {
                if count[c] > 0 && rd[c] >= MIN_COMPONENT_REDUNDANCY {
                    let f = om[c] / rd[c];
                    st.k[c] *= f;
                    change = change.max((f - 1.0).abs());
                }
            }
        }
        if cfg.joint_prior.estimated() && rd[3] >= MIN_COMPONENT_REDUNDANCY {
            if let Some(s) = st.joint.as_mut() {
                let f = om[3] / rd[3];
                *s *= f.sqrt();
                change = change.max((f - 1.0).abs());
            }
        }
        if cfg.ball_prior.estimated() && rd[4] >= MIN_COMPONENT_REDUNDANCY {
            if let Some(s) = st.ball.as_mut() {
                let f = om[4] / rd[4];
                *s *= f.sqrt();
                change = change.max((f - 1.0).abs());
            }
        }
        if !st.k.iter().all(|v| v.is_finite() && *v > 0.0)
            || !st.joint.is_none_or(|v| v.is_finite() && v > 0.0)
            || !st.ball.is_none_or(|v| v.is_finite() && v > 0.0)
        {
            return Err(BundleError::Solver(
                "variance component estimation diverged".into(),
            ));
        }
        if change < VCE_TOLERANCE {
            st.apply(bundle);
            let (x, _, _) = bundle::solve(bundle, x, &cfg.solver)?;
            return Ok((x, st, it));
        }
    }
    st.apply(bundle);
    let (x, _, _) = bundle::solve(bundle, x, &cfg.solver)?;
    Ok((x, st, MAX_VCE_ITERATIONS))
}

/// The tests of every point at a linearisation.
fn point_tests(
    bundle: &Bundle,
    lin: &Linear,
    k: &[f64; N_COMPONENTS],
    lambda0: f64,
) -> Vec<PointTest> {
    let ids = point_ids(bundle.data());
    ids.into_iter()
        .zip(bundle.observations())
        .enumerate()
        .map(|(p, ((id, line, pose, what), obs))| {
            let r0 = 3 * p;
            let jb = lin.j.rows(r0, 3).into_owned();
            let qvv = Matrix3::identity() - {
                let m = &jb * &lin.q * jb.transpose();
                Matrix3::from_fn(|a, b| m[(a, b)])
            };
            let v = Vector3::new(lin.res[r0], lin.res[r0 + 1], lin.res[r0 + 2]);
            let redundancy = (lin.red[r0] + lin.red[r0 + 1] + lin.red[r0 + 2]) / 3.0;
            let w_max = (0..3)
                .map(|a| v[a].abs() / qvv[(a, a)].max(1e-300).sqrt())
                .fold(0.0f64, f64::max);
            // The point's whitening with the variance factors in force (tracker frame).
            let s = obs.row_scales(k);
            let w_tr = Matrix3::from_diagonal(&Vector3::from(s)) * obs.whitening();
            let eig = qvv.symmetric_eigen();
            let min_eig = eig.eigenvalues.min();
            let (t, error_mm, mdb_mm) = match qvv.try_inverse() {
                Some(qi) if min_eig > MIN_TESTABLE_REDUNDANCY => {
                    let nabla = qi * v;
                    let t = v.dot(&nabla);
                    // Error in tracker coordinates: W^-1 nabla.
                    let e = w_tr.try_inverse().map(|wi| wi * nabla).unwrap_or_default();
                    let m = w_tr.transpose() * qvv * w_tr;
                    let mu = m.symmetric_eigen().eigenvalues.min().max(1e-300);
                    (t, [e.x, e.y, e.z], (lambda0 / mu).sqrt())
                }
                _ => (f64::NAN, [0.0; 3], f64::INFINITY),
            };
            PointTest {
                id,
                line,
                pose,
                what,
                t,
                w_max,
                redundancy,
                mdb_mm,
                error_mm,
            }
        })
        .collect()
}

/// The data without one point.
fn without(data: &BundleData, id: PointId) -> Result<BundleData, BundleError> {
    let mut d = data.clone();
    match id {
        PointId::Fiducial(k) => {
            if d.fiducials.len() <= MIN_FIDUCIALS_LEFT {
                return Err(BundleError::Data(format!(
                    "removing fiducial {} would leave fewer than {MIN_FIDUCIALS_LEFT} fiducials",
                    d.fiducials[k].name
                )));
            }
            d.fiducials.remove(k);
        }
        PointId::Ball { pose, ball } => {
            d.poses[pose].balls.retain(|b| b.ball != ball);
            if d.poses[pose].balls.is_empty() {
                d.poses.remove(pose);
            }
        }
    }
    Ok(d)
}

/// Component estimates at the final linearisation.
fn components(
    bundle: &Bundle,
    lin: &Linear,
    st: &State,
    cfg: &AdjustConfig,
    start: &State,
) -> Vec<ComponentEstimate> {
    let (om, rd, count) = group_sums(bundle, lin);
    let names = [
        "tracker range (line of sight)",
        "tracker transverse (angles)",
        "export sigmas",
        "joint prior",
        "ball prior",
    ];
    (0..5)
        .map(|g| {
            let (factor, estimated) = match g {
                0..=2 => (
                    st.k[g],
                    cfg.estimate_noise && count[g] > 0 && rd[g] >= MIN_COMPONENT_REDUNDANCY,
                ),
                3 => (
                    match (st.joint, start.joint) {
                        (Some(a), Some(b)) => (a / b).powi(2),
                        _ => 1.0,
                    },
                    cfg.joint_prior.estimated() && rd[3] >= MIN_COMPONENT_REDUNDANCY,
                ),
                _ => (
                    match (st.ball, start.ball) {
                        (Some(a), Some(b)) => (a / b).powi(2),
                        _ => 1.0,
                    },
                    cfg.ball_prior.estimated() && rd[4] >= MIN_COMPONENT_REDUNDANCY,
                ),
            };
            let r = rd[g].max(1e-9);
            let a = GLOBAL_TEST_ALPHA;
            let ci = if count[g] > 0 {
                (
                    factor * r / chi2_quantile(1.0 - a / 2.0, r),
                    factor * r / chi2_quantile(a / 2.0, r),
                )
            } else {
                (f64::NAN, f64::NAN)
            };
            ComponentEstimate {
                name: names[g].to_string(),
                factor,
                factor_ci: ci,
                omega: om[g],
                redundancy: rd[g],
                rows: count[g],
                estimated,
            }
        })
        .collect()
}

/// The a-priori model's global test at `x` (data rows, variance factors 1).
fn global_test(bundle: &mut Bundle, x: &[f64], st: &State) -> Result<GlobalTest, BundleError> {
    let mut s1 = *st;
    s1.k = [1.0; N_COMPONENTS];
    s1.apply(bundle);
    let lin = linearise(bundle, x)?;
    st.apply(bundle);
    let nd = bundle.n_data_rows();
    let omega: f64 = lin.res[..nd].iter().map(|v| v * v).sum();
    let red: f64 = lin.red[..nd].iter().sum();
    Ok(GlobalTest::new(omega, red))
}

/// Log marginal likelihood (Laplace) of the data and priors in force at the MAP `x`,
/// up to a constant: `-(chi2 + ln det N + 36 ln s_j^2) / 2` (the ball prior and the
/// noise factors held fixed).
fn log_evidence(lin: &Linear, joint_mm: f64) -> Option<f64> {
    let chi2: f64 = lin.res.iter().map(|v| v * v).sum();
    let n = lin.j.transpose() * &lin.j;
    let ld: f64 = n
        .cholesky()?
        .l()
        .diagonal()
        .iter()
        .map(|v| 2.0 * v.ln())
        .sum();
    Some(-0.5 * (chi2 + ld + N_PARAMS as f64 * (joint_mm * joint_mm).ln()))
}

/// Bayesian model averaging over the joints' spread: the MAP fit at every point of a log
/// grid over [`SPREAD_RANGE_MM`], weighted by its marginal likelihood (the hyperprior
/// log-uniform: equal weight per grid point). Returns the averaged unknowns, the
/// mixture covariance `sum w (C_s + (x_s - x)(x_s - x)^T)` with the estimated noise
/// factors and with the a-priori ones, and the posterior.
#[allow(clippy::type_complexity)]
fn average_over_spread(
    b: &mut Bundle,
    x_vce: &[f64],
    st: &State,
    cfg: &AdjustConfig,
) -> Result<(Vec<f64>, DMatrix<f64>, DMatrix<f64>, SpreadPosterior), BundleError> {
    let (lo, hi) = SPREAD_RANGE_MM;
    let grid: Vec<f64> = (0..SPREAD_GRID)
        .map(|i| lo * (hi / lo).powf(i as f64 / (SPREAD_GRID - 1) as f64))
        .collect();
    let mut xs = Vec::with_capacity(grid.len());
    let mut qs = Vec::with_capacity(grid.len());
    let mut q1s = Vec::with_capacity(grid.len());
    let mut ev = Vec::with_capacity(grid.len());
    // Warm starts: up the grid from the VCE solution's spread, then down.
    let start = grid
        .iter()
        .position(|s| *s >= st.joint.unwrap_or(lo))
        .unwrap_or(grid.len() - 1);
    let mut order: Vec<usize> = (start..grid.len()).collect();
    order.extend((0..start).rev());
    let mut results: Vec<Option<(Vec<f64>, DMatrix<f64>, DMatrix<f64>, f64)>> =
        vec![None; grid.len()];
    let mut warm = x_vce.to_vec();
    for &i in &order {
        if i + 1 == start {
            warm = x_vce.to_vec();
        }
        let mut si = *st;
        si.joint = Some(grid[i]);
        si.apply(b);
        let (x, _, _) = bundle::solve(b, warm.clone(), &cfg.solver)?;
        let lin = linearise(b, &x)?;
        let e = log_evidence(&lin, grid[i]).ok_or_else(|| {
            BundleError::Solver("marginal likelihood: singular normal matrix".into())
        })?;
        // The same information with the a-priori variances: the data rows unscaled.
        let mut j1 = lin.j.clone();
        for (i, c) in b.row_scales().iter().enumerate() {
            j1.row_mut(i).scale_mut(1.0 / c);
        }
        let q1 = (j1.transpose() * &j1)
            .cholesky()
            .ok_or_else(|| BundleError::Solver("singular normal matrix".into()))?
            .inverse();
        warm = x.clone();
        results[i] = Some((x, lin.q, q1, e));
    }
    st.apply(b);
    for r in results.into_iter() {
        let (x, q, q1, e) =
            r.ok_or_else(|| BundleError::Solver("spread grid incomplete".into()))?;
        xs.push(x);
        qs.push(q);
        q1s.push(q1);
        ev.push(e);
    }
    let m = ev.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let w: Vec<f64> = ev.iter().map(|e| (e - m).exp()).collect();
    let sum: f64 = w.iter().sum();
    let w: Vec<f64> = w.iter().map(|v| v / sum).collect();
    let n = xs.first().map_or(0, |x| x.len());
    let mut x = vec![0.0; n];
    for (wi, xi) in w.iter().zip(&xs) {
        for (a, v) in x.iter_mut().zip(xi) {
            *a += wi * v;
        }
    }
    let xv = DVector::from_column_slice(&x);
    let mut c = DMatrix::zeros(n, n);
    let mut c1 = DMatrix::zeros(n, n);
    for ((wi, xi), (q, q1)) in w.iter().zip(&xs).zip(qs.iter().zip(&q1s)) {
        let d = DVector::from_column_slice(xi) - &xv;
        let dd = &d * d.transpose();
        c += (q + &dd) * *wi;
        c1 += (q1 + &dd) * *wi;
    }
    let mut post = SpreadPosterior {
        grid_mm: grid,
        log_evidence: ev,
        weights: w,
        median_mm: 0.0,
        interval_mm: (0.0, 0.0),
        grid_x: xs,
    };
    post.median_mm = post.quantile(0.5);
    post.interval_mm = (post.quantile(0.16), post.quantile(0.84));
    Ok((x, c, c1, post))
}

/// The adjustment: variance components, tests, outliers removed one at a time.
pub fn adjust(data: &BundleData, cfg: &AdjustConfig) -> Result<Adjustment, BundleError> {
    let started = Instant::now();
    let start = State {
        k: [1.0; N_COMPONENTS],
        joint: cfg.joint_prior.start(),
        ball: cfg.ball_prior.start(),
    };
    let n_points_all =
        data.fiducials.len() + data.poses.iter().map(|p| p.balls.len()).sum::<usize>();
    let max_removed =
        ((MAX_REMOVED_FRACTION * n_points_all as f64).floor() as usize).max(MIN_REMOVED_LIMIT);
    let mut cur = data.clone();
    let mut st = start;
    let mut x: Option<Vec<f64>> = None;
    let mut removed: Vec<Outlier> = Vec::new();
    let mut iterations = 0;
    let mut global_before = None;
    loop {
        let mut b = Bundle::new(
            &cur,
            Priors {
                joint_sigma_mm: st.joint,
                ball_sigma_mm: st.ball,
            },
        )?;
        bundle::check_count(&b)?;
        let x0 = x.take().unwrap_or_else(|| b.start());
        let (xs, st_new, its) = estimate(&mut b, x0, st, cfg)?;
        st = st_new;
        iterations += its;
        if global_before.is_none() {
            global_before = Some(global_test(&mut b, &xs, &st)?);
        }
        st.apply(&mut b);
        // With the spread marginalised, the tests (and the final figures) are those of
        // the fit at the posterior median spread: the type-II ML spread can collapse far
        // below it, biasing the fit and inflating the residuals of the extreme poses.
        let marginalise = cfg.marginalise_spread && cfg.joint_prior.estimated();
        let grid = if marginalise {
            let g = average_over_spread(&mut b, &xs, &st, cfg)?;
            let mut sm = st;
            sm.joint = Some(g.3.median_mm);
            sm.apply(&mut b);
            let (xm, _, _) = bundle::solve(&b, xs.clone(), &cfg.solver)?;
            Some((g, xm))
        } else {
            None
        };
        let x_test = grid.as_ref().map_or(&xs, |g| &g.1).clone();
        let lin = linearise(&b, &x_test)?;
        st.apply(&mut b);
        let n_points = cur.fiducials.len() + cur.poses.iter().map(|p| p.balls.len()).sum::<usize>();
        let alpha_per_test = cfg.alpha / n_points.max(1) as f64;
        let critical = chi2_quantile(1.0 - alpha_per_test, 3.0);
        let lambda0 = noncentrality_for_power(critical, 3.0, OUTLIER_POWER);
        let tests = point_tests(&b, &lin, &st.k, lambda0);
        let worst = tests
            .iter()
            .filter(|t| t.t.is_finite())
            .max_by(|a, b| a.t.total_cmp(&b.t))
            .cloned();
        if let Some(w) = worst.filter(|w| w.t > critical) {
            let outlier = Outlier {
                test: w.clone(),
                critical,
            };
            if cfg.rule == OutlierRule::Refuse {
                return Err(BundleError::Outlier {
                    line: w.line,
                    sigmas: w.t.sqrt(),
                    what: format!(
                        "{} fails the outlier test: T = {:.1} > {:.1} (chi-square, 3 dof, alpha {:.1e} per point; p = {:.1e}); estimated error {:.0} um",
                        w.what,
                        w.t,
                        critical,
                        alpha_per_test,
                        chi2_sf(w.t, 3.0),
                        Vector3::from(w.error_mm).norm() * 1e3
                    ),
                });
            }
            removed.push(outlier);
            if removed.len() > max_removed {
                return Err(BundleError::Data(format!(
                    "more than {max_removed} points ({:.0} % of {n_points_all}) fail the outlier test: the data are not within any noise model (check the tracker's setup, the strokes and the target file); removed so far: {}",
                    100.0 * MAX_REMOVED_FRACTION,
                    removed
                        .iter()
                        .map(|o| format!("line {} ({}, T {:.1})", o.test.line, o.test.what, o.test.t))
                        .collect::<Vec<_>>()
                        .join(", ")
                )));
            }
            drop(b);
            cur = without(&cur, w.id).map_err(|e| match e {
                BundleError::Data(s) => BundleError::Data(format!(
                    "line {}: {} fails the outlier test (T = {:.1} > {:.1}), but {s}",
                    w.line, w.what, w.t, critical
                )),
                e => e,
            })?;
            x = Some(x_test);
            continue;
        }
        let global_after = global_test(&mut b, &xs, &st)?;
        let comps = components(&b, &lin, &st, cfg, &start);
        let start_rms = bundle::data_rms(&b, &b.start());
        let (fit, covariance_unscaled, spread_posterior) = if let Some((g, _)) = grid {
            let (x_avg, c_scaled, c_unscaled, post) = g;
            // The fit's figures at the averaged unknowns with the median spread.
            let mut sm = st;
            sm.joint = Some(post.median_mm);
            sm.apply(&mut b);
            let mut fit = bundle::finish(
                &b,
                x_avg,
                start_rms,
                iterations,
                format!(
                    "{iterations} variance-component iterations, {SPREAD_GRID} fits averaged over the joints' spread"
                ),
                started,
            )?;
            fit.covariance = c_scaled;
            fit.covariance_pseudo_inverse = false;
            (fit, c_unscaled, Some(post))
        } else {
            // Unscaled covariance: the a-priori noise model at the same solution and priors.
            let mut s1 = st;
            s1.k = [1.0; N_COMPONENTS];
            s1.apply(&mut b);
            let c_unscaled = linearise(&b, &xs)?.q;
            st.apply(&mut b);
            let fit = bundle::finish(
                &b,
                xs,
                start_rms,
                iterations,
                format!("{iterations} variance-component iterations"),
                started,
            )?;
            (fit, c_unscaled, None)
        };
        drop(b);
        return Ok(Adjustment {
            fit,
            data: cur,
            components: comps,
            joint_prior_mm: st.joint,
            spread_posterior,
            ball_prior_mm: st.ball,
            global_before: global_before.unwrap_or_else(|| global_after.clone()),
            global_after,
            tests,
            critical,
            alpha_per_test,
            lambda0,
            removed,
            covariance_unscaled,
            vce_iterations: iterations,
        });
    }
}
