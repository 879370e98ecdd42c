//! One-dimensional trapezoidal motion profile in whole control cycles.
//!
//! A [`Ramp`] moves a normalised path parameter `s` from 0 to 1 (dimensionless) with
//! bounded rate `ds/dt` and bounded acceleration `d2s/dt2`. Its three phases (accelerate,
//! cruise, decelerate) last a whole number of control cycles, so every setpoint is a
//! closed-form function of the integer cycle count: nothing is accumulated, and a move of
//! millions of cycles is as exact at its end as at its start.
//!
//! With `n_a` acceleration cycles, `n_c` cruise cycles and `N = 2 n_a + n_c`, the peak
//! rate is `V = 1 / (n_a + n_c)` per cycle and the acceleration `A = V / n_a` per cycle^2:
//!
//! ```text
//! k <  n_a          s = A k^2 / 2                 (from start)
//! n_a <= k < n_a+n_c s = V (k - n_a/2)             r = 1 - s = V ((N - k) - n_a/2)
//! n_a+n_c <= k < N   r = A (N - k)^2 / 2           (remaining, to the end)
//! k >= N             s = 1, r = 0
//! ```
//!
//! `n_a = ceil(min(V_max / A_max, sqrt(1 / A_max)))` and
//! `n_c = ceil(max(0, 1 / V_max - n_a))` (limits per cycle) guarantee `V <= V_max` and
//! `A <= A_max`: rounding up only lengthens the move.
//!
//! A stop ([`Ramp::stop`]) replaces the rest of the profile by a deceleration at `A_max`
//! from the current rate to rest; the rest point lies before the original end because the
//! original profile decelerates no harder (`A <= A_max`).

use crate::kinematics::Real;

/// Control period (s): the controller calls the trajectory once per cycle.
pub use crate::timing::CYCLE_S;

/// Longest move (control cycles): `2^24`, the largest count an `f32` holds exactly
/// (4.6 h at 1 kHz). Longer plans are refused.
pub const MAX_MOVE_CYCLES: u32 = 1 << 24;

/// Why a profile could not be planned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RampError {
    /// A rate or acceleration limit is not positive (or NaN).
    BadLimits,
    /// The move would last more than [`MAX_MOVE_CYCLES`].
    TooLong,
}

/// The deceleration that replaced the rest of a profile after [`Ramp::stop`].
#[derive(Clone, Copy, Debug, PartialEq)]
struct StopRamp {
    /// First cycle of the stop ramp (its sample equals the original profile's).
    from_cycle: u32,
    /// Progress `s` at `from_cycle`.
    progress_from: f32,
    /// Remaining `1 - s` at `from_cycle`.
    remaining_from: f32,
    /// Rate at `from_cycle` (per cycle).
    rate_from_per_cycle: f32,
    /// Deceleration (per cycle^2).
    decel_per_cycle2: f32,
    /// Time to rest (cycles, fractional).
    duration_cycles: f32,
    /// First cycle at rest.
    end_cycle: u32,
}

/// A sample of a [`Ramp`] at one control cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RampSample {
    /// Path parameter `s` in [0, 1] (dimensionless), accurate near 0.
    pub progress: f32,
    /// `1 - s`, computed directly where that is more accurate (near the end).
    pub remaining: f32,
    /// `ds/dt` of the continuous profile at this cycle (per cycle), >= 0.
    pub rate_per_cycle: f32,
    /// The profile is at rest for good (arrived, or stopped).
    pub at_rest: bool,
}

/// Trapezoidal profile of the path parameter over whole control cycles (see the module
/// documentation for the formulas).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ramp {
    accel_cycles: u32,
    cruise_cycles: u32,
    end_cycle: u32,
    peak_rate_per_cycle: f32,
    accel_per_cycle2: f32,
    stop_decel_per_cycle2: f32,
    stop: Option<StopRamp>,
}

/// `ceil(x)` as a cycle count; `None` if `x` is NaN or beyond [`MAX_MOVE_CYCLES`].
fn ceil_cycles(x: f32) -> Option<u32> {
    // `!(x <= max)` also rejects NaN.
    if !(x <= MAX_MOVE_CYCLES as f32) {
        return None;
    }
    if x <= 0.0 {
        return Some(0);
    }
    // Exact: x < 2^24, and `as` truncates toward zero.
    let t = x as u32;
    Some(if (t as f32) < x {
        t.saturating_add(1)
    } else {
        t
    })
}

impl Ramp {
    /// The profile of a zero-length move: at rest at `s = 1` from cycle 0.
    #[inline(never)]
    pub const fn immediate() -> Self {
        Self {
            accel_cycles: 0,
            cruise_cycles: 0,
            end_cycle: 0,
            peak_rate_per_cycle: 0.0,
            accel_per_cycle2: 0.0,
            stop_decel_per_cycle2: 0.0,
            stop: None,
        }
    }

    /// Plans `s: 0 -> 1` with `ds/dt <= max_rate_per_s` (1/s) and
    /// `|d2s/dt2| <= max_accel_per_s2` (1/s^2). `+inf` is accepted (the move then takes
    /// the fewest cycles, at least 2); zero, negative or NaN limits are refused.
    pub fn plan(max_rate_per_s: f32, max_accel_per_s2: f32) -> Result<Self, RampError> {
        if !(max_rate_per_s > 0.0) || !(max_accel_per_s2 > 0.0) {
            return Err(RampError::BadLimits);
        }
        // Per cycle; a rate above 1 per cycle (or an acceleration above 1 per cycle^2)
        // gains nothing, the move takes at least one cycle per phase.
        let v_max = (max_rate_per_s * CYCLE_S).min(1.0);
        let a_max = (max_accel_per_s2 * CYCLE_S * CYCLE_S).min(1.0);
        if !(v_max > 0.0) || !(a_max > 0.0) {
            // Underflow: far slower than MAX_MOVE_CYCLES allows.
            return Err(RampError::TooLong);
        }
        let t_accel = (v_max / a_max).min(Real::sqrt(1.0 / a_max));
        let accel_cycles = ceil_cycles(t_accel).ok_or(RampError::TooLong)?.max(1);
        let cruise_cycles =
            ceil_cycles(1.0 / v_max - accel_cycles as f32).ok_or(RampError::TooLong)?;
        let moving_cycles = accel_cycles
            .checked_add(cruise_cycles)
            .ok_or(RampError::TooLong)?;
        let end_cycle = moving_cycles
            .checked_add(accel_cycles)
            .filter(|n| *n <= MAX_MOVE_CYCLES)
            .ok_or(RampError::TooLong)?;
        let peak = 1.0 / moving_cycles as f32;
        let accel = peak / accel_cycles as f32;
        Ok(Self {
            accel_cycles,
            cruise_cycles,
            end_cycle,
            peak_rate_per_cycle: peak,
            accel_per_cycle2: accel,
            // A stop may use the full allowed deceleration, never less than the profile's.
            stop_decel_per_cycle2: a_max.max(accel),
            stop: None,
        })
    }

    /// First cycle at which the profile is at rest for good (the end of the stop ramp
    /// after [`Ramp::stop`]).
    pub fn end_cycle(&self) -> u32 {
        match &self.stop {
            Some(st) => st.end_cycle,
            None => self.end_cycle,
        }
    }

    /// Cycles of the acceleration phase (equal to the deceleration phase).
    pub fn accel_cycles(&self) -> u32 {
        self.accel_cycles
    }

    /// Cycles of the cruise phase.
    pub fn cruise_cycles(&self) -> u32 {
        self.cruise_cycles
    }

    /// Peak rate of the planned profile (per cycle).
    pub fn peak_rate_per_cycle(&self) -> f32 {
        self.peak_rate_per_cycle
    }

    /// Acceleration of the planned profile (per cycle^2).
    pub fn accel_per_cycle2(&self) -> f32 {
        self.accel_per_cycle2
    }

    /// Deceleration of a stop (per cycle^2): the largest the limits allow.
    pub fn stop_decel_per_cycle2(&self) -> f32 {
        self.stop_decel_per_cycle2
    }

    /// The cycle at which a stop was requested, if one was.
    pub fn stopped_at(&self) -> Option<u32> {
        self.stop.map(|s| s.from_cycle)
    }

    /// The profile at control cycle `cycle` (0 = start of the move). About 10 f32
    /// operations; no loop, no accumulation.
    pub fn sample(&self, cycle: u32) -> RampSample {
        if let Some(st) = &self.stop {
            if cycle >= st.from_cycle {
                return st.sample(cycle);
            }
        }
        if cycle >= self.end_cycle {
            return RampSample {
                progress: 1.0,
                remaining: 0.0,
                rate_per_cycle: 0.0,
                at_rest: true,
            };
        }
        let a = self.accel_per_cycle2;
        let v = self.peak_rate_per_cycle;
        let half_accel_cycles = 0.5 * self.accel_cycles as f32;
        let to_end = self.end_cycle.saturating_sub(cycle) as f32;
        if cycle < self.accel_cycles {
            let k = cycle as f32;
            let s = 0.5 * a * k * k;
            RampSample {
                progress: s,
                remaining: 1.0 - s,
                rate_per_cycle: a * k,
                at_rest: false,
            }
        } else if cycle < self.accel_cycles.saturating_add(self.cruise_cycles) {
            RampSample {
                progress: v * (cycle as f32 - half_accel_cycles),
                remaining: v * (to_end - half_accel_cycles),
                rate_per_cycle: v,
                at_rest: false,
            }
        } else {
            let r = 0.5 * a * to_end * to_end;
            RampSample {
                progress: 1.0 - r,
                remaining: r,
                rate_per_cycle: a * to_end,
                at_rest: false,
            }
        }
    }

    /// Replaces the rest of the profile, from `cycle` on, by a deceleration at
    /// [`Ramp::stop_decel_per_cycle2`] to rest on the same path. The sample at `cycle` is
    /// unchanged (position and rate are continuous). No effect once at rest or when a stop
    /// is already under way.
    pub fn stop(&mut self, cycle: u32) {
        if self.stop.is_some() || cycle >= self.end_cycle {
            return;
        }
        let now = self.sample(cycle);
        let decel = self.stop_decel_per_cycle2;
        let (duration, end) = if now.rate_per_cycle > 0.0 && decel > 0.0 {
            let d = now.rate_per_cycle / decel;
            let n = ceil_cycles(d).unwrap_or(self.end_cycle);
            (d, cycle.saturating_add(n))
        } else {
            (0.0, cycle)
        };
        self.stop = Some(StopRamp {
            from_cycle: cycle,
            progress_from: now.progress,
            remaining_from: now.remaining,
            rate_from_per_cycle: now.rate_per_cycle,
            decel_per_cycle2: decel,
            duration_cycles: duration,
            end_cycle: end,
        });
    }
}

impl StopRamp {
    fn sample(&self, cycle: u32) -> RampSample {
        let at_rest = cycle >= self.end_cycle;
        let t = if at_rest {
            self.duration_cycles
        } else {
            (cycle.saturating_sub(self.from_cycle) as f32).min(self.duration_cycles)
        };
        let moved = t * (self.rate_from_per_cycle - 0.5 * self.decel_per_cycle2 * t);
        RampSample {
            progress: self.progress_from + moved,
            remaining: self.remaining_from - moved,
            rate_per_cycle: (self.rate_from_per_cycle - self.decel_per_cycle2 * t).max(0.0),
            at_rest,
        }
    }
}
