//! Optimal measurement plan: which poses to measure, chosen from a candidate set by an
//! observability criterion on the bundle Jacobian ([`super::bundle`]).
//!
//! Each candidate pose `j` adds the information `U_j^T U_j` of its whitened ball rows
//! (`U_j`: 3 rows per ball, one column per unknown) to the information `A0` of the
//! fiducials and the priors. With `C = A^-1`:
//!
//! * **D-optimality on the joints**: maximise `log det` of the joints' marginal
//!   information (balls and registration free), `log det A - log det A_nn`. Adding `j`
//!   gains `log det(I + U C U^T) - log det(I + U_n C_nn U_n^T)` (determinant lemma;
//!   `U_n` the nuisance columns, `C_nn = A_nn^-1`).
//! * **I-optimality** (task-oriented): minimise the mean predicted pose variance over a
//!   set of evaluation poses, `trace(M C_tt)` with `M = mean_p G_p^T W G_p`
//!   ([`super::bundle::pose_sensitivity`] `G`, `W` weighting 1 um and 1 arcsec alike).
//!   Adding `j` lowers it by `trace(S^-1 V^T M V)`, `V = C U^T`, `S = I + U V`.
//!
//! Greedy forward selection (each candidate at most once), then exchange passes: a
//! selected pose is swapped for a candidate while that improves the criterion. The
//! information is that of the nominal geometry (a local design).

use nalgebra::DMatrix;

use super::bundle::{pose_sensitivity, Bundle, BundleData, BundleError, Priors};
use super::N_PARAMS;
use m2ctl::kinematics::{Geometry, GeometryParams, Pose};
use m2ctl::units::{ARCSEC_PER_RAD, UM_PER_MM};

/// Most exchange passes after the greedy selection.
pub const MAX_EXCHANGE_PASSES: usize = 3;

/// The design criterion.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Criterion {
    /// D-optimality of the joints' marginal information.
    D,
    /// I-optimality: mean predicted pose variance over the evaluation poses.
    I,
}

impl Criterion {
    /// Command-line name.
    pub fn name(&self) -> &'static str {
        match self {
            Criterion::D => "d-optimal",
            Criterion::I => "i-optimal",
        }
    }

    /// Parses a command-line name.
    pub fn parse(s: &str) -> Option<Self> {
        [Criterion::D, Criterion::I]
            .into_iter()
            .find(|c| c.name() == s)
    }
}

/// The information pieces of a design problem.
#[derive(Clone, Debug)]
pub struct DesignProblem {
    /// Information of the fiducials and priors (n x n).
    pub info0: DMatrix<f64>,
    /// Whitened ball rows of each candidate (rows x n).
    pub candidates: Vec<DMatrix<f64>>,
    /// `M` of the I-criterion, padded to n x n (um^2 and arcsec^2 per mm^2).
    pub m: DMatrix<f64>,
    /// Number of joint unknowns (the first columns).
    pub n_joint: usize,
}

/// Builds the design problem: `data` holds one pose per candidate (noise-free predicted
/// measurements at nominal, weighted with the tracker's noise model), `eval_poses` the
/// poses whose mean predicted variance the I-criterion minimises.
pub fn problem(
    data: &BundleData,
    priors: Priors,
    eval_poses: &[Pose<f64>],
) -> Result<DesignProblem, BundleError> {
    let bundle = Bundle::new(data, priors)?;
    let x = bundle.start();
    let j = bundle.jacobian(&x);
    let n = bundle.n_params();
    let nf = 3 * data.fiducials.len();
    let mut candidates = Vec::with_capacity(data.poses.len());
    let mut row = nf;
    for p in &data.poses {
        let rows = 3 * p.balls.len();
        candidates.push(j.rows(row, rows).into_owned());
        row += rows;
    }
    let fixed_rows: Vec<usize> = (0..nf).chain(row..bundle.n_rows()).collect();
    let j0 = j.select_rows(fixed_rows.iter());
    let info0 = j0.transpose() * j0;
    let geom = Geometry::<f64>::new(&GeometryParams::new(data.nominal.legs, data.nominal.p0_mm))
        .map_err(|e| BundleError::Data(crate::files::describe_geometry_error(&e)))?;
    let mut m = DMatrix::zeros(n, n);
    for p in eval_poses {
        let mut g = pose_sensitivity(&geom, p)
            .ok_or_else(|| BundleError::Data("evaluation pose singular".into()))?;
        for r in 0..6 {
            let s = if r < 3 { UM_PER_MM } else { ARCSEC_PER_RAD };
            g.row_mut(r).scale_mut(s);
        }
        let gtg = g.transpose() * g;
        let mut block = m.view_mut((0, 0), (N_PARAMS, N_PARAMS));
        block += gtg / eval_poses.len().max(1) as f64;
    }
    Ok(DesignProblem {
        info0,
        candidates,
        m,
        n_joint: N_PARAMS,
    })
}

fn inverse(a: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    a.clone().cholesky().map(|c| c.inverse())
}

fn logdet(a: &DMatrix<f64>) -> Option<f64> {
    let c = a.clone().cholesky()?;
    Some(2.0 * c.l().diagonal().iter().map(|v| v.ln()).sum::<f64>())
}

impl DesignProblem {
    /// Information of a selection.
    pub fn info(&self, selected: &[usize]) -> DMatrix<f64> {
        let mut a = self.info0.clone();
        for &k in selected {
            let u = &self.candidates[k];
            a += u.transpose() * u;
        }
        a
    }

    /// The criterion to be maximised: D: `log det` of the marginal joint information;
    /// I: minus the mean predicted pose variance (um^2 / arcsec^2).
    pub fn value(&self, criterion: Criterion, selected: &[usize]) -> Option<f64> {
        let a = self.info(selected);
        match criterion {
            Criterion::D => {
                let nj = self.n_joint;
                let nn = a.nrows() - nj;
                let ann = a.view((nj, nj), (nn, nn)).into_owned();
                Some(logdet(&a)? - logdet(&ann)?)
            }
            Criterion::I => {
                let c = inverse(&a)?;
                Some(-(&self.m * c).trace())
            }
        }
    }

    /// Mean predicted pose variance of a selection (um^2 and arcsec^2 summed over the six
    /// axes, averaged over the evaluation poses).
    pub fn mean_variance(&self, selected: &[usize]) -> Option<f64> {
        self.value(Criterion::I, selected).map(|v| -v)
    }

    /// Gain of adding candidate `k` given `C = A^-1` (and `C_nn` for D).
    fn gain(&self, criterion: Criterion, k: usize, c: &DMatrix<f64>, cnn: &DMatrix<f64>) -> f64 {
        let u = &self.candidates[k];
        let r = u.nrows();
        let v = c * u.transpose();
        let s = DMatrix::identity(r, r) + u * &v;
        match criterion {
            Criterion::D => {
                let nj = self.n_joint;
                let un = u.columns(nj, u.ncols() - nj).into_owned();
                let sn = DMatrix::identity(r, r) + &un * cnn * un.transpose();
                logdet(&s).unwrap_or(f64::NEG_INFINITY) - logdet(&sn).unwrap_or(0.0)
            }
            Criterion::I => match s.clone().cholesky() {
                Some(ch) => {
                    let mv = &self.m * &v;
                    (ch.inverse() * (v.transpose() * mv)).trace()
                }
                None => f64::NEG_INFINITY,
            },
        }
    }

    /// Greedy forward selection of `n` distinct candidates, then exchange passes.
    pub fn select(&self, criterion: Criterion, n: usize) -> Vec<usize> {
        let n = n.min(self.candidates.len());
        let mut selected: Vec<usize> = Vec::with_capacity(n);
        let mut a = self.info0.clone();
        let nj = self.n_joint;
        let nn = a.nrows() - nj;
        for _ in 0..n {
            let (Some(c), Some(cnn)) = (
                inverse(&a),
                inverse(&a.view((nj, nj), (nn, nn)).into_owned()),
            ) else {
                break;
            };
            let best = (0..self.candidates.len())
                .filter(|k| !selected.contains(k))
                .map(|k| (k, self.gain(criterion, k, &c, &cnn)))
                .max_by(|p, q| p.1.total_cmp(&q.1));
            let Some((k, _)) = best else { break };
            let u = &self.candidates[k];
            a += u.transpose() * u;
            selected.push(k);
        }
        // Exchange: swap a selected pose for an unselected one while that helps.
        for _ in 0..MAX_EXCHANGE_PASSES {
            let mut improved = false;
            let mut current = self
                .value(criterion, &selected)
                .unwrap_or(f64::NEG_INFINITY);
            for slot in 0..selected.len() {
                let mut rest = selected.clone();
                rest.remove(slot);
                let a_rest = self.info(&rest);
                let (Some(c), Some(cnn)) = (
                    inverse(&a_rest),
                    inverse(&a_rest.view((nj, nj), (nn, nn)).into_owned()),
                ) else {
                    continue;
                };
                let base = self.value(criterion, &rest).unwrap_or(f64::NEG_INFINITY);
                let best = (0..self.candidates.len())
                    .filter(|k| !rest.contains(k))
                    .map(|k| (k, self.gain(criterion, k, &c, &cnn)))
                    .max_by(|p, q| p.1.total_cmp(&q.1));
                if let Some((k, g)) = best {
                    let value = base + g;
                    if k != selected[slot] && value > current + 1e-12 * current.abs() {
                        selected[slot] = k;
                        current = value;
                        improved = true;
                    }
                }
            }
            if !improved {
                break;
            }
        }
        selected
    }
}

/// The candidate grid: every combination of `{-1, 0, +1} x translation_mm` on x, y, z and
/// `{-1, 0, +1} x rotation_arcsec` on the three angles (3^6 = 729 poses).
pub fn grid_candidates(translation_mm: f64, rotation_arcsec: f64) -> Vec<Pose<f64>> {
    let levels = [-1.0, 0.0, 1.0];
    let mut out = Vec::with_capacity(729);
    for code in 0..729usize {
        let mut c = code;
        let mut v = [0.0; 6];
        for vk in v.iter_mut() {
            *vk = levels[c % 3];
            c /= 3;
        }
        out.push(Pose::from_mm_arcsec(
            [
                v[0] * translation_mm,
                v[1] * translation_mm,
                v[2] * translation_mm,
            ],
            [
                v[3] * rotation_arcsec,
                v[4] * rotation_arcsec,
                v[5] * rotation_arcsec,
            ],
        ));
    }
    out
}
