//! The drive train between a slider's drive and the slider itself (host simulation,
//! opt-in): microsteps, microstep nonlinearity, the lead screw's periodic error,
//! backlash, stiction and a settling transient.
//!
//! Without it ([`DriveTrainConfig::ideal`], the plant's default) the true slider is
//! exactly where the drive has moved it, as it always was. With it, per leg and in this
//! order, from the drive's position `x` (mm along base z, the bounded-speed position the
//! drive has reached toward its setpoint, less any travel lost to missed steps) to the
//! true slider `s` the encoder reads:
//!
//! 1. **Microsteps.** The motor stands on whole microsteps: `m = round(x / q) q`, `q` the
//!    microstep ([`LegDriveTrain::microstep_um`]).
//! 2. **Microstep nonlinearity.** A real rotor does not stand at the ideal microstep
//!    angle; the error repeats every full step: `m += a_ms sin(2 pi m / p_fs)`, `p_fs` one
//!    full step of travel ([`LegDriveTrain::full_step_um`]), zero at whole and half steps
//!    (home is taken at a whole step).
//! 3. **Lead error.** The screw's lead varies periodically with its angle, one period per
//!    screw turn: the nut is at `n = m + a_l sin(2 pi m / p_l + phi)`.
//! 4. **Backlash.** The nut drives the slider through a gap of total width `b`: the
//!    slider side `g` stays put while the nut is inside the gap and is pushed along
//!    when the nut reaches either side: `g = clamp(g, n - b/2, n + b/2)` (the "play"
//!    operator). A reversal loses exactly `b`. The gap starts centred.
//! 5. **Stiction.** The slider is held by static friction through the drive's finite
//!    stiffness: stuck at `e`, it breaks away only when the drive side has wound up
//!    more than the break-away deadband `d_s` from it (`|g - e| > d_s`); while sliding,
//!    kinetic friction keeps it `d_k` behind the drive side (`e = g -+ d_k`, `d_k <=
//!    d_s`); when the drive side stops or turns back, it sticks where it is. With
//!    `d_k = d_s` this is Coulomb friction with equal static and kinetic coefficients (a
//!    second play of half-width `d_s`); with `d_k = 0` the slider catches up with the
//!    drive once it has broken away (stick-slip).
//! 6. **Settling.** The slider mass on the finite stiffness of screw, nut and bearings
//!    reaches its equilibrium `e` with a first-order lag of time constant `tau`:
//!    `s += (e - s)(1 - exp(-dt / tau))`. (A first-order model: it gives the settling
//!    time and the lag during motion, `v tau`, not the ringing of a lightly damped
//!    mode; the friction of step 5 acts on the equilibrium, not on the moving mass.)
//!
//! Every parameter is per leg ([`DriveTrainConfig::legs`]); a parameter of zero removes
//! its stage exactly (the stage is skipped, no arithmetic is done), so the all-zero
//! configuration gives bit for bit the slider positions of the ideal plant (host test
//! `drive_train::ideal_configuration_is_bit_identical_to_the_plant_core`).
//!
//! The encoders read `s` (the plant adds their quantisation and noise); the drives
//! still report and hold their own position `x`: what the controller commands is the
//! drive, what it measures is the slider.

use crate::drivers::stepper::{StepperConfig, StepperPolarity};
use crate::kinematics::LEGS;
use crate::nominal;
use crate::units::{MM_PER_UM, NM_PER_MM, UM_PER_MM};

/// The slider drives' mechanics, the same constants the second board's step/direction
/// drives are configured with (`board::netduinoplus2::STEPPERS`; both take them from
/// [`crate::nominal`]): a 1 mm lead screw, 200-step motors, 64 microsteps, direct drive,
/// so 12,800 microsteps per mm (0.078 um) and 5 um per full step. The microstep, full step
/// and screw lead of [`LegDriveTrain::realistic`] are derived from it with the driver's
/// own arithmetic ([`StepperConfig::microsteps_per_mm`]). The pulse rate, travel limit
/// and pin levels are placeholders: the simulation uses none of them.
pub const DRIVE_STEPPERS: StepperConfig = StepperConfig {
    lead_screw_pitch_nm: nominal::DRIVE_LEAD_SCREW_PITCH_NM,
    full_steps_per_rev: nominal::DRIVE_FULL_STEPS_PER_REV,
    microsteps_per_step: nominal::DRIVE_MICROSTEPS_PER_STEP,
    gear_motor_revs: nominal::DRIVE_GEAR_MOTOR_REVS,
    gear_screw_revs: nominal::DRIVE_GEAR_SCREW_REVS,
    max_microsteps_per_cycle: 1,
    travel_limit_nm: 6_000_000,
    polarity: StepperPolarity {
        dir_high_is_positive: true,
        enable_active_high: false,
        fault_active_high: false,
    },
};

/// Default backlash (um, total lost motion on a reversal): "a few micrometres" (issue
/// 21), the axial play of a fine-pitch screw with a plain (not preloaded) nut after
/// running in; a preloaded or anti-backlash nut brings it to about 1 um, a worn one to
/// 10 um and more. Issue 21's combined configuration uses 3 um.
pub const DEFAULT_BACKLASH_UM: f64 = 3.0;
/// Default amplitude of the lead screw's periodic error (um; peak-to-peak twice this).
/// Sub-micrometre (issue 21): ISO 3408-3 allows a per-revolution variation of 3 um
/// peak-to-peak to a class-0 ground ball screw of 5 to 10 mm lead; a 1 mm fine-pitch
/// precision screw of the same angular quality has about a tenth of that travel per
/// turn. Issue 21's combined configuration uses 0.3 um.
pub const DEFAULT_LEAD_ERROR_UM: f64 = 0.3;
/// Default amplitude of the microstep nonlinearity (um): catalogue 1.8 degree hybrid
/// steppers give a stop-position accuracy of +-3 arcmin (+-0.05 degree, 2.8 % of a
/// full step), which on [`DRIVE_STEPPERS`]' 5 um full step is 0.14 um.
pub const DEFAULT_MICROSTEP_ERROR_UM: f64 = 0.14;
/// Default stiction break-away deadband (um): the drive-side wind-up static friction
/// holds before the slider moves. Issue 21's combined configuration uses 0.1 um (a
/// slider on preloaded rolling guides: friction of a few newtons against an axial
/// stiffness of some tens of N/um).
pub const DEFAULT_STICTION_UM: f64 = 0.1;
/// Default kinetic lag as a share of the break-away deadband: 1, Coulomb friction with
/// equal static and kinetic coefficients (the conservative case: the slider stops the
/// whole deadband short of the drive).
pub const DEFAULT_KINETIC_SHARE: f64 = 1.0;
/// Default settling time constant (s): stepper-driven slides settle in tens of
/// milliseconds after a move (to 1 % in 4.6 time constants, 23 ms for 5 ms); issue 21
/// measured a 20 ms settling lag.
pub const DEFAULT_SETTLING_TIME_CONSTANT_S: f64 = 0.005;
/// Default lead-error phases (rad) of the six screws: evenly spread (the screws are
/// mounted at unrelated angles; the spread keeps the six errors from adding up in
/// one pose direction by construction).
pub const DEFAULT_LEAD_ERROR_PHASE_RAD: [f64; LEGS] = {
    let step = core::f64::consts::PI / 3.0;
    [0.0, step, 2.0 * step, 3.0 * step, 4.0 * step, 5.0 * step]
};
/// A settling slider within this distance (mm, 1 pm) of its equilibrium is taken as
/// there (the exponential approach would otherwise never end).
pub const SETTLED_SNAP_MM: f64 = 1.0e-9;

/// One leg's drive train (module documentation for the model). Zero removes a stage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegDriveTrain {
    /// Microstep `q` (um of slider travel); 0: the motor stands anywhere.
    pub microstep_um: f64,
    /// Amplitude `a_ms` of the microstep nonlinearity (um); 0: none.
    pub microstep_error_um: f64,
    /// Period `p_fs` of the microstep nonlinearity: one full step (um of travel).
    pub full_step_um: f64,
    /// Amplitude `a_l` of the periodic lead error (um); 0: none.
    pub lead_error_um: f64,
    /// Period `p_l` of the lead error: one screw turn (mm of travel).
    pub lead_error_period_mm: f64,
    /// Phase `phi` of the lead error at zero stroke (rad).
    pub lead_error_phase_rad: f64,
    /// Backlash `b`: total lost motion on a reversal (um); 0: none.
    pub backlash_um: f64,
    /// Stiction break-away deadband `d_s` (um); 0: none.
    pub stiction_um: f64,
    /// Kinetic lag `d_k` while sliding (um), at most [`LegDriveTrain::stiction_um`].
    pub kinetic_lag_um: f64,
    /// Settling time constant `tau` (s); 0: the slider is at its equilibrium at once.
    pub settling_time_constant_s: f64,
}

impl LegDriveTrain {
    /// Every stage removed: the slider is where the drive is.
    pub const IDEAL: Self = Self {
        microstep_um: 0.0,
        microstep_error_um: 0.0,
        full_step_um: 0.0,
        lead_error_um: 0.0,
        lead_error_period_mm: 0.0,
        lead_error_phase_rad: 0.0,
        backlash_um: 0.0,
        stiction_um: 0.0,
        kinetic_lag_um: 0.0,
        settling_time_constant_s: 0.0,
    };

    /// The realistic defaults (constants of this module, each with its reasoning), leg
    /// `leg`'s screw at its [`DEFAULT_LEAD_ERROR_PHASE_RAD`].
    pub fn realistic(leg: usize) -> Self {
        Self {
            microstep_um: drive_microstep_um(),
            microstep_error_um: DEFAULT_MICROSTEP_ERROR_UM,
            full_step_um: drive_full_step_um(),
            lead_error_um: DEFAULT_LEAD_ERROR_UM,
            lead_error_period_mm: drive_screw_lead_mm(),
            lead_error_phase_rad: DEFAULT_LEAD_ERROR_PHASE_RAD
                .get(leg)
                .copied()
                .unwrap_or(0.0),
            backlash_um: DEFAULT_BACKLASH_UM,
            stiction_um: DEFAULT_STICTION_UM,
            kinetic_lag_um: DEFAULT_STICTION_UM * DEFAULT_KINETIC_SHARE,
            settling_time_constant_s: DEFAULT_SETTLING_TIME_CONSTANT_S,
        }
    }

    /// Why this leg's parameters cannot be simulated, if they cannot.
    fn check(&self) -> Result<(), DriveTrainParam> {
        let non_negative = [
            (self.microstep_um, DriveTrainParam::MicrostepUm),
            (self.microstep_error_um, DriveTrainParam::MicrostepErrorUm),
            (self.lead_error_um, DriveTrainParam::LeadErrorUm),
            (self.backlash_um, DriveTrainParam::BacklashUm),
            (self.stiction_um, DriveTrainParam::StictionUm),
            (self.kinetic_lag_um, DriveTrainParam::KineticLagUm),
            (
                self.settling_time_constant_s,
                DriveTrainParam::SettlingTimeConstantS,
            ),
        ];
        for (v, p) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(p);
            }
        }
        if !self.lead_error_phase_rad.is_finite() {
            return Err(DriveTrainParam::LeadErrorPhaseRad);
        }
        // A period is needed (and must be positive) only where its error is on.
        if self.microstep_error_um > 0.0
            && !(self.full_step_um.is_finite() && self.full_step_um > 0.0)
        {
            return Err(DriveTrainParam::FullStepUm);
        }
        if self.lead_error_um > 0.0
            && !(self.lead_error_period_mm.is_finite() && self.lead_error_period_mm > 0.0)
        {
            return Err(DriveTrainParam::LeadErrorPeriodMm);
        }
        if self.kinetic_lag_um > self.stiction_um {
            return Err(DriveTrainParam::KineticLagUm);
        }
        Ok(())
    }
}

/// The microstep of [`DRIVE_STEPPERS`] (um of slider travel): 0.078125 um (the fine
/// positioning's `motion::fine::MICROSTEP_MM`, from the same constants).
pub fn drive_microstep_um() -> f64 {
    UM_PER_MM / DRIVE_STEPPERS.microsteps_per_mm()
}

/// One full step of [`DRIVE_STEPPERS`] (um of slider travel): 5 um.
pub fn drive_full_step_um() -> f64 {
    drive_microstep_um() * f64::from(DRIVE_STEPPERS.microsteps_per_step)
}

/// Slider travel per screw turn of [`DRIVE_STEPPERS`] (mm): the lead, 1 mm.
pub fn drive_screw_lead_mm() -> f64 {
    f64::from(DRIVE_STEPPERS.lead_screw_pitch_nm) / NM_PER_MM
}

/// The six legs' drive trains.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveTrainConfig {
    /// Per leg (0-based).
    pub legs: [LegDriveTrain; LEGS],
}

impl Default for DriveTrainConfig {
    /// [`DriveTrainConfig::ideal`]: the plant's behaviour before drive trains existed.
    fn default() -> Self {
        Self::ideal()
    }
}

impl DriveTrainConfig {
    /// No drive train: each slider is exactly where its drive is.
    pub const fn ideal() -> Self {
        Self::uniform(LegDriveTrain::IDEAL)
    }

    /// The same drive train on every leg.
    pub const fn uniform(leg: LegDriveTrain) -> Self {
        Self { legs: [leg; LEGS] }
    }

    /// Every leg with its realistic defaults ([`LegDriveTrain::realistic`]).
    pub fn realistic() -> Self {
        Self {
            legs: core::array::from_fn(LegDriveTrain::realistic),
        }
    }

    /// Whether these parameters can be simulated: every amplitude, deadband and time
    /// constant finite and not negative, a positive period under every periodic error,
    /// the kinetic lag at most the break-away deadband.
    pub fn check(&self) -> Result<(), DriveTrainError> {
        for (leg, l) in self.legs.iter().enumerate() {
            l.check().map_err(|param| DriveTrainError { leg, param })?;
        }
        Ok(())
    }
}

/// Which parameter of [`LegDriveTrain`] is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriveTrainParam {
    /// [`LegDriveTrain::microstep_um`].
    MicrostepUm,
    /// [`LegDriveTrain::microstep_error_um`].
    MicrostepErrorUm,
    /// [`LegDriveTrain::full_step_um`].
    FullStepUm,
    /// [`LegDriveTrain::lead_error_um`].
    LeadErrorUm,
    /// [`LegDriveTrain::lead_error_period_mm`].
    LeadErrorPeriodMm,
    /// [`LegDriveTrain::lead_error_phase_rad`].
    LeadErrorPhaseRad,
    /// [`LegDriveTrain::backlash_um`].
    BacklashUm,
    /// [`LegDriveTrain::stiction_um`].
    StictionUm,
    /// [`LegDriveTrain::kinetic_lag_um`] (negative, not finite, or above the
    /// break-away deadband).
    KineticLagUm,
    /// [`LegDriveTrain::settling_time_constant_s`].
    SettlingTimeConstantS,
}

/// A drive-train configuration refused by [`DriveTrainConfig::check`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DriveTrainError {
    /// 0-based leg.
    pub leg: usize,
    /// The parameter.
    pub param: DriveTrainParam,
}

/// Where the stiction stage is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Friction {
    /// Held by static friction.
    Stuck,
    /// Sliding toward larger strokes.
    SlidingUp,
    /// Sliding toward smaller strokes.
    SlidingDown,
}

/// One leg's state.
#[derive(Clone, Copy, Debug, PartialEq)]
struct LegState {
    /// Slider side of the backlash gap `g` (mm).
    gap_mm: f64,
    /// Friction state.
    friction: Friction,
    /// The slider's equilibrium `e` (mm).
    equilibrium_mm: f64,
    /// The true slider `s` (mm).
    slider_mm: f64,
}

/// The six drive trains' state: feed it the drives' positions with
/// [`DriveTrain::update`], read the true sliders with [`DriveTrain::sliders_mm`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveTrain {
    cfg: DriveTrainConfig,
    legs: [LegState; LEGS],
}

impl DriveTrain {
    /// Drive trains at rest with the drives at `drive_mm` (mm): the backlash gaps
    /// centred, the sliders stuck at their equilibria. Refuses parameters
    /// [`DriveTrainConfig::check`] refuses.
    pub fn new(cfg: DriveTrainConfig, drive_mm: &[f64; LEGS]) -> Result<Self, DriveTrainError> {
        cfg.check()?;
        let mut legs = [LegState {
            gap_mm: 0.0,
            friction: Friction::Stuck,
            equilibrium_mm: 0.0,
            slider_mm: 0.0,
        }; LEGS];
        for ((st, c), x) in legs.iter_mut().zip(cfg.legs.iter()).zip(drive_mm.iter()) {
            let n = nut_mm(c, *x);
            *st = LegState {
                gap_mm: n,
                friction: Friction::Stuck,
                equilibrium_mm: n,
                slider_mm: n,
            };
        }
        Ok(Self { cfg, legs })
    }

    /// The configuration.
    pub fn config(&self) -> &DriveTrainConfig {
        &self.cfg
    }

    /// Advances by `dt_s` with the drives now at `drive_mm` (mm): the quasi-static
    /// stages (microsteps to stiction) follow at once, the slider settles for `dt_s`
    /// (0: the equilibria move, the sliders do not yet).
    pub fn update(&mut self, drive_mm: &[f64; LEGS], dt_s: f64) {
        let dt_s = dt_s.max(0.0);
        for ((st, c), x) in self
            .legs
            .iter_mut()
            .zip(self.cfg.legs.iter())
            .zip(drive_mm.iter())
        {
            let n = nut_mm(c, *x);
            // Backlash: the play operator.
            st.gap_mm = if c.backlash_um > 0.0 {
                let half_mm = 0.5 * c.backlash_um * MM_PER_UM;
                st.gap_mm.clamp(n - half_mm, n + half_mm)
            } else {
                n
            };
            let g = st.gap_mm;
            // Stiction.
            if c.stiction_um > 0.0 {
                let ds_mm = c.stiction_um * MM_PER_UM;
                let dk_mm = c.kinetic_lag_um * MM_PER_UM;
                let e = st.equilibrium_mm;
                (st.friction, st.equilibrium_mm) = if g - e > ds_mm
                    || (st.friction == Friction::SlidingUp && g - e > dk_mm)
                {
                    (Friction::SlidingUp, g - dk_mm)
                } else if e - g > ds_mm || (st.friction == Friction::SlidingDown && e - g > dk_mm) {
                    (Friction::SlidingDown, g + dk_mm)
                } else {
                    (Friction::Stuck, e)
                };
            } else {
                st.equilibrium_mm = g;
            }
            // Settling.
            let e = st.equilibrium_mm;
            st.slider_mm = if c.settling_time_constant_s > 0.0 {
                let s = st.slider_mm
                    + (e - st.slider_mm) * -(-dt_s / c.settling_time_constant_s).exp_m1();
                if (e - s).abs() <= SETTLED_SNAP_MM {
                    e
                } else {
                    s
                }
            } else {
                e
            };
        }
    }

    /// The true sliders (mm along base z).
    pub fn sliders_mm(&self) -> [f64; LEGS] {
        self.legs.map(|l| l.slider_mm)
    }

    /// Whether every slider has reached its equilibrium (within
    /// [`SETTLED_SNAP_MM`]: it is then exactly there).
    pub fn at_rest(&self) -> bool {
        self.legs.iter().all(|l| l.slider_mm == l.equilibrium_mm)
    }
}

/// Stages 1 to 3 (module documentation): the nut's position (mm) for the drive at
/// `x_mm`.
fn nut_mm(c: &LegDriveTrain, x_mm: f64) -> f64 {
    let mut m = x_mm;
    if c.microstep_um > 0.0 {
        let q_mm = c.microstep_um * MM_PER_UM;
        m = (m / q_mm).round() * q_mm;
    }
    if c.microstep_error_um > 0.0 {
        let tau = core::f64::consts::TAU;
        m += c.microstep_error_um * MM_PER_UM * (tau * m / (c.full_step_um * MM_PER_UM)).sin();
    }
    if c.lead_error_um > 0.0 {
        let tau = core::f64::consts::TAU;
        m += c.lead_error_um
            * MM_PER_UM
            * (tau * m / c.lead_error_period_mm + c.lead_error_phase_rad).sin();
    }
    m
}
