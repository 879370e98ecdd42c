//! What the data can and cannot see of the joints: the marginal information with the
//! balls and the registration free against known, its weakest and most hidden
//! directions, described in words.

use nalgebra::{DMatrix, DVector};

use super::engine::Bundle;
use super::observations::BundleData;
use super::settings::{BundleError, Priors};
use crate::calib::{param_name, to_vec, ParamVec, N_PARAMS, PARAMS_PER_LEG};
use m2ctl::kinematics::LEGS;

/// One direction of the joint-parameter space and how well the data see it.
#[derive(Clone, Debug, PartialEq)]
pub struct Direction {
    /// Singular value with the balls and the registration free (marginal information,
    /// in units of the scale: 1 = the data know it as well as one scale sigma).
    pub singular_free: f64,
    /// The same direction's singular value with the balls and registration known.
    pub singular_known: f64,
    /// The unit direction (36, in scale units).
    pub vector: Vec<f64>,
    /// Plain-words description.
    pub description: String,
}

/// What the data can and cannot see of the joints.
#[derive(Clone, Debug, PartialEq)]
pub struct Observability {
    /// Scale of the joint coordinates (mm): singular values are relative to it.
    pub scale_mm: f64,
    /// Singular values of the marginal joint information, balls and registration free,
    /// largest first.
    pub singular_free: Vec<f64>,
    /// Singular values with the balls and registration known, largest first.
    pub singular_known: Vec<f64>,
    /// The weakest directions (balls and registration free), weakest first.
    pub weakest: Vec<Direction>,
    /// The directions that freeing the balls and registration hides most, by the
    /// fraction of information kept (smallest first).
    pub hidden: Vec<(f64, Direction)>,
}

/// Named patterns of the joint space (unit vectors in raw mm): global translations, the
/// rotation about B's z and the per-leg common shifts.
fn describe_direction(v: &[f64], nominal: &ParamVec) -> String {
    let norm = |u: &[f64]| u.iter().map(|x| x * x).sum::<f64>().sqrt();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut shares = Vec::new();
    // Global translations: every a and b shifted by e_axis.
    let mut trans2 = 0.0;
    for axis in 0..3 {
        let mut u = vec![0.0; N_PARAMS];
        for leg in 0..LEGS {
            u[leg * PARAMS_PER_LEG + axis] = 1.0;
            u[leg * PARAMS_PER_LEG + 3 + axis] = 1.0;
        }
        let p = dot(v, &u) / norm(&u);
        trans2 += p * p;
    }
    shares.push(("global translation", trans2));
    // Rotation about B's z: d a = e_z x a, d b = e_z x b.
    let mut u = vec![0.0; N_PARAMS];
    for leg in 0..LEGS {
        let a = leg * PARAMS_PER_LEG;
        u[a] = -nominal[a + 1];
        u[a + 1] = nominal[a];
        u[a + 3] = -nominal[a + 4];
        u[a + 4] = nominal[a + 3];
    }
    let p = dot(v, &u) / norm(&u);
    shares.push(("rotation about z", p * p));
    // Per-leg common shifts (a_i and b_i by the same vector): an 18-dim subspace.
    let mut common2 = 0.0;
    for leg in 0..LEGS {
        for axis in 0..3 {
            let i = leg * PARAMS_PER_LEG;
            let p = (v[i + axis] + v[i + 3 + axis]) / 2f64.sqrt();
            common2 += p * p;
        }
    }
    shares.push(("per-leg common shifts", common2));
    let mut idx: Vec<usize> = (0..N_PARAMS).collect();
    idx.sort_by(|a, b| v[*b].abs().total_cmp(&v[*a].abs()));
    let top: Vec<String> = idx
        .iter()
        .take(4)
        .map(|k| format!("{:+.2} {}", v[*k], param_name(*k)))
        .collect();
    format!(
        "{}; largest: {}",
        shares
            .iter()
            .map(|(n, s)| format!("{:.0} % {n}", 100.0 * s))
            .collect::<Vec<_>>()
            .join(", "),
        top.join(", ")
    )
}

/// Sorted (descending) square roots of the eigenvalues of a symmetric matrix.
fn sqrt_spectrum(m: &DMatrix<f64>) -> Vec<f64> {
    let mut s: Vec<f64> = m
        .clone()
        .symmetric_eigen()
        .eigenvalues
        .iter()
        .map(|v| v.max(0.0).sqrt())
        .collect();
    s.sort_by(|a, b| b.total_cmp(a));
    s
}

/// The observability of the joints from the data alone (priors left out) at `x`:
/// marginal information `S = A_tt - A_tn A_nn^-1 A_nt` (balls and registration free)
/// against `A_tt` (known), both in units of `scale_mm`; `n_report` weakest and most
/// hidden directions.
pub fn observability(
    data: &BundleData,
    x: &[f64],
    scale_mm: f64,
    n_report: usize,
) -> Result<Observability, BundleError> {
    let bundle = Bundle::new(data, Priors::NONE)?;
    let j = bundle.jacobian(x);
    let a = j.transpose() * &j;
    let nt = N_PARAMS;
    let nn = bundle.layout().n_nuisance();
    let att = a.view((0, 0), (nt, nt)).into_owned() * (scale_mm * scale_mm);
    let atn = a.view((0, nt), (nt, nn)).into_owned() * scale_mm;
    let ann = a.view((nt, nt), (nn, nn)).into_owned();
    let ann_inv = ann
        .cholesky()
        .ok_or_else(|| {
            BundleError::Data("balls and registration not determined by the data".into())
        })?
        .inverse();
    let s = &att - &atn * ann_inv * atn.transpose();
    let nominal = to_vec(&data.nominal);
    let rayleigh =
        |m: &DMatrix<f64>, v: &DVector<f64>| (v.transpose() * m * v)[(0, 0)].max(0.0).sqrt();
    // Direction `v` (unit, scale units) with its singular value with the nuisance free.
    let direction = |v: &DVector<f64>, singular_free: f64| Direction {
        singular_free,
        singular_known: rayleigh(&att, v),
        description: describe_direction(v.as_slice(), &nominal),
        vector: v.as_slice().to_vec(),
    };
    // The eigenvector indices of `e`, smallest eigenvalue first.
    let ascending = |e: &DVector<f64>| {
        let mut order: Vec<usize> = (0..nt).collect();
        order.sort_by(|p, q| e[*p].total_cmp(&e[*q]));
        order
    };
    let eig = s.clone().symmetric_eigen();
    let weakest = ascending(&eig.eigenvalues)
        .iter()
        .take(n_report)
        .map(|k| {
            let v = eig.eigenvectors.column(*k).into_owned();
            direction(&v, eig.eigenvalues[*k].max(0.0).sqrt())
        })
        .collect();
    // Generalised problem S v = mu A_tt v via A_tt^-1/2 S A_tt^-1/2.
    let ke = att.clone().symmetric_eigen();
    let k_inv_sqrt = &ke.eigenvectors
        * DMatrix::from_diagonal(
            &ke.eigenvalues
                .map(|v| 1.0 / v.max(f64::MIN_POSITIVE).sqrt()),
        )
        * ke.eigenvectors.transpose();
    let g = (&k_inv_sqrt * &s * &k_inv_sqrt).symmetric_eigen();
    let hidden = ascending(&g.eigenvalues)
        .iter()
        .take(n_report)
        .map(|k| {
            let w = g.eigenvectors.column(*k).into_owned();
            let v = &k_inv_sqrt * w;
            let v = &v / v.norm();
            (g.eigenvalues[*k].max(0.0), direction(&v, rayleigh(&s, &v)))
        })
        .collect();
    Ok(Observability {
        scale_mm,
        singular_free: sqrt_spectrum(&s),
        singular_known: sqrt_spectrum(&att),
        weakest,
        hidden,
    })
}
