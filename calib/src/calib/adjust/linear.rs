//! The adjustment's linearisation at a solution (residuals, Jacobian, `Q_xx`, redundancy
//! numbers), the state of the variance factors and priors, and the sums of squared
//! residuals and redundancies per variance component.

use nalgebra::DMatrix;

use crate::calib::bundle::{Bundle, BundleError, Priors, N_COMPONENTS};
use crate::calib::N_PARAMS;

/// Row bookkeeping of one linearisation.
pub(super) struct Linear {
    /// Residuals (all rows).
    pub(super) res: Vec<f64>,
    /// Jacobian.
    pub(super) j: DMatrix<f64>,
    /// `Q_xx`.
    pub(super) q: DMatrix<f64>,
    /// Redundancy numbers (all rows).
    pub(super) red: Vec<f64>,
}

/// The redundancy numbers `r_i = 1 - j_i^T Q_xx j_i` of every row (data, then priors)
/// of `bundle` at `x`, with its variance factors and priors in force.
pub fn redundancy_numbers(bundle: &Bundle, x: &[f64]) -> Result<Vec<f64>, BundleError> {
    Ok(linearise(bundle, x)?.red)
}

pub(super) fn linearise(bundle: &Bundle, x: &[f64]) -> Result<Linear, BundleError> {
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
pub(super) struct State {
    pub(super) k: [f64; N_COMPONENTS],
    pub(super) joint: Option<f64>,
    pub(super) ball: Option<f64>,
}

impl State {
    pub(super) fn apply(&self, bundle: &mut Bundle) {
        bundle.set_variance_factors(&self.k);
        bundle.set_priors(Priors {
            joint_sigma_mm: self.joint,
            ball_sigma_mm: self.ball,
        });
    }
}

/// Sums of squared residuals and redundancies per group: tracker components (ball rows
/// only), joint prior, ball prior; and their row counts.
pub(super) fn group_sums(bundle: &Bundle, lin: &Linear) -> ([f64; 5], [f64; 5], [usize; 5]) {
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
