//! Bayesian model averaging over the joints' spread: the marginal likelihood (Laplace)
//! of each spread on a log grid and the fits averaged by their posterior weights.

use nalgebra::{DMatrix, DVector};

use super::linear::{linearise, Linear, State};
use super::results::SpreadPosterior;
use super::settings::AdjustConfig;
use super::{SPREAD_GRID, SPREAD_RANGE_MM};
use crate::calib::bundle::{self, Bundle, BundleError};
use crate::calib::N_PARAMS;

/// Log marginal likelihood (Laplace) of the data and priors in force at the MAP `x`,
/// up to a constant: `-(chi2 + ln det N + 36 ln s_j^2) / 2` (the ball prior and the
/// noise factors held fixed).
pub(super) fn log_evidence(lin: &Linear, joint_mm: f64) -> Option<f64> {
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
pub(super) fn average_over_spread(
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
