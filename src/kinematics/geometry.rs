//! Mechanism geometry: six legs, the home position and the optional limits.
//!
//! Frames and units (mm throughout):
//! * base frame B: origin at the fixed platform centre, z up, sliders move along B's z;
//! * moving frame M: origin at the moving platform's rotation centre.
//!
//! [`GeometryParams`] is the `f64` source of truth (what a geometry file or a calibrated
//! parameter table holds). [`Geometry<T>`] is what the kinematics evaluate: the same
//! parameters in the working float type plus quantities derived *in `f64`* and rounded
//! once, so that an `f32` evaluation starts from the best `f32` approximation of each
//! derived quantity rather than from a difference of rounded large numbers.

use nalgebra::Vector3;

use super::real::Real;

/// Number of legs (sliders) of the 6-PSS platform.
pub const LEGS: usize = 6;

/// Nominal parameters of one leg, `f64`, mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegParams {
    /// Lower spherical-joint centre at zero slider stroke, base frame B (mm).
    pub a_mm: [f64; 3],
    /// Upper spherical-joint centre, moving frame M (mm).
    pub b_mm: [f64; 3],
}

/// Slider stroke limits, per leg (mm, along B's z, relative to the home stroke 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrokeLimits {
    /// Lowest allowed stroke of each slider (mm).
    pub min_mm: [f64; LEGS],
    /// Highest allowed stroke of each slider (mm).
    pub max_mm: [f64; LEGS],
}

/// Symmetric workspace box around the home pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorkspaceLimits {
    /// Largest |x|, |y|, |z| translation from p0 (mm, base axes).
    pub translation_mm: [f64; 3],
    /// Largest |alpha|, |beta|, |gamma| (rad).
    pub rotation_rad: [f64; 3],
}

/// Everything that defines a mechanism for the kinematics, in `f64`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GeometryParams {
    /// The six legs, in slider order 1..6.
    pub legs: [LegParams; LEGS],
    /// Home position of M's origin in B (mm): the pose where every stroke is zero.
    pub p0_mm: [f64; 3],
    /// Slider limits; `None` applies none.
    pub stroke_limits: Option<StrokeLimits>,
    /// Workspace limits; `None` applies none.
    pub workspace: Option<WorkspaceLimits>,
}

/// Why a set of parameters does not describe a usable mechanism.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GeometryError {
    /// A coordinate, p0 component or limit is NaN or infinite.
    NonFinite,
    /// Leg (0-based): the upper joint is not above the lower joint at home
    /// (the vertical component of the rod must be positive).
    UpperNotAboveLower {
        /// 0-based leg index.
        leg: u8,
    },
    /// Leg (0-based): stroke limits with min > max, or not containing the home stroke 0.
    BadStrokeLimits {
        /// 0-based leg index.
        leg: u8,
    },
    /// A workspace half-range is negative.
    BadWorkspaceLimits,
}

impl GeometryError {
    /// Stable numeric code for telemetry.
    pub const fn code(&self) -> u16 {
        match self {
            GeometryError::NonFinite => 0x0101,
            GeometryError::UpperNotAboveLower { .. } => 0x0102,
            GeometryError::BadStrokeLimits { .. } => 0x0103,
            GeometryError::BadWorkspaceLimits => 0x0104,
        }
    }
}

/// Smallest accepted vertical rod component at home (mm): below this the IK of the
/// leg degenerates (the rod would be horizontal).
pub const MIN_ROD_VERTICAL_MM: f64 = 1.0;

/// One leg in the working float type.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Leg<T: Real> {
    /// Lower joint at zero stroke, frame B (mm).
    pub a_mm: Vector3<T>,
    /// Upper joint, frame M (mm).
    pub b_mm: Vector3<T>,
    /// Rod vector at home, `b + p0 - a`, frame B (mm); derived in f64.
    pub d0_mm: Vector3<T>,
    /// Rod length `|d0|` (mm); derived in f64.
    pub rod_mm: T,
    /// `2 d0_x`, `2 d0_y` (mm; exact doubles of `d0_mm`), the factors of the IK's change
    /// of the horizontal rod length squared.
    pub two_d0_xy_mm: [T; 2],
    /// `d0_z^2` (mm^2); derived in f64.
    pub d0z_sq_mm2: T,
    /// `1 / (2 d0_z)` (1/mm); derived in f64. Scales the first-order guess of the
    /// vertical rod component in the IK.
    pub inv_two_d0z_per_mm: T,
    /// Largest change of the horizontal rod length squared (mm^2) for which the IK's
    /// two-step square root is exact to f32/f64 rounding: [`SQRT_FAST_FRACTION`] `* d0_z^2`.
    pub fast_sqrt_delta_mm2: T,
}

/// Fraction of `d0_z^2` up to which the IK's first-order guess of the vertical rod
/// component (relative error <= 0.1^2/8 = 1.3e-3) plus two Newton steps (-> 8.5e-7 ->
/// 4e-13) is exact to rounding. That is a horizontal joint displacement of about 5 mm,
/// beyond the mechanism's reach; larger values take the general square root.
pub const SQRT_FAST_FRACTION: f64 = 0.1;

/// Stroke limits in the working float type (mm).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StrokeBounds<T> {
    /// Per-leg lower limit (mm).
    pub min_mm: [T; LEGS],
    /// Per-leg upper limit (mm).
    pub max_mm: [T; LEGS],
}

/// Workspace limits in the working float type.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WorkspaceBounds<T> {
    /// Half-range of x, y, z (mm).
    pub translation_mm: [T; 3],
    /// Half-range of alpha, beta, gamma (rad).
    pub rotation_rad: [T; 3],
}

/// The mechanism as the kinematics evaluate it, in float type `T`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Geometry<T: Real> {
    /// Legs 1..6.
    pub legs: [Leg<T>; LEGS],
    /// Home position (mm, frame B).
    pub p0_mm: [T; 3],
    /// Slider limits, if any.
    pub stroke: Option<StrokeBounds<T>>,
    /// Workspace limits, if any.
    pub workspace: Option<WorkspaceBounds<T>>,
}

impl Geometry<f32> {
    /// A check word over every `f32` of the working geometry (each word's bits rotated
    /// in): any single flipped bit changes it. Not used by the flight image, which
    /// checks the geometry by re-deriving it in the scrub; it is what a per-cycle check
    /// would cost, measured by `m2cyclebench` (`geometry_check_word`, docs/budgets.md).
    pub fn check_word(&self) -> u32 {
        let mut c = 0u32;
        let mut fold = |x: f32| c = c.rotate_left(1) ^ x.to_bits();
        for l in &self.legs {
            for v in [&l.a_mm, &l.b_mm, &l.d0_mm] {
                v.iter().for_each(|x| fold(*x));
            }
            l.two_d0_xy_mm.iter().for_each(|x| fold(*x));
            for x in [
                l.rod_mm,
                l.d0z_sq_mm2,
                l.inv_two_d0z_per_mm,
                l.fast_sqrt_delta_mm2,
            ] {
                fold(x);
            }
        }
        self.p0_mm.iter().for_each(|x| fold(*x));
        if let Some(s) = &self.stroke {
            s.min_mm.iter().chain(&s.max_mm).for_each(|x| fold(*x));
        }
        if let Some(w) = &self.workspace {
            w.translation_mm
                .iter()
                .chain(&w.rotation_rad)
                .for_each(|x| fold(*x));
        }
        c
    }
}

fn all_finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Each component rounded to `T`. Not inlined: [`Geometry::new`] calls it six times
/// per leg and table (84 bytes of flash less).
#[inline(never)]
fn map3<T: Real>(v: [f64; 3]) -> [T; 3] {
    [T::from_f64(v[0]), T::from_f64(v[1]), T::from_f64(v[2])]
}

fn map6<T: Real>(v: [f64; LEGS]) -> [T; LEGS] {
    let mut out = [T::ZERO; LEGS];
    for (o, x) in out.iter_mut().zip(v.iter()) {
        *o = T::from_f64(*x);
    }
    out
}

impl GeometryParams {
    /// Parameters without limits.
    pub const fn new(legs: [LegParams; LEGS], p0_mm: [f64; 3]) -> Self {
        Self {
            legs,
            p0_mm,
            stroke_limits: None,
            workspace: None,
        }
    }

    /// Checks that the parameters describe a usable mechanism.
    pub fn validate(&self) -> Result<(), GeometryError> {
        if !all_finite(&self.p0_mm) {
            return Err(GeometryError::NonFinite);
        }
        for (i, leg) in self.legs.iter().enumerate() {
            if !all_finite(&leg.a_mm) || !all_finite(&leg.b_mm) {
                return Err(GeometryError::NonFinite);
            }
            let d0z = leg.b_mm[2] + self.p0_mm[2] - leg.a_mm[2];
            if d0z.is_nan() || d0z < MIN_ROD_VERTICAL_MM {
                return Err(GeometryError::UpperNotAboveLower { leg: i as u8 });
            }
        }
        if let Some(s) = &self.stroke_limits {
            if !all_finite(&s.min_mm) || !all_finite(&s.max_mm) {
                return Err(GeometryError::NonFinite);
            }
            for (i, (lo, hi)) in s.min_mm.iter().zip(s.max_mm.iter()).enumerate() {
                if lo > hi || *lo > 0.0 || *hi < 0.0 {
                    return Err(GeometryError::BadStrokeLimits { leg: i as u8 });
                }
            }
        }
        if let Some(w) = &self.workspace {
            if !all_finite(&w.translation_mm) || !all_finite(&w.rotation_rad) {
                return Err(GeometryError::NonFinite);
            }
            if w.translation_mm
                .iter()
                .chain(w.rotation_rad.iter())
                .any(|v| *v < 0.0)
            {
                return Err(GeometryError::BadWorkspaceLimits);
            }
        }
        Ok(())
    }

    /// Rod length of each leg, `|b_i + p0 - a_i|` (mm).
    pub fn rod_lengths_mm(&self) -> [f64; LEGS] {
        let mut out = [0.0; LEGS];
        for (o, leg) in out.iter_mut().zip(self.legs.iter()) {
            *o = norm3(home_rod(leg, &self.p0_mm));
        }
        out
    }
}

/// Rod vector at home, `b + p0 - a` (mm, frame B), in f64. Out of line: the one copy
/// serves the geometry derivation and the table validation (`table::validate`).
#[inline(never)]
pub(crate) fn home_rod(leg: &LegParams, p0: &[f64; 3]) -> [f64; 3] {
    [
        leg.b_mm[0] + p0[0] - leg.a_mm[0],
        leg.b_mm[1] + p0[1] - leg.a_mm[1],
        leg.b_mm[2] + p0[2] - leg.a_mm[2],
    ]
}

/// Euclidean norm of `v` in f64 (its unit), `sqrt(v0^2 + v1^2 + v2^2)` in that order.
/// Out of line: the one copy serves the geometry derivation (rod length at home) and
/// the table validation (`table::validate`).
#[inline(never)]
pub(crate) fn norm3(v: [f64; 3]) -> f64 {
    crate::kinematics::real::sqrt_f64(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
}

impl<T: Real> Geometry<T> {
    /// Validates the parameters and derives the working geometry (derived quantities are
    /// computed in f64 and rounded once to `T`).
    pub fn new(params: &GeometryParams) -> Result<Self, GeometryError> {
        params.validate()?;
        let mut legs = [Leg::default(); LEGS];
        for (out, leg) in legs.iter_mut().zip(params.legs.iter()) {
            let d0 = home_rod(leg, &params.p0_mm);
            *out = Leg {
                a_mm: map3(leg.a_mm).into(),
                b_mm: map3(leg.b_mm).into(),
                d0_mm: map3(d0).into(),
                two_d0_xy_mm: [T::from_f64(2.0 * d0[0]), T::from_f64(2.0 * d0[1])],
                d0z_sq_mm2: T::from_f64(d0[2] * d0[2]),
                rod_mm: T::from_f64(norm3(d0)),
                inv_two_d0z_per_mm: T::from_f64(0.5 / d0[2]),
                fast_sqrt_delta_mm2: T::from_f64(SQRT_FAST_FRACTION * d0[2] * d0[2]),
            };
        }
        Ok(Self {
            legs,
            p0_mm: map3(params.p0_mm),
            stroke: params.stroke_limits.map(|s| StrokeBounds {
                min_mm: map6(s.min_mm),
                max_mm: map6(s.max_mm),
            }),
            workspace: params.workspace.map(|w| WorkspaceBounds {
                translation_mm: map3(w.translation_mm),
                rotation_rad: map3(w.rotation_rad),
            }),
        })
    }
}
