//! The bundle fit as a geodetic adjustment: variance components estimated from the
//! data, a global test of the noise model, outliers found by data snooping.
//!
//! The bundle ([`crate::calib::bundle`]) is a Gauss-Markov model with pseudo-observations: every
//! measured point gives three whitened rows (in the basis of its covariance: for a
//! tracker point the line of sight, [`crate::calib::bundle::Component::Range`], and two transverse directions,
//! [`crate::calib::bundle::Component::Transverse`]; a point with its own sigma from the export,
//! [`crate::calib::bundle::Component::Export`]); the priors give one row per joint coordinate
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
//!
//! The parts, one job each (their public items re-exported here, the one public path):
//! `settings`, `results` (what is reported), `linear` (linearisation, factors, sums per
//! component), `variance` (the estimation and the global test), `snooping` (the point
//! tests), `spread` (averaging over the joints' spread) and `driver` ([`adjust`], the
//! loop that ties them together).

mod driver;
mod linear;
mod results;
mod settings;
mod snooping;
mod spread;
mod variance;

pub use driver::adjust;
pub use linear::redundancy_numbers;
pub use results::{
    Adjustment, ComponentEstimate, GlobalTest, Outlier, PointId, PointTest, SpreadPosterior,
};
pub use settings::{AdjustConfig, OutlierRule, PriorSetting};

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
