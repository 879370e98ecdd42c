//! Thermal compensation's stepping (issue 22): how the applied stroke offsets follow
//! the thermal model, in bounded steps (the design: docs/decisions.md, "Thermal
//! compensation (issue 22)", "Bounded steps" and "Exposure hold").
//!
//! # Frame
//! The offsets are per leg, in mm along each slider (base z), at the geometry of the
//! table's reference temperature: [`super::stroke_offsets_mm`]'s output, the change of
//! each stroke that keeps a pose where the reference geometry puts it. The controller
//! will subtract the **applied** offset ([`Compensation::applied_mm`]) from every
//! encoder reading and add it to every drive command, so that IK, FK, the path, fine
//! positioning and the supervision keep reasoning at the reference temperature.
//!
//! # The rule ([`Compensation::step`], once per [`STEP_PERIOD_CYCLES`])
//! * **Enabled, at rest, no exposure hold, sensors good:** the applied offset moves
//!   toward the target (the model's offsets at the held pose) by at most
//!   [`CompensationParams::max_step_mm`] on any leg, every leg's difference scaled by
//!   the same factor (the step keeps the direction of the whole difference), and only
//!   when some leg differs by at least [`CompensationParams::min_step_mm`] (the dead
//!   band: no step, so no fine positioning, for what the sensors' noise moves). A step
//!   is reported ([`StepOutcome::Stepped`]): the controller then runs a fine
//!   positioning on the held setpoint.
//! * **Disabled:** the applied offset ramps to zero by the same bounded steps, at rest
//!   and outside a hold only, down to exactly zero (no dead band: zero is no
//!   measurement, and disabled means the reference geometry exactly). The sensors are
//!   not used then.
//! * **A used sensor faults** (`sensors_ok` false, or no target, or a target that is
//!   not finite) while enabled: the applied offset is frozen at its last value, and
//!   [`StepOutcome::Frozen`] is reported once (the warning event), again only after a
//!   recovery and a new fault (or a disable and an enable). The fault is tracked on
//!   every call, during moves and holds too (freezing changes no offset). Recovery
//!   resumes the steps from the frozen value: never a jump.
//! * **During a move (not at rest) or an exposure hold:** the applied offset does not
//!   change.
//! * **Parameters out of range** ([`CompensationParams::validate`]): nothing changes.
//!
//! So no sensor loss, no enable or disable and no target change moves the mirror by
//! more than one step per period (host tests `thermal_compensation`).
//!
//! The controller calls it once a second (`Controller::step_compensation`), with the
//! ST\[20\] parameters 0x0060..0x0062 and the exposure hold; a step's fine
//! positioning creeps onto the held setpoint (`motion::fine`).

use crate::kinematics::geometry::LEGS;
use crate::timing::CONTROL_RATE_HZ;
use crate::units::MM_PER_UM;

/// Control cycles between two calls of [`Compensation::step`]: one second. The
/// temperatures change by kelvins over an orbit (their means are refreshed every
/// 1.6 s: [`super::MEAN_SAMPLES`] readings at 10 Hz), and each step costs a fine
/// positioning, so a step per second follows the model with steps of a fraction of a
/// micrometre without keeping the mechanism busy.
pub const STEP_PERIOD_CYCLES: u32 = CONTROL_RATE_HZ;

/// Smallest accepted maximum step (mm): 0.05 um, half an encoder count (0.1 um), about
/// the smallest change one fine positioning can make (a drive microstep is 0.078 um);
/// at a step per second it still follows 5 um in under two minutes.
pub const MAX_STEP_LOWEST_MM: f32 = (0.05 * MM_PER_UM) as f32;
/// Largest accepted maximum step (mm): 5 um, a quarter of the reach of fine
/// positioning's corrections (`motion::fine::MAX_CORRECTION_MM`, 20 um), so that a step
/// is always a small correction of the held setpoint.
pub const MAX_STEP_HIGHEST_MM: f32 = (5.0 * MM_PER_UM) as f32;
/// Smallest accepted minimum step (mm): 0.005 um, about half the offsets' noise from
/// the sensors' means (5 mK times micrometres per kelvin); the highest is the maximum
/// step in force.
pub const MIN_STEP_LOWEST_MM: f32 = (0.005 * MM_PER_UM) as f32;
/// Default maximum step (mm): 0.5 um, five encoder counts: a step per second follows
/// 0.2 K/s at 2.5 um/K, far faster than the mechanism's temperatures change, and a
/// step is within what one fine positioning corrects.
pub const DEFAULT_MAX_STEP_MM: f32 = (0.5 * MM_PER_UM) as f32;
/// Default minimum step (mm): 0.05 um, half an encoder count and below a drive
/// microstep (0.078 um), five times the offsets' noise from the sensors' means (about
/// 0.01 um), so the mean's noise alone does not start a step.
pub const DEFAULT_MIN_STEP_MM: f32 = (0.05 * MM_PER_UM) as f32;

/// The stepping's parameters (to become ST\[20\] parameters).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompensationParams {
    /// Largest change of a leg's applied offset per step (mm),
    /// [`MAX_STEP_LOWEST_MM`]..=[`MAX_STEP_HIGHEST_MM`].
    pub max_step_mm: f32,
    /// A step is made only when some leg differs from its target by at least this
    /// (mm), [`MIN_STEP_LOWEST_MM`]..=`max_step_mm`.
    pub min_step_mm: f32,
}

/// Why stepping parameters are refused. Stable codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompensationParamError {
    /// The maximum step is outside its range, or not finite.
    MaxStep,
    /// The minimum step is outside its range (above the maximum step included), or not
    /// finite.
    MinStep,
}

impl CompensationParamError {
    /// Stable code.
    pub const fn code(self) -> u8 {
        match self {
            CompensationParamError::MaxStep => 1,
            CompensationParamError::MinStep => 2,
        }
    }
}

impl CompensationParams {
    /// The defaults.
    pub const DEFAULT: CompensationParams = CompensationParams {
        max_step_mm: DEFAULT_MAX_STEP_MM,
        min_step_mm: DEFAULT_MIN_STEP_MM,
    };

    /// Checks both ranges (NaN is out of every range); the maximum step first.
    pub fn validate(&self) -> Result<(), CompensationParamError> {
        if !(self.max_step_mm >= MAX_STEP_LOWEST_MM && self.max_step_mm <= MAX_STEP_HIGHEST_MM) {
            return Err(CompensationParamError::MaxStep);
        }
        if !(self.min_step_mm >= MIN_STEP_LOWEST_MM && self.min_step_mm <= self.max_step_mm) {
            return Err(CompensationParamError::MinStep);
        }
        Ok(())
    }
}

impl Default for CompensationParams {
    fn default() -> Self {
        CompensationParams::DEFAULT
    }
}

/// What one [`Compensation::step`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepOutcome {
    /// The applied offset moved by one step: run a fine positioning.
    Stepped,
    /// No change: every leg is within the minimum step of its target (or, disabled,
    /// the offset is zero).
    Settled,
    /// No change: a move or an exposure hold is in progress.
    Held,
    /// No change: a used sensor has just faulted; the offset is frozen (the warning, once
    /// per fault).
    Frozen,
    /// No change: the offset is still frozen (already reported).
    StillFrozen,
    /// No change: the parameters are out of range.
    InvalidParams,
}

/// The thermal compensation's state. Its default (disabled, zero offsets) is all zero
/// bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Compensation {
    /// The offset per leg in force (mm): subtracted from the encoder readings, added to
    /// the drive commands.
    applied_mm: [f32; LEGS],
    /// Compensation enabled (else ramping to, or at, zero).
    enabled: bool,
    /// Enabled and a used sensor faulted: the offset is held.
    frozen: bool,
    /// The exposure hold at the last step.
    hold: bool,
}

impl Compensation {
    /// The offset per leg in force (mm).
    pub fn applied_mm(&self) -> [f32; LEGS] {
        self.applied_mm
    }

    /// Compensation enabled.
    pub fn is_enabled(&self) -> bool {
        self.enabled
    }

    /// The offset is frozen by a sensor fault.
    pub fn is_frozen(&self) -> bool {
        self.frozen
    }

    /// The exposure hold was active at the last step.
    pub fn on_hold(&self) -> bool {
        self.hold
    }

    /// Enables or disables the compensation; the offset itself changes only by the
    /// steps. Disabling ends a freeze (the offset ramps to zero, which needs no sensor),
    /// so enabling with a sensor still faulty freezes and reports again.
    pub fn set_enabled(&mut self, enabled: bool) {
        if !enabled {
            self.frozen = false;
        }
        self.enabled = enabled;
    }

    /// One period's step (module documentation): `at_rest` (no move in progress),
    /// `target_mm` (the model's offsets at the held pose, mm per leg; `None` when they
    /// cannot be computed), `sensors_ok` (every sensor the model uses is good), `hold`
    /// (the exposure hold).
    pub fn step(
        &mut self,
        at_rest: bool,
        target_mm: Option<[f32; LEGS]>,
        sensors_ok: bool,
        hold: bool,
        params: &CompensationParams,
    ) -> StepOutcome {
        if params.validate().is_err() {
            return StepOutcome::InvalidParams;
        }
        self.hold = hold;
        let still = !at_rest || hold;
        if !self.enabled {
            if still {
                return StepOutcome::Held;
            }
            return self.toward(&[0.0; LEGS], 0.0, params.max_step_mm);
        }
        let target = match target_mm {
            Some(t) if sensors_ok && t.iter().all(|x| x.is_finite()) => t,
            _ => {
                let first = !self.frozen;
                self.frozen = true;
                return if first {
                    StepOutcome::Frozen
                } else {
                    StepOutcome::StillFrozen
                };
            }
        };
        self.frozen = false;
        if still {
            return StepOutcome::Held;
        }
        self.toward(&target, params.min_step_mm, params.max_step_mm)
    }

    /// Moves the applied offset toward `goal_mm` by at most `max_mm` on any leg, every
    /// leg scaled alike, when some leg differs by at least `dead_mm` (and by anything).
    fn toward(&mut self, goal_mm: &[f32; LEGS], dead_mm: f32, max_mm: f32) -> StepOutcome {
        let mut worst = 0.0f32;
        for (a, g) in self.applied_mm.iter().zip(goal_mm.iter()) {
            worst = worst.max((g - a).abs());
        }
        if !(worst > 0.0 && worst >= dead_mm) {
            return StepOutcome::Settled;
        }
        if worst <= max_mm {
            // The last step lands on the goal exactly.
            self.applied_mm = *goal_mm;
        } else {
            let scale = max_mm / worst;
            for (a, g) in self.applied_mm.iter_mut().zip(goal_mm.iter()) {
                *a += (g - *a) * scale;
            }
        }
        StepOutcome::Stepped
    }
}
