//! Step/direction stepper drives for the six sliders.
//!
//! Each cycle [`SliderDrives::command_strokes_mm`] turns the stroke setpoint of every
//! leg into a whole number of microsteps and a direction, and hands the pulses to a
//! [`StepPulses`] generator (the board's timer) that spreads them over the cycle.
//!
//! ## No drift, by construction
//!
//! The driver keeps the **absolute** position it has issued, in integer microsteps.
//! A setpoint becomes the microstep nearest to it, `round(s_nm * N / D)` with the exact
//! integers `N = full steps per motor revolution * microsteps per step * motor
//! revolutions` and `D = lead-screw pitch (nm) * screw revolutions` of the gear; the
//! cycle's pulses are the difference to the issued position. The sub-step remainder is
//! therefore never rounded away cycle after cycle: after any sequence of setpoints the
//! issued position is the microstep nearest to the last one (while no per-cycle rate
//! limit or direction inhibit held it back). Pulses a generator could not send by the
//! next command ([`StepPulses::stop`] returns them) are subtracted again, so the issued
//! position counts pulses actually sent.
//!
//! ## Pins
//!
//! Enable and direction are `OutputPin`s, the drive's fault output an `InputPin`; the
//! active levels are configuration ([`StepperPolarity`]). A pin that cannot be read or
//! written is a drive fault of its leg.
//!
//! ## Safety behaviour
//!
//! * Until [`IssuedStrokes::align_issued_mm`] has told the driver where the sliders are
//!   (the encoder reading), every motion command is refused: an open-loop drive does
//!   not know its position at power-on.
//! * A fault input active on any leg: the command is refused for all legs, every pulse
//!   train is stopped (the sliders hold), and the first faulted leg is reported, as the
//!   simulated plant does.
//! * [`StepDirDrives::inhibit`] blocks a direction per leg (the end-of-travel switches):
//!   a train already running in a blocked direction is stopped at once, and no pulse in
//!   that direction is issued until the block is lifted; moves away stay possible.
//! * A non-finite setpoint leaves its leg where it is; a setpoint beyond
//!   [`StepperConfig::travel_limit_nm`] is clamped to it; at most
//!   [`StepperConfig::max_microsteps_per_cycle`] pulses per leg and cycle.

use crate::units::{NM_PER_MM, NM_PER_MM_F32, NM_PER_MM_I64};
use embedded_hal::digital::{InputPin, OutputPin};

use crate::drivers::biss::round_div;
use crate::hw::{DriveError, IssuedStrokes, SliderDrives, EVERY_LEG};
use crate::kinematics::LEGS;

/// Finest drive accepted: microsteps per mm of stroke (1 pm per microstep).
pub const MAX_MICROSTEPS_PER_MM: i64 = 1_000_000_000;
/// Stored mantissa bits of an f32.
const F32_MANTISSA_BITS: u32 = 23;
/// Mask of the stored mantissa.
const F32_MANTISSA_MASK: u32 = (1 << F32_MANTISSA_BITS) - 1;
/// The implicit leading mantissa bit of a normal f32.
const F32_IMPLICIT_BIT: u32 = 1 << F32_MANTISSA_BITS;
/// Exponent bias of an f32 with the mantissa taken as an integer (127 + 23).
const F32_EXP_BIAS: i32 = 150;
/// Smallest exponent converted exactly (|stroke| >= 2^-40 mm); below, the stroke is
/// less than half a microstep at [`MAX_MICROSTEPS_PER_MM`]. Keeps `D * 2^64` in i128.
const MIN_EXACT_EXP: i32 = -64;

/// A step-pulse generator for one drive (embedded-hal has no pulse-train trait). The
/// board implements it with a timer.
///
/// Contract: the driver calls [`StepPulses::stop`] and then at most one
/// [`StepPulses::start`] per control cycle, always after setting the direction pin;
/// the implementation's first step edge must come no earlier than the drive's
/// direction set-up time after `start`, and a train of `count` pulses must fit in one
/// control cycle at the configured maximum ([`StepperConfig::max_microsteps_per_cycle`]).
pub trait StepPulses {
    /// Why a train could not be started.
    type Error;
    /// Starts a train of `count` (> 0) step pulses, spread over the coming cycle.
    fn start(&mut self, count: u32) -> Result<(), Self::Error>;
    /// Stops the current train at once and returns how many of its pulses were not
    /// sent (0 when it had completed, or none was started).
    fn stop(&mut self) -> u32;
}

/// Active levels of the drive's pins.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepperPolarity {
    /// The direction pin is high for motion towards larger strokes.
    pub dir_high_is_positive: bool,
    /// The enable pin is high to energise the drive (false: active-low ENABLE, as on
    /// most step/direction drivers).
    pub enable_active_high: bool,
    /// The fault output is high when faulted (false: active-low open-drain FAULT).
    pub fault_active_high: bool,
}

/// Mechanics and limits of the six (identical) slider drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepperConfig {
    /// Slider travel per lead-screw revolution (nm).
    pub lead_screw_pitch_nm: u32,
    /// Full steps per motor revolution (200 for a 1.8 degree motor).
    pub full_steps_per_rev: u16,
    /// Microsteps per full step set on the drive.
    pub microsteps_per_step: u16,
    /// Gear ratio: this many motor revolutions ...
    pub gear_motor_revs: u16,
    /// ... turn the lead screw this many revolutions.
    pub gear_screw_revs: u16,
    /// Most pulses issued per leg and control cycle (the generator's and the motor's
    /// limit; the motion planner stays well below it).
    pub max_microsteps_per_cycle: u32,
    /// Largest |stroke| ever commanded (nm); setpoints beyond are clamped to it.
    pub travel_limit_nm: u32,
    /// Pin levels.
    pub polarity: StepperPolarity,
}

/// Why a configuration was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepperConfigError {
    /// A zero pitch, step count, microstep count, gear term or rate.
    Zero,
    /// Finer than [`MAX_MICROSTEPS_PER_MM`], or the travel in microsteps overflows the
    /// exact integer arithmetic.
    Range,
}

impl StepperConfig {
    /// Microsteps per nm as the exact fraction `(N, D)`.
    fn ratio(&self) -> (i64, i64) {
        let n = i64::from(self.full_steps_per_rev)
            * i64::from(self.microsteps_per_step)
            * i64::from(self.gear_motor_revs);
        let d = i64::from(self.lead_screw_pitch_nm) * i64::from(self.gear_screw_revs);
        (n, d)
    }

    fn check(&self) -> Result<(), StepperConfigError> {
        let (n, d) = self.ratio();
        if n == 0 || d == 0 || self.max_microsteps_per_cycle == 0 || self.travel_limit_nm == 0 {
            return Err(StepperConfigError::Zero);
        }
        if n.checked_mul(NM_PER_MM_I64)
            .is_none_or(|v| v / d > MAX_MICROSTEPS_PER_MM)
        {
            return Err(StepperConfigError::Range);
        }
        // travel * N, and the issued microsteps (plus one cycle's) times D, must fit i64.
        let travel = i64::from(self.travel_limit_nm);
        let max_usteps = travel
            .checked_mul(n)
            .map(|v| v / d + 1 + i64::from(self.max_microsteps_per_cycle))
            .ok_or(StepperConfigError::Range)?;
        max_usteps
            .checked_mul(d)
            .and_then(|v| v.checked_mul(2))
            .ok_or(StepperConfigError::Range)?;
        Ok(())
    }

    /// Microsteps per millimetre of stroke (f64, for display and tests).
    pub fn microsteps_per_mm(&self) -> f64 {
        let (n, d) = self.ratio();
        n as f64 * NM_PER_MM / d as f64
    }
}

/// The pins and pulse generator of one leg's drive.
pub struct StepperLeg<P, DIR, EN, FLT> {
    /// Step-pulse generator.
    pub pulses: P,
    /// Direction output.
    pub dir: DIR,
    /// Enable output.
    pub enable: EN,
    /// Fault input.
    pub fault: FLT,
}

/// The legs handed back with a refused configuration.
pub type RefusedLegs<P, DIR, EN, FLT> = (StepperConfigError, [StepperLeg<P, DIR, EN, FLT>; LEGS]);

/// Six step/direction drives ([`SliderDrives`], [`IssuedStrokes`]).
pub struct StepDirDrives<P, DIR, EN, FLT> {
    legs: [StepperLeg<P, DIR, EN, FLT>; LEGS],
    cfg: StepperConfig,
    /// Microsteps per nm: numerator and denominator.
    n: i64,
    d: i64,
    /// Issued absolute position (microsteps, 0 at zero stroke).
    issued: [i64; LEGS],
    /// Direction of each leg's last train: +1, -1, or 0 (none yet).
    last_dir: [i8; LEGS],
    aligned: bool,
    enabled: bool,
    inhibit_negative: u8,
    inhibit_positive: u8,
}

impl<P, DIR, EN, FLT> StepDirDrives<P, DIR, EN, FLT>
where
    P: StepPulses,
    DIR: OutputPin,
    EN: OutputPin,
    FLT: InputPin,
{
    /// Takes the six drives: energises them (enable active) and sets every direction
    /// pin to "positive". Motion is refused until [`IssuedStrokes::align_issued_mm`].
    /// A pin that cannot be driven is the leg's [`DriveError`]; a bad configuration is
    /// refused before any pin is touched.
    pub fn new(
        legs: [StepperLeg<P, DIR, EN, FLT>; LEGS],
        cfg: StepperConfig,
    ) -> Result<Self, RefusedLegs<P, DIR, EN, FLT>> {
        if let Err(e) = cfg.check() {
            return Err((e, legs));
        }
        let (n, d) = cfg.ratio();
        let mut s = Self {
            legs,
            cfg,
            n,
            d,
            issued: [0; LEGS],
            last_dir: [0; LEGS],
            aligned: false,
            enabled: false,
            inhibit_negative: 0,
            inhibit_positive: 0,
        };
        let positive = cfg.polarity.dir_high_is_positive;
        for leg in s.legs.iter_mut() {
            // Best effort here; a failing pin shows as that leg's fault when used.
            let _ = set_level(&mut leg.dir, positive);
        }
        let _ = s.enable();
        Ok(s)
    }

    /// The configuration in use.
    pub fn config(&self) -> &StepperConfig {
        &self.cfg
    }

    /// Energises every drive. The first leg whose enable pin fails is the error.
    pub fn enable(&mut self) -> Result<(), DriveError> {
        let level = self.cfg.polarity.enable_active_high;
        let mut first = Ok(());
        for (i, leg) in self.legs.iter_mut().enumerate() {
            if set_level(&mut leg.enable, level).is_err() && first.is_ok() {
                first = Err(DriveError::DriveFault { leg: i as u8 });
            }
        }
        self.enabled = first.is_ok();
        first
    }

    /// De-energises every drive (safe mode): stops all pulses. The sliders may then move
    /// unseen (a de-energised stepper holds nothing), so the issued position must be
    /// aligned again before the next motion.
    pub fn disable(&mut self) -> Result<(), DriveError> {
        self.hold();
        self.enabled = false;
        self.aligned = false;
        let level = !self.cfg.polarity.enable_active_high;
        let mut first = Ok(());
        for (i, leg) in self.legs.iter_mut().enumerate() {
            if set_level(&mut leg.enable, level).is_err() && first.is_ok() {
                first = Err(DriveError::DriveFault { leg: i as u8 });
            }
        }
        first
    }

    /// Blocks motion towards smaller (`negative_legs`) and larger (`positive_legs`)
    /// strokes, per leg (bit i = leg i+1), until changed; a running train in a newly
    /// blocked direction is stopped now. Pass the end-of-travel switches of this cycle
    /// (`TravelSwitches::blocked_negative`/`blocked_positive`).
    pub fn inhibit(&mut self, negative_legs: u8, positive_legs: u8) {
        self.inhibit_negative = negative_legs;
        self.inhibit_positive = positive_legs;
        for i in 0..LEGS {
            let bit = 1u8 << i;
            let dir = self.last_dir.get(i).copied().unwrap_or(0);
            if (dir < 0 && negative_legs & bit != 0) || (dir > 0 && positive_legs & bit != 0) {
                self.reclaim(i);
            }
        }
    }

    /// Issued position of every leg (microsteps from zero stroke).
    pub fn issued_microsteps(&self) -> [i64; LEGS] {
        self.issued
    }

    /// The microstep nearest to a stroke (mm), clamped to the travel limit; `None` if
    /// not finite (or the ratio's denominator is not positive, which construction refuses). Exact: the f32 is `m * 2^e` with an integer `m`, so the microsteps are
    /// the integer ratio `m * 10^6 * N / (D * 2^-e)`, rounded once (ties away from zero).
    fn microsteps_of_mm(&self, stroke_mm: f32) -> Option<i64> {
        if !stroke_mm.is_finite() {
            return None;
        }
        let limit_nm = i64::from(self.cfg.travel_limit_nm);
        if stroke_mm.abs() >= limit_nm as f32 / NM_PER_MM_F32 {
            let u = round_div(limit_nm.saturating_mul(self.n), self.d);
            return Some(if stroke_mm < 0.0 { -u } else { u });
        }
        let bits = stroke_mm.to_bits();
        let biased_exp = ((bits >> F32_MANTISSA_BITS) & 0xFF) as i32;
        let exp = biased_exp - F32_EXP_BIAS;
        if biased_exp == 0 || exp < MIN_EXACT_EXP {
            // |stroke| < 2^-40 mm: below half a microstep at any accepted ratio.
            return Some(0);
        }
        let mut m = i128::from((bits & F32_MANTISSA_MASK) | F32_IMPLICIT_BIT);
        if stroke_mm < 0.0 {
            m = -m;
        }
        let mut num = m * i128::from(NM_PER_MM_I64) * i128::from(self.n);
        let mut den = i128::from(self.d);
        if exp >= 0 {
            num <<= exp; // not reached: |stroke| < travel limit < 2^23 mm
        } else {
            den <<= -exp;
        }
        let half = den / 2;
        // Checked: `den` > 0 (the ratio is validated at construction), and the flight
        // image keeps no division panic.
        let q = if num >= 0 {
            (num + half).checked_div(den)?
        } else {
            -(-num + half).checked_div(den)?
        };
        Some(q as i64)
    }

    /// Stops leg `i`'s train and takes its unsent pulses off the issued position.
    fn reclaim(&mut self, i: usize) {
        let (Some(leg), Some(issued), Some(dir)) = (
            self.legs.get_mut(i),
            self.issued.get_mut(i),
            self.last_dir.get(i),
        ) else {
            return;
        };
        let unsent = i64::from(leg.pulses.stop());
        *issued -= i64::from(*dir) * unsent;
    }

    /// The first leg whose fault input is active (or unreadable).
    fn first_fault(&mut self) -> Option<u8> {
        let active = self.cfg.polarity.fault_active_high;
        let mut first = None;
        for (i, leg) in self.legs.iter_mut().enumerate() {
            let faulted = match leg.fault.is_high() {
                Ok(high) => high == active,
                Err(_) => true,
            };
            if faulted && first.is_none() {
                first = Some(i as u8);
            }
        }
        first
    }
}

/// Drives an output to a level.
fn set_level<O: OutputPin>(pin: &mut O, high: bool) -> Result<(), O::Error> {
    if high {
        pin.set_high()
    } else {
        pin.set_low()
    }
}

impl<P, DIR, EN, FLT> SliderDrives for StepDirDrives<P, DIR, EN, FLT>
where
    P: StepPulses,
    DIR: OutputPin,
    EN: OutputPin,
    FLT: InputPin,
{
    fn command_strokes_mm(&mut self, setpoint_mm: &[f32; LEGS]) -> Result<(), DriveError> {
        if let Some(leg) = self.first_fault() {
            self.hold();
            return Err(DriveError::DriveFault { leg });
        }
        if !self.enabled || !self.aligned {
            self.hold();
            return Err(DriveError::DriveFault { leg: EVERY_LEG });
        }
        let max = i64::from(self.cfg.max_microsteps_per_cycle);
        let positive_level = self.cfg.polarity.dir_high_is_positive;
        let mut first_err = Ok(());
        for (i, sp) in setpoint_mm.iter().enumerate() {
            self.reclaim(i);
            let Some(target) = self.microsteps_of_mm(*sp) else {
                continue; // not finite: this leg holds
            };
            let bit = 1u8 << i;
            let (Some(leg), Some(issued), Some(last_dir)) = (
                self.legs.get_mut(i),
                self.issued.get_mut(i),
                self.last_dir.get_mut(i),
            ) else {
                continue;
            };
            let mut delta = (target - *issued).clamp(-max, max);
            if (delta < 0 && self.inhibit_negative & bit != 0)
                || (delta > 0 && self.inhibit_positive & bit != 0)
            {
                delta = 0;
            }
            if delta == 0 {
                continue;
            }
            let dir: i8 = if delta > 0 { 1 } else { -1 };
            let started = set_level(&mut leg.dir, (dir > 0) == positive_level).is_ok()
                && leg.pulses.start(delta.unsigned_abs() as u32).is_ok();
            if started {
                *issued += delta;
                *last_dir = dir;
            } else if first_err.is_ok() {
                first_err = Err(DriveError::DriveFault { leg: i as u8 });
            }
        }
        first_err
    }

    fn hold(&mut self) {
        for i in 0..LEGS {
            self.reclaim(i);
        }
    }

    /// A stepper holds where its issued steps put it.
    fn setpoints_mm(&mut self) -> [f32; LEGS] {
        self.issued_strokes_mm()
    }

    fn status(&mut self) -> Result<(), DriveError> {
        match self.first_fault() {
            Some(leg) => Err(DriveError::DriveFault { leg }),
            None => Ok(()),
        }
    }
}

impl<P, DIR, EN, FLT> IssuedStrokes for StepDirDrives<P, DIR, EN, FLT>
where
    P: StepPulses,
    DIR: OutputPin,
    EN: OutputPin,
    FLT: InputPin,
{
    fn issued_strokes_mm(&self) -> [f32; LEGS] {
        // Exact nm (|nm| < 2^24 over any slider travel), then one correctly rounded
        // division: within half an f32 ulp of the issued stroke.
        self.issued
            .map(|u| round_div(u.saturating_mul(self.d), self.n) as f32 / NM_PER_MM_F32)
    }

    fn align_issued_mm(&mut self, measured_mm: &[f32; LEGS]) {
        self.hold();
        let mut all = true;
        for (i, m) in measured_mm.iter().enumerate() {
            match (self.microsteps_of_mm(*m), self.issued.get_mut(i)) {
                (Some(u), Some(issued)) => *issued = u,
                _ => all = false,
            }
        }
        // A non-finite reading leaves the drives unaligned (refusing motion).
        self.aligned = all && self.enabled;
    }
}
