//! What the adjustment reports: the variance components, the global test, the
//! posterior of the joints' spread, each point's outlier test, the removed outliers and
//! the [`Adjustment`] that gathers them.

use nalgebra::DMatrix;

use super::GLOBAL_TEST_ALPHA;
use crate::calib::bundle::{BundleData, BundleFit, N_COMPONENTS};
use crate::calib::stats::chi2_quantile;
use crate::calib::N_PARAMS;

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
    /// [`MIN_COMPONENT_REDUNDANCY`](super::MIN_COMPONENT_REDUNDANCY)).
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
    pub(super) fn new(omega: f64, redundancy: f64) -> Self {
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
    pub(super) fn quantile(&self, q: f64) -> f64 {
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
