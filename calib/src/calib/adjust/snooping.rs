//! Data snooping: the identity of every point in row order, each point's outlier test
//! with its minimal detectable bias, and the data without a rejected point.

use nalgebra::{Matrix3, Vector3};

use super::linear::Linear;
use super::results::{PointId, PointTest};
use super::{MIN_FIDUCIALS_LEFT, MIN_TESTABLE_REDUNDANCY};
use crate::calib::bundle::{Bundle, BundleData, BundleError, N_COMPONENTS};

/// The point identities in row order.
pub(super) fn point_ids(data: &BundleData) -> Vec<(PointId, usize, Option<u32>, String)> {
    let mut out: Vec<(PointId, usize, Option<u32>, String)> = data
        .fiducials
        .iter()
        .enumerate()
        .map(|(k, f)| {
            (
                PointId::Fiducial(k),
                f.obs.line,
                None,
                format!("fiducial {}", f.name),
            )
        })
        .collect();
    for (pi, p) in data.poses.iter().enumerate() {
        for b in &p.balls {
            out.push((
                PointId::Ball {
                    pose: pi,
                    ball: b.ball,
                },
                b.obs.line,
                Some(p.pose),
                format!("ball {} of pose {}", data.ball_names[b.ball], p.pose),
            ));
        }
    }
    out
}

/// The tests of every point at a linearisation.
pub(super) fn point_tests(
    bundle: &Bundle,
    lin: &Linear,
    k: &[f64; N_COMPONENTS],
    lambda0: f64,
) -> Vec<PointTest> {
    let ids = point_ids(bundle.data());
    ids.into_iter()
        .zip(bundle.observations())
        .enumerate()
        .map(|(p, ((id, line, pose, what), obs))| {
            let r0 = 3 * p;
            let jb = lin.j.rows(r0, 3).into_owned();
            let qvv = Matrix3::identity() - {
                let m = &jb * &lin.q * jb.transpose();
                Matrix3::from_fn(|a, b| m[(a, b)])
            };
            let v = Vector3::new(lin.res[r0], lin.res[r0 + 1], lin.res[r0 + 2]);
            let redundancy = (lin.red[r0] + lin.red[r0 + 1] + lin.red[r0 + 2]) / 3.0;
            let w_max = (0..3)
                .map(|a| v[a].abs() / qvv[(a, a)].max(1e-300).sqrt())
                .fold(0.0f64, f64::max);
            // The point's whitening with the variance factors in force (tracker frame).
            let s = obs.row_scales(k);
            let w_tr = Matrix3::from_diagonal(&Vector3::from(s)) * obs.whitening();
            let eig = qvv.symmetric_eigen();
            let min_eig = eig.eigenvalues.min();
            let (t, error_mm, mdb_mm) = match qvv.try_inverse() {
                Some(qi) if min_eig > MIN_TESTABLE_REDUNDANCY => {
                    let nabla = qi * v;
                    let t = v.dot(&nabla);
                    // Error in tracker coordinates: W^-1 nabla.
                    let e = w_tr.try_inverse().map(|wi| wi * nabla).unwrap_or_default();
                    let m = w_tr.transpose() * qvv * w_tr;
                    let mu = m.symmetric_eigen().eigenvalues.min().max(1e-300);
                    (t, [e.x, e.y, e.z], (lambda0 / mu).sqrt())
                }
                _ => (f64::NAN, [0.0; 3], f64::INFINITY),
            };
            PointTest {
                id,
                line,
                pose,
                what,
                t,
                w_max,
                redundancy,
                mdb_mm,
                error_mm,
            }
        })
        .collect()
}

/// The data without one point.
pub(super) fn without(data: &BundleData, id: PointId) -> Result<BundleData, BundleError> {
    let mut d = data.clone();
    match id {
        PointId::Fiducial(k) => {
            if d.fiducials.len() <= MIN_FIDUCIALS_LEFT {
                return Err(BundleError::Data(format!(
                    "removing fiducial {} would leave fewer than {MIN_FIDUCIALS_LEFT} fiducials",
                    d.fiducials[k].name
                )));
            }
            d.fiducials.remove(k);
        }
        PointId::Ball { pose, ball } => {
            d.poses[pose].balls.retain(|b| b.ball != ball);
            if d.poses[pose].balls.is_empty() {
                d.poses.remove(pose);
            }
        }
    }
    Ok(d)
}
