//! Ground calibration of the 36 joint-centre parameters (host only, f64).
//!
//! Model (seed notes, "The calibration model"): the parameter vector holds, leg by leg,
//! the lower joint centre at zero stroke `a_i` (frame B, mm) and the upper joint centre
//! `b_i` (frame M, mm): `[a1x, a1y, a1z, b1x, b1y, b1z, a2x, ...]`, 36 values. The rod
//! lengths are derived (`|b_i + p0 - a_i|`) and the home position p0 is fixed.
//!
//! For measured pose `P*_j` (tracker) and measured strokes `s*_ij` (encoders) the residual
//! is `e_ij = s*_ij - IK_i(P*_j, params)` (mm); the objective is `E = sum e_ij^2` (mm^2),
//! minimised over a box Omega around the nominal parameters.
//!
//! Solvers: [`lm`] (Levenberg-Marquardt, analytic Jacobian, regularised toward nominal and
//! kept inside Omega) and [`cuckoo`] (the paper's SMCS and its improved variant).

pub mod adjust;
pub mod bundle;
pub mod cuckoo;
pub mod design;
pub mod lm;
pub mod registration;
pub mod stats;

use std::fmt;
use std::time::Duration;

use crate::files::{parse_csv, FileError, CSV_COLUMNS};
use m2ctl::kinematics::geometry::Leg;
use m2ctl::kinematics::ik::leg_state;
use m2ctl::kinematics::pose::RotationDelta;
use m2ctl::kinematics::{Geometry, GeometryParams, LegParams, Pose, LEGS};
use m2ctl::units::{ARCSEC_PER_RAD, UM_PER_MM};

/// Parameters per leg: `a` (3) then `b` (3).
pub const PARAMS_PER_LEG: usize = 6;
/// Number of calibrated parameters (12 joint centres, x/y/z each).
pub const N_PARAMS: usize = LEGS * PARAMS_PER_LEG;
/// Default half-width of the feasible box Omega around nominal, per parameter (mm).
/// The paper's digit is unreadable; the seed notes read it as 0.5 mm.
pub const DEFAULT_OMEGA_HALF_WIDTH_MM: f64 = 0.5;
/// Largest plausible |measured stroke - IK(measured pose, nominal)| (mm). Joint
/// coordinates within the flight validation's 1 mm of nominal change a stroke by at most
/// ~0.07 mm per coordinate anywhere in the +-2 mm, +-600" workspace (the stroke gradients
/// of [`Problem::jacobian_into`] are bounded by `|u| / q` <= 4.4 mm / 70 mm), ~0.4 mm for
/// all six of a leg together; a larger mismatch is a wrong column, unit or reading.
pub const MAX_NOMINAL_STROKE_MISMATCH_MM: f64 = 0.5;
/// Residual (mm) given to a leg that cannot reach a measured pose with the trial
/// parameters: large against any real residual (um), finite so every solver can compare.
pub const UNREACHABLE_RESIDUAL_MM: f64 = 1.0e3;

/// The 36 calibrated parameters (mm), leg-major `[a_x, a_y, a_z, b_x, b_y, b_z] x 6`.
pub type ParamVec = [f64; N_PARAMS];

/// Name of parameter `k` for reports, e.g. `a3y` or `b6z`.
pub fn param_name(k: usize) -> String {
    let leg = k / PARAMS_PER_LEG + 1;
    let r = k % PARAMS_PER_LEG;
    let joint = if r < 3 { 'a' } else { 'b' };
    let axis = ['x', 'y', 'z'][r % 3];
    format!("{joint}{leg}{axis}")
}

/// Parameter vector of a geometry (mm).
pub fn to_vec(params: &GeometryParams) -> ParamVec {
    let mut v = [0.0; N_PARAMS];
    for (chunk, leg) in v.chunks_exact_mut(PARAMS_PER_LEG).zip(params.legs.iter()) {
        chunk[..3].copy_from_slice(&leg.a_mm);
        chunk[3..].copy_from_slice(&leg.b_mm);
    }
    v
}

/// A geometry with the joint centres of `v` and everything else (p0, limits) of `base`.
pub fn from_vec(v: &ParamVec, base: &GeometryParams) -> GeometryParams {
    let mut out = *base;
    for (leg, chunk) in out.legs.iter_mut().zip(v.chunks_exact(PARAMS_PER_LEG)) {
        *leg = LegParams {
            a_mm: [chunk[0], chunk[1], chunk[2]],
            b_mm: [chunk[3], chunk[4], chunk[5]],
        };
    }
    out
}

/// The feasible box Omega: per-parameter lower and upper bounds (mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamBox {
    /// Lower bounds (mm).
    pub lower_mm: ParamVec,
    /// Upper bounds (mm).
    pub upper_mm: ParamVec,
}

impl ParamBox {
    /// `nominal +- half_width_mm` on every parameter.
    pub fn around(nominal: &ParamVec, half_width_mm: f64) -> Self {
        Self {
            lower_mm: nominal.map(|v| v - half_width_mm),
            upper_mm: nominal.map(|v| v + half_width_mm),
        }
    }

    /// Centre of the box (mm).
    pub fn centre(&self) -> ParamVec {
        let mut c = [0.0; N_PARAMS];
        for (k, ck) in c.iter_mut().enumerate() {
            *ck = 0.5 * (self.lower_mm[k] + self.upper_mm[k]);
        }
        c
    }

    /// Component-wise clamp into the box (the paper's improvement 2: `x = Omega_L` if
    /// below, `Omega_U` if above). NaN components are put at the box centre.
    pub fn clamp(&self, v: &mut ParamVec) {
        for (k, x) in v.iter_mut().enumerate() {
            let (lo, hi) = (self.lower_mm[k], self.upper_mm[k]);
            *x = if x.is_nan() {
                0.5 * (lo + hi)
            } else {
                x.clamp(lo, hi)
            };
        }
    }

    /// Whether every component is inside the box (bounds included).
    pub fn contains(&self, v: &ParamVec) -> bool {
        v.iter()
            .enumerate()
            .all(|(k, x)| *x >= self.lower_mm[k] && *x <= self.upper_mm[k])
    }

    /// Number of components on or outside a bound.
    pub fn active_bounds(&self, v: &ParamVec) -> usize {
        v.iter()
            .enumerate()
            .filter(|(k, x)| **x <= self.lower_mm[*k] || **x >= self.upper_mm[*k])
            .count()
    }
}

/// One measured pose with the strokes read at the same time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement {
    /// 1-based line in the measurement file (0 for generated data).
    pub line: usize,
    /// Pose measured by the tracker (mm, rad).
    pub pose: Pose<f64>,
    /// Slider strokes read from the encoders (mm).
    pub strokes_mm: [f64; LEGS],
}

/// Parses a calibration measurement file (12-column CSV: pose mm/arcsec, strokes mm).
///
/// Beyond the CSV checks of [`parse_csv`] (header, duplicated columns, field count,
/// numbers, NaN), it needs at least [`N_PARAMS`] rows (one stroke per leg per row gives
/// 6 residuals, but every row must add an independent pose) and refuses two identical
/// rows (a duplicated measurement weighs twice without adding information).
pub fn parse_measurements(text: &str) -> Result<Vec<Measurement>, FileError> {
    let rows = parse_csv(text, 0..CSV_COLUMNS.len())?;
    if rows.len() < N_PARAMS {
        return Err(FileError {
            line: 0,
            message: format!(
                "{} measurement rows, calibration of {N_PARAMS} parameters needs at least {N_PARAMS}",
                rows.len()
            ),
        });
    }
    let mut out: Vec<Measurement> = Vec::with_capacity(rows.len());
    for r in &rows {
        let v = &r.values;
        let m = Measurement {
            line: r.line,
            pose: Pose::from_mm_arcsec([v[0], v[1], v[2]], [v[3], v[4], v[5]]),
            strokes_mm: [v[6], v[7], v[8], v[9], v[10], v[11]],
        };
        if let Some(prev) = out
            .iter()
            .find(|p| p.pose == m.pose && p.strokes_mm == m.strokes_mm)
        {
            return Err(FileError {
                line: r.line,
                message: format!("row repeats the measurement of line {}", prev.line),
            });
        }
        out.push(m);
    }
    Ok(out)
}

/// Refuses implausible measurements, naming the file line: a pose outside the workspace,
/// a stroke outside the slider range (both from `nominal`'s `[limits]`, else the
/// compiled-in flight limits: the controller never goes beyond them), a stroke that the
/// measured pose cannot explain under the nominal geometry by more than
/// [`MAX_NOMINAL_STROKE_MISMATCH_MM`], or a non-finite value.
pub fn check_measurements(meas: &[Measurement], nominal: &GeometryParams) -> Result<(), FileError> {
    let flight = m2ctl::nominal::prototype_with_flight_limits();
    let stroke = nominal
        .stroke_limits
        .or(flight.stroke_limits)
        .ok_or_else(|| FileError {
            line: 0,
            message: "no stroke limits".into(),
        })?;
    let ws = nominal
        .workspace
        .or(flight.workspace)
        .ok_or_else(|| FileError {
            line: 0,
            message: "no workspace limits".into(),
        })?;
    let geom =
        Geometry::<f64>::new(&GeometryParams::new(nominal.legs, nominal.p0_mm)).map_err(|e| {
            FileError {
                line: 0,
                message: format!(
                    "nominal geometry: {}",
                    crate::files::describe_geometry_error(&e)
                ),
            }
        })?;
    let bad = |m: &Measurement, message: String| FileError {
        line: m.line,
        message,
    };
    for m in meas {
        let v = pose_mm_arcsec(&m.pose);
        let half = [
            ws.translation_mm[0],
            ws.translation_mm[1],
            ws.translation_mm[2],
            ws.rotation_rad[0] * ARCSEC_PER_RAD,
            ws.rotation_rad[1] * ARCSEC_PER_RAD,
            ws.rotation_rad[2] * ARCSEC_PER_RAD,
        ];
        for (k, (x, h)) in v.iter().zip(half.iter()).enumerate() {
            let col = crate::files::CSV_COLUMNS[k];
            if !x.is_finite() || x.abs() > *h {
                return Err(bad(
                    m,
                    format!("pose {col} = {x} is outside the workspace (+-{h})"),
                ));
            }
        }
        for (i, s) in m.strokes_mm.iter().enumerate() {
            let (lo, hi) = (stroke.min_mm[i], stroke.max_mm[i]);
            if !s.is_finite() || *s < lo || *s > hi {
                return Err(bad(
                    m,
                    format!(
                        "stroke s{}_mm = {s} mm is outside the slider range [{lo}, {hi}] mm",
                        i + 1
                    ),
                ));
            }
        }
        let expected = m2ctl::kinematics::ik(&geom, &m.pose).map_err(|e| {
            bad(
                m,
                format!(
                    "pose not reachable with the nominal geometry: {}",
                    crate::ikfk::describe_ik_error(&e)
                ),
            )
        })?;
        for (i, (s, e)) in m.strokes_mm.iter().zip(expected.iter()).enumerate() {
            if (s - e).abs() > MAX_NOMINAL_STROKE_MISMATCH_MM {
                return Err(bad(
                    m,
                    format!(
                        "stroke s{}_mm = {s} mm is inconsistent with the measured pose: the nominal geometry needs {e:.4} mm there (more than {MAX_NOMINAL_STROKE_MISMATCH_MM} mm apart)",
                        i + 1
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Formats measurements as the 12-column CSV (with header).
pub fn format_measurements(meas: &[Measurement], header_comment: &str) -> String {
    let mut s = String::new();
    for l in header_comment.lines() {
        s.push_str(&format!("# {l}\n"));
    }
    s.push_str(&crate::files::csv_header());
    s.push('\n');
    for m in meas {
        let r = m.pose.rotation_arcsec();
        let t = m.pose.translation_mm;
        s.push_str(&crate::files::csv_line(
            &[t[0], t[1], t[2], r[0], r[1], r[2]],
            &m.strokes_mm,
        ));
        s.push('\n');
    }
    s
}

/// The least-squares problem: measurements with precomputed rotations, and p0.
#[derive(Clone, Debug)]
pub struct Problem {
    /// The measurements.
    pub meas: Vec<Measurement>,
    rots: Vec<RotationDelta<f64>>,
    /// Home position (mm, frame B), fixed.
    pub p0_mm: [f64; 3],
    /// Geometry with p0 and without limits, whose joints are replaced by each trial.
    base: GeometryParams,
}

impl Problem {
    /// A problem for the given measurements and home position.
    pub fn new(meas: Vec<Measurement>, p0_mm: [f64; 3]) -> Self {
        let rots = meas
            .iter()
            .map(|m| RotationDelta::new(&m.pose.rotation_rad))
            .collect();
        let base = GeometryParams::new(m2ctl::nominal::PROTOTYPE.legs, p0_mm);
        Self {
            meas,
            rots,
            p0_mm,
            base,
        }
    }

    /// Number of residuals (6 per measurement).
    pub fn n_residuals(&self) -> usize {
        self.meas.len() * LEGS
    }

    /// The working legs for `v` (derived quantities as the kinematics derive them);
    /// `None` if `v` is not a valid geometry.
    fn legs(&self, v: &ParamVec) -> Option<[Leg<f64>; LEGS]> {
        Geometry::<f64>::new(&from_vec(v, &self.base))
            .ok()
            .map(|g| g.legs)
    }

    /// Residuals `e_ij = s*_ij - IK_i(P*_j, v)` (mm), measurement-major, into `out`
    /// (length [`Problem::n_residuals`]).
    pub fn residuals_into(&self, v: &ParamVec, out: &mut [f64]) {
        let Some(legs) = self.legs(v) else {
            out.iter_mut().for_each(|e| *e = UNREACHABLE_RESIDUAL_MM);
            return;
        };
        for ((m, rot), e) in self
            .meas
            .iter()
            .zip(self.rots.iter())
            .zip(out.chunks_exact_mut(LEGS))
        {
            for ((ei, leg), s) in e.iter_mut().zip(legs.iter()).zip(m.strokes_mm.iter()) {
                *ei = match leg_state(leg, rot, &m.pose.translation_mm) {
                    Some(st) => s - st.stroke_mm,
                    None => UNREACHABLE_RESIDUAL_MM,
                };
            }
        }
    }

    /// Residual vector (mm).
    pub fn residuals(&self, v: &ParamVec) -> Vec<f64> {
        let mut out = vec![0.0; self.n_residuals()];
        self.residuals_into(v, &mut out);
        out
    }

    /// Objective `E = sum e_ij^2` (mm^2).
    pub fn objective(&self, v: &ParamVec) -> f64 {
        let Some(legs) = self.legs(v) else {
            return self.n_residuals() as f64 * UNREACHABLE_RESIDUAL_MM * UNREACHABLE_RESIDUAL_MM;
        };
        let mut sum = 0.0;
        for (m, rot) in self.meas.iter().zip(self.rots.iter()) {
            for (leg, s) in legs.iter().zip(m.strokes_mm.iter()) {
                let e = match leg_state(leg, rot, &m.pose.translation_mm) {
                    Some(st) => s - st.stroke_mm,
                    None => UNREACHABLE_RESIDUAL_MM,
                };
                sum += e * e;
            }
        }
        sum
    }

    /// RMS residual (mm).
    pub fn rms_mm(&self, v: &ParamVec) -> f64 {
        (self.objective(v) / self.n_residuals() as f64).sqrt()
    }

    /// Analytic Jacobian `d e_ij / d v_k` (dimensionless), row-major, rows
    /// measurement-major like the residuals, 36 columns: residual `e = s* - dl`, so the
    /// entries are minus [`stroke_gradient`]. Every column of leg i is zero in the rows of
    /// the other legs. Unreachable legs get zero rows.
    pub fn jacobian_into(&self, v: &ParamVec, out: &mut [f64]) {
        out.iter_mut().for_each(|x| *x = 0.0);
        let Some(legs) = self.legs(v) else {
            return;
        };
        for (j, (m, rot)) in self.meas.iter().zip(self.rots.iter()).enumerate() {
            for (i, leg) in legs.iter().enumerate() {
                let Some(st) = leg_state(leg, rot, &m.pose.translation_mm) else {
                    continue;
                };
                let row = &mut out[(j * LEGS + i) * N_PARAMS..(j * LEGS + i + 1) * N_PARAMS];
                let c = &mut row[i * PARAMS_PER_LEG..(i + 1) * PARAMS_PER_LEG];
                for (ck, g) in c.iter_mut().zip(stroke_gradient(leg, rot, &st)) {
                    *ck = -g;
                }
            }
        }
    }

    /// Jacobian as a new row-major vector (`n_residuals x 36`).
    pub fn jacobian(&self, v: &ParamVec) -> Vec<f64> {
        let mut out = vec![0.0; self.n_residuals() * N_PARAMS];
        self.jacobian_into(v, &mut out);
        out
    }

    /// Singular values of the Jacobian at `v`, largest first (mm/mm).
    pub fn singular_values(&self, v: &ParamVec) -> Vec<f64> {
        let j = self.jacobian(v);
        let m = nalgebra::DMatrix::from_row_slice(self.n_residuals(), N_PARAMS, &j);
        let mut sv: Vec<f64> = m.singular_values().iter().copied().collect();
        sv.sort_by(|a, b| b.total_cmp(a));
        sv
    }
}

/// Gradient of leg `i`'s stroke `dl_i` at a pose (its [`leg_state`] `st` under rotation
/// `rot`) with respect to the leg's own parameters `[a_x, a_y, a_z, b_x, b_y, b_z]`
/// (dimensionless), p0 fixed and the rod length derived (`h` horizontal rod components and
/// `q` vertical one at the pose, `d0` home rod, `R = I + W`):
///
/// ```text
/// d dl / d a_x = -(h_x - d0_x) / q      d dl / d a_y = -(h_y - d0_y) / q
/// d dl / d a_z = d0_z / q - 1
/// d dl / d b_k = R_zk - (d0_k - h_x R_xk - h_y R_yk) / q
/// ```
pub(crate) fn stroke_gradient(
    leg: &Leg<f64>,
    rot: &RotationDelta<f64>,
    st: &m2ctl::kinematics::ik::LegState<f64>,
) -> [f64; PARAMS_PER_LEG] {
    let inv_q = 1.0 / st.q_mm;
    let d0 = &leg.d0_mm;
    let h = &st.h_mm;
    let w = &rot.w;
    let mut g = [0.0; PARAMS_PER_LEG];
    g[0] = -(h[0] - d0[0]) * inv_q;
    g[1] = -(h[1] - d0[1]) * inv_q;
    g[2] = d0[2] * inv_q - 1.0;
    for k in 0..3 {
        let r_xk = w[(0, k)] + if k == 0 { 1.0 } else { 0.0 };
        let r_yk = w[(1, k)] + if k == 1 { 1.0 } else { 0.0 };
        let r_zk = w[(2, k)] + if k == 2 { 1.0 } else { 0.0 };
        g[3 + k] = r_zk - (d0[k] - h[0] * r_xk - h[1] * r_yk) * inv_q;
    }
    g
}

/// Which solver to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverKind {
    /// Levenberg-Marquardt, regularised toward nominal, kept in Omega.
    Lm,
    /// Levenberg-Marquardt without regularisation or bounds (for comparison only).
    LmUnbounded,
    /// The paper's baseline: cuckoo search + Nelder-Mead.
    Smcs,
    /// The paper's improved algorithm (adaptive Levy step, NM clamped into Omega).
    Improved,
    /// The improved algorithm followed by LM polish.
    ImprovedLm,
}

impl SolverKind {
    /// Command-line name.
    pub fn name(&self) -> &'static str {
        match self {
            SolverKind::Lm => "lm",
            SolverKind::LmUnbounded => "lm-unbounded",
            SolverKind::Smcs => "smcs",
            SolverKind::Improved => "improved",
            SolverKind::ImprovedLm => "improved+lm",
        }
    }

    /// Parses a command-line name.
    pub fn parse(s: &str) -> Option<Self> {
        [
            SolverKind::Lm,
            SolverKind::LmUnbounded,
            SolverKind::Smcs,
            SolverKind::Improved,
            SolverKind::ImprovedLm,
        ]
        .into_iter()
        .find(|k| k.name() == s)
    }
}

impl fmt::Display for SolverKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Settings of a calibration run.
#[derive(Clone, Debug)]
pub struct CalibConfig {
    /// Solver.
    pub solver: SolverKind,
    /// Half-width of Omega around nominal (mm).
    pub omega_half_width_mm: f64,
    /// RNG seed of the stochastic solvers.
    pub seed: u64,
    /// Cuckoo-search settings (SMCS / improved).
    pub cuckoo: cuckoo::CuckooConfig,
    /// Levenberg-Marquardt settings.
    pub lm: lm::LmConfig,
    /// Show a progress bar on stderr (long cuckoo runs).
    pub progress: bool,
}

impl Default for CalibConfig {
    fn default() -> Self {
        Self {
            solver: SolverKind::Lm,
            omega_half_width_mm: DEFAULT_OMEGA_HALF_WIDTH_MM,
            seed: 1,
            cuckoo: cuckoo::CuckooConfig::default(),
            lm: lm::LmConfig::default(),
            progress: false,
        }
    }
}

/// Result of a calibration run.
#[derive(Clone, Debug)]
pub struct CalibResult {
    /// Calibrated geometry (nominal's p0 and limits, calibrated joints).
    pub params: GeometryParams,
    /// Calibrated parameter vector (mm).
    pub vec_mm: ParamVec,
    /// RMS stroke residual at the start (nominal) (mm).
    pub rms_before_mm: f64,
    /// RMS stroke residual at the solution (mm).
    pub rms_after_mm: f64,
    /// Largest |residual| at the solution (mm).
    pub max_residual_mm: f64,
    /// Singular values of the residual Jacobian at the solution, largest first.
    pub singular_values: Vec<f64>,
    /// Solver iterations (LM: residual evaluations; cuckoo: generations).
    pub iterations: usize,
    /// Objective evaluations.
    pub evaluations: usize,
    /// Number of parameters on or outside a bound of Omega.
    pub active_bounds: usize,
    /// Whether the solution is inside Omega.
    pub inside_omega: bool,
    /// Wall time of the solver.
    pub elapsed: Duration,
    /// Solver-specific note (termination reason).
    pub note: String,
}

impl CalibResult {
    /// Condition number of the Jacobian (largest / smallest singular value).
    pub fn condition(&self) -> f64 {
        match (self.singular_values.first(), self.singular_values.last()) {
            (Some(a), Some(b)) if *b > 0.0 => a / b,
            _ => f64::INFINITY,
        }
    }

    /// One-paragraph fit summary.
    pub fn summary(&self) -> String {
        let sv = &self.singular_values;
        format!(
            "residual RMS {:.4} um -> {:.4} um (max {:.4} um)\n\
             Jacobian singular values {:.3e} .. {:.3e}, condition {:.3e}\n\
             iterations {}, objective evaluations {}, time {:.1} ms\n\
             parameters on or outside a bound of Omega: {}, inside Omega: {}\n\
             solver: {}",
            self.rms_before_mm * UM_PER_MM,
            self.rms_after_mm * UM_PER_MM,
            self.max_residual_mm * UM_PER_MM,
            sv.first().copied().unwrap_or(0.0),
            sv.last().copied().unwrap_or(0.0),
            self.condition(),
            self.iterations,
            self.evaluations,
            self.elapsed.as_secs_f64() * 1e3,
            self.active_bounds,
            self.inside_omega,
            self.note
        )
    }
}

/// Why a calibration failed.
#[derive(Clone, Debug, PartialEq)]
pub enum CalibError {
    /// Fewer measurements than parameters.
    TooFewMeasurements(usize),
    /// A setting is out of range.
    BadConfig(String),
    /// The solver produced no usable result.
    Solver(String),
    /// The calibrated parameters are not a valid geometry.
    InvalidResult(String),
    /// A measurement is implausible (see [`check_measurements`]); names the file line.
    Implausible(FileError),
}

impl fmt::Display for CalibError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CalibError::TooFewMeasurements(n) => write!(
                f,
                "{n} measurements, calibration of {N_PARAMS} parameters needs at least {N_PARAMS}"
            ),
            CalibError::BadConfig(s) => write!(f, "bad setting: {s}"),
            CalibError::Solver(s) => write!(f, "solver failed: {s}"),
            CalibError::InvalidResult(s) => write!(f, "calibrated geometry invalid: {s}"),
            CalibError::Implausible(e) => write!(f, "implausible measurement: {e}"),
        }
    }
}

impl std::error::Error for CalibError {}

/// Runs a calibration of `nominal`'s joint centres on `meas`.
pub fn calibrate(
    nominal: &GeometryParams,
    meas: &[Measurement],
    cfg: &CalibConfig,
) -> Result<CalibResult, CalibError> {
    if meas.len() < N_PARAMS {
        return Err(CalibError::TooFewMeasurements(meas.len()));
    }
    if !(cfg.omega_half_width_mm > 0.0 && cfg.omega_half_width_mm.is_finite()) {
        return Err(CalibError::BadConfig(format!(
            "Omega half-width must be a positive number of mm, got {}",
            cfg.omega_half_width_mm
        )));
    }
    check_measurements(meas, nominal).map_err(CalibError::Implausible)?;
    let problem = Problem::new(meas.to_vec(), nominal.p0_mm);
    let nominal_v = to_vec(nominal);
    let omega = ParamBox::around(&nominal_v, cfg.omega_half_width_mm);
    let start = std::time::Instant::now();
    let (v, iterations, evaluations, note) = match cfg.solver {
        SolverKind::Lm | SolverKind::LmUnbounded => {
            let bounded = cfg.solver == SolverKind::Lm;
            let r = lm::solve(&problem, &nominal_v, &omega, &cfg.lm, bounded)?;
            (r.vec_mm, r.iterations, r.evaluations, r.note)
        }
        SolverKind::Smcs | SolverKind::Improved | SolverKind::ImprovedLm => {
            let variant = if cfg.solver == SolverKind::Smcs {
                cuckoo::Variant::Smcs
            } else {
                cuckoo::Variant::Improved
            };
            let r = cuckoo::solve(
                &problem,
                &omega,
                &cfg.cuckoo,
                variant,
                cfg.seed,
                cfg.progress,
            )?;
            if cfg.solver == SolverKind::ImprovedLm {
                let p = lm::solve(&problem, &r.best, &omega, &cfg.lm, true)?;
                (
                    p.vec_mm,
                    r.generations + p.iterations,
                    r.evaluations + p.evaluations,
                    format!("{}; then {}", r.note, p.note),
                )
            } else {
                (r.best, r.generations, r.evaluations, r.note)
            }
        }
    };
    let elapsed = start.elapsed();
    let params = from_vec(&v, nominal);
    params
        .validate()
        .map_err(|e| CalibError::InvalidResult(crate::files::describe_geometry_error(&e)))?;
    let res = problem.residuals(&v);
    let max_residual_mm = res.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    if !max_residual_mm.is_finite() {
        return Err(CalibError::InvalidResult(
            "the residual is not finite".into(),
        ));
    }
    Ok(CalibResult {
        params,
        vec_mm: v,
        rms_before_mm: problem.rms_mm(&nominal_v),
        rms_after_mm: problem.rms_mm(&v),
        max_residual_mm,
        singular_values: problem.singular_values(&v),
        iterations,
        evaluations,
        active_bounds: omega.active_bounds(&v),
        inside_omega: omega.contains(&v),
        elapsed,
        note,
    })
}

/// Pose as `[x, y, z]` mm and `[alpha, beta, gamma]` arcsec in one array.
pub fn pose_mm_arcsec(p: &Pose<f64>) -> [f64; 6] {
    let t = p.translation_mm;
    let r = p.rotation_rad.map(|a| a * ARCSEC_PER_RAD);
    [t[0], t[1], t[2], r[0], r[1], r[2]]
}
