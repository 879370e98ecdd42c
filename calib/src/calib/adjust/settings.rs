//! How the adjustment is set up: each prior's spread estimated, given or left free, what
//! to do with an outlier, the significance and the solver's budget.

use super::DEFAULT_ALPHA;
use crate::calib::bundle::{self, BundleConfig};

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
    pub(super) fn start(&self) -> Option<f64> {
        match self {
            PriorSetting::Estimate { start_mm } => Some(*start_mm),
            PriorSetting::Fixed(v) => Some(*v),
            PriorSetting::Free => None,
        }
    }
    pub(super) fn estimated(&self) -> bool {
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
    /// [`SPREAD_RANGE_MM`](super::SPREAD_RANGE_MM)), instead of fitting with the single most likely spread.
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
