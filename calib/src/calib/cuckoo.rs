//! The paper's solvers: cuckoo search with a Nelder-Mead stage (SMCS), and the improved
//! algorithm (adaptive Levy step, Nelder-Mead results clamped into Omega), following the
//! seed notes step by step:
//!
//! 1. `nests` parameter vectors uniformly in Omega; evaluate; keep the best.
//! 2. Levy flight of every nest (Mantegna): `step = u / |v|^(1/beta)`,
//!    `u ~ N(0, sigma_u^2)`, `v ~ N(0, 1)`. SMCS: `s_t = step`. Improved (adaptive step):
//!    `s_t = lambda(t) step + s_min(t)` with `lambda(t) = exp(-rho (t/T_max)^k)` and
//!    `s_min(t) = s_1 (1 - t/T_max)`. New position `x + alpha s_t (x) (x - x_best)`,
//!    kept inside Omega (the standard cuckoo-search bound handling, both variants) and
//!    kept only if better (greedy).
//! 3. Each nest is abandoned with probability `p_a` and replaced by a uniform random
//!    vector in Omega; the better of the two is kept.
//! 4. Nelder-Mead on the worse part of the population (fraction `nm_fraction`): each of
//!    those nests starts a simplex of its own and runs `nm_iterations` iterations; the
//!    result replaces the nest if better. SMCS: NM points are not bounded. Improved:
//!    every NM point is clamped into Omega component-wise before it is evaluated.
//! 5. Stop when the best RMS residual is below the target, or after `T_max` generations.
//!
//! Our addition (not in the paper): by default both variants run in Jacobian-whitened
//! search coordinates ([`Coordinates`]), a fixed linear preconditioning computed once from
//! the residual Jacobian at nominal. The objective, the steps above and Omega (a box in
//! the joint coordinates, clamped there) are unchanged; [`Coordinates::Original`] is the
//! paper's setting.
//!
//! Constants the seed notes leave open (the paper's values are unreadable) are named
//! settings with the values used in the literature the paper builds on (Yang & Deb's
//! cuckoo search: `n = 25`, `p_a = 0.25`, `alpha = 0.01`, `beta = 1.5`; standard
//! Nelder-Mead coefficients 1, 2, 0.5, 0.5).

use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal, StandardNormal};
use rand_pcg::Pcg64;

// The Gamma function lives with the other special functions (stats); re-exported so
// `cuckoo::gamma` stays where Mantegna's formula uses it.
pub use super::stats::gamma;
use super::{CalibError, ParamBox, ParamVec, Problem, N_PARAMS};
use m2ctl::units::UM_PER_MM;

/// Default number of nests (Yang & Deb).
pub const DEFAULT_NESTS: usize = 25;
/// Default generation budget T_max.
pub const DEFAULT_MAX_GENERATIONS: usize = 200;
/// Default discovery (abandonment) probability p_a (Yang & Deb).
pub const DEFAULT_DISCOVERY_PROBABILITY: f64 = 0.25;
/// Default Levy exponent beta (the seed notes: "1.5 usual").
pub const DEFAULT_LEVY_BETA: f64 = 1.5;
/// Default step-size factor alpha (Yang & Deb).
pub const DEFAULT_STEP_SCALE: f64 = 0.01;
/// Default decay rate rho of the adaptive coefficient `lambda(t) = exp(-rho (t/T)^k)`:
/// lambda falls from 1 to e^-3 = 5 % at T_max (paper's value unreadable).
pub const DEFAULT_LAMBDA_DECAY: f64 = 3.0;
/// Default adjustment exponent k of the adaptive coefficient (paper's value unreadable).
pub const DEFAULT_LAMBDA_EXPONENT: f64 = 2.0;
/// Default initial minimum step s_1 of `s_min(t) = s_1 (1 - t/T)` (paper's value
/// unreadable).
pub const DEFAULT_MIN_STEP_INITIAL: f64 = 0.5;
/// Default fraction of the population (the worst nests) refined by Nelder-Mead.
pub const DEFAULT_NM_FRACTION: f64 = 0.5;
/// Default Nelder-Mead iterations per refined nest per generation.
pub const DEFAULT_NM_ITERATIONS: usize = 100;
/// Default initial simplex edge, as a fraction of the nest's distance to the best nest
/// (per parameter).
pub const DEFAULT_NM_STEP_FRACTION: f64 = 0.5;
/// Smallest initial simplex edge, in search coordinates (mm in the original coordinates,
/// mm of residual norm in the whitened ones, see [`Coordinates`]): a nest that coincides
/// with the best one still gets a non-degenerate simplex.
pub const NM_MIN_STEP_MM: f64 = 1.0e-7;
/// Nelder-Mead reflection coefficient.
pub const NM_REFLECTION: f64 = 1.0;
/// Nelder-Mead expansion coefficient.
pub const NM_EXPANSION: f64 = 2.0;
/// Nelder-Mead contraction coefficient.
pub const NM_CONTRACTION: f64 = 0.5;
/// Nelder-Mead shrink coefficient.
pub const NM_SHRINK: f64 = 0.5;

/// Coordinates of the search (our addition, not in the paper).
///
/// The residual Jacobian at nominal has a condition number of ~1e4 (18 barely observable
/// directions), and Nelder-Mead in 36 dimensions does not resolve the ill-conditioned
/// directions of such a problem in a reasonable budget. [`Coordinates::Whitened`] runs
/// the unchanged algorithm in the coordinates `z = S' V^T (x - x_nominal)` (mm of
/// residual norm), where `J = U S V^T` is the singular value decomposition of the
/// residual Jacobian at nominal (computed once per run, `x_nominal` the centre of Omega)
/// and `S' = diag(max(s_k, f s_1))` (`f` = [`WHITENING_FLOOR`]): a fixed linear change
/// of variables that makes the objective nearly isotropic near the solution, the usual
/// preconditioning. The objective is unchanged (plain sum of squares). Omega stays a box
/// in the original coordinates: every point the algorithm puts into Omega (Levy moves,
/// and in the improved variant every Nelder-Mead point) is mapped back to `x`, clamped
/// into Omega component-wise there, and mapped to `z` again; random nests are drawn
/// uniformly in Omega in `x`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coordinates {
    /// The joint coordinates themselves (mm), as in the paper.
    Original,
    /// Jacobian-whitened coordinates (see the enum documentation).
    Whitened,
}

/// Default search coordinates: whitened (see [`Coordinates`]).
pub const DEFAULT_COORDINATES: Coordinates = Coordinates::Whitened;
/// Floor of the whitening scale, as a fraction of the largest singular value: a guard
/// against a singular Jacobian (e.g. a degenerate sampling plan), far below the weakest
/// direction of the paper's plan (1e-4 of the largest), so it does not change the map
/// there. Stretching is limited to 1 / floor.
pub const WHITENING_FLOOR: f64 = 1.0e-8;

/// Which algorithm.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// The paper's baseline SMCS.
    Smcs,
    /// The paper's improved algorithm.
    Improved,
}

/// Cuckoo-search settings (see the module documentation for each symbol).
#[derive(Clone, Debug, PartialEq)]
pub struct CuckooConfig {
    /// Number of nests n.
    pub nests: usize,
    /// Generation budget T_max.
    pub max_generations: usize,
    /// Discovery probability p_a.
    pub discovery_probability: f64,
    /// Levy exponent beta.
    pub levy_beta: f64,
    /// Step-size factor alpha.
    pub step_scale: f64,
    /// Adaptive coefficient decay rate rho (improved only).
    pub lambda_decay: f64,
    /// Adaptive coefficient exponent k (improved only).
    pub lambda_exponent: f64,
    /// Initial minimum step s_1 (improved only).
    pub min_step_initial: f64,
    /// Fraction of the nests refined by Nelder-Mead each generation.
    pub nm_fraction: f64,
    /// Nelder-Mead iterations per refined nest.
    pub nm_iterations: usize,
    /// Initial simplex edge as a fraction of the distance to the best nest.
    pub nm_step_fraction: f64,
    /// Stop when the RMS residual (mm) is at or below this; `None` runs T_max generations.
    pub target_rms_mm: Option<f64>,
    /// Coordinates the search runs in (our addition; see [`Coordinates`]).
    pub coordinates: Coordinates,
}

impl Default for CuckooConfig {
    fn default() -> Self {
        Self {
            nests: DEFAULT_NESTS,
            max_generations: DEFAULT_MAX_GENERATIONS,
            discovery_probability: DEFAULT_DISCOVERY_PROBABILITY,
            levy_beta: DEFAULT_LEVY_BETA,
            step_scale: DEFAULT_STEP_SCALE,
            lambda_decay: DEFAULT_LAMBDA_DECAY,
            lambda_exponent: DEFAULT_LAMBDA_EXPONENT,
            min_step_initial: DEFAULT_MIN_STEP_INITIAL,
            nm_fraction: DEFAULT_NM_FRACTION,
            nm_iterations: DEFAULT_NM_ITERATIONS,
            nm_step_fraction: DEFAULT_NM_STEP_FRACTION,
            target_rms_mm: None,
            coordinates: DEFAULT_COORDINATES,
        }
    }
}

/// Result of a cuckoo-search run.
#[derive(Clone, Debug)]
pub struct CuckooResult {
    /// Best nest (mm).
    pub best: ParamVec,
    /// Its objective (mm^2).
    pub best_objective: f64,
    /// Generations run.
    pub generations: usize,
    /// Objective evaluations.
    pub evaluations: usize,
    /// Best RMS residual (mm) after each generation.
    pub history_rms_mm: Vec<f64>,
    /// Summary.
    pub note: String,
}

/// Mantegna's sigma_u for Levy exponent `beta`.
pub fn mantegna_sigma(beta: f64) -> f64 {
    let num = gamma(1.0 + beta) * (std::f64::consts::PI * beta / 2.0).sin();
    let den = gamma((1.0 + beta) / 2.0) * beta * 2f64.powf((beta - 1.0) / 2.0);
    (num / den).powf(1.0 / beta)
}

/// The improved algorithm's step coefficients at generation `t` of `t_max`:
/// `(lambda(t), s_min(t))`.
pub fn adaptive_coefficients(cfg: &CuckooConfig, t: usize, t_max: usize) -> (f64, f64) {
    let frac = t as f64 / t_max.max(1) as f64;
    let lambda = (-cfg.lambda_decay * frac.powf(cfg.lambda_exponent)).exp();
    let s_min = cfg.min_step_initial * (1.0 - frac);
    (lambda, s_min)
}

/// The search coordinates: `x = origin + T z` and `z = T^-1 (x - origin)` (row-major
/// 36 x 36 matrices); `None` is the identity map (original coordinates).
struct Frame {
    origin: ParamVec,
    maps: Option<(Vec<f64>, Vec<f64>)>,
}

fn mat_vec(m: &[f64], v: &ParamVec) -> ParamVec {
    let mut out = [0.0; N_PARAMS];
    for (o, row) in out.iter_mut().zip(m.chunks_exact(N_PARAMS)) {
        *o = row.iter().zip(v.iter()).map(|(a, b)| a * b).sum();
    }
    out
}

impl Frame {
    fn new(problem: &Problem, omega: &ParamBox, cfg: &CuckooConfig) -> Result<Self, CalibError> {
        let origin = omega.centre();
        if cfg.coordinates == Coordinates::Original {
            return Ok(Self { origin, maps: None });
        }
        let j = problem.jacobian(&origin);
        let m = nalgebra::DMatrix::from_row_slice(problem.n_residuals(), N_PARAMS, &j);
        let svd = m.svd(false, true);
        let v_t = svd
            .v_t
            .ok_or_else(|| CalibError::Solver("Jacobian SVD failed".into()))?;
        let s_max = svd.singular_values.max();
        let floor = WHITENING_FLOOR * s_max;
        let mut to_x = vec![0.0; N_PARAMS * N_PARAMS];
        let mut to_z = vec![0.0; N_PARAMS * N_PARAMS];
        for (r, s) in svd.singular_values.iter().enumerate() {
            let scale = s.max(floor);
            if !(scale > 0.0 && scale.is_finite()) {
                return Err(CalibError::Solver(
                    "zero or non-finite Jacobian at nominal: cannot whiten (use original coordinates)"
                        .into(),
                ));
            }
            for k in 0..N_PARAMS {
                // z_r = scale_r (V^T)_rk x_k ;  x_k = sum_r V_kr z_r / scale_r.
                to_z[r * N_PARAMS + k] = scale * v_t[(r, k)];
                to_x[k * N_PARAMS + r] = v_t[(r, k)] / scale;
            }
        }
        Ok(Self {
            origin,
            maps: Some((to_x, to_z)),
        })
    }

    fn to_x(&self, z: &ParamVec) -> ParamVec {
        match &self.maps {
            None => *z,
            Some((to_x, _)) => {
                let mut x = mat_vec(to_x, z);
                x.iter_mut()
                    .zip(self.origin.iter())
                    .for_each(|(a, o)| *a += o);
                x
            }
        }
    }

    fn to_z(&self, x: &ParamVec) -> ParamVec {
        match &self.maps {
            None => *x,
            Some((_, to_z)) => {
                let mut d = *x;
                d.iter_mut()
                    .zip(self.origin.iter())
                    .for_each(|(a, o)| *a -= o);
                mat_vec(to_z, &d)
            }
        }
    }

    /// Maps `z` to `x`, clamps into Omega there, maps back.
    fn clamp(&self, omega: &ParamBox, z: &mut ParamVec) {
        let mut x = self.to_x(z);
        if !omega.contains(&x) {
            omega.clamp(&mut x);
            *z = self.to_z(&x);
        }
    }
}

struct Counter<'a> {
    problem: &'a Problem,
    frame: &'a Frame,
    /// Improved variant: the box every evaluated point is in. Points reach the counter
    /// already clamped (in `x`) and mapped to `z`; the round trip `z -> x` can put a
    /// coordinate on a bound a few ulps outside, which this clamp removes (exact no-op in
    /// original coordinates), so no point outside Omega is ever evaluated or returned.
    omega: Option<&'a ParamBox>,
    evaluations: usize,
}

impl Counter<'_> {
    /// The parameter vector (mm) of search-coordinate point `z`.
    fn point(&self, z: &ParamVec) -> ParamVec {
        let mut x = self.frame.to_x(z);
        if let Some(o) = self.omega {
            o.clamp(&mut x);
        }
        x
    }

    /// The objective `E` (mm^2) at the search-coordinate point `z`.
    fn eval(&mut self, z: &ParamVec) -> f64 {
        self.evaluations += 1;
        let x = self.point(z);
        let e = self.problem.objective(&x);
        if e.is_nan() {
            f64::INFINITY
        } else {
            e
        }
    }
}

fn uniform_in(omega: &ParamBox, rng: &mut Pcg64) -> ParamVec {
    let mut v = [0.0; N_PARAMS];
    for (k, x) in v.iter_mut().enumerate() {
        let u: f64 = rng.random();
        *x = omega.lower_mm[k] + u * (omega.upper_mm[k] - omega.lower_mm[k]);
    }
    v
}

/// Nelder-Mead from a simplex around `x0` (edges `step`), `iterations` iterations.
/// `clamp`: every trial point is clamped into `omega` (improvement 2).
/// Returns the best vertex and its objective.
pub fn nelder_mead(
    f: &mut dyn FnMut(&ParamVec) -> f64,
    x0: &ParamVec,
    step: &ParamVec,
    iterations: usize,
    omega: Option<&ParamBox>,
) -> (ParamVec, f64) {
    match omega {
        Some(o) => nelder_mead_projected(f, x0, step, iterations, Some(&|v| o.clamp(v))),
        None => nelder_mead_projected(f, x0, step, iterations, None),
    }
}

/// [`nelder_mead`] with a general projection applied to every trial point (the improved
/// variant in whitened coordinates: map to `x`, clamp into Omega, map back).
pub fn nelder_mead_projected(
    f: &mut dyn FnMut(&ParamVec) -> f64,
    x0: &ParamVec,
    step: &ParamVec,
    iterations: usize,
    project: Option<&dyn Fn(&mut ParamVec)>,
) -> (ParamVec, f64) {
    let fix = |mut v: ParamVec| {
        if let Some(p) = project {
            p(&mut v);
        }
        v
    };
    let mut simplex: Vec<(ParamVec, f64)> = Vec::with_capacity(N_PARAMS + 1);
    let x0 = fix(*x0);
    simplex.push((x0, f(&x0)));
    for k in 0..N_PARAMS {
        let mut v = x0;
        v[k] += step[k];
        let mut v = fix(v);
        if v == x0 {
            // Clamped back onto x0 (at an upper bound): step the other way.
            v[k] -= step[k];
            v = fix(v);
        }
        let fv = f(&v);
        simplex.push((v, fv));
    }
    let comb = |a: &ParamVec, b: &ParamVec, t: f64| {
        // a + t (b - a)
        let mut out = [0.0; N_PARAMS];
        for k in 0..N_PARAMS {
            out[k] = a[k] + t * (b[k] - a[k]);
        }
        out
    };
    for _ in 0..iterations {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let n = N_PARAMS;
        let mut c = [0.0; N_PARAMS];
        for (v, _) in &simplex[..n] {
            for k in 0..N_PARAMS {
                c[k] += v[k];
            }
        }
        c.iter_mut().for_each(|x| *x /= n as f64);
        let (xw, fw) = simplex[n];
        let f_best = simplex[0].1;
        let f_second_worst = simplex[n - 1].1;
        let xr = fix(comb(&c, &xw, -NM_REFLECTION));
        let fr = f(&xr);
        if fr < f_best {
            let xe = fix(comb(&c, &xr, NM_EXPANSION));
            let fe = f(&xe);
            simplex[n] = if fe < fr { (xe, fe) } else { (xr, fr) };
            continue;
        }
        if fr < f_second_worst {
            simplex[n] = (xr, fr);
            continue;
        }
        let (xc, fc) = if fr < fw {
            let xc = fix(comb(&c, &xr, NM_CONTRACTION));
            (xc, f(&xc))
        } else {
            let xc = fix(comb(&c, &xw, NM_CONTRACTION));
            (xc, f(&xc))
        };
        if fc < fr.min(fw) {
            simplex[n] = (xc, fc);
            continue;
        }
        let xb = simplex[0].0;
        for v in simplex.iter_mut().skip(1) {
            let x = fix(comb(&xb, &v.0, NM_SHRINK));
            *v = (x, f(&x));
        }
    }
    simplex
        .into_iter()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((x0, f64::INFINITY))
}

fn check(cfg: &CuckooConfig) -> Result<(), CalibError> {
    let bad = |s: &str| Err(CalibError::BadConfig(s.to_string()));
    if cfg.nests < 2 {
        return bad("at least 2 nests");
    }
    if !(0.0..=1.0).contains(&cfg.discovery_probability) {
        return bad("discovery probability must be in [0, 1]");
    }
    if !(cfg.levy_beta > 0.0 && cfg.levy_beta <= 2.0) {
        return bad("Levy beta must be in (0, 2]");
    }
    if !(0.0..=1.0).contains(&cfg.nm_fraction) {
        return bad("NM fraction must be in [0, 1]");
    }
    if !(cfg.step_scale.is_finite()
        && cfg.lambda_decay.is_finite()
        && cfg.lambda_exponent.is_finite()
        && cfg.min_step_initial.is_finite()
        && cfg.nm_step_fraction > 0.0)
    {
        return bad("cuckoo step settings must be finite, NM step fraction positive");
    }
    Ok(())
}

/// Runs SMCS or the improved algorithm on `problem` within `omega`, seeded.
pub fn solve(
    problem: &Problem,
    omega: &ParamBox,
    cfg: &CuckooConfig,
    variant: Variant,
    seed: u64,
    progress: bool,
) -> Result<CuckooResult, CalibError> {
    check(cfg)?;
    let mut rng = Pcg64::seed_from_u64(seed);
    let frame = Frame::new(problem, omega, cfg)?;
    let mut f = Counter {
        problem,
        frame: &frame,
        omega: match variant {
            Variant::Smcs => None,
            Variant::Improved => Some(omega),
        },
        evaluations: 0,
    };
    let sigma_u = mantegna_sigma(cfg.levy_beta);
    let normal_u =
        Normal::new(0.0, sigma_u).map_err(|e| CalibError::BadConfig(format!("Levy sigma: {e}")))?;
    let n_res = problem.n_residuals().max(1) as f64;
    let rms = |e: f64| (e / n_res).sqrt();

    // Nests are stored in search coordinates (see [`Coordinates`]).
    let mut nests: Vec<(ParamVec, f64)> = (0..cfg.nests)
        .map(|_| {
            let v = frame.to_z(&uniform_in(omega, &mut rng));
            let e = f.eval(&v);
            (v, e)
        })
        .collect();
    let best_of = |nests: &[(ParamVec, f64)]| {
        nests
            .iter()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .copied()
            .unwrap_or(([0.0; N_PARAMS], f64::INFINITY))
    };
    let mut best = best_of(&nests);
    let bar = if progress {
        let b = indicatif::ProgressBar::new(cfg.max_generations as u64);
        if let Ok(style) = indicatif::ProgressStyle::with_template(
            "{prefix} [{bar:30}] {pos}/{len} generations, {msg} ({elapsed})",
        ) {
            b.set_style(style.progress_chars("=> "));
        }
        b.set_prefix(match variant {
            Variant::Smcs => "smcs",
            Variant::Improved => "improved",
        });
        b
    } else {
        indicatif::ProgressBar::hidden()
    };
    let mut history = Vec::with_capacity(cfg.max_generations);
    let mut generations = 0;
    let n_nm = ((cfg.nests as f64) * cfg.nm_fraction).round() as usize;
    for t in 0..cfg.max_generations {
        if let Some(target) = cfg.target_rms_mm {
            if rms(best.1) <= target {
                break;
            }
        }
        generations = t + 1;
        // 2. Levy flights.
        let (lambda, s_min) = match variant {
            Variant::Smcs => (1.0, 0.0),
            Variant::Improved => adaptive_coefficients(cfg, t, cfg.max_generations),
        };
        for nest in nests.iter_mut() {
            let mut x = nest.0;
            for ((xk, nk), bk) in x.iter_mut().zip(nest.0.iter()).zip(best.0.iter()) {
                let u: f64 = normal_u.sample(&mut rng);
                let v: f64 = StandardNormal.sample(&mut rng);
                let step = u / v.abs().powf(1.0 / cfg.levy_beta);
                let s_t = lambda * step + s_min;
                *xk += cfg.step_scale * s_t * (nk - bk);
            }
            frame.clamp(omega, &mut x);
            let e = f.eval(&x);
            if e < nest.1 {
                *nest = (x, e);
            }
        }
        // 3. Abandonment.
        for nest in nests.iter_mut() {
            if rng.random::<f64>() < cfg.discovery_probability {
                let x = frame.to_z(&uniform_in(omega, &mut rng));
                let e = f.eval(&x);
                if e < nest.1 {
                    *nest = (x, e);
                }
            }
        }
        best = best_of(&nests);
        // 4. Nelder-Mead on the worse part.
        nests.sort_by(|a, b| a.1.total_cmp(&b.1));
        let project = |z: &mut ParamVec| frame.clamp(omega, z);
        let bounds: Option<&dyn Fn(&mut ParamVec)> = match variant {
            Variant::Smcs => None,
            Variant::Improved => Some(&project),
        };
        let start = nests.len() - n_nm.min(nests.len());
        for nest in nests[start..].iter_mut() {
            let mut step = [0.0; N_PARAMS];
            for ((sk, nk), bk) in step.iter_mut().zip(nest.0.iter()).zip(best.0.iter()) {
                *sk = (cfg.nm_step_fraction * (nk - bk).abs()).max(NM_MIN_STEP_MM);
            }
            let mut fe = |v: &ParamVec| f.eval(v);
            let (x, e) = nelder_mead_projected(&mut fe, &nest.0, &step, cfg.nm_iterations, bounds);
            if e < nest.1 {
                *nest = (x, e);
            }
        }
        best = best_of(&nests);
        history.push(rms(best.1));
        bar.set_position(generations as u64);
        bar.set_message(format!("RMS {:.4} um", rms(best.1) * UM_PER_MM));
    }
    bar.finish_and_clear();
    let best_x = f.point(&best.0);
    Ok(CuckooResult {
        best: best_x,
        best_objective: best.1,
        generations,
        evaluations: f.evaluations,
        history_rms_mm: history,
        note: format!(
            "{}: {} nests, {} generations, {} coordinates, residual RMS {:.4} um",
            match variant {
                Variant::Smcs => "smcs",
                Variant::Improved => "improved",
            },
            cfg.nests,
            generations,
            match cfg.coordinates {
                Coordinates::Original => "original",
                Coordinates::Whitened => "whitened",
            },
            rms(best.1) * UM_PER_MM
        ),
    })
}
