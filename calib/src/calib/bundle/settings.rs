//! How a bundle fit is set up and how it fails: priors toward nominal, the solver's
//! budget and tolerances, and the error type.

use super::MAX_POINT_SIGMAS;

// The LM budget and tolerances: the same defaults as calib::lm's fit.
pub use crate::calib::lm::{DEFAULT_PATIENCE, DEFAULT_TOL_EPS};

/// Priors toward nominal (1 sigma, mm); `None` leaves the parameter group free.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Priors {
    /// Spread of the true joint coordinates about nominal.
    pub joint_sigma_mm: Option<f64>,
    /// Spread of the true ball centres about nominal.
    pub ball_sigma_mm: Option<f64>,
}

impl Priors {
    /// No prior at all: the plain maximum-likelihood fit.
    pub const NONE: Priors = Priors {
        joint_sigma_mm: None,
        ball_sigma_mm: None,
    };
}

/// Bundle-fit settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BundleConfig {
    /// Priors.
    pub priors: Priors,
    /// LM residual-evaluation budget per (parameter + 1).
    pub patience: usize,
    /// LM tolerances in machine epsilons.
    pub tol_eps: f64,
}

/// Default prior spread of the joints (mm): the simulated plant's manufacturing sigma.
pub const DEFAULT_JOINT_PRIOR_SIGMA_MM: f64 = m2ctl::sim::manufacturing::DEFAULT_JOINT_SIGMA_MM;

impl BundleConfig {
    /// With a joint prior of `joint_sigma_mm` and a ball prior of `ball_sigma_mm`.
    pub fn with_priors(joint_sigma_mm: f64, ball_sigma_mm: f64) -> Self {
        Self {
            priors: Priors {
                joint_sigma_mm: Some(joint_sigma_mm),
                ball_sigma_mm: Some(ball_sigma_mm),
            },
            patience: DEFAULT_PATIENCE,
            tol_eps: DEFAULT_TOL_EPS,
        }
    }

    /// The unregularised fit.
    pub fn unbounded() -> Self {
        Self {
            priors: Priors::NONE,
            patience: DEFAULT_PATIENCE,
            tol_eps: DEFAULT_TOL_EPS,
        }
    }
}

/// Why a bundle fit failed.
#[derive(Clone, Debug, PartialEq)]
pub enum BundleError {
    /// The data cannot be fitted (too few poses, a degenerate registration...).
    Data(String),
    /// A measured point is far from the fit: `(file line, distance in sigmas, which)`.
    Outlier {
        /// Line in the point export.
        line: usize,
        /// Mahalanobis distance from the fit.
        sigmas: f64,
        /// Which point.
        what: String,
    },
    /// The solver failed.
    Solver(String),
}

impl std::fmt::Display for BundleError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BundleError::Data(s) => write!(f, "{s}"),
            BundleError::Outlier { line, sigmas, what } => write!(
                f,
                "line {line}: {what} is {sigmas:.1} sigma from the fit (limit {MAX_POINT_SIGMAS}): a mis-measured, swapped or moved point?"
            ),
            BundleError::Solver(s) => write!(f, "solver: {s}"),
        }
    }
}

impl std::error::Error for BundleError {}
