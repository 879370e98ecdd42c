//! Direct-stroke moves for recovery: one slider by a given stroke, no kinematics.
//!
//! Used when the pose is unknown or untrustworthy (FK failing, a slider beyond its soft
//! limit): the other five sliders hold their strokes, the chosen one follows a
//! trapezoidal [`Ramp`] over `delta_mm` with its own, usually gentler, limits.

use super::ramp::{Ramp, RampError};
use crate::kinematics::LEGS;

/// Fraction of the direct-stroke limits the plan uses: the profile is exact (no path
/// curvature); the 1 % absorbs the f32 rounding of the setpoints (a few 1e-8 mm, which
/// over 10 ms is ~0.3 % of a 0.2 mm/s^2 acceleration limit).
pub const DIRECT_LIMIT_USE_FRACTION: f32 = 0.99;

/// Default direct-stroke speed limit (mm/s): slow, for recovery.
pub const DEFAULT_DIRECT_SPEED_MM_PER_S: f32 = 0.05;
/// Default direct-stroke acceleration limit (mm/s^2).
pub const DEFAULT_DIRECT_ACCEL_MM_PER_S2: f32 = 0.5;
/// Default largest stroke of one direct move (mm).
pub const DEFAULT_DIRECT_MAX_DELTA_MM: f32 = 1.0;

/// Limits of a direct-stroke move.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectStrokeLimits {
    /// Largest slider speed (mm/s).
    pub max_speed_mm_per_s: f32,
    /// Largest slider acceleration (mm/s^2).
    pub max_accel_mm_per_s2: f32,
    /// Largest |delta| of one move (mm).
    pub max_delta_mm: f32,
    /// Allowed stroke range per slider (mm, along base z, 0 at home). A destination
    /// outside it is refused unless it is closer to the range than the current stroke
    /// (moving a slider back from beyond a limit is what recovery is for).
    pub stroke_min_mm: [f32; LEGS],
    /// Upper end of the allowed stroke range (mm).
    pub stroke_max_mm: [f32; LEGS],
}

impl DirectStrokeLimits {
    /// The default speed, acceleration and delta with a symmetric stroke range
    /// `[-stroke_limit_mm, stroke_limit_mm]` on every slider.
    pub fn with_symmetric_range(stroke_limit_mm: f32) -> Self {
        Self {
            max_speed_mm_per_s: DEFAULT_DIRECT_SPEED_MM_PER_S,
            max_accel_mm_per_s2: DEFAULT_DIRECT_ACCEL_MM_PER_S2,
            max_delta_mm: DEFAULT_DIRECT_MAX_DELTA_MM,
            stroke_min_mm: [-stroke_limit_mm; LEGS],
            stroke_max_mm: [stroke_limit_mm; LEGS],
        }
    }
}

impl Default for DirectStrokeLimits {
    /// Defaults with the nominal flight stroke range ([`crate::nominal::STROKE_LIMIT_MM`]).
    fn default() -> Self {
        Self::with_symmetric_range(crate::nominal::STROKE_LIMIT_MM as f32)
    }
}

/// Why a direct-stroke move was refused. Stable numeric codes (family 0x06xx, from 0x0611).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StrokeMoveError {
    /// Leg index not in 0..6.
    BadLeg,
    /// A current stroke or the delta is NaN or infinite.
    NonFinite,
    /// A speed, acceleration or delta limit is not a positive number.
    BadLimits,
    /// |delta| exceeds `max_delta_mm`.
    DeltaTooLarge,
    /// The destination is outside the stroke range and no closer to it than now.
    OutsideStrokeRange,
    /// The move would last more than [`super::MAX_MOVE_CYCLES`] cycles.
    TooLong,
}

impl StrokeMoveError {
    /// Stable numeric code for telemetry.
    pub const fn code(&self) -> u16 {
        match self {
            StrokeMoveError::BadLeg => 0x0611,
            StrokeMoveError::NonFinite => 0x0612,
            StrokeMoveError::BadLimits => 0x0613,
            StrokeMoveError::DeltaTooLarge => 0x0614,
            StrokeMoveError::OutsideStrokeRange => 0x0615,
            StrokeMoveError::TooLong => 0x0616,
        }
    }
}

/// The commanded strokes at one control cycle of a direct-stroke move.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrokeSetpoint {
    /// Commanded strokes (mm, along base z, 0 at home), slider order.
    pub strokes_mm: [f32; LEGS],
    /// The slider is commanded to move at this cycle.
    pub moving: bool,
    /// The move is over (arrived, or at rest after a stop).
    pub done: bool,
}

/// A planned direct-stroke move of one slider.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrokeMove {
    start_mm: [f32; LEGS],
    leg: u8,
    delta_mm: f32,
    destination_mm: f32,
    ramp: Ramp,
}

/// A usable limit: finite and above zero. Not inlined: three limits are checked with
/// it (60 bytes of flash less than three inlined copies).
#[inline(never)]
fn positive(v: f32) -> bool {
    v.is_finite() && v > 0.0
}

/// How far `x` is outside `[lo, hi]` (mm), 0 inside.
fn excursion_mm(x: f32, lo: f32, hi: f32) -> f32 {
    (lo - x).max(x - hi).max(0.0)
}

impl StrokeMove {
    /// Plans moving slider `leg` (0-based) by `delta_mm` from `current_strokes_mm`, the
    /// other sliders holding. `delta_mm == 0` is an immediate arrival.
    pub fn plan(
        current_strokes_mm: &[f32; LEGS],
        leg: u8,
        delta_mm: f32,
        limits: &DirectStrokeLimits,
    ) -> Result<Self, StrokeMoveError> {
        let idx = usize::from(leg);
        let (Some(now), Some(lo), Some(hi)) = (
            current_strokes_mm.get(idx),
            limits.stroke_min_mm.get(idx),
            limits.stroke_max_mm.get(idx),
        ) else {
            return Err(StrokeMoveError::BadLeg);
        };
        if !current_strokes_mm.iter().all(|s| s.is_finite()) || !delta_mm.is_finite() {
            return Err(StrokeMoveError::NonFinite);
        }
        if !(positive(limits.max_speed_mm_per_s)
            && positive(limits.max_accel_mm_per_s2)
            && positive(limits.max_delta_mm)
            && lo.is_finite()
            && hi.is_finite())
        {
            return Err(StrokeMoveError::BadLimits);
        }
        if delta_mm.abs() > limits.max_delta_mm {
            return Err(StrokeMoveError::DeltaTooLarge);
        }
        let destination = *now + delta_mm;
        let out_after = excursion_mm(destination, *lo, *hi);
        if out_after > 0.0 && out_after >= excursion_mm(*now, *lo, *hi) {
            return Err(StrokeMoveError::OutsideStrokeRange);
        }
        let ramp = if delta_mm == 0.0 {
            Ramp::immediate()
        } else {
            let d = delta_mm.abs();
            Ramp::plan(
                DIRECT_LIMIT_USE_FRACTION * limits.max_speed_mm_per_s / d,
                DIRECT_LIMIT_USE_FRACTION * limits.max_accel_mm_per_s2 / d,
            )
            .map_err(|e| match e {
                RampError::BadLimits => StrokeMoveError::BadLimits,
                RampError::TooLong => StrokeMoveError::TooLong,
            })?
        };
        Ok(Self {
            start_mm: *current_strokes_mm,
            leg,
            delta_mm,
            destination_mm: destination,
            ramp,
        })
    }

    /// The commanded strokes at control cycle `cycle` (0 = start; cycle 0 commands the
    /// current strokes). Closed form in the cycle count.
    pub fn setpoint(&self, cycle: u32) -> StrokeSetpoint {
        let smp = self.ramp.sample(cycle);
        let mut strokes = self.start_mm;
        if let Some(s) = strokes.get_mut(usize::from(self.leg)) {
            *s = if smp.progress <= 0.5 {
                *s + smp.progress * self.delta_mm
            } else {
                self.destination_mm - smp.remaining * self.delta_mm
            };
        }
        StrokeSetpoint {
            strokes_mm: strokes,
            moving: smp.rate_per_cycle > 0.0,
            done: smp.at_rest,
        }
    }

    /// Decelerates from `cycle` on at the acceleration limit to rest (short of the
    /// destination). No effect once done or already stopping.
    pub fn stop(&mut self, cycle: u32) {
        self.ramp.stop(cycle);
    }

    /// The move is over at `cycle`.
    pub fn is_done(&self, cycle: u32) -> bool {
        cycle >= self.ramp.end_cycle()
    }

    /// First cycle at which the move is over.
    pub fn end_cycle(&self) -> u32 {
        self.ramp.end_cycle()
    }

    /// The moving slider (0-based).
    pub fn leg(&self) -> u8 {
        self.leg
    }

    /// Planned stroke change (mm).
    pub fn delta_mm(&self) -> f32 {
        self.delta_mm
    }

    /// The profile of the slider's progress.
    pub fn ramp(&self) -> &Ramp {
        &self.ramp
    }
}
