//! The evaluation engine: the layout of the unknown vector and [`Bundle`], which holds the
//! prepared data (start registration, nominal FK, local observations) and evaluates the
//! whitened residuals and their analytic Jacobian.

use nalgebra::{DMatrix, Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};

use super::jacobians::{kinematic_jacobians, point_pose_jacobian, rotation_columns};
use super::observations::{BundleData, LocalObs, PointObs, N_COMPONENTS};
use super::settings::{BundleError, Priors};
use super::{BUNDLE_FK_ITERATIONS, FAILED_POSE_RESIDUAL, REGISTRATION_PARAMS};
use crate::calib::registration::kabsch;
use crate::calib::{from_vec, to_vec, ParamVec, N_PARAMS};
use m2ctl::kinematics::{fk, FkConfig, Geometry, GeometryParams, Pose};
use m2ctl::sim::tracker::rotation_matrix;

/// Index layout of the unknown vector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Number of balls.
    pub n_balls: usize,
}

impl Layout {
    /// First index of ball `k`'s centre.
    pub const fn ball(&self, k: usize) -> usize {
        N_PARAMS + 3 * k
    }
    /// First index of the registration correction.
    pub const fn registration(&self) -> usize {
        N_PARAMS + 3 * self.n_balls
    }
    /// Number of unknowns.
    pub const fn n(&self) -> usize {
        self.registration() + REGISTRATION_PARAMS
    }
    /// Number of nuisance unknowns (balls and registration).
    pub const fn n_nuisance(&self) -> usize {
        self.n() - N_PARAMS
    }
}

/// The evaluation engine of a bundle fit.
#[derive(Clone, Debug)]
pub struct Bundle<'a> {
    data: &'a BundleData,
    layout: Layout,
    /// Nominal geometry without limits (trial joints replace its legs).
    base: GeometryParams,
    /// Registration rotation from the fiducials' Kabsch fit.
    q0: Matrix3<f64>,
    /// Registration translation from the fiducials' Kabsch fit (mm).
    tau0: Vector3<f64>,
    /// FK start of each pose (FK with the nominal joints).
    starts: Vec<Pose<f64>>,
    priors: Priors,
    /// Data rows (3 per point).
    n_data_rows: usize,
    /// Nominal joints (mm).
    theta0: ParamVec,
    /// Fiducial observations, local coordinates.
    fid_local: Vec<LocalObs>,
    /// Ball observations pose by pose, local coordinates.
    ball_local: Vec<Vec<LocalObs>>,
    /// Scale of each data row (variance factors, [`Bundle::set_variance_factors`]).
    row_scale: Vec<f64>,
}

impl<'a> Bundle<'a> {
    /// Prepares the fit: registration from the fiducials (weighted Kabsch), FK of every
    /// pose with the nominal joints.
    pub fn new(data: &'a BundleData, priors: Priors) -> Result<Self, BundleError> {
        let layout = Layout {
            n_balls: data.ball_names.len(),
        };
        if data.balls_nominal_m.len() != layout.n_balls {
            return Err(BundleError::Data(
                "ball list and nominal centres differ".into(),
            ));
        }
        let from: Vec<[f64; 3]> = data.fiducials.iter().map(|f| f.drawing_b_mm).collect();
        let to: Vec<[f64; 3]> = data.fiducials.iter().map(|f| f.obs.y_mm).collect();
        let w: Vec<f64> = data
            .fiducials
            .iter()
            .map(|f| 3.0 / f.obs.cov_mm2.trace())
            .collect();
        let reg = kabsch(&from, &to, Some(&w))
            .map_err(|e| BundleError::Data(format!("fiducial registration: {e}")))?;
        let base = GeometryParams::new(data.nominal.legs, data.nominal.p0_mm);
        let nom = Geometry::<f64>::new(&base)
            .map_err(|e| BundleError::Data(crate::files::describe_geometry_error(&e)))?;
        let cfg = FkConfig {
            max_iterations: BUNDLE_FK_ITERATIONS,
            ..FkConfig::default()
        };
        let starts = data
            .poses
            .iter()
            .map(|p| {
                fk(&nom, &p.strokes_mm, &Pose::home(), &cfg)
                    .map(|s| s.pose)
                    .map_err(|e| {
                        BundleError::Data(format!(
                            "line {}: pose {}: nominal forward kinematics: {}",
                            p.stroke_line,
                            p.pose,
                            crate::ikfk::describe_fk_error(&e)
                        ))
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let n_points =
            data.fiducials.len() + data.poses.iter().map(|p| p.balls.len()).sum::<usize>();
        let q0 = *reg.rotation.to_rotation_matrix().matrix();
        let tau0 = reg.translation.vector;
        let local = |o: &PointObs| LocalObs {
            z_mm: q0.transpose() * (Vector3::from(o.y_mm) - tau0),
            whiten: o.whiten * q0,
        };
        Ok(Self {
            data,
            layout,
            base,
            q0,
            tau0,
            starts,
            priors,
            n_data_rows: 3 * n_points,
            theta0: to_vec(&data.nominal),
            fid_local: data.fiducials.iter().map(|f| local(&f.obs)).collect(),
            ball_local: data
                .poses
                .iter()
                .map(|p| p.balls.iter().map(|b| local(&b.obs)).collect())
                .collect(),
            row_scale: vec![1.0; 3 * n_points],
        })
    }

    /// The observations in row order (fiducials, then the balls pose by pose).
    pub fn observations(&self) -> impl Iterator<Item = &PointObs> {
        self.data.fiducials.iter().map(|f| &f.obs).chain(
            self.data
                .poses
                .iter()
                .flat_map(|p| p.balls.iter().map(|b| &b.obs)),
        )
    }

    /// Scales every point's tracker variance by its component's factor `k` (1: the
    /// noise model as given).
    pub fn set_variance_factors(&mut self, k: &[f64; N_COMPONENTS]) {
        let scales: Vec<f64> = self.observations().flat_map(|o| o.row_scales(k)).collect();
        self.row_scale = scales;
    }

    /// Replaces the priors (the number of prior rows must not change: `Some` stays
    /// `Some`).
    pub fn set_priors(&mut self, priors: Priors) {
        debug_assert_eq!(
            priors.joint_sigma_mm.is_some(),
            self.priors.joint_sigma_mm.is_some()
        );
        debug_assert_eq!(
            priors.ball_sigma_mm.is_some(),
            self.priors.ball_sigma_mm.is_some()
        );
        self.priors = priors;
    }

    /// The scale of each data row set by [`Bundle::set_variance_factors`].
    pub fn row_scales(&self) -> &[f64] {
        &self.row_scale
    }

    /// The priors in force.
    pub fn priors(&self) -> Priors {
        self.priors
    }

    /// The data the bundle fits.
    pub fn data(&self) -> &BundleData {
        self.data
    }

    /// Index layout of the unknowns.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// Number of unknowns.
    pub fn n_params(&self) -> usize {
        self.layout.n()
    }

    /// Number of data rows (3 per measured point).
    pub fn n_data_rows(&self) -> usize {
        self.n_data_rows
    }

    /// Number of residual rows (data and priors).
    pub fn n_rows(&self) -> usize {
        self.n_data_rows
            + if self.priors.joint_sigma_mm.is_some() {
                N_PARAMS
            } else {
                0
            }
            + if self.priors.ball_sigma_mm.is_some() {
                3 * self.layout.n_balls
            } else {
                0
            }
    }

    /// The start: nominal joints, nominal balls, the fiducial registration (all zero).
    pub fn start(&self) -> Vec<f64> {
        vec![0.0; self.n_params()]
    }

    /// The registration (base -> tracker) of an unknown vector:
    /// `y = Q0 Rd x + Q0 d + tau0`.
    pub fn registration(&self, x: &[f64]) -> Isometry3<f64> {
        let (rd, d) = self.reg_parts(x);
        let rot = nalgebra::Rotation3::from_matrix_unchecked(self.q0 * rd);
        Isometry3::from_parts(
            Translation3::from(self.q0 * d + self.tau0),
            UnitQuaternion::from_rotation_matrix(&rot),
        )
    }

    /// `Rd` and `d` of the registration correction.
    fn reg_parts(&self, x: &[f64]) -> (Matrix3<f64>, Vector3<f64>) {
        let r = self.layout.registration();
        let rd = rotation_matrix(&[x[r], x[r + 1], x[r + 2]]);
        (rd, Vector3::new(x[r + 3], x[r + 4], x[r + 5]))
    }

    /// Joint coordinates of an unknown vector (mm).
    pub fn joints(&self, x: &[f64]) -> ParamVec {
        let mut v = self.theta0;
        for (vk, dk) in v.iter_mut().zip(x.iter()) {
            *vk += dk;
        }
        v
    }

    /// Ball centres (frame M, mm) of an unknown vector.
    pub fn balls(&self, x: &[f64]) -> Vec<[f64; 3]> {
        self.data
            .balls_nominal_m
            .iter()
            .enumerate()
            .map(|(k, c)| {
                let i = self.layout.ball(k);
                [c[0] + x[i], c[1] + x[i + 1], c[2] + x[i + 2]]
            })
            .collect()
    }

    /// The poses `FK(s_j, theta)` (None where FK fails).
    pub fn poses(&self, x: &[f64]) -> Vec<Option<Pose<f64>>> {
        let Ok(geom) = Geometry::<f64>::new(&from_vec(&self.joints(x), &self.base)) else {
            return vec![None; self.data.poses.len()];
        };
        let cfg = FkConfig {
            max_iterations: BUNDLE_FK_ITERATIONS,
            ..FkConfig::default()
        };
        self.data
            .poses
            .iter()
            .zip(self.starts.iter())
            .map(|(p, s)| fk(&geom, &p.strokes_mm, s, &cfg).ok().map(|s| s.pose))
            .collect()
    }

    /// Residuals (whitened, dimensionless): fiducials, then the balls pose by pose, then
    /// the priors. With `jac` (row-major, [`Bundle::n_rows`] x [`Bundle::n_params`]), also
    /// the analytic Jacobian `d r / d x`.
    pub fn evaluate(&self, x: &[f64], mut jac: Option<&mut [f64]>) -> Vec<f64> {
        let n = self.n_params();
        let mut res = vec![0.0; self.n_rows()];
        if let Some(j) = jac.as_deref_mut() {
            j.iter_mut().for_each(|v| *v = 0.0);
        }
        let (rd, dreg) = self.reg_parts(x);
        let rr = self.layout.registration();
        let gamma_d = x[rr + 2];
        let balls = self.balls(x);
        let mut row = 0;
        // Writes one point's whitened residual and its registration columns.
        let point = |row: usize,
                     obs: &LocalObs,
                     x_b: &Vector3<f64>,
                     res: &mut [f64],
                     jac: &mut Option<&mut [f64]>| {
            let z = rd * x_b + dreg;
            let r = obs.whiten * (obs.z_mm - z);
            res[row..row + 3].copy_from_slice(r.as_slice());
            if let Some(j) = jac.as_deref_mut() {
                let cols = rotation_columns(&rd, gamma_d, x_b);
                for (k, c) in cols.iter().enumerate() {
                    let d = -(obs.whiten * c);
                    for a in 0..3 {
                        j[(row + a) * n + rr + k] = d[a];
                    }
                }
                for a in 0..3 {
                    for k in 0..3 {
                        j[(row + a) * n + rr + 3 + k] = -obs.whiten[(a, k)];
                    }
                }
            }
        };
        for (f, obs) in self.data.fiducials.iter().zip(self.fid_local.iter()) {
            point(row, obs, &Vector3::from(f.drawing_b_mm), &mut res, &mut jac);
            row += 3;
        }
        let geom = Geometry::<f64>::new(&from_vec(&self.joints(x), &self.base)).ok();
        let cfg = FkConfig {
            max_iterations: BUNDLE_FK_ITERATIONS,
            ..FkConfig::default()
        };
        let p0 = Vector3::from(self.data.nominal.p0_mm);
        for ((pose, start), local) in self
            .data
            .poses
            .iter()
            .zip(self.starts.iter())
            .zip(self.ball_local.iter())
        {
            let solved = geom.as_ref().and_then(|g| {
                let p = fk(g, &pose.strokes_mm, start, &cfg).ok()?.pose;
                if jac.is_some() {
                    let (d, jp) = kinematic_jacobians(g, &p)?;
                    let inv = jp.try_inverse()?;
                    let inv_d = DMatrix::from_fn(6, 6, |r, c| inv[(r, c)]);
                    Some((p, Some(-(inv_d * d))))
                } else {
                    Some((p, None))
                }
            });
            let Some((p, dp_dtheta)) = solved else {
                for _ in &pose.balls {
                    res[row..row + 3]
                        .iter_mut()
                        .for_each(|v| *v = FAILED_POSE_RESIDUAL);
                    row += 3;
                }
                continue;
            };
            let r = rotation_matrix(&p.rotation_rad);
            let t = Vector3::from(p.translation_mm);
            for (b, obs) in pose.balls.iter().zip(local.iter()) {
                let c = Vector3::from(balls[b.ball]);
                let x_b = p0 + t + r * c;
                point(row, obs, &x_b, &mut res, &mut jac);
                if let (Some(j), Some(m)) = (jac.as_deref_mut(), dp_dtheta.as_ref()) {
                    let h = point_pose_jacobian(&r, p.rotation_rad[2], &c);
                    let wq = obs.whiten * rd;
                    // d r / d theta = -W Q0 Rd H dP/dtheta
                    let wqh = -(wq * h);
                    let wqh_d = DMatrix::from_fn(3, 6, |a, k| wqh[(a, k)]);
                    let dth = wqh_d * m;
                    for a in 0..3 {
                        for k in 0..N_PARAMS {
                            j[(row + a) * n + k] = dth[(a, k)];
                        }
                    }
                    // d r / d c = -W Q0 Rd R
                    let dc = -(wq * r);
                    let cb = self.layout.ball(b.ball);
                    for a in 0..3 {
                        for k in 0..3 {
                            j[(row + a) * n + cb + k] = dc[(a, k)];
                        }
                    }
                }
                row += 3;
            }
        }
        if let Some(s) = self.priors.joint_sigma_mm {
            for k in 0..N_PARAMS {
                res[row] = x[k] / s;
                if let Some(j) = jac.as_deref_mut() {
                    j[row * n + k] = 1.0 / s;
                }
                row += 1;
            }
        }
        if let Some(s) = self.priors.ball_sigma_mm {
            for k in 0..self.layout.n_balls {
                for a in 0..3 {
                    let i = self.layout.ball(k) + a;
                    res[row] = x[i] / s;
                    if let Some(j) = jac.as_deref_mut() {
                        j[row * n + i] = 1.0 / s;
                    }
                    row += 1;
                }
            }
        }
        for (i, c) in self.row_scale.iter().enumerate() {
            if *c != 1.0 {
                res[i] *= c;
                if let Some(j) = jac.as_deref_mut() {
                    j[i * n..(i + 1) * n].iter_mut().for_each(|v| *v *= c);
                }
            }
        }
        res
    }

    /// The Jacobian at `x` as a matrix (rows as [`Bundle::evaluate`]).
    pub fn jacobian(&self, x: &[f64]) -> DMatrix<f64> {
        let mut j = vec![0.0; self.n_rows() * self.n_params()];
        self.evaluate(x, Some(&mut j));
        DMatrix::from_row_slice(self.n_rows(), self.n_params(), &j)
    }

    /// Line and description of every data row block (3 rows per point), in row order.
    pub fn point_labels(&self) -> Vec<(usize, String)> {
        let mut out: Vec<(usize, String)> = self
            .data
            .fiducials
            .iter()
            .map(|f| (f.obs.line, format!("fiducial {}", f.name)))
            .collect();
        for p in &self.data.poses {
            for b in &p.balls {
                out.push((
                    b.obs.line,
                    format!("ball {} of pose {}", self.data.ball_names[b.ball], p.pose),
                ));
            }
        }
        out
    }
}
