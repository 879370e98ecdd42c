//! The adjustment itself: fit with the variance components estimated, test every point,
//! remove the worst outlier and fit again until none is left, then report.

use std::time::Instant;

use nalgebra::Vector3;

use super::linear::{linearise, State};
use super::results::{Adjustment, Outlier};
use super::settings::{AdjustConfig, OutlierRule};
use super::snooping::{point_tests, without};
use super::spread::average_over_spread;
use super::variance::{components, estimate, global_test};
use super::{MAX_REMOVED_FRACTION, MIN_REMOVED_LIMIT, OUTLIER_POWER, SPREAD_GRID};
use crate::calib::bundle::{self, Bundle, BundleData, BundleError, Priors, N_COMPONENTS};
use crate::calib::stats::{chi2_quantile, chi2_sf, noncentrality_for_power};

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
