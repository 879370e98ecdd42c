//! Coordinated moves between mirror poses along a straight line in pose space.
//!
//! The pose follows `p(s) = start + s (target - start)` (components
//! `[x, y, z, alpha, beta, gamma]`, mm and rad, see [`Pose`]) with one path parameter
//! `s(t)` from a [`Ramp`]: every slider starts at cycle 0 and arrives at the same cycle,
//! because all of them are functions of the one `s`.
//!
//! ## How the limits on `s` are derived
//!
//! Slider i's stroke along the path is `S_i(s)`. Its speed is `S_i' sdot` and its
//! acceleration `S_i' sddot + S_i'' sdot^2`. At plan time the strokes are evaluated by IK
//! at [`PATH_SAMPLE_INTERVALS`]` + 1` equally spaced points (which also checks that the
//! whole path is accepted by the workspace check), and per slider
//!
//! ```text
//! C_i = CURVATURE_SAFETY_FACTOR * (max |second difference| * n^2 + 4 e n^2)    >= |S_i''|
//! G_i = max |first difference| * n + 2 e n + C_i / n                          >= |S_i'|
//! ```
//!
//! with `n` = [`PATH_SAMPLE_INTERVALS`] and `e` = [`STROKE_ROUNDING_MM`]. A first
//! difference is `S'` somewhere in its interval, so `S'` anywhere in the interval differs
//! from it by at most `|S''| / n`. A second difference is `S''` somewhere in two
//! intervals; `S''` itself changes by `|S'''| 2/n`, and along this mechanism's paths
//! `|S'''| ~ |S''| * |dp| / L` (rod `L` ~ 220 mm, move `|dp|` <= 4 mm): the factor 2 covers it
//! with a wide margin. Then, with `u` = [`LIMIT_USE_FRACTION`] of each slider limit:
//!
//! ```text
//! sdot_max  = min_i min( u v_i / G_i,  sqrt(CURVATURE_ACCEL_SHARE u a_i / C_i) )
//! sddot_max = min_i (u a_i - C_i sdot_max^2) / G_i          (>= 3/4 u a_i / G_i)
//! ```
//!
//! so `G_i sdot <= u v_i` and `G_i |sddot| + C_i sdot^2 <= u a_i` whatever the phase: the
//! limits hold on the continuous profile, and hence on the sampled setpoints too (a
//! difference quotient of samples is an average of the derivative). The remaining
//! `1 - u` absorbs f32 rounding of the setpoints.
//!
//! Planning costs [`PATH_SAMPLE_INTERVALS`]` + 1` IK evaluations (~12,000 Cortex-M4
//! instructions); it is done once per move, not every cycle. [`Trajectory::setpoint`]
//! costs a handful of f32 operations plus 6 multiply-adds.

use super::ramp::{Ramp, RampError, CYCLE_S};
use crate::kinematics::workspace::evaluate;
use crate::kinematics::{Frames, Geometry, Pose, Real, Refusals, LEGS};

/// Intervals of the path sampled at plan time (IK at this many + 1 points).
pub const PATH_SAMPLE_INTERVALS: usize = 16;
/// Fraction of every speed and acceleration limit the plan uses; the rest covers f32
/// rounding of the setpoints and of the sampled bounds.
pub const LIMIT_USE_FRACTION: f32 = 0.9;
/// Factor on the sampled second derivative of each stroke along the path (covers the
/// variation of the curvature between samples, see the module documentation).
pub const CURVATURE_SAFETY_FACTOR: f32 = 2.0;
/// Largest share of a slider's acceleration budget that the curvature term
/// `S'' sdot^2` may take (caps the cruise rate); the rest is left to `S' sddot`.
pub const CURVATURE_ACCEL_SHARE: f32 = 0.25;
/// Bound of the f32 rounding of one IK stroke evaluation (mm): 1 nm, above the measured
/// 0.56 nm f32-vs-f64 IK error. Enters the finite-difference bounds.
pub const STROKE_ROUNDING_MM: f32 = 1.0e-6;

/// Speed and acceleration limits of the six sliders for coordinated moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionLimits {
    /// Largest slider speed (mm/s of stroke), per slider.
    pub max_speed_mm_per_s: [f32; LEGS],
    /// Largest slider acceleration (mm/s^2 of stroke), per slider.
    pub max_accel_mm_per_s2: [f32; LEGS],
}

/// Default slider speed limit of a coordinated move (mm/s): 0.2, below the drives'
/// 0.5 mm/s, so the drives follow the setpoints without lag.
pub const DEFAULT_MAX_SPEED_MM_PER_S: f32 = 0.2;
/// Default slider acceleration limit of a coordinated move (mm/s^2): full speed in 0.2 s.
pub const DEFAULT_MAX_ACCEL_MM_PER_S2: f32 = 1.0;

impl Default for MotionLimits {
    fn default() -> Self {
        Self {
            max_speed_mm_per_s: [DEFAULT_MAX_SPEED_MM_PER_S; LEGS],
            max_accel_mm_per_s2: [DEFAULT_MAX_ACCEL_MM_PER_S2; LEGS],
        }
    }
}

/// Why a move was not planned. Stable numeric codes for telemetry (family 0x06xx).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotionError {
    /// The start or target pose has a NaN or infinite component.
    NonFinite,
    /// A speed or acceleration limit of this slider (0-based) is not a positive number.
    BadLimits {
        /// 0-based leg index.
        leg: u8,
    },
    /// The start pose itself is refused by the workspace check (plan from the last
    /// commanded pose, or recover with a direct-stroke move).
    StartRefused(Refusals),
    /// The target pose is refused by the workspace check; every reason.
    TargetRefused(Refusals),
    /// A point of the straight path between accepted ends is refused.
    PathRefused {
        /// Sample index along the path, 1..[`PATH_SAMPLE_INTERVALS`]-1.
        sample: u8,
        /// Every reason at that point.
        refusals: Refusals,
    },
    /// The move would last more than [`super::MAX_MOVE_CYCLES`] cycles.
    TooLong,
}

impl MotionError {
    /// Stable numeric code for telemetry.
    pub const fn code(&self) -> u16 {
        match self {
            MotionError::NonFinite => 0x0601,
            MotionError::BadLimits { .. } => 0x0602,
            MotionError::StartRefused(_) => 0x0603,
            MotionError::TargetRefused(_) => 0x0604,
            MotionError::PathRefused { .. } => 0x0605,
            MotionError::TooLong => 0x0606,
        }
    }
}

/// What the plan derived along the path (for telemetry and tests).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathBounds {
    /// Bound of `|d stroke_i / ds|` over the path (mm per unit of s).
    pub stroke_slope_mm: [f32; LEGS],
    /// Bound of `|d2 stroke_i / ds2|` over the path (mm per unit of s^2).
    pub stroke_curvature_mm: [f32; LEGS],
    /// Largest `ds/dt` allowed by the limits (1/s).
    pub max_rate_per_s: f32,
    /// Largest `|d2s/dt2|` allowed by the limits (1/s^2).
    pub max_accel_per_s2: f32,
}

/// The commanded pose at one control cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setpoint {
    /// Commanded pose (internal: M's origin; mm, rad); the controller turns it into
    /// strokes by IK.
    pub pose: Pose<f32>,
    /// The same setpoint in the operator's frames (pivot, user frame): what the path is
    /// a straight line in.
    pub operator: Pose<f32>,
    /// The path parameter is changing at this cycle (motion commanded), for supervision.
    pub moving: bool,
    /// The move is over: at the target, or at rest after a stop. The pose no longer
    /// changes.
    pub done: bool,
}

/// A planned move from `start` to `target` (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trajectory {
    /// Start, target and their difference in the operator's frames.
    start: [f32; 6],
    target: [f32; 6],
    delta: [f32; 6],
    ramp: Ramp,
    bounds: PathBounds,
    frames: Frames<f32>,
}

fn validate_limits(limits: &MotionLimits) -> Result<(), MotionError> {
    for (i, (v, a)) in limits
        .max_speed_mm_per_s
        .iter()
        .zip(limits.max_accel_mm_per_s2.iter())
        .enumerate()
    {
        if !(v.is_finite() && *v > 0.0 && a.is_finite() && *a > 0.0) {
            return Err(MotionError::BadLimits { leg: i as u8 });
        }
    }
    Ok(())
}

/// `start + s * delta`, per component.
fn along(start: &[f32; 6], delta: &[f32; 6], s: f32) -> [f32; 6] {
    let mut p = *start;
    for (pk, dk) in p.iter_mut().zip(delta.iter()) {
        *pk += s * *dk;
    }
    p
}

impl Trajectory {
    /// Plans a move from `start` to `target` within `limits`, in one call. A
    /// zero-length move is an immediate arrival. Every error is reported before anything
    /// moves. [`TrajectoryPlanner`] does the same in steps, to spread the path sampling
    /// over several control cycles.
    pub fn plan(
        geom: &Geometry<f32>,
        start: &Pose<f32>,
        target: &Pose<f32>,
        limits: &MotionLimits,
    ) -> Result<Self, MotionError> {
        Self::plan_in(geom, &Frames::identity(), start, target, limits)
    }

    /// [`Trajectory::plan`] with `start` and `target` given in the operator's `frames`:
    /// the path is straight in those coordinates (a rotation about the pivot keeps the
    /// pivot fixed), every sample is checked in internal coordinates.
    pub fn plan_in(
        geom: &Geometry<f32>,
        frames: &Frames<f32>,
        start: &Pose<f32>,
        target: &Pose<f32>,
        limits: &MotionLimits,
    ) -> Result<Self, MotionError> {
        match TrajectoryPlanner::begin_in(geom, frames, start, target, limits)? {
            PlanStart::Ready(t) => Ok(t),
            PlanStart::Sampling(mut p) => loop {
                if let Some(done) = p.advance(geom, PATH_SAMPLE_INTERVALS) {
                    return done;
                }
            },
        }
    }

    /// The commanded pose at control cycle `cycle` (0 = the cycle the move starts; the
    /// setpoint of cycle 0 is the start pose). Closed form in the cycle count.
    pub fn setpoint(&self, cycle: u32) -> Setpoint {
        let smp = self.ramp.sample(cycle);
        // From the nearer end, so that the small factor carries the precision.
        let p = if smp.progress <= 0.5 {
            along(&self.start, &self.delta, smp.progress)
        } else {
            along(&self.target, &self.delta, -smp.remaining)
        };
        let operator = Pose::from_array(p);
        Setpoint {
            pose: self.frames.to_internal(&operator),
            operator,
            moving: smp.rate_per_cycle > 0.0,
            done: smp.at_rest,
        }
    }

    /// Turns the rest of the move, from `cycle` on, into a deceleration at the
    /// acceleration limit to rest on the same straight path (short of the target). The
    /// setpoint of `cycle` is unchanged. No effect once done or already stopping.
    pub fn stop(&mut self, cycle: u32) {
        self.ramp.stop(cycle);
    }

    /// The move is over at `cycle` (arrived, or at rest after a stop).
    pub fn is_done(&self, cycle: u32) -> bool {
        cycle >= self.ramp.end_cycle()
    }

    /// First cycle at which the move is over; the setpoint no longer changes from there.
    pub fn end_cycle(&self) -> u32 {
        self.ramp.end_cycle()
    }

    /// Duration of the move (s), `end_cycle * CYCLE_S`.
    pub fn duration_s(&self) -> f32 {
        self.ramp.end_cycle() as f32 * CYCLE_S
    }

    /// The path-parameter profile.
    pub fn ramp(&self) -> &Ramp {
        &self.ramp
    }

    /// The bounds derived along the path at plan time.
    pub fn bounds(&self) -> &PathBounds {
        &self.bounds
    }

    /// Start pose (operator frames).
    pub fn start(&self) -> Pose<f32> {
        Pose::from_array(self.start)
    }

    /// Target pose (operator frames).
    pub fn target(&self) -> Pose<f32> {
        Pose::from_array(self.target)
    }
}

/// The result of [`TrajectoryPlanner::begin`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PlanStart {
    /// Nothing to sample (zero-length move): the trajectory is ready.
    Ready(Trajectory),
    /// The ends are accepted; the path samples remain to be evaluated.
    Sampling(TrajectoryPlanner),
}

/// A trajectory being planned: [`TrajectoryPlanner::begin`] checks the inputs and both
/// ends (two IK evaluations), then [`TrajectoryPlanner::advance`] evaluates a bounded
/// number of path samples per call, so that a controller can spread the ~17 IK
/// evaluations of a plan over several control cycles. The result is the same as
/// [`Trajectory::plan`]'s (which is `begin` + `advance` to the end).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrajectoryPlanner {
    start: [f32; 6],
    target: [f32; 6],
    delta: [f32; 6],
    target_strokes: [f32; LEGS],
    limits: MotionLimits,
    /// Next sample index (1..=PATH_SAMPLE_INTERVALS).
    k: usize,
    prev: [f32; LEGS],
    prev2: [f32; LEGS],
    slope: [f32; LEGS],
    curvature: [f32; LEGS],
    frames: Frames<f32>,
}

impl TrajectoryPlanner {
    /// Checks the inputs and both ends; a zero-length move is ready at once.
    pub fn begin(
        geom: &Geometry<f32>,
        start: &Pose<f32>,
        target: &Pose<f32>,
        limits: &MotionLimits,
    ) -> Result<PlanStart, MotionError> {
        Self::begin_in(geom, &Frames::identity(), start, target, limits)
    }

    /// [`TrajectoryPlanner::begin`] with `start` and `target` in the operator's `frames`.
    pub fn begin_in(
        geom: &Geometry<f32>,
        frames: &Frames<f32>,
        start: &Pose<f32>,
        target: &Pose<f32>,
        limits: &MotionLimits,
    ) -> Result<PlanStart, MotionError> {
        if !start.is_finite() || !target.is_finite() {
            return Err(MotionError::NonFinite);
        }
        validate_limits(limits)?;
        let (start_a, target_a) = (start.to_array(), target.to_array());
        let mut delta = [0.0f32; 6];
        for ((d, t), s) in delta.iter_mut().zip(target_a.iter()).zip(start_a.iter()) {
            *d = *t - *s;
        }
        if !delta.iter().all(|d| d.is_finite()) {
            return Err(MotionError::NonFinite);
        }
        let (target_strokes, refused) = evaluate(geom, &frames.to_internal(target));
        if !refused.is_empty() {
            return Err(MotionError::TargetRefused(refused));
        }
        let (start_strokes, refused) = evaluate(geom, &frames.to_internal(start));
        if !refused.is_empty() {
            return Err(MotionError::StartRefused(refused));
        }
        if delta.iter().all(|d| *d == 0.0) {
            return Ok(PlanStart::Ready(Trajectory {
                start: start_a,
                target: target_a,
                delta,
                ramp: Ramp::immediate(),
                bounds: PathBounds {
                    stroke_slope_mm: [0.0; LEGS],
                    stroke_curvature_mm: [0.0; LEGS],
                    max_rate_per_s: f32::INFINITY,
                    max_accel_per_s2: f32::INFINITY,
                },
                frames: *frames,
            }));
        }
        Ok(PlanStart::Sampling(TrajectoryPlanner {
            start: start_a,
            target: target_a,
            delta,
            target_strokes,
            limits: *limits,
            k: 1,
            prev: start_strokes,
            prev2: start_strokes,
            slope: [0.0; LEGS],
            curvature: [0.0; LEGS],
            frames: *frames,
        }))
    }

    /// Evaluates up to `max_samples` more path samples (IK each); returns the finished
    /// plan (or the refusal) once the last sample is done, `None` while samples remain.
    pub fn advance(
        &mut self,
        geom: &Geometry<f32>,
        max_samples: usize,
    ) -> Option<Result<Trajectory, MotionError>> {
        let n = PATH_SAMPLE_INTERVALS as f32;
        for _ in 0..max_samples.max(1) {
            let k = self.k;
            if k > PATH_SAMPLE_INTERVALS {
                break;
            }
            let strokes = if k == PATH_SAMPLE_INTERVALS {
                self.target_strokes
            } else {
                let pose = Pose::from_array(along(&self.start, &self.delta, k as f32 / n));
                let (strokes, refused) = evaluate(geom, &self.frames.to_internal(&pose));
                if !refused.is_empty() {
                    return Some(Err(MotionError::PathRefused {
                        sample: k as u8,
                        refusals: refused,
                    }));
                }
                strokes
            };
            for ((((s, p1), p2), sl), cu) in strokes
                .iter()
                .zip(self.prev.iter())
                .zip(self.prev2.iter())
                .zip(self.slope.iter_mut())
                .zip(self.curvature.iter_mut())
            {
                *sl = sl.max((*s - *p1).abs());
                if k >= 2 {
                    *cu = cu.max((*s - 2.0 * *p1 + *p2).abs());
                }
            }
            self.prev2 = self.prev;
            self.prev = strokes;
            self.k = k + 1;
        }
        if self.k <= PATH_SAMPLE_INTERVALS {
            return None;
        }
        Some(self.finish())
    }

    /// Bounds of S' and S'' (see the module documentation), then the limits on s.
    /// Out of line: inlined into [`TrajectoryPlanner::advance`], 24 bytes of flash more.
    #[inline(never)]
    fn finish(&self) -> Result<Trajectory, MotionError> {
        let n = PATH_SAMPLE_INTERVALS as f32;
        let mut slope = self.slope;
        let mut curvature = self.curvature;
        let limits = &self.limits;
        let mut rate = f32::INFINITY;
        for (((sl, cu), v), a) in slope
            .iter_mut()
            .zip(curvature.iter_mut())
            .zip(limits.max_speed_mm_per_s.iter())
            .zip(limits.max_accel_mm_per_s2.iter())
        {
            let c = CURVATURE_SAFETY_FACTOR * (*cu + 4.0 * STROKE_ROUNDING_MM) * n * n;
            let g = *sl * n + 2.0 * STROKE_ROUNDING_MM * n + c / n;
            *cu = c;
            *sl = g;
            rate = rate.min(LIMIT_USE_FRACTION * *v / g).min(Real::sqrt(
                CURVATURE_ACCEL_SHARE * LIMIT_USE_FRACTION * *a / c,
            ));
        }
        let mut accel = f32::INFINITY;
        for ((g, c), a) in slope
            .iter()
            .zip(curvature.iter())
            .zip(limits.max_accel_mm_per_s2.iter())
        {
            accel = accel.min((LIMIT_USE_FRACTION * *a - *c * rate * rate) / *g);
        }
        let ramp = Ramp::plan(rate, accel).map_err(|e| match e {
            RampError::BadLimits => MotionError::NonFinite,
            RampError::TooLong => MotionError::TooLong,
        })?;
        Ok(Trajectory {
            start: self.start,
            target: self.target,
            delta: self.delta,
            ramp,
            bounds: PathBounds {
                stroke_slope_mm: slope,
                stroke_curvature_mm: curvature,
                max_rate_per_s: rate,
                max_accel_per_s2: accel,
            },
            frames: self.frames,
        })
    }
}
