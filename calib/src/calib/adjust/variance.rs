//! Variance component estimation (Foerstner's iterative estimator), the component
//! estimates it reports and the global test of the a-priori noise model.

use nalgebra::DVector;

use super::linear::{group_sums, linearise, Linear, State};
use super::results::{ComponentEstimate, GlobalTest};
use super::settings::AdjustConfig;
use super::{GLOBAL_TEST_ALPHA, MAX_VCE_ITERATIONS, MIN_COMPONENT_REDUNDANCY, VCE_TOLERANCE};
use crate::calib::bundle::{self, Bundle, BundleError, N_COMPONENTS};
use crate::calib::stats::chi2_quantile;

/// Variance component estimation from `x`: returns the solution, the final state and
/// the iterations.
pub(super) fn estimate(
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

/// Component estimates at the final linearisation.
pub(super) fn components(
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
pub(super) fn global_test(
    bundle: &mut Bundle,
    x: &[f64],
    st: &State,
) -> Result<GlobalTest, BundleError> {
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
